/* The compiled kernel of the Gaussian filters: a bank of mode-matched Kalman filters.
 *
 * se_filter_bank runs, for every trial and every sample, L Kalman filters (one per mode) with
 * an interaction between them before each prediction: the IMM's mixing (SE_MIX: Blom &
 * Bar-Shalom, 1988; Bar-Shalom, Li & Kirubarajan §11.6.6) or GPB1's collapse of all of them
 * into one Gaussian (SE_COLLAPSE: Bar-Shalom, Li & Kirubarajan §11.6.4). With one mode the
 * interaction and the combination reduce to copies and it is the Kalman filter (Shankar et
 * al. eqs (6)-(10)). On request it writes the mode-matched posteriors after each sample's
 * update, the input of a smoother. engine/imm.py calls this kernel for a whole record (run)
 * or for one sample (step, the streaming API); the Kalman filter has a kernel of its own
 * (trials that share their covariance run its equations once) on the same equations of
 * linalg.c, so each equation has one implementation.
 *
 * Trials are processed in blocks of `lanes` laid across SIMD lanes (linalg.c); the results do
 * not depend on the block size. Each trial may have a model of its own (its entries of the
 * transition and output tables, its mode transition matrix): one record filtered under many
 * candidate parameters fills the lanes as many trials do.
 */
#include "bank.h"

#include <math.h>
#include <string.h>

#include "linalg.h"

/* Each lane's exact transition of mode j into sample k, trans[trial, k, j] (se_lane_index) of
 * the table F, G, Qd, into Fl (n, n, B), Gl (n, l, B), Ql (n, n, B); idx (B,) is scratch. */
void se_gather_transition(se_int n, se_int l, se_int L, se_int B, se_int trans_N,
                          se_int trans_K, const double *restrict F, const double *restrict G,
                          const double *restrict Qd, const se_int *restrict trans, se_int i0,
                          se_int nb, se_int k, se_int j, se_int *restrict idx,
                          double *restrict Fl, double *restrict Gl, double *restrict Ql)
{
    se_lane_index(L, trans_N, trans_K, trans, i0, nb, k, j, idx);
    se_gather_matrices(n, n, B, F, idx, nb, Fl);
    se_gather_matrices(n, l, B, G, idx, nb, Gl);
    se_gather_matrices(n, n, B, Qd, idx, nb, Ql);
}

/* Every mode-matched Gaussian x[j], P[j] predicted into sample k through mode j's own
 * transition (se_gather_transition, se_predict), in place. */
static void se_predict_modes(se_int n, se_int l, se_int L, se_int B, se_int trans_N,
                             se_int trans_K, double *restrict x, double *restrict P,
                             const double *restrict F, const double *restrict G,
                             const double *restrict Qd, const se_int *restrict trans,
                             se_int i0, se_int nb, se_int k, const double *restrict ul,
                             se_int *restrict idx, double *restrict Fl, double *restrict Gl,
                             double *restrict Ql, double *restrict AP, double *restrict xs)
{
    for (se_int j = 0; j < L; j++) {
        se_gather_transition(n, l, L, B, trans_N, trans_K, F, G, Qd, trans, i0, nb, k, j, idx,
                             Fl, Gl, Ql);
        se_predict(n, l, B, x + j * n * B, P + j * n * n * B, Fl, Gl, ul, Ql, nb, AP, xs);
    }
}

/* dst[:, :nb] = src[:, :nb] of two (L, B) lane arrays: the first nb lanes of each row. */
static void se_copy_rows(se_int L, se_int B, const double *restrict src, double *restrict dst,
                         se_int nb)
{
    for (se_int j = 0; j < L; j++)
        for (se_int b = 0; b < nb; b++)
            dst[j * B + b] = src[j * B + b];
}

/* The bank's interaction, in place on the mode-matched x (L, n, B), P, weighted by the mode
 * probabilities prob of the previous sample and each lane's transition matrix
 * transition (L, L, B): se_mix (SE_MIX) or se_collapse (SE_COLLAPSE); with one mode only
 * log_c = log_prob. */
static void se_interact(se_int n, se_int L, se_int B, double *restrict x, double *restrict P,
                        const double *restrict prob, const double *restrict log_prob,
                        const double *restrict transition,
                        const double *restrict log_transition, se_int interaction, se_int nb,
                        double *restrict log_c, double *restrict w, double *restrict xm,
                        double *restrict Pm)
{
    if (L == 1)
        se_copy_rows(L, B, log_prob, log_c, nb);
    else if (interaction == SE_COLLAPSE)
        se_collapse(n, L, B, x, P, prob, log_prob, transition, log_transition, nb, log_c, w, xm,
                    Pm);
    else
        se_mix(n, L, B, x, P, prob, log_prob, transition, log_transition, nb, log_c, w, xm, Pm);
}

