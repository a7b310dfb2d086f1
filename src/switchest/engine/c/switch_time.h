/* The Kalman filter with estimated switching times (Shankar et al. §III-§IV). The
 * documentation of each function (and the layout of the transition table) is at its
 * definition in switch_time.c; here: the prototypes and the shapes.
 *
 * Conventions as linalg.h: sizes first (se_int), then the arrays and scalars in the order of
 * the prototype (the binding, engine/_switch_time.pyx, keeps it); booleans int, boolean arrays
 * uint8_t, index arrays se_int, the rest double; every array C-contiguous of the shape given.
 */
#ifndef SE_SWITCH_TIME_H
#define SE_SWITCH_TIME_H

#include <stdint.h>

#include "se_common.h"

/* Switch-time Kalman filter of N trials over K samples, in blocks of `lanes` trials.
 * y (N, K, m), u (N, K, l), which (K,), mode, prev (N, K), C (L, m, n), R (L, m, m),
 * F (M, n, n), G (M, n, l), Qd (M, n, n) (M = D L (1 + L g + N1 + L (N0 + 1))), steps (D,),
 * grid_tau (D, g), n_coarse = N1, n_switch = N0 + 1, x_init (N, n), P_init (N, n, n);
 * CF (H, m, n), CG (H, m, l), CQC (H, m, m) (H = D L N1: the binding's `outputs`, from
 * switchest.engine.switch_time.coarse_outputs);
 * written: x_out (N, K, n), P_out (N, K, n, n), loglik_out, offset_out (N, K),
 * flag_out (N, K), report (2,) {repaired, smallest eigenvalue}.
 * Returns SE_OK, SE_NO_MEMORY or the failure code that stopped the kernel. */
/* the parameter list, written once for the prototype and the definition (switch_time.c) */
#define SE_SWITCH_TIME_FILTER_PARAMETERS                                                          \
    se_int n, se_int m, se_int l, se_int L, se_int N, se_int K, se_int D, se_int g,               \
    const double *restrict y, const double *restrict u, const se_int *restrict which,             \
    const se_int *restrict mode, const se_int *restrict prev, const double *restrict C,           \
    const double *restrict R, const double *restrict F, const double *restrict G,                 \
    const double *restrict Qd, const double *restrict steps, const double *restrict grid_tau,     \
    se_int n_coarse, se_int n_switch, const double *restrict x_init,                              \
    const double *restrict P_init, int predict_first, int marginal, int printed, double gate,     \
    se_int iterations, double tolerance, const double *restrict CF, const double *restrict CG,    \
    const double *restrict CQC, se_int lanes, double *restrict x_out, double *restrict P_out,     \
    double *restrict loglik_out, double *restrict offset_out, uint8_t *restrict flag_out,         \
    double *restrict report
se_int se_switch_time_filter(SE_SWITCH_TIME_FILTER_PARAMETERS);

#endif
