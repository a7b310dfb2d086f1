/* The backward pass of the fixed-interval smoother with mode probabilities (Kim 1994,
 * Murphy 1998). The documentation of the equations is at the top of smoother.c and at each
 * function there; here: the prototypes and the shapes.
 *
 * Sizes first (se_int, the extents of the arrays: n states, l inputs, L modes, then the trial
 * axis N, samples K, the trial axis T and the sample axis TK of trans, the trial axis Ns of the
 * mode-matched outputs (N, or 0 when they are not asked for), the interval axis J of the lagged
 * outputs (K - 1, or 0 when they are not asked for)); then the arrays and scalars in the order
 * of the prototype (the binding's kim_backward, engine/_backward.pyx, keeps it). Booleans are
 * int, boolean arrays uint8_t, index arrays se_int.
 */
#ifndef SE_SMOOTHER_H
#define SE_SMOOTHER_H

#include <stdint.h>

#include "se_common.h"

/* The backward recursion over every trial, in blocks of `lanes` trials (smoother.c).
 *
 * Read: x_f (N, K, L, n), P_f (N, K, L, n, n), log_prob_f (N, K, L), u (N, K, l),
 * F (M, n, n), G (M, n, l), Qd (M, n, n), trans (T, TK, L) with T = N or 1 (indices into the
 * table, checked), log_transition (L, L).
 * Written: x_out (N, K, n), P_out (N, K, n, n), prob_out (N, K, L), mode_out (N, K),
 * x_s (Ns, K, L, n), P_s (Ns, K, L, n, n) (Ns = 0: not written), report (2,)
 * [repairs, smallest eigenvalue], and when `lagged`: pair_out (N, J, L, L),
 * lag_x (N, J, L, n), lag_P (N, J, L, n, n), lag_cross (N, J, L, n, n) with J = K - 1.
 * Returns SE_OK, the failure code of a predicted covariance that could not be factored even
 * repaired, or SE_NO_MEMORY. */
/* the parameter list, written once for the prototype and the definition (smoother.c) */
#define SE_KIM_BACKWARD_PARAMETERS                                                                \
    se_int n, se_int l, se_int L, se_int N, se_int K, se_int T, se_int TK, se_int Ns,             \
    se_int J, const double *restrict x_f, const double *restrict P_f,                             \
    const double *restrict log_prob_f, const double *restrict u, const double *restrict F,        \
    const double *restrict G, const double *restrict Qd, const se_int *restrict trans,            \
    const double *restrict log_transition, se_int lanes, int sample_timing,                       \
    double *restrict x_out, double *restrict P_out, double *restrict prob_out,                    \
    se_int *restrict mode_out, double *restrict x_s, double *restrict P_s,                        \
    double *restrict report, int lagged, double *restrict pair_out, double *restrict lag_x,       \
    double *restrict lag_P, double *restrict lag_cross
se_int se_kim_backward(SE_KIM_BACKWARD_PARAMETERS);

/* Symmetrize a stack A (M, n, n) into sym (M, n, n) and certify its matrices positive
 * semidefinite to within a shift, as far as a Cholesky factorization can (smoother.c):
 * failed (M,) uint8 written; *scale gets max(max |A|, tiny) and *asym max |A - A'|.
 * Returns SE_OK, or SE_NO_MEMORY if the factor's scratch (n beyond SE_SCREEN_STACK) could not
 * be allocated (nothing written then). */
se_int se_screen_psd(se_int M, se_int n, const double *restrict A, double relative_shift,
                     double *restrict sym, uint8_t *restrict failed, double *restrict scale,
                     double *restrict asym);

/* largest n whose Cholesky factor in se_screen_psd lives on the stack */
#define SE_SCREEN_STACK 32

#endif
