/* Driver of tests/c/test_c_embedded.py and benchmarks/embedded.py, compiled with one generated solver
   (-DSOLVER_H="<name>_solver.h" -DP=<name> -DPU=<NAME>): "rows t0 h n q0..."
   prints a trajectory's rows (%.17g); "time t0 h n q0..." prints the
   microseconds per instant of the trajectory loop and of instants continued
   from the last solution (the minimum over repeats: the machine is shared);
   "describe" prints what the header says of the mechanism, a line each;
   "sweep t0 h n K" runs K variants through <name>_sweep (benchmarks/cases/c_level.py). */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
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

static real work[M(_WORK)], state[M(_STATE)];
static int iwork[M(_IWORK)];

static int run(real t0, real h, long n, const real *q0, real *rows)
{
    long solved = 0;
    int status;
    memset(state, 0, sizeof state);
    memcpy(state, q0, sizeof(real) * M(_NG));
    status = FN(_trajectory)(t0, h, n, FN(_default_params), (real)1e-12, state, rows, &solved, work, iwork);
    return status != M(_OK) ? status : (solved == n ? 0 : 99);
}

/* K variants through the sweep, variant v the default parameters each scaled by
   1 + 1e-6 v: the microseconds per variant-instant (the least of 5 rounds) and the
   lanes a group takes, then per variant its status, instants solved and figures. */
static int run_sweep(real t0, real h, long n, long k)
{
    real *p = (real *)malloc(sizeof(real) * (size_t)(k * M(_NP) + 1));
    real *figures = (real *)malloc(sizeof(real) * (size_t)(k * M(_SWEEP_FIGURES) + 1));
    real *t_end = (real *)malloc(sizeof(real) * (size_t)k);
    real *sweep_work = (real *)malloc(sizeof(real) * (size_t)M(_SWEEP_WORK));
    long *solved = (long *)malloc(sizeof(long) * (size_t)k), v, j;
    int *status = (int *)malloc(sizeof(int) * (size_t)k), rep, failed = 0;
    double best = 1e300;
    if (p == NULL || figures == NULL || t_end == NULL || sweep_work == NULL || solved == NULL || status == NULL) return 2;
    for (v = 0; v < k; ++v)
        for (j = 0; j < M(_NP); ++j) p[v * M(_NP) + j] = FN(_default_params)[j] * (real)(1.0 + 1e-6 * (double)v);
    for (rep = 0; rep < 5 && !failed; ++rep) {
        double start = now(), took;
        failed = FN(_sweep)(k, p, t0, h, n, (real)1e-12, figures, status, t_end, solved, sweep_work, iwork) != M(_OK);
        took = (now() - start) / ((double)k * (double)n);
        best = took < best ? took : best;
    }
    if (!failed) {
        printf("%.4f %ld\n", 1e6 * best, FN(_sweep_lanes)(NULL));
        for (v = 0; v < k; ++v) {
            printf("%d %ld", status[v], solved[v]);
            for (j = 0; j < M(_SWEEP_FIGURES); ++j) printf(" %.17g", (double)figures[v * M(_SWEEP_FIGURES) + j]);
            printf("\n");
        }
    }
    free(p), free(figures), free(t_end), free(sweep_work), free(solved), free(status);
    return failed;
}

int main(int argc, char **argv)
{
    real q0[M(_NG)], t0, h, *rows;
    long n, k, i;
    int status;
    if (argc == 2 && strcmp(argv[1], "describe") == 0) {
        for (k = 0; k < M(_ROW); ++k) printf("%s%c", FN(_row_names)[k], k + 1 == M(_ROW) ? '\n' : ' ');
        for (k = 0; k < M(_NP); ++k) printf("%s%c", FN(_param_names)[k], k + 1 == M(_NP) ? '\n' : ' ');
        for (k = 0; k < M(_NG); ++k) printf("%.17g%c", (double)FN(_default_q0)[k], k + 1 == M(_NG) ? '\n' : ' ');
        printf("%.17g %.17g %ld %.17g %d\n", (double)M(_T0), (double)M(_T1), (long)M(_STEPS), (double)M(_TOL),
               M(_OPS_INSTANT));
        return 0;
    }
    if (argc == 6 && strcmp(argv[1], "sweep") == 0)
        return run_sweep((real)atof(argv[2]), (real)atof(argv[3]), atol(argv[4]), atol(argv[5]));
    if (argc != 5 + M(_NG)) return 2;
    t0 = (real)atof(argv[2]);
    h = (real)atof(argv[3]);
    n = atol(argv[4]);
    for (k = 0; k < M(_NG); ++k) q0[k] = (real)atof(argv[5 + k]);
    rows = (real *)malloc(sizeof(real) * (size_t)(n * M(_ROW)));
    if (rows == NULL) return 2;
    if ((status = run(t0, h, n, q0, rows)) != 0) {
        fprintf(stderr, "status %d\n", status);
        return 1;
    }
    if (strcmp(argv[1], "rows") == 0) {
        for (i = 0; i < n; ++i)
            for (k = 0; k < M(_ROW); ++k)
                printf("%.17g%c", (double)rows[i * M(_ROW) + k], k + 1 == M(_ROW) ? '\n' : ' ');
    } else {
        double best_run = 1e300, best_instant = 1e300;
        int rep;
        real q[M(_NG)];
        for (rep = 0; rep < 7; ++rep) {
            double start = now();
            int r;
            for (r = 0; r < 5; ++r) run(t0, h, n, q0, rows);
            best_run = best_run < (now() - start) / (5.0 * (double)n) ? best_run : (now() - start) / (5.0 * (double)n);
            start = now();
            for (r = 0; r < 5; ++r)
                for (memcpy(q, q0, sizeof q), i = 0; i < n; ++i)
                    if (FN(_instant)(t0 + (real)i * h, FN(_default_params), (real)1e-12, q, NULL, NULL, NULL, NULL, NULL,
                                     work, iwork) != M(_OK)) return 1;
            best_instant = best_instant < (now() - start) / (5.0 * (double)n) ? best_instant
                                                                               : (now() - start) / (5.0 * (double)n);
        }
        printf("%.4f %.4f\n", 1e6 * best_run, 1e6 * best_instant);
    }
    return 0;
}
