/* The CasADi baseline's compiled form: a C loop over a CasADi-generated
 * instant Function (guess, t) -> (q, qd, qdd, lam, reac), with the same
 * 2nd-order Taylor predictor symid uses, timed inside C.
 * Build: gcc -O2 -fPIC -shared -DFN=<function name> -I<dir of casadi_fn.h>
 *        casadi_fn.c casadi_loop.c -o loop.so -lm   (benchmarks/baselines.py) */
#define _POSIX_C_SOURCE 199309L
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "casadi_fn.h"

#define CAT(a, b) a##b
#define XCAT(a, b) CAT(a, b)
#define FN_(suffix) XCAT(FN, suffix)

/* Solve n instants t_k = t0 + k h from the initial guess q0 (size ng);
 * torque[k] = reac[motor]. *ns = nanoseconds of the loop alone (allocation
 * and the function's setup are outside). Returns the instants solved. */
long bench_loop(double t0, double h, long n, int ng, int motor, const double *q0, double *torque, double *ns)
{
    casadi_int sz_arg, sz_res, sz_iw, sz_w;
    const casadi_real **arg;
    casadi_real **res, *w, *state, *q, *qd, *qdd, *guess, *lam, *reac;
    casadi_int *iw;
    struct timespec a, b;
    long k, solved = 0;
    int i, mem;

    FN_(_work)(&sz_arg, &sz_res, &sz_iw, &sz_w);
    arg = malloc(sizeof(*arg) * (size_t)(sz_arg > 5 ? sz_arg : 5));
    res = malloc(sizeof(*res) * (size_t)(sz_res > 5 ? sz_res : 5));
    iw = malloc(sizeof(*iw) * (size_t)(sz_iw + 1));
    w = malloc(sizeof(*w) * (size_t)(sz_w + 1));
    /* q, qd, qdd, guess: ng each; lam and reac: generous upper bounds */
    state = calloc((size_t)(4 * ng + 2 * (3 * ng + 3) * 4), sizeof(*state));
    q = state;
    qd = q + ng;
    qdd = qd + ng;
    guess = qdd + ng;
    lam = guess + ng;
    reac = lam + 4 * (3 * ng + 3);
    memcpy(q, q0, sizeof(*q) * (size_t)ng);
    FN_(_incref)();
    mem = FN_(_checkout)();

    clock_gettime(CLOCK_MONOTONIC, &a);
    for (k = 0; k < n; ++k) {
        const double t = t0 + (double)k * h;
        for (i = 0; i < ng; ++i)
            guess[i] = k ? q[i] + h * qd[i] + 0.5 * h * h * qdd[i] : q[i];
        arg[0] = guess;
        arg[1] = &t;
        res[0] = q;
        res[1] = qd;
        res[2] = qdd;
        res[3] = lam;
        res[4] = reac;
        if (FN(arg, res, iw, w, mem)) break;
        if (reac[motor] != reac[motor]) break; /* NaN: Newton failed */
        torque[k] = reac[motor];
        solved = k + 1;
    }
    clock_gettime(CLOCK_MONOTONIC, &b);
    *ns = (double)(b.tv_sec - a.tv_sec) * 1e9 + (double)(b.tv_nsec - a.tv_nsec);

    FN_(_release)(mem);
    FN_(_decref)();
    free(arg);
    free(res);
    free(iw);
    free(w);
    free(state);
    return solved;
}
