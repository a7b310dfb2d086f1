/* The backward pass of the two-filter smoother of a bank of mode-matched filters: backward
 * information messages, log-linear pooling (Helmick, Blair & Hoffman 1995). The documentation
 * of the equations is at the top of two_filter.c and at each function there (and in the module
 * docstring of switchest.estimators.two_filter); here: the prototype and the shapes.
 *
 * Sizes first (se_int, the extents of the arrays: n states, m outputs, l inputs, L modes, then
 * the trial axis N, samples K, the trial axis T and the sample axis TK of trans, the trial axis
 * Ns of the mode-matched outputs); then the
 * arrays and scalars in the order of the prototype (the binding's two_filter_backward,
 * engine/_backward.pyx, keeps it). Booleans are int, boolean arrays uint8_t, index arrays
 * se_int.
 */
#ifndef SE_TWO_FILTER_H
#define SE_TWO_FILTER_H

#include <stdint.h>

#include "se_common.h"

/* The backward recursion over every trial, in blocks of `lanes` trials (two_filter.c).
 *
 * Read: x_f (N, K, L, n), P_f (N, K, L, n, n), log_prob_f (N, K, L) (the forward filter's
 * mode-matched posteriors and log mode probabilities after each sample's update), y (N, K, m)
 * (NaN: a missing component), u (N, K, l), outlier (N, K) uint8 (samples the filter rejected:
 * missing), F (M, n, n), G (M, n, l), Qd (M, n, n), trans (T, TK, L) with T = N or 1 (indices
 * into the table, checked), log_transition (L, L), C (L, m, n), R (L, m, m).
 * Written: x_s (Ns, K, L, n), P_s (Ns, K, L, n, n) with Ns = N (Ns = 0: not written),
 * prob_s (N, K, L); the combined moments of the
 * smoothed mixture x_c (N, K, n), P_c (N, K, n, n) and its most probable mode mode_c (N, K)
 * (se_combine); report (2,) (no covariance is repaired: {0, inf}).
 * Returns SE_OK; SE_NOT_FINITE at the first block and sample whose smoothed posterior or mode
 * probabilities are not finite (the outputs are then incomplete); SE_NOT_POSITIVE_DEFINITE if
 * an observed part of some R_l fails its Cholesky factorization; SE_NO_MEMORY. */
/* the parameter list, written once for the prototype and the definition (two_filter.c) */
#define SE_TWO_FILTER_PARAMETERS                                                                  \
    se_int n, se_int m, se_int l, se_int L, se_int N, se_int K, se_int T, se_int TK, se_int Ns,   \
    const double *restrict x_f, const double *restrict P_f, const double *restrict log_prob_f,    \
    const double *restrict y, const double *restrict u, const uint8_t *restrict outlier,          \
    const double *restrict F, const double *restrict G, const double *restrict Qd,                \
    const se_int *restrict trans, const double *restrict log_transition,                          \
    const double *restrict C, const double *restrict R, se_int lanes, int sample_timing,          \
    double *restrict x_s, double *restrict P_s, double *restrict prob_s,                         \
    double *restrict x_c, double *restrict P_c, se_int *restrict mode_c, double *restrict report
se_int se_two_filter_backward(SE_TWO_FILTER_PARAMETERS);

#endif
