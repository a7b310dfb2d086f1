/* The compiled kernel of the Gaussian filters: a bank of mode-matched Kalman filters (the port
 * of switchest/estimators/_compiled/bank.py).
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
void se_gather_transitions(se_int L, se_int B, se_int transition_N,
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

/* dst[:, :nb] = src[:, :nb] as loops (numba compiles slice assignment slowly). */
void se_copy_rows(se_int L, se_int B, const double *restrict src, double *restrict dst,
                  se_int nb)
{
    for (se_int j = 0; j < L; j++)
        for (se_int b = 0; b < nb; b++)
            dst[j * B + b] = src[j * B + b];
}

/* Write sample k of the block's trials: the combined output of the mode-matched Gaussians
 * x (L, n, B), P with probabilities prob (Bar-Shalom, Li & Kirubarajan §11.6.6; xc, Pc, best
 * scratch), the most probable mode, the log-likelihood total (0 where nothing was observed or
 * the sample was gated), the flag, the mode probabilities and, if modes_wanted, the
 * mode-matched Gaussians themselves. */
void se_report_sample(se_int n, se_int L, se_int B, se_int K, const double *restrict x,
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

/* the scratch of se_filter_bank, the arrays of numba's np.empty (shapes as there) */
typedef struct {
    double *x, *P, *log_prob, *prob, *Fl, *Gl, *Ql, *Cl, *Rl, *yl, *ul, *obs, *n_obs, *e, *z,
        *scale, *PCt, *chol, *nis, *loglik, *work, *gain, *T, *AP, *xs, *log_c, *w, *pi,
        *log_pi, *xm, *Pm, *a, *total, *xc, *Pc, *prior, *root;
    se_int *idx, *best;
    uint8_t *use, *flag, *bad, *lost;
} bank_scratch;

static void bank_carve(se_arena *ar, bank_scratch *s, se_int n, se_int m, se_int l, se_int L,
                       se_int B)
{
    const size_t d = sizeof(double);
    s->x = se_carve(ar, L * n * B, d);
    s->P = se_carve(ar, L * n * n * B, d);
    s->log_prob = se_carve(ar, L * B, d);
    s->prob = se_carve(ar, L * B, d);
    s->Fl = se_carve(ar, n * n * B, d);
    s->Gl = se_carve(ar, n * l * B, d);
    s->Ql = se_carve(ar, n * n * B, d);
    s->Cl = se_carve(ar, L * m * n * B, d);
    s->Rl = se_carve(ar, L * m * m * B, d);
    s->yl = se_carve(ar, m * B, d);
    s->ul = se_carve(ar, l * B, d);
    s->obs = se_carve(ar, m * B, d);
    s->n_obs = se_carve(ar, B, d);
    s->e = se_carve(ar, L * m * B, d);
    s->z = se_carve(ar, L * m * B, d);
    s->scale = se_carve(ar, L * m * B, d);
    s->PCt = se_carve(ar, L * n * m * B, d);
    s->chol = se_carve(ar, L * m * m * B, d);
    s->nis = se_carve(ar, L * B, d);
    s->loglik = se_carve(ar, L * B, d);
    s->work = se_carve(ar, 3 * B, d);
    s->gain = se_carve(ar, n * m * B, d);
    s->T = se_carve(ar, n * m * B, d);
    s->AP = se_carve(ar, n * n * B, d);
    s->xs = se_carve(ar, n * B, d);
    s->log_c = se_carve(ar, L * B, d);
    s->w = se_carve(ar, L * L * B, d);
    s->pi = se_carve(ar, L * L * B, d);
    s->log_pi = se_carve(ar, L * L * B, d);
    s->xm = se_carve(ar, L * n * B, d);
    s->Pm = se_carve(ar, L * n * n * B, d);
    s->a = se_carve(ar, L * B, d);
    s->total = se_carve(ar, B, d);
    s->xc = se_carve(ar, n * B, d);
    s->Pc = se_carve(ar, n * n * B, d);
    s->prior = se_carve(ar, n * n * B, d);
    s->root = se_carve(ar, n * B, d);
    s->idx = se_carve(ar, B, sizeof(se_int));
    s->best = se_carve(ar, B, sizeof(se_int));
    s->use = se_carve(ar, L * B, 1);
    s->flag = se_carve(ar, B, 1);
    s->bad = se_carve(ar, B, 1);
    s->lost = se_carve(ar, B, 1);
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
 * x_out, P_out, prob_out, mode_out, loglik_out, flag_out
 *     Written: combined estimate (N, K, n), (N, K, n, n), mode probabilities (N, K, L), most
 *     probable mode, log-likelihood (0 when nothing was observed or the sample was gated) and
 *     flag (N, K).
 * x_modes_out, P_modes_out
 *     Written when their first axis has length N (pass zero-size arrays otherwise): the
 *     mode-matched posteriors after each sample's update, (N, K, L, n), (N, K, L, n, n).
 * x_last, P_last, log_prob_last
 *     Written: the mode-matched state after the last sample, shaped as x_init etc.
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
se_int se_filter_bank(se_int n, se_int m, se_int l, se_int L, se_int N, se_int K,
                      se_int trans_N, se_int trans_K, se_int out_N, se_int out_K,
                      se_int transition_N, se_int modes_N, const double *restrict y,
                      const double *restrict u, const double *restrict F,
                      const double *restrict G, const double *restrict Qd,
                      const se_int *restrict trans, const double *restrict C,
                      const double *restrict R, const se_int *restrict out_index,
                      const double *restrict transition, const double *restrict log_transition,
                      const double *restrict x_init, const double *restrict P_init,
                      const double *restrict log_prob_init, se_int interaction,
                      int sample_timing, int predict_first, double gate, se_int lanes,
                      double *restrict x_out, double *restrict P_out,
                      double *restrict prob_out, se_int *restrict mode_out,
                      double *restrict loglik_out, uint8_t *restrict flag_out,
                      double *restrict x_modes_out, double *restrict P_modes_out,
                      double *restrict x_last, double *restrict P_last,
                      double *restrict log_prob_last, double *restrict report)
{
    const se_int B = lanes < N ? lanes : (N > 0 ? N : 1);
    const int modes_wanted = modes_N == N;
    se_int status = SE_OK;
    report[0] = 0.0;
    report[1] = INFINITY;

    se_arena ar = {NULL, 0};
    bank_scratch s;
    bank_carve(&ar, &s, n, m, l, L, B);
    char *block = se_arena_alloc(&ar);
    if (!block)
        return SE_NO_MEMORY;
    ar.base = block;
    ar.used = 0;
    bank_carve(&ar, &s, n, m, l, L, B);
    memset(s.bad, 0, (size_t)B);

    for (se_int i0 = 0; i0 < N; i0 += B) {
        const se_int nb = B < N - i0 ? B : N - i0;
        se_gather_rows(L, B, 1, log_prob_init, i0, nb, s.log_prob);
        se_gather_modes(n, L, B, 1, x_init, P_init, i0, nb, s.x, s.P);
        se_gather_transitions(L, B, transition_N, transition, log_transition, i0, nb, s.pi,
                              s.log_pi);
        for (se_int j = 0; j < L; j++)
            for (se_int b = 0; b < nb; b++)
                s.prob[j * B + b] = exp(s.log_prob[j * B + b]);
        for (se_int k = 0; k < K; k++) {
            se_gather_samples(m, B, K, y, i0, nb, k, s.yl);
            se_observe(m, B, s.yl, nb, s.obs, s.n_obs);
            if (k > 0 || predict_first) {
                se_gather_samples(l, B, K, u, i0, nb, k > 0 ? k - 1 : 0, s.ul);
                if (!sample_timing) /* "interval": interact, then predict */
                    se_interact(n, L, B, s.x, s.P, s.prob, s.log_prob, s.pi, s.log_pi,
                                interaction, nb, s.log_c, s.w, s.xm, s.Pm);
                se_predict_modes(n, l, L, B, trans_N, trans_K, s.x, s.P, F, G, Qd, trans, i0,
                                 nb, k, s.ul, s.idx, s.Fl, s.Gl, s.Ql, s.AP, s.xs);
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
            for (se_int j = 0; j < L; j++) {
                status = se_innovation(n, m, B, s.x + j * n * B, s.P + j * n * n * B, s.yl,
                                       s.Cl + j * m * n * B, s.Rl + j * m * m * B, s.obs,
                                       s.n_obs, nb, s.e + j * m * B, s.PCt + j * n * m * B,
                                       s.chol + j * m * m * B, s.scale + j * m * B,
                                       s.z + j * m * B, s.nis + j * B, s.loglik + j * B,
                                       s.work, s.bad, report);
                if (status != SE_OK)
                    goto done;
            }
            for (se_int b = 0; b < nb; b++) { /* the gating decision, before anything changes */
                double top = -INFINITY;
                for (se_int j = 0; j < L; j++) {
                    const double lk = s.loglik[j * B + b];
                    const int use = isfinite(lk) && s.nis[j * B + b] <= gate;
                    s.use[j * B + b] = (uint8_t)use;
                    s.a[j * B + b] = use ? s.log_c[j * B + b] + lk : -INFINITY;
                    if (s.a[j * B + b] > top)
                        top = s.a[j * B + b];
                }
                s.flag[b] = SE_ACCEPTED;
                for (se_int j = 0; j < L; j++) {
                    if (top == -INFINITY) { /* no mode can use it: the sample counts as missing */
                        s.flag[b] = SE_GATED;
                        s.use[j * B + b] = 0;
                        s.a[j * B + b] = s.log_c[j * B + b];
                    } else if (!s.use[j * B + b]) {
                        s.flag[b] = SE_PARTLY_GATED;
                    }
                }
            }
            for (se_int j = 0; j < L; j++) {
                double *Pj = s.P + j * n * n * B;
                const uint8_t *usej = s.use + j * B;
                se_correct(n, m, B, s.x + j * n * B, Pj, s.Cl + j * m * n * B,
                           s.Rl + j * m * m * B, usej, nb, s.PCt + j * n * m * B,
                           s.chol + j * m * m * B, s.scale + j * m * B, s.z + j * m * B,
                           s.gain, s.T, s.AP, s.prior);
                if (se_joseph_lost(n, B, Pj, s.prior, usej, nb, s.root, s.lost)) /* rare */
                    se_information_or_repair(n, m, B, Pj, s.prior, s.Cl + j * m * n * B,
                                             s.Rl + j * m * m * B, s.obs, s.n_obs, s.lost, nb,
                                             report);
            }
            /* log mu_j = log c_j + log Lambda_j, normalized */
            se_log_normalize(L, B, s.a, s.prob, s.total, nb);
            se_copy_rows(L, B, s.a, s.log_prob, nb);
            se_report_sample(n, L, B, K, s.x, s.P, s.prob, s.log_prob, s.total, s.flag,
                             s.n_obs, i0, nb, k, modes_wanted, s.xc, s.Pc, s.best, x_out,
                             P_out, prob_out, mode_out, loglik_out, flag_out, x_modes_out,
                             P_modes_out);
        }
        se_scatter_rows(L, B, 1, s.log_prob, i0, nb, log_prob_last);
        se_scatter_modes(n, L, B, 1, s.x, s.P, i0, nb, x_last, P_last);
    }
done:
    free(block);
    return status;
}
