/* The predictor sweep's compiled driver: symid's generated `<name>_instant`
 * (Newton, qdot, qddot, lambda, reactions) called in a C loop with a
 * predictor of order 0, 1 or 2, timed inside C.
 * Build: gcc -O2 -fPIC -shared -DP=<name> -DPU=<NAME> -I<solver folder>
 *        <name>_solver.c predictor_loop.c -o loop.so -lm   (benchmarks/sweep.py) */
#define _POSIX_C_SOURCE 199309L
#include <string.h>
#include <time.h>

#define CAT(a, b) a##b
#define XCAT(a, b) CAT(a, b)
#define STR(a) #a
#define XSTR(a) STR(a)
#define HEADER XSTR(XCAT(P, _solver.h))
#include HEADER

#define NG XCAT(PU, _NG)
#define NC XCAT(PU, _NC)
#define NR XCAT(PU, _NR)
#define WORK XCAT(PU, _WORK)
#define IWORK XCAT(PU, _IWORK)
#define INSTANT XCAT(P, _instant)

static double work[WORK], q[NG], qd[NG], qdd[NG], qn[NG], qdn[NG], qddn[NG], lam[NC + 1], reac[NR + 1];
static double m1[NG], m2[NG], m3[NG]; /* the three accelerations before qdd */
static int iwork[IWORK + 1];

/* n instants t0 + k h from q0; iterations[k] = Newton iterations, torque[k] =
 * reactions[index]. *ns = nanoseconds of the loop. Returns instants solved.
 * Order 5 is the generated trajectory's predictor (Taylor to h^5, the
 * derivatives past qdd from the cubic through the last four accelerations;
 * order 2 until they exist). */
long predictor_loop(double t0, double h, long n, int order, double tol, const double *p, const double *q0,
                    int index, double *torque, int *iterations, double *ns)
{
    struct timespec a, b;
    long k, solved = 0;
    int i, info[2];
    memcpy(q, q0, sizeof(q));
    memset(qd, 0, sizeof(qd));
    memset(qdd, 0, sizeof(qdd));
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (k = 0; k < n; ++k) {
        const double t = t0 + (double)k * h;
        for (i = 0; i < NG; ++i)
            qn[i] = (k == 0 || order == 0) ? q[i]
                  : order == 1 ? q[i] + h * qd[i]
                  : order == 2 || k < 4 ? q[i] + h * qd[i] + 0.5 * h * h * qdd[i]
                  : q[i] + h * (qd[i] + h * (323.0 * qdd[i] - 264.0 * m1[i] + 159.0 * m2[i] - 38.0 * m3[i]) / 360.0);
        if (INSTANT(t, p, tol, qn, qdn, qddn, lam, reac, info, work, iwork) != 0) break;
        memcpy(q, qn, sizeof(q));
        memcpy(m3, m2, sizeof(m3));
        memcpy(m2, m1, sizeof(m2));
        memcpy(m1, qdd, sizeof(m1));
        memcpy(qd, qdn, sizeof(qd));
        memcpy(qdd, qddn, sizeof(qdd));
        iterations[k] = info[0];
        torque[k] = reac[index];
        solved = k + 1;
    }
    clock_gettime(CLOCK_MONOTONIC, &b);
    *ns = (double)(b.tv_sec - a.tv_sec) * 1e9 + (double)(b.tv_nsec - a.tv_nsec);
    return solved;
}