/* Each lane's transition matrix and its logarithm, [trial] of transition (N or 1, L, L) and
 * log_transition for trial i0 + b (an axis of length 1 is shared), into pi (L, L, B),
 * log_pi. */
static void se_gather_transitions(se_int L, se_int B, se_int transition_N,
                                  const double *restrict transition,
                                  const double *restrict log_transition, se_int i0, se_int nb,
                                  double *restrict pi, double *restrict log_pi)
{
    for (se_int b = 0; b < nb; b++) {
        se_int i = transition_N > 1 ? i0 + b : 0;
        for (se_int r = 0; r < L; r++)
            for (se_int c = 0; c < L; c++) {
                pi[(r * L + c) * B + b] = transition[(i * L + r) * L + c];
                log_pi[(r * L + c) * B + b] = log_transition[(i * L + r) * L + c];
            }
    }
}

/* Write sample k of the block's trials: the combined output of the mode-matched Gaussians
 * x (L, n, B), P with probabilities prob (Bar-Shalom, Li & Kirubarajan §11.6.6; xc, Pc, best
 * scratch), the most probable mode, the log-likelihood total (0 where nothing was observed or
 * the sample was gated), the flag, the mode probabilities and, if modes_wanted, the
 * mode-matched Gaussians themselves. */
static void se_report_sample(se_int n, se_int L, se_int B, se_int K, const double *restrict x,
                             const double *restrict P, const double *restrict prob,
                             const double *restrict log_prob, const double *restrict total,
                             const uint8_t *restrict flag, const double *restrict n_obs, se_int i0,
                             se_int nb, se_int k, int modes_wanted, double *restrict xc,
                             double *restrict Pc, se_int *restrict best, double *restrict x_out,
                             double *restrict P_out, double *restrict prob_out,
                             se_int *restrict mode_out, double *restrict loglik_out,
                             uint8_t *restrict flag_out, double *restrict x_modes_out,
                             double *restrict P_modes_out)
{
    se_combine(n, L, B, x, P, prob, log_prob, nb, xc, Pc, best);
    for (se_int b = 0; b < nb; b++) {
        se_int i = i0 + b;
        mode_out[i * K + k] = best[b];
        int seen = flag[b] != SE_GATED && n_obs[b] > 0.0;
        loglik_out[i * K + k] = seen ? total[b] : 0.0;
        flag_out[i * K + k] = flag[b];
        for (se_int j = 0; j < L; j++)
            prob_out[(i * K + k) * L + j] = prob[j * B + b];
        se_write_lane(n, B, K, xc, Pc, b, i, k, x_out, P_out);
        if (modes_wanted)
            se_write_modes(n, L, B, K, x, P, b, i, k, x_modes_out, P_modes_out);
    }
}

/* ---- the skeleton of the bank kernels ------------------------------------------------------- */

/* The scratch of se_filter_bank (pairs 0) or se_gpb2_bank (pairs 1), carved from the arena
 * (bank.h gives the shapes); the arrays one kind does not use are carved with size 0. */
