/* The second-order generalized pseudo-Bayesian filter, GPB2 (Bar-Shalom, Li & Kirubarajan
 * 2001, §11.6.5). The documentation of the kernel (paper and equation citations) is at its
 * definition in gpb.c; here: the prototype and the shapes. It links bank.c (the skeleton of
 * the bank kernels, se_bank_*, and se_gather_transition) and linalg.c.
 *
 * Sizes first (n states, m outputs, l inputs, L modes, N trials, K samples, then trans's first
 * two extents), then the inputs in the order of the binding's gpb2_bank (engine/_bank.pyx), the
 * outputs gathered in out.
 * Shapes (C-contiguous): y (N, K, m), u (N, K, l), F, G, Qd (M, n, n), (M, n, l), (M, n, n),
 * trans (trans_N, trans_K, L) se_int, C (L, m, n), R (L, m, m),
 * log_transition (L, L), x_init (N, L, n), P_init (N, L, n, n), log_prob_init (N, L);
 * written: out (se_bank_out, bank.h), report (2,). Booleans are int.
 * Returns SE_OK, SE_NOT_POSITIVE_DEFINITE, SE_NOT_FINITE or SE_NO_MEMORY.
 */
#ifndef SE_GPB_H
#define SE_GPB_H

#include <stdint.h>

#include "bank.h"
#include "se_common.h"

/* the parameter list, written once for the prototype and the definition (gpb.c) */
#define SE_GPB2_BANK_PARAMETERS                                                                   \
    se_int n, se_int m, se_int l, se_int L, se_int N, se_int K, se_int trans_N,                   \
    se_int trans_K, const double *restrict y, const double *restrict u,                           \
    const double *restrict F, const double *restrict G, const double *restrict Qd,                \
    const se_int *restrict trans, const double *restrict C, const double *restrict R,             \
    const double *restrict log_transition, const double *restrict x_init,                         \
    const double *restrict P_init, const double *restrict log_prob_init, int sample_timing,       \
    int predict_first, double gate, se_int lanes, const se_bank_out *out,                         \
    double *restrict report
se_int se_gpb2_bank(SE_GPB2_BANK_PARAMETERS);

#endif
