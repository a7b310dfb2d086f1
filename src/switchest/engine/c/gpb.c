/* The compiled second-order generalized pseudo-Bayesian filter, GPB2 (Bar-Shalom, Li &
 * Kirubarajan 2001, §11.6.5).
 *
 * The state of a trial after sample k - 1 is one Gaussian per mode, N(x_i, P_i) with
 * probability mu_i. Into sample k run L^2 Kalman filters, one per pair (mode i at k - 1,
 * mode j at k): predicted from mode i's Gaussian and updated with C[j], R[j], with
 * probability mu_ij ∝ Lambda_ij pi_ij mu_i. The prediction goes through the transition of the
 * mode that governs the interval into k (the timing, docs/conventions.rst): mode i's,
 * trans[k, i] of the table F, G, Qd, in the "sample" timing (the same for every j: computed
 * once per i), mode j's, trans[k, j], in the "interval" timing (Bar-Shalom, Li & Kirubarajan
 * §11.6.5). Each mode's pairs are then merged into one Gaussian, mu_j = sum_i mu_ij,
 * mu_{i|j} = mu_ij / mu_j, x_j = sum_i mu_{i|j} x_ij,
 * P_j = sum_i mu_{i|j} (P_ij + (x_ij - x_j)(x_ij - x_j)'), and the output is the moments of
 * the mixture over j (as the IMM's). Sample 0 has only the prior: L filters, mode j's from its
 * prior Gaussian with probability mu_j(0) (the first sample of se_filter_bank).
 *
 * gpb2_run filters every trial over every sample, gpb2_step one sample (the streaming API;
 * engine/gpb.py); both run se_gpb2_bank on the equations of linalg.c (prediction,
 * innovation, Joseph-form correction with its information-form fallback, merging,
 * combination), over blocks of trials laid across SIMD lanes. Convention of switchest:
 * transition[i, j] = P(mode j at k+1 | mode i at k), passed as its logarithm; probabilities
 * are log-weights.
 *
 * Gating is decided pair by pair, as se_filter_bank decides it mode by mode: a pair whose
 * normalized innovation squared exceeds the gate, or whose likelihood is not finite, is not
 * updated and gets weight 0 (SE_PARTLY_GATED); a sample no pair can use counts as missing (no
 * update, mu_ij ∝ pi_ij mu_i, log-likelihood 0, SE_GATED).
 */
#include "gpb.h"

#include <math.h>
#include <string.h>

#include "bank.h"
#include "linalg.h"

/* log sum_i exp(a[i, b]) over the L rows of a (L, B), -inf when every term is -inf. */
static inline double se_log_sum_exp(se_int L, se_int B, const double *restrict a, se_int b)
{
    double top = -INFINITY;
    for (se_int i = 0; i < L; i++)
        if (a[i * B + b] > top)
            top = a[i * B + b];
    if (top == -INFINITY)
        return -INFINITY;
    double acc = 0.0;
    for (se_int i = 0; i < L; i++)
        acc += exp(a[i * B + b] - top);
    return top + log(acc);
}

/* Mode j's merging weights over its L pairs, per lane, and its log-weight.
 *
 * log_mu[b] = log sum_i exp(a[i, b]) (a (L, B): the pairs' log-weights log mu_ij, up to a
 * common constant) and w[i, b] = mu_{i|j} = exp(a[i, b] - log_mu[b]) (Bar-Shalom, Li &
 * Kirubarajan §11.6.5). A mode whose pairs all have weight 0 (every one gated) is merged with
 * the weights the pairs had before the measurement, prior (L, B), and one that had none
 * either (unreachable) with equal weights: its probability is 0 and its Gaussian only needs
 * to be finite. log_mu (B,), w (L, B) written. */
