/* The IMM extended-Viterbi filter with gridded switching times (Shankar, Yang & Hespanha,
 * Algorithm 1). The documentation of the kernel (paper and equation citations, the two
 * passes of each sample) is at its definition in imm_ev1.c; here: the prototype and the
 * shapes.
 *
 * Sizes first (n states, m outputs, l inputs, L modes, N trials, K samples, g grid points),
 * then the arguments in the order of the binding's viterbi_bank (engine/_imm_ev1.pyx). Shapes
 * (C-contiguous):
 *   y (N, K, m), u (N, K, l), table (K,) se_int,
 *   F, G, Qd (M, n, n), (M, n, l), (M, n, n), H, Gy, S0 (M, m, n), (M, m, l), (M, m, m)
 *     with M = D L L g, entry ((d L + j) L + i) g + k,
 *   tau (D, g), C (L, m, n), R (L, m, m), log_transition (L, L),
 *   x_init (N, L, n), P_init (N, L, n, n), log_w_init (N, L), chosen_init (N, L) se_int,
 *   offset_init (N, L);
 *   written: x_out (N, K, n), P_out (N, K, n, n) (the MAP destination's, or with combined the
 *   mixture's over the destinations), prob_out (N, K, L), mode_out (N, K) se_int,
 *   offset_out (N, K), outlier_out (N, K) uint8 (0/1), x_last, P_last, log_w_last,
 *   chosen_last, offset_last shaped as the _init arrays, report (2,).
 * Booleans are int. Returns SE_OK, SE_NOT_POSITIVE_DEFINITE, SE_NOT_FINITE or SE_NO_MEMORY.
 */
#ifndef SE_IMM_EV1_H
#define SE_IMM_EV1_H

#include <stdint.h>

#include "se_common.h"

/* the parameter list, written once for the prototype and the definition (imm_ev1.c) */
#define SE_VITERBI_BANK_PARAMETERS                                                                \
    se_int n, se_int m, se_int l, se_int L, se_int N, se_int K, se_int g,                         \
    const double *restrict y, const double *restrict u, const se_int *restrict table,             \
    const double *restrict F, const double *restrict G, const double *restrict Qd,                \
    const double *restrict H, const double *restrict Gy, const double *restrict S0,               \
    const double *restrict tau, const double *restrict C, const double *restrict R,               \
    const double *restrict log_transition, double epsilon, const double *restrict x_init,         \
    const double *restrict P_init, const double *restrict log_w_init,                             \
    const se_int *restrict chosen_init, const double *restrict offset_init, int predict_first,    \
    double gate, int printed, int marginal, int by_path, int combined, se_int lanes,               \
    double *restrict x_out, double *restrict P_out, double *restrict prob_out,                    \
    se_int *restrict mode_out, double *restrict offset_out, uint8_t *restrict outlier_out,        \
    double *restrict x_last,                                                                      \
    double *restrict P_last, double *restrict log_w_last, se_int *restrict chosen_last,           \
    double *restrict offset_last, double *restrict report
se_int se_viterbi_bank(SE_VITERBI_BANK_PARAMETERS);

#endif