static void se_bank_carve(se_arena *ar, se_bank_scratch *s, se_int n, se_int m, se_int l,
                          se_int L, se_int B, int pairs)
{
    const se_int F = pairs ? L * L : L; /* filters per sample: modes, or pairs of modes */
    const se_int bank = pairs ? 0 : 1, gpb = pairs ? 1 : 0;
    SE_DOUBLES(ar, L * n * B, &s->x);
    SE_DOUBLES(ar, L * n * n * B, &s->P);
    SE_DOUBLES(ar, L * B, &s->log_prob, &s->prob);
    SE_DOUBLES(ar, gpb * F * n * B, &s->xp);
    SE_DOUBLES(ar, gpb * F * n * n * B, &s->Pp);
    SE_DOUBLES(ar, n * n * B, &s->Fl, &s->Ql, &s->Pc);
    SE_DOUBLES(ar, n * l * B, &s->Gl);
    SE_DOUBLES(ar, L * m * n * B, &s->Cl);
    SE_DOUBLES(ar, L * m * m * B, &s->Rl);
    SE_DOUBLES(ar, m * B, &s->yl, &s->obs);
    SE_DOUBLES(ar, l * B, &s->ul);
    SE_DOUBLES(ar, B, &s->n_obs, &s->total);
    SE_DOUBLES(ar, F * m * B, &s->e, &s->z, &s->scale);
    SE_DOUBLES(ar, F * n * m * B, &s->PCt);
    SE_DOUBLES(ar, F * m * m * B, &s->chol);
    SE_DOUBLES(ar, F * B, &s->nis, &s->loglik, &s->a);
    SE_DOUBLES(ar, gpb * F * B, &s->prior_w);
    SE_DOUBLES(ar, (pairs ? L : L * L) * B, &s->w);
    SE_DOUBLES(ar, gpb * L * B, &s->log_mu);
    SE_DOUBLES(ar, 3 * B, &s->work);
    SE_DOUBLES(ar, n * B, &s->xs, &s->xc);
    SE_DOUBLES(ar, bank * L * B, &s->log_c);
    SE_DOUBLES(ar, bank * L * L * B, &s->pi, &s->log_pi);
    SE_DOUBLES(ar, bank * L * n * B, &s->xm);
    SE_DOUBLES(ar, bank * L * n * n * B, &s->Pm);
    SE_INTS(ar, B, &s->idx, &s->best);
    SE_FLAGS(ar, F * B, &s->use);
    SE_FLAGS(ar, B, &s->flag, &s->bad);
    se_carve_update(ar, n, m, B, &s->upd);
}

int se_bank_open(se_arena *ar, se_bank_scratch *s, se_int n, se_int m, se_int l, se_int L,
                 se_int B, int pairs, double *report)
{
    se_report_start(report);
    do
        se_bank_carve(ar, s, n, m, l, L, B, pairs);
    while (se_arena_open(ar));
    return ar->base != NULL;
}

void se_bank_open_block(se_int n, se_int L, se_int B, const double *restrict x_init,
                        const double *restrict P_init, const double *restrict log_prob_init,
                        se_int i0, se_int nb, se_bank_scratch *s)
{
    se_gather_rows(L, B, 1, log_prob_init, i0, nb, s->log_prob);
    se_gather_modes(n, L, B, 1, x_init, P_init, i0, nb, s->x, s->P);
}

void se_bank_observe(se_int m, se_int B, se_int K, const double *restrict y, se_int i0,
                     se_int nb, se_int k, se_bank_scratch *s)
{
    se_gather_samples(m, B, K, y, i0, nb, k, s->yl);
    se_observe(m, B, s->yl, nb, s->obs, s->n_obs);
}

/* The measurement update of the bank's filters at one sample, in this fixed order:
 * each filter's innovation (se_innovation: e = y - C x, S = C P C' + R over the observed
 * components, Shankar et al. eq. (8)), the gating decision over all of them before anything
 * changes (se_gate: a = prior + log Lambda where used), then each filter's update (se_update:
 * Joseph's form, eqs (9)-(10), with the covariance rule of the filters). Filter (j, i),
 * j < rows, i < cols, is x, P at q = j * stride + i (the bank: stride 1, cols 1, filter j mode
 * j; GPB2: stride L, pair (i at k - 1, j at k)) with mode j's Cl, Rl and its innovation, use
 * and a at q of s's per-filter arrays. Returns SE_OK or the failure of an innovation. */
se_int se_bank_measure(se_int n, se_int m, se_int B, se_int rows, se_int cols, se_int stride,
                       double *x, double *P, const double *prior, double gate, se_int nb,
                       se_bank_scratch *s, double *report)
{
    for (se_int j = 0; j < rows; j++)
        for (se_int i = 0; i < cols; i++) {
            const se_int q = j * stride + i;
            se_int status = se_innovation(
                n, m, B, x + q * n * B, P + q * n * n * B, s->yl, s->Cl + j * m * n * B,
                s->Rl + j * m * m * B, s->obs, s->n_obs, nb, s->e + q * m * B,
                s->PCt + q * n * m * B, s->chol + q * m * m * B, s->scale + q * m * B,
                s->z + q * m * B, s->nis + q * B, s->loglik + q * B, s->work, s->bad, report);
            if (status != SE_OK)
                return status;
        }
    se_gate(rows, cols, stride, B, prior, s->loglik, s->nis, gate, nb, s->use, s->a, s->flag);
    for (se_int j = 0; j < rows; j++)
        for (se_int i = 0; i < cols; i++) {
            const se_int q = j * stride + i;
            se_update(n, m, B, x + q * n * B, P + q * n * n * B, s->Cl + j * m * n * B,
                      s->Rl + j * m * m * B, s->obs, s->n_obs, s->use + q * B, nb,
                      s->PCt + q * n * m * B, s->chol + q * m * m * B, s->scale + q * m * B,
                      s->z + q * m * B, &s->upd, report);
        }
    return SE_OK;
}

