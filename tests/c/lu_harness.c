/* The generated sparse LU alone, on a matrix read from stdin: built by
   tests/codegen/test_codegen.py with lu.c, templates/c/sparse_lu.j2 rendered for a
   random plan with the prefix t. Reads the pattern's NNZ values, then b (N
   values); prints "fallback" where a fixed pivot fails its test, else x with
   A x = b and z with A^T z = b, one value a line, to 17 digits. */
#include <math.h>
#include <stdio.h>
#include <string.h>

typedef double t_real;

#include "lu.c"

int main(void)
{
    static double lu[T_LU_SIZE], b[T_N], x[T_N], y[T_N], z[T_N];
    int k;
    for (k = 0; k < T_NNZ; ++k)
        if (scanf("%lf", &lu[k]) != 1) return 2;
    for (k = 0; k < T_N; ++k)
        if (scanf("%lf", &b[k]) != 1) return 2;
    if (t_sparse_factor(lu)) {
        printf("fallback\n");
        return 0;
    }
    t_sparse_solve(lu, b, x, y);
    t_sparse_solve_t(lu, b, z);
    for (k = 0; k < T_N; ++k) printf("%.17g\n", x[k]);
    for (k = 0; k < T_N; ++k) printf("%.17g\n", z[k]);
    return 0;
}
