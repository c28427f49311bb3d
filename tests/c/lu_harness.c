/* The generated sparse LU alone, on a matrix read from stdin: built by
   tests/codegen/test_codegen.py with lu.c, templates/c/sparse_lu.j2 rendered
   for T_CASES random plans, each with its own prefix (t0, t1, ...), and
   tables of their sizes and entry points. Runs case argv[1]: reads its
   pattern's NNZ values, then b (N values); prints "fallback" where a fixed
   pivot fails its test, else x with A x = b and z with A^T z = b, one value
   a line, to 17 digits. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lu.c"

int main(int argc, char **argv)
{
    static double lu[T_LU_SIZE], b[T_N], x[T_N], y[T_N], z[T_N];
    int c, k;
    if (argc != 2) return 2;
    c = atoi(argv[1]);
    if (c < 0 || c >= T_CASES) return 2;
    for (k = 0; k < t_nnz[c]; ++k)
        if (scanf("%lf", &lu[k]) != 1) return 2;
    for (k = 0; k < t_n[c]; ++k)
        if (scanf("%lf", &b[k]) != 1) return 2;
    if (t_factor[c](lu)) {
        printf("fallback\n");
        return 0;
    }
    t_solve[c](lu, b, x, y);
    t_solve_t[c](lu, b, z);
    for (k = 0; k < t_n[c]; ++k) printf("%.17g\n", x[k]);
    for (k = 0; k < t_n[c]; ++k) printf("%.17g\n", z[k]);
    return 0;
}
