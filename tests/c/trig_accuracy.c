/* The generated solver's sines and cosines against long double sinl/cosl.
   Built by tests/codegen/test_codegen.py with the slider-crank's solver included
   (its static functions are the ones under test). Prints four figures:
   values that should be libm's and are not; configurations that moved
   farther than the rotation radius (libm again); and the worst absolute
   error, in units of 2^-53, of rotated values and of first-order steps. */
#include <math.h>
#include <stdio.h>

#include "slider_crank_solver.c"

#define NB (SLIDER_CRANK_NG / 3)

static unsigned long long state = 88172645463325252ULL;

/* xorshift64: a reproducible uniform in [lo, hi) */
static double uniform(double lo, double hi)
{
    state ^= state << 13;
    state ^= state >> 7;
    state ^= state << 17;
    return lo + (hi - lo) * (double)(state >> 11) * 0x1p-53;
}

static double error(double got, long double exact)
{
    return (double)(fabsl((long double)got - exact) / 0x1p-53L);
}

static double worst(const double *q, const double *tr, double w)
{
    int b;
    for (b = 0; b < NB; ++b) {
        w = fmax(w, error(tr[2 * b], sinl((long double)q[3 * b + 2])));
        w = fmax(w, error(tr[2 * b + 1], cosl((long double)q[3 * b + 2])));
    }
    return w;
}

static long not_libm(const double *q, const double *tr)
{
    long n = 0;
    int b;
    for (b = 0; b < NB; ++b) n += tr[2 * b] != sin(q[3 * b + 2]) || tr[2 * b + 1] != cos(q[3 * b + 2]);
    return n;
}

int main(void)
{
    double q[SLIDER_CRANK_NG] = {0.0}, dq[SLIDER_CRANK_NG] = {0.0}, tr[2 * NB], base[3 * NB];
    double rotated = 0.0, stepped = 0.0;
    long k, wrong = 0, far = 0;
    int b;
    for (k = 0; k < 200000; ++k) {
        /* angles up to 1e3 rad, moved by up to 0.07 rad, then corrected by up to 1e-9 */
        const double a = uniform(-1e3, 1e3), d = uniform(-0.07, 0.07), e = uniform(-1e-9, 1e-9);
        for (b = 0; b < NB; ++b) {
            base[3 * b] = NAN;
            q[3 * b + 2] = a + b;
        }
        slider_crank_trig_near(q, tr, base);
        wrong += not_libm(q, tr);
        for (b = 0; b < NB; ++b) q[3 * b + 2] += d;
        slider_crank_trig_near(q, tr, base);
        if (fabs(d) > 0.0625) {
            ++far;
            wrong += not_libm(q, tr);
            continue;
        }
        rotated = worst(q, tr, rotated);
        for (b = 0; b < NB; ++b) dq[3 * b + 2] = e * (b + 1);
        slider_crank_correct(q, dq);
        slider_crank_trig_step(q, dq, tr, base);
        stepped = worst(q, tr, stepped);
    }
    printf("%ld %ld %.4f %.4f\n", wrong, far, rotated, stepped);
    return 0;
}