static void se_merge_weights(se_int L, se_int B, const double *restrict a,
                             const double *restrict prior, se_int nb, double *restrict log_mu,
                             double *restrict w)
{
    for (se_int b = 0; b < nb; b++) {
        log_mu[b] = se_log_sum_exp(L, B, a, b);
        double ref = log_mu[b];
        const double *source = a;
        if (ref == -INFINITY) {
            ref = se_log_sum_exp(L, B, prior, b);
            source = prior;
        }
        for (se_int i = 0; i < L; i++)
            w[i * B + b] = ref > -INFINITY ? exp(source[i * B + b] - ref) : 1.0 / (double)L;
    }
}

/* GPB2 over N trials and K samples (Bar-Shalom, Li & Kirubarajan §11.6.5).
 *
 * Parameters
 * ----------
 * y, u, F, G, Qd, trans
 *     As in se_filter_bank: measurements (N, K, m) (NaN components missing), inputs
 *     (N, K, l) (u[:, k-1] held over the interval into sample k), the table of exact
 *     transitions and trans (N or 1, K, L), the transition of mode j into sample k.
 * C, R : (L, m, n), (L, m, m) float64
 *     Output matrix and measurement-noise covariance of each mode.
 * log_transition : (L, L) float64
 *     log transition[i, j], -inf for an impossible switch.
 * x_init, P_init, log_prob_init : (N, L, n), (N, L, n, n), (N, L) float64
 *     The merged Gaussian and log-probability of each mode before the first sample.
 * sample_timing : bool
 *     Which transition the pair (i at k - 1, j at k) is predicted through: mode i's,
 *     trans[k, i] (True: the "sample" timing; one prediction per i, copied to its L pairs),
 *     or mode j's, trans[k, j] (False: the "interval" timing, Bar-Shalom, Li & Kirubarajan
 *     §11.6.5).
 * predict_first : bool
 *     Whether the first sample is predicted into through the L^2 pairs (a streaming step) or
 *     only updated, L filters (the start of a record).
 * gate : float
 *     Largest normalized innovation squared a pair accepts.
 * lanes : int
 *     Trials per block (the results do not depend on it).
 * out : se_bank_out (bank.h)
 *     Written as by se_filter_bank: combined estimate, mode probabilities mu_j, most probable
 *     mode, log-likelihood log sum_ij exp(a_ij) (0 when nothing was observed or the sample
 *     was gated) and flag; if out->modes_wanted, the merged Gaussians x_j, P_j after each
 *     sample; the merged state after the last sample, shaped as x_init etc.
 * report : (2,) float64
 *     Written: covariances repaired and the smallest eigenvalue one had (inf if none).
 *
 * Returns
 * -------
 * status : int
 *     SE_OK or the failure code of the innovation covariance that stopped the kernel;
 *     SE_NO_MEMORY if the scratch could not be allocated (nothing written).
 *
 * The scratch has min(lanes, N) lanes (one block either way when lanes >= N).
 */
