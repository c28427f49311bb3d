/* Calling a symid-generated C solver: the bundled slider-crank, one crank
   revolution in 11 instants, printing the motor torque.
   Build: make -C <generated folder>, then
   cc -std=c99 -I<folder> main.c <folder>/libslider_crank_solver.a -lm */
#include <stdio.h>

#include "slider_crank_solver.h"

int main(void)
{
    static double work[SLIDER_CRANK_WORK], rows[11 * SLIDER_CRANK_ROW];
    static int iwork[SLIDER_CRANK_IWORK];
    double state[SLIDER_CRANK_STATE] = {0.0};
    const double q0[SLIDER_CRANK_NG] = {0.05, 0.0, 0.0, 0.25, 0.0, 0.0, 0.4, 0.0, 0.0};
    long solved = 0, k;
    int status, i;

    for (i = 0; i < SLIDER_CRANK_NG; ++i) state[SLIDER_CRANK_STATE_Q + i] = q0[i]; /* guess; count 0 */
    status = slider_crank_trajectory(0.0, 0.02, 11, slider_crank_default_params, 1e-12, state, rows, &solved,
                                     work, iwork);
    for (k = 0; k < solved; ++k) /* t is the first value of a row, motor.T_j the last */
        printf("%.17g %.17g\n", rows[k * SLIDER_CRANK_ROW], rows[k * SLIDER_CRANK_ROW + SLIDER_CRANK_ROW - 1]);
    return status == SLIDER_CRANK_OK ? 0 : 1;
}
