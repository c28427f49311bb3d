/* The file's trajectory (T0, STEPS, default parameters and q0) on the
   emulated Cortex-M4F, each value of each row written as the 16 hex digits
   of its bits as a double, a line each; exit status: 0, the solver's
   status, or 99 when fewer rows than asked were solved.
   -DSOLVER_H="<name>_solver.h" -DP=<name> -DPU=<NAME>; -DINSTANTS=N solves
   the first N instants only, -DQUIET writes nothing (benchmarks' cortex_m4
   case counts the instructions of runs of two lengths). */
#include <stdint.h>
#include <string.h>

#include SOLVER_H

#define CAT_(a, b) a##b
#define CAT(a, b) CAT_(a, b)
#define FN(x) CAT(P, x)
#define M(x) CAT(PU, x)
typedef FN(_real) real;

#ifndef INSTANTS
#define INSTANTS M(_STEPS)
#endif

void out_text(const char *s);

static real work[M(_WORK)], state[M(_STATE)], rows[INSTANTS * M(_ROW)];
static int iwork[M(_IWORK)];

static void out_bits(double v)
{
    uint64_t b;
    char line[18];
    int k;
    memcpy(&b, &v, sizeof b);
    for (k = 0; k < 16; ++k) line[k] = "0123456789abcdef"[(b >> (60 - 4 * k)) & 15u];
    line[16] = '\n';
    line[17] = '\0';
    out_text(line);
}

int main(void)
{
    long solved = 0, k;
    int status;
    real h = (M(_T1) - M(_T0)) / (real)(M(_STEPS) - 1);
    memcpy(state, FN(_default_q0), sizeof(real) * M(_NG));
    status = FN(_trajectory)((real)M(_T0), h, INSTANTS, FN(_default_params), (real)M(_TOL), state, rows, &solved,
                             work, iwork);
#ifndef QUIET
    for (k = 0; k < solved * M(_ROW); ++k) out_bits((double)rows[k]);
#else
    (void)k;
    (void)out_bits;
#endif
    return status != M(_OK) ? status : (solved == INSTANTS ? 0 : 99);
}