/* log mu_j normalized (se_log_normalize: log_w, then log_prob, prob and total = the sample's
 * log-likelihood), and sample k written (se_report_sample). */
void se_bank_close_sample(se_int n, se_int L, se_int B, double *log_w, se_int i0, se_int nb,
                          se_int k, se_bank_scratch *s, const se_bank_out *out)
{
    se_log_normalize(L, B, log_w, s->prob, s->total, nb);
    se_copy_rows(L, B, log_w, s->log_prob, nb);
    se_report_sample(n, L, B, out->K, s->x, s->P, s->prob, s->log_prob, s->total, s->flag,
                     s->n_obs, i0, nb, k, out->modes_wanted, s->xc, s->Pc, s->best, out->x,
                     out->P, out->prob, out->mode, out->loglik, out->flag, out->x_modes,
                     out->P_modes);
}

void se_bank_close_block(se_int n, se_int L, se_int B, se_int i0, se_int nb,
                         const se_bank_scratch *s, const se_bank_out *out)
{
    se_scatter_rows(L, B, 1, s->log_prob, i0, nb, out->log_prob_last);
    se_scatter_modes(n, L, B, 1, s->x, s->P, i0, nb, out->x_last, out->P_last);
}

/* Filter N trials over K samples with L interacting mode-matched filters.
 *
 * Parameters
 * ----------
 * y : (N, K, m) float64
 *     Measurements; NaN components are missing.
 * u : (N, K, l) float64
 *     Inputs; u[:, k-1] is held over the interval into sample k, u[:, 0] over the interval
 *     into sample 0 when predict_first.
 * F, G, Qd : (M, n, n), (M, n, l), (M, n, n) float64
 *     Table of exact transitions.
 * trans : (N or 1, K, L) int64
 *     Transition of mode j into sample k of each trial (shared if the first axis has
 *     length 1).
 * C, R : (M', m, n), (M', m, m) float64
 *     Table of output matrices and measurement-noise covariances.
 * out_index : (N or 1, K or 1, L) int64
 *     Which C, R mode j uses at sample k of each trial.
 * transition, log_transition : (N or 1, L, L) float64
 *     Mode transition matrix of each trial (shared if the first axis has length 1) and its
 *     logarithm (transition[trial, i, j] = P(j next | i now)).
 * x_init, P_init, log_prob_init : (N, L, n), (N, L, n, n), (N, L) float64
 *     Mode-matched state of every trial before the first sample.
 * interaction : int
 *     SE_MIX: the IMM's interaction (se_mix); SE_COLLAPSE: GPB1's (se_collapse). The
 *     predicted mode probabilities are c_j = sum_i pi_ij mu_i either way.
 * sample_timing : bool
 *     The order of interaction and prediction into each sample k. False (the "interval"
 *     timing, Bar-Shalom, Li & Kirubarajan §11.6.6): interact, then predict each mode's
 *     restarted prior through its own transition trans[k, j]. True (the "sample" timing):
 *     predict each mode-matched posterior i of sample k - 1 through its own transition
 *     trans[k, i], then interact the predictions with the same weights
 *     (mu_{i|j} = pi_ij mu_i / c_j for the IMM, mu_i for GPB1).
 * predict_first : bool
 *     Whether the first sample is mixed and predicted into (a streaming step) or only updated
 *     (the start of a record).
 * gate : float
 *     Largest normalized innovation squared a mode accepts.
 * lanes : int
 *     Trials per block.
 * out : se_bank_out (bank.h)
 *     Written: the combined estimate x (N, K, n), P (N, K, n, n), the mode probabilities
 *     prob (N, K, L), the most probable mode, the log-likelihood (0 when nothing was observed
 *     or the sample was gated) and the flag (N, K); if out->modes_wanted, the mode-matched
 *     posteriors after each sample's update, x_modes (N, K, L, n), P_modes (N, K, L, n, n);
 *     the mode-matched state after the last sample, x_last, P_last, log_prob_last, shaped as
 *     x_init etc.
 * report : (2,) float64
 *     Written: the number of covariances repaired (se_repair) and the smallest eigenvalue one
 *     had before its repair (inf if none), for the caller's warning.
 *
 * Returns
 * -------
 * status : int
 *     SE_OK, or the failure code of the mode-matched innovation covariance that stopped the
 *     kernel (outputs then incomplete); SE_NO_MEMORY if the scratch could not be allocated
 *     (nothing written).
 *
 * Notes
 * -----
 * Gating (mode by mode): a mode whose normalized innovation squared exceeds gate, or whose
 * likelihood is not finite (an outlier such as 1e300 overflows it), does not use the
 * measurement: its estimate is not updated and its likelihood is taken as 0 (a truncated
 * likelihood), flag SE_PARTLY_GATED. If no mode can use it the sample is treated as missing:
 * no mode is updated, the mode probabilities stay the predicted c, the log-likelihood is 0,
 * flag SE_GATED.
 *
 * Ill-conditioned covariances, lane by lane: where Joseph's form loses its digits the
 * posterior is taken in information form (se_joseph_lost, se_information_form); a posterior
 * neither form resolves is repaired if indefinite, and a lane whose innovation covariance
 * fails its factorization has its prior P repaired and is factored once more (se_repair);
 * report counts the repairs. Only a lane whose P needs no repair and still fails stops the
 * kernel.
 *
 * The scratch has min(lanes, N) lanes (one block either way when lanes >= N).
 */
