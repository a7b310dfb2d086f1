/* The second-order generalized pseudo-Bayesian filter, GPB2 (Bar-Shalom, Li & Kirubarajan
 * 2001, §11.6.5): the port of switchest/estimators/_compiled/gpb.py. The documentation of the
 * kernel (paper and equation citations) is at its definition in gpb.c; here: the prototype
 * and the shapes. It links bank.c (se_gather_transition, se_copy_rows, se_report_sample) and
 * linalg.c.
 *
 * Sizes first (n states, m outputs, l inputs, L modes, N trials, K samples, then trans's first
 * two extents and the first extent of x_modes_out), then numba's gpb2_bank arguments in its
 * order. Shapes (C-contiguous): y (N, K, m), u (N, K, l), F, G, Qd (M, n, n), (M, n, l),
 * (M, n, n), trans (trans_N, trans_K, L) se_int, C (L, m, n), R (L, m, m),
 * log_transition (L, L), x_init (N, L, n), P_init (N, L, n, n), log_prob_init (N, L);
 * written: x_out (N, K, n), P_out (N, K, n, n), prob_out (N, K, L), mode_out (N, K) se_int,
 * loglik_out (N, K), flag_out (N, K) uint8, x_modes_out (modes_N, K, L, n),
 * P_modes_out (modes_N, K, L, n, n) (written if modes_N == N), x_last, P_last,
 * log_prob_last shaped as the _init arrays, report (2,). Booleans are int.
 * Returns SE_OK, SE_NOT_POSITIVE_DEFINITE, SE_NOT_FINITE or SE_NO_MEMORY.
 */
#ifndef SE_GPB_H
#define SE_GPB_H

#include <stdint.h>

#include "se_common.h"

se_int se_gpb2_bank(se_int n, se_int m, se_int l, se_int L, se_int N, se_int K, se_int trans_N,
                    se_int trans_K, se_int modes_N, const double *restrict y,
                    const double *restrict u, const double *restrict F,
                    const double *restrict G, const double *restrict Qd,
                    const se_int *restrict trans, const double *restrict C,
                    const double *restrict R, const double *restrict log_transition,
                    const double *restrict x_init, const double *restrict P_init,
                    const double *restrict log_prob_init, int sample_timing, int predict_first,
                    double gate, se_int lanes, double *restrict x_out, double *restrict P_out,
                    double *restrict prob_out, se_int *restrict mode_out,
                    double *restrict loglik_out, uint8_t *restrict flag_out,
                    double *restrict x_modes_out, double *restrict P_modes_out,
                    double *restrict x_last, double *restrict P_last,
                    double *restrict log_prob_last, double *restrict report);

#endif
