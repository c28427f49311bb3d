/* Driver of tests/c/test_c_edges.py, compiled with one generated solver
   (-DSOLVER_H="<name>_solver.h" -DP=<name> -DPU=<NAME>, and any of the
   header's overrides): "t tol q0..." solves one instant with the default
   parameters from the guess q0, then, for each further "t tol" group
   after a "--", another instant from the q the previous call left (so a
   failed call's q is what the next one starts from). Per call it prints a
   line: status, info[0], info[1], then q (%.17g). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include SOLVER_H

#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#define FN(x) CAT(P, x)
#define M(x) CAT(PU, x)
typedef FN(_real) real;

static real work[M(_WORK)];
static int iwork[M(_IWORK)];

static void one(real t, real tol, real *q)
{
    int info[2] = {-1, -1}, k;
    const int status = FN(_instant)(t, FN(_default_params), tol, q, NULL, NULL, NULL, NULL, info, work, iwork);
    printf("%d %d %d", status, info[0], info[1]);
    for (k = 0; k < M(_NG); ++k) printf(" %.17g", (double)q[k]);
    printf("\n");
}

int main(int argc, char **argv)
{
    real q[M(_NG)];
    int k, a;
    if (argc < 3 + M(_NG)) {
        fprintf(stderr, "usage: %s t tol q0... [-- t tol]...\n", argv[0]);
        return 2;
    }
    for (k = 0; k < M(_NG); ++k) q[k] = (real)strtod(argv[3 + k], NULL);
    one((real)strtod(argv[1], NULL), (real)strtod(argv[2], NULL), q);
    for (a = 3 + M(_NG); a + 2 < argc && strcmp(argv[a], "--") == 0; a += 3)
        one((real)strtod(argv[a + 1], NULL), (real)strtod(argv[a + 2], NULL), q);
    return 0;
}