se_int se_filter_bank(SE_FILTER_BANK_PARAMETERS)
{
    const se_int B = se_lanes(lanes, N);
    se_arena ar = {NULL, 0};
    se_bank_scratch s;
    if (!se_bank_open(&ar, &s, n, m, l, L, B, 0, report))
        return SE_NO_MEMORY;
    se_int status = SE_OK;

    for (se_int i0 = 0; i0 < N; i0 += B) {
        const se_int nb = se_block_trials(B, N, i0);
        se_bank_open_block(n, L, B, x_init, P_init, log_prob_init, i0, nb, &s);
        se_gather_transitions(L, B, transition_N, transition, log_transition, i0, nb, s.pi,
                              s.log_pi);
        for (se_int j = 0; j < L; j++)
            for (se_int b = 0; b < nb; b++)
                s.prob[j * B + b] = exp(s.log_prob[j * B + b]);
        for (se_int k = 0; k < K; k++) {
            se_bank_observe(m, B, K, y, i0, nb, k, &s);
            if (k > 0 || predict_first) {
                se_gather_samples(l, B, K, u, i0, nb, k > 0 ? k - 1 : 0, s.ul);
                if (!sample_timing) /* "interval": interact, then predict */
                    se_interact(n, L, B, s.x, s.P, s.prob, s.log_prob, s.pi, s.log_pi,
                                interaction, nb, s.log_c, s.w, s.xm, s.Pm);
                se_predict_modes(n, l, L, B, trans_N, trans_K, s.x, s.P, F, G, Qd, trans, i0,
                                 nb, k, s.ul, s.idx, s.Fl, s.Gl, s.Ql, s.upd.AP, s.xs);
                if (sample_timing) /* "sample": predict, then interact */
                    se_interact(n, L, B, s.x, s.P, s.prob, s.log_prob, s.pi, s.log_pi,
                                interaction, nb, s.log_c, s.w, s.xm, s.Pm);
            } else {
                se_copy_rows(L, B, s.log_prob, s.log_c, nb);
            }
            if (k == 0 || out_K > 1) {
                for (se_int j = 0; j < L; j++) {
                    se_lane_index(L, out_N, out_K, out_index, i0, nb, k, j, s.idx);
                    se_gather_matrices(m, n, B, C, s.idx, nb, s.Cl + j * m * n * B);
                    se_gather_matrices(m, m, B, R, s.idx, nb, s.Rl + j * m * m * B);
                }
            }
            /* each mode's update, gated mode by mode; log mu_j = log c_j + log Lambda_j */
            status = se_bank_measure(n, m, B, L, 1, 1, s.x, s.P, s.log_c, gate, nb, &s, report);
            if (status != SE_OK)
                goto done;
            se_bank_close_sample(n, L, B, s.a, i0, nb, k, &s, out);
        }
        se_bank_close_block(n, L, B, i0, nb, &s, out);
    }
done:
    se_arena_close(&ar);
    return status;
}
