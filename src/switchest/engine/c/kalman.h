/* The Kalman filter along given transitions (covariances shared by the trials of a group) and
 * the fixed-gain filter. The documentation of each function is at its definition in kalman.c;
 * here: the prototypes and the shapes.
 *
 * Conventions as linalg.h: sizes first (se_int), then the arrays and scalars in the order of
 * the prototype (the binding, engine/_kalman.pyx, keeps it); booleans int, boolean arrays
 * uint8_t, index arrays se_int, the rest double; every array C-contiguous of the shape given.
 */
#ifndef SE_KALMAN_H
#define SE_KALMAN_H

#include <stdint.h>

#include "se_common.h"

#define SE_KALMAN_LANES 256 /* trials per block: a group's covariance equations serve up to this many */
#define SE_KALMAN_CHUNK 16  /* samples buffered per block before they are written out, trial by trial */

/* Kalman filter of N trials over K samples, in blocks of `lanes` trials.
 * y (N, K, m), u (N, K, l), F (M, n, n), G (M, n, l), Qd (M, n, n), trans (N, K),
 * C (L, m, n), R (L, m, m), mode (N, K), x_init (N, n), P_init (N, n, n);
 * written: x_out (N, K, n), P_out (N, K, n, n), loglik_out (N, K), flag_out (N, K),
 * report (2,) {repaired, smallest eigenvalue}. Returns SE_OK or the failure code. */
/* the parameter list, written once for the prototype and the definition (kalman.c) */
#define SE_KALMAN_FILTER_PARAMETERS                                                               \
    se_int n, se_int m, se_int l, se_int N, se_int K, const double *restrict y,                   \
    const double *restrict u, const double *restrict F, const double *restrict G,                 \
    const double *restrict Qd, const se_int *restrict trans, const double *restrict C,            \
    const double *restrict R, const se_int *restrict mode, const double *restrict x_init,         \
    const double *restrict P_init, int predict_first, double gate, se_int lanes,                  \
    double *restrict x_out, double *restrict P_out, double *restrict loglik_out,                  \
    uint8_t *restrict flag_out, double *restrict report
se_int se_kalman_filter(SE_KALMAN_FILTER_PARAMETERS);

/* Fixed-gain filter of every trial from x_init[i]:
 * y (N, K, m), u (N, K, l), F (M, n, n), G (M, n, l), trans (N, K), C (L, m, n), mode (N, K),
 * gain (L, n, m), P_prior, P_post (L, n, n), whiten (L, m, m), x_init (N, n); written x_out
 * (N, K, n), P_out (N, K, n, n), loglik_out (N, K) (NaN), flag_out (N, K). Returns SE_OK, or
 * SE_NO_MEMORY if its scratch cannot be allocated. */
/* the parameter list, written once for the prototype and the definition (kalman.c) */
#define SE_STEADY_FILTER_PARAMETERS                                                               \
    se_int n, se_int m, se_int l, se_int L, se_int N, se_int K, const double *restrict y,         \
    const double *restrict u, const double *restrict F, const double *restrict G,                 \
    const se_int *restrict trans, const double *restrict C, const se_int *restrict mode,          \
    const double *restrict gain, const double *restrict P_prior,                                  \
    const double *restrict P_post, const double *restrict whiten,                                 \
    const double *restrict x_init, int predict_first, double gate, se_int lanes,                  \
    double *restrict x_out, double *restrict P_out, double *restrict loglik_out,                  \
    uint8_t *restrict flag_out
se_int se_steady_filter(SE_STEADY_FILTER_PARAMETERS);

#endif
