/* Driver of benchmarks/cases/c_level.py: the study build's <name>_sweep over K variants.
   Build: cc -std=c99 -O<level> -I<solver folder> -DSOLVER_H="<name>_solver.h" -DP=<name> -DPU=<NAME>
          sweep_driver.c <name>_solver.c -lm
   Run: driver K t0 h n  -> first line: microseconds per variant-instant (the least of 5
   rounds: the machine is shared) and the lanes a group takes; then each variant's
   status, instants solved and figures (%.17g). Variant v runs the default parameters
   with each one scaled by 1 + 1e-6 v (distinct variants, all near the file's). */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include SOLVER_H

#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#define FN(x) CAT(P, x)
#define M(x) CAT(PU, x)
typedef FN(_real) real;

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    long k, n, v, j, solved_total = 0, *solved;
    real t0, h, *p, *figures, *t_end, *work;
    int *status, *iwork, rep;
    double best = 1e300;
    if (argc != 5) return 2;
    k = atol(argv[1]);
    t0 = (real)atof(argv[2]);
    h = (real)atof(argv[3]);
    n = atol(argv[4]);
    p = malloc(sizeof(real) * (size_t)(k * M(_NP) + 1));
    figures = malloc(sizeof(real) * (size_t)(k * M(_SWEEP_FIGURES)));
    t_end = malloc(sizeof(real) * (size_t)k);
    solved = malloc(sizeof(long) * (size_t)k);
    status = malloc(sizeof(int) * (size_t)k);
    work = malloc(sizeof(real) * (size_t)M(_SWEEP_WORK));
    iwork = malloc(sizeof(int) * (size_t)(M(_IWORK) + 1));
    if (!p || !figures || !t_end || !solved || !status || !work || !iwork) return 2;
    for (v = 0; v < k; ++v)
        for (j = 0; j < M(_NP); ++j) p[v * M(_NP) + j] = FN(_default_params)[j] * (real)(1.0 + 1e-6 * (double)v);
    for (rep = 0; rep < 5; ++rep) {
        double start = now(), took;
        if (FN(_sweep)(k, p, t0, h, n, (real)1e-12, figures, status, t_end, solved, work, iwork) != M(_OK)) return 1;
        took = (now() - start) / ((double)k * (double)n);
        best = took < best ? took : best;
    }
    printf("%.4f %ld\n", 1e6 * best, FN(_sweep_lanes)(NULL));
    for (v = 0; v < k; ++v) {
        solved_total += solved[v];
        printf("%d %ld", status[v], solved[v]);
        for (j = 0; j < M(_SWEEP_FIGURES); ++j) printf(" %.17g", (double)figures[v * M(_SWEEP_FIGURES) + j]);
        printf("\n");
    }
    return solved_total == k * n ? 0 : 3;
}
