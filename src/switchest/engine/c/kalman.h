/* The Kalman filter along given transitions (covariances shared by the trials of a group) and
 * the fixed-gain filter: the port of switchest/estimators/_compiled/kalman_kernel.py and of
 * the kernels of _compiled/kalman.py. The documentation of each function is at its definition
 * in kalman.c; here: the prototypes and the shapes.
 *
 * Conventions as linalg.h: sizes first (se_int), then the Python arguments in the order of the
 * Python signature; booleans int, boolean arrays uint8_t, index arrays se_int, the rest double;
 * every array C-contiguous of the shape given.
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
se_int se_kalman_filter(se_int n, se_int m, se_int l, se_int N, se_int K,
                        const double *restrict y, const double *restrict u,
                        const double *restrict F, const double *restrict G,
                        const double *restrict Qd, const se_int *restrict trans,
                        const double *restrict C, const double *restrict R,
                        const se_int *restrict mode, const double *restrict x_init,
                        const double *restrict P_init, int predict_first, double gate,
                        se_int lanes, double *restrict x_out, double *restrict P_out,
                        double *restrict loglik_out, uint8_t *restrict flag_out,
                        double *restrict report);

/* held[b] <- index[i0 + b, k] for every lane, index (N, K), held (B,); returns whether one
 * changed. */
int se_lane_entries(se_int K, const se_int *restrict index, se_int i0, se_int nb, se_int k,
                    se_int *restrict held);

/* Every trial's mean predicted into sample k, x <- F x + G u: trans (N, K), F (M, n, n),
 * G (M, n, l), u (N, K, l), held (B,), Fl (n, n, B), Gl (n, l, B), ul (l, B), x (n, B),
 * xs (n, B). */
void se_predict_means(se_int n, se_int l, se_int B, se_int K, const se_int *restrict trans,
                      const double *restrict F, const double *restrict G,
                      const double *restrict u, se_int i0, se_int nb, se_int k,
                      se_int *restrict held, double *restrict Fl, double *restrict Gl,
                      double *restrict ul, double *restrict x, double *restrict xs);

/* The `count` buffered samples of the block's trials as samples k0 .. of the outputs:
 * x_buf (B, CHUNK, n), P_buf (J, CHUNK, n * n), group_buf (B, CHUNK), loglik_buf (B, CHUNK),
 * flag_buf (B, CHUNK); x_out (N, K, n), P_out (N, K, n * n), loglik_out (N, K),
 * flag_out (N, K). */
void se_write_out(se_int n, se_int K, const double *restrict x_buf,
                  const double *restrict P_buf, const se_int *restrict group_buf,
                  const double *restrict loglik_buf, const uint8_t *restrict flag_buf,
                  se_int i0, se_int nb, se_int k0, se_int count, double *restrict x_out,
                  double *restrict P_out, double *restrict loglik_out,
                  uint8_t *restrict flag_out);

/* Fixed-gain filter (numba's _steady_filter) of every trial from x_init[i]:
 * y (N, K, m), u (N, K, l), F (M, n, n), G (M, n, l), trans (N, K), C (L, m, n), mode (N, K),
 * gain (L, n, m), P_prior, P_post (L, n, n), whiten (L, m, m), x_init (N, n); written x_out
 * (N, K, n), P_out (N, K, n, n), loglik_out (N, K) (NaN), flag_out (N, K). Returns SE_OK, or
 * SE_NO_MEMORY (numba returns nothing). */
se_int se_steady_filter(se_int n, se_int m, se_int l, se_int L, se_int N, se_int K,
                        const double *restrict y, const double *restrict u,
                        const double *restrict F, const double *restrict G,
                        const se_int *restrict trans, const double *restrict C,
                        const se_int *restrict mode, const double *restrict gain,
                        const double *restrict P_prior, const double *restrict P_post,
                        const double *restrict whiten, const double *restrict x_init,
                        int predict_first, double gate, se_int lanes, double *restrict x_out,
                        double *restrict P_out, double *restrict loglik_out,
                        uint8_t *restrict flag_out);

#endif