se_int se_gpb2_bank(SE_GPB2_BANK_PARAMETERS)
{
    const se_int B = se_lanes(lanes, N);
    se_arena ar = {NULL, 0};
    se_bank_scratch s;
    if (!se_bank_open(&ar, &s, n, m, l, L, B, 1, report))
        return SE_NO_MEMORY;
    se_int status = SE_OK;

/* pair (i, j)'s lane arrays: x (n, B), P (n, n, B) of xp, Pp (L, L, ...), j first */
#define XP(j, i) (s.xp + ((j) * L + (i)) * n * B)
#define PP(j, i) (s.Pp + ((j) * L + (i)) * n * n * B)

    for (se_int i0 = 0; i0 < N; i0 += B) {
        const se_int nb = se_block_trials(B, N, i0);
        se_bank_open_block(n, L, B, x_init, P_init, log_prob_init, i0, nb, &s);
        for (se_int j = 0; j < L; j++) {
            for (se_int b = 0; b < nb; b++)
                s.idx[b] = j;
            se_gather_matrices(m, n, B, C, s.idx, nb, s.Cl + j * m * n * B);
            se_gather_matrices(m, m, B, R, s.idx, nb, s.Rl + j * m * m * B);
        }
        for (se_int k = 0; k < K; k++) {
            se_bank_observe(m, B, K, y, i0, nb, k, &s);
            const int paired = k > 0 || predict_first;
            /* sources per mode: the modes at k-1, or the prior */
            const se_int n_src = paired ? L : 1;
            if (paired) {
                se_gather_samples(l, B, K, u, i0, nb, k > 0 ? k - 1 : 0, s.ul);
                if (sample_timing) { /* x_i(k|k-1) through mode i's transition, once per i */
                    for (se_int i = 0; i < L; i++) {
                        se_gather_transition(n, l, L, B, trans_N, trans_K, F, G, Qd, trans, i0,
                                             nb, k, i, s.idx, s.Fl, s.Gl, s.Ql);
                        se_predict(n, l, B, s.x + i * n * B, s.P + i * n * n * B, s.Fl, s.Gl,
                                   s.ul, s.Ql, nb, s.upd.AP, s.xs);
                    }
                }
                for (se_int j = 0; j < L; j++) {
                    if (!sample_timing) /* every pair into j through mode j's transition */
                        se_gather_transition(n, l, L, B, trans_N, trans_K, F, G, Qd, trans, i0,
                                             nb, k, j, s.idx, s.Fl, s.Gl, s.Ql);
                    /* pair (i at k-1, j at k): log mu_i + log pi_ij */
                    for (se_int i = 0; i < L; i++) {
                        se_copy_gaussian(n, B, s.x + i * n * B, s.P + i * n * n * B, nb,
                                         XP(j, i), PP(j, i));
                        if (!sample_timing)
                            se_predict(n, l, B, XP(j, i), PP(j, i), s.Fl, s.Gl, s.ul, s.Ql, nb,
                                       s.upd.AP, s.xs);
                        const double lt = log_transition[i * L + j];
                        double *pw = s.prior_w + (j * L + i) * B;
                        for (se_int b = 0; b < nb; b++)
                            pw[b] = s.log_prob[i * B + b] + lt;
                    }
                }
            } else {
                for (se_int j = 0; j < L; j++) { /* the prior of mode j: log mu_j(0) */
                    se_copy_gaussian(n, B, s.x + j * n * B, s.P + j * n * n * B, nb, XP(j, 0),
                                     PP(j, 0));
                    double *pw = s.prior_w + (j * L) * B;
                    for (se_int b = 0; b < nb; b++)
                        pw[b] = s.log_prob[j * B + b];
                }
            }
            /* every pair's update, gated pair by pair (as the bank gates mode by mode):
             * a_ij = log mu_i + log pi_ij + log Lambda_ij */
            status = se_bank_measure(n, m, B, L, n_src, L, s.xp, s.Pp, s.prior_w, gate, nb, &s,
                                     report);
            if (status != SE_OK)
                goto done;
            for (se_int j = 0; j < L; j++) { /* mu_j = sum_i mu_ij, x_j, P_j: the moments over i */
                if (paired) {
                    se_merge_weights(L, B, s.a + j * L * B, s.prior_w + j * L * B, nb,
                                     s.log_mu + j * B, s.w);
                    se_merge(n, L, B, s.w, XP(j, 0), PP(j, 0), nb, s.x + j * n * B,
                             s.P + j * n * n * B);
                } else {
                    for (se_int b = 0; b < nb; b++)
                        s.log_mu[j * B + b] = s.a[(j * L) * B + b];
                    se_copy_gaussian(n, B, XP(j, 0), PP(j, 0), nb, s.x + j * n * B,
                                     s.P + j * n * n * B);
                }
            }
            se_bank_close_sample(n, L, B, s.log_mu, i0, nb, k, &s, out);
        }
        se_bank_close_block(n, L, B, i0, nb, &s, out);
    }
#undef XP
#undef PP
done:
    se_arena_close(&ar);
    return status;
}
