/* The compiled IMM extended-Viterbi filter with gridded switching times.
 *
 * Shankar, Yang & Hespanha, Algorithm 1, on the IMM-EV1 of Ho & Chen (2006): one Kalman filter
 * per destination mode `i`. At each sample every predecessor `j` and, when `j != i`, every
 * switching instant `tau_k` of the grid of eq. (23) is a hypothesis, predicted with the exact
 * transition of that switch (eqs (4)-(5)), `epsilon I` added to its predicted covariance
 * (§IV), and scored by its likelihood `J` of the measurement. `imm_ev1_run` filters every
 * trial over every sample; `imm_ev1_step` processes one sample (the streaming API). Both call
 * se_viterbi_bank, which uses the Kalman equations of linalg.c; trials are laid across SIMD
 * lanes in blocks as in the bank, and so are the hypotheses: a lane holds one hypothesis of one
 * trial, so that each equation runs once per sample over all of them.
 *
 * Each sample takes two passes (se_viterbi_bank, Notes): the likelihoods of all `L^2 g`
 * hypotheses, without forming their predictions; then, once each destination has chosen its
 * predecessor and instant, the prediction and update of the chosen hypotheses only.
 *
 * Layout: the scratch arrays keep the shape and axis order of the quantity they hold, with
 * the lanes last; a lane array's last axis is either B (a block of trials: x (L, n, B),
 * J (L, L, g, B) ...) or W (the lanes of the widest pass, one hypothesis of one trial per
 * lane: xs (n, W), C1 (m, n, W) ...), addressed e.g. J[((j * L + i) * g + k) * B + b]. Every
 * linalg call gets arrays of one lane stride, except the update without prediction
 * (update_only), which pairs B-wide states with the W-wide measurement and scratch arrays:
 * there the measurement of the sample is gathered at stride B (the only lanes it uses, as its
 * width is nb) and the scratch is read at stride B, which gives the same numbers as stride W.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "imm_ev1.h"
#include "linalg.h"

/* the sizes of one call: states, outputs, inputs, modes, grid points, block of trials and the
 * lanes of the widest pass */
typedef struct {
    se_int n, m, l, L, g, B, W;
} dims;

/* the workspaces: pred of hypothesis (xs, Ps, Fl, Gl, Ql, FP, xv), inn of se_innovation and
 * fix of se_update (se_innovation_ws, se_update_ws: linalg.h); all W lanes wide */
typedef struct {
    double *xs, *Ps, *Fl, *Gl, *Ql, *FP, *xv;
} pred_ws;

/* v[a, q nb + b] = v[a, b] for every lane below width: each trial's row, in lanes
 * 0 .. nb - 1, repeated for every hypothesis. v (rows, W) */
static void spread(se_int rows, se_int W, double *restrict v, se_int nb, se_int width)
{
    se_int nq = width / nb;
    for (se_int a = 0; a < rows; a++) {
        double *restrict va = v + a * W;
        for (se_int q = 1; q < nq; q++)
            for (se_int b = 0; b < nb; b++)
                va[q * nb + b] = va[b];
    }
}

/* xs[:, l] = x[source[l], :, l % nb], Ps[:, :, l] = P[source[l], :, :, l % nb]: in each lane,
 * the filter of mode source[l] of its trial. x (L, n, B), P (L, n, n, B), xs (n, W),
 * Ps (n, n, W). (A hypothesis whose nb lanes share their source, as every one of the likelihood
 * pass does, is copied row by row; the others lane by lane.) */
static void gather_states(se_int n, se_int B, se_int W, const double *restrict x,
                          const double *restrict P, const se_int *restrict source, se_int nb,
                          se_int width, double *restrict xs, double *restrict Ps)
{
    se_int nq = width / nb;
    for (se_int q = 0; q < nq; q++) {
        const se_int *restrict sq = source + q * nb;
        int uniform = 1;
        for (se_int b = 1; b < nb; b++)
            uniform &= sq[b] == sq[0];
        double *restrict xq = xs + q * nb, *restrict Pq = Ps + q * nb;
        if (uniform) {
            const double *restrict xj = x + sq[0] * n * B, *restrict Pj = P + sq[0] * n * n * B;
            for (se_int r = 0; r < n; r++)
                for (se_int b = 0; b < nb; b++)
                    xq[r * W + b] = xj[r * B + b];
            for (se_int rc = 0; rc < n * n; rc++)
                for (se_int b = 0; b < nb; b++)
                    Pq[rc * W + b] = Pj[rc * B + b];
            continue;
        }
        for (se_int b = 0; b < nb; b++) {
            const double *restrict xj = x + sq[b] * n * B + b;
            const double *restrict Pj = P + sq[b] * n * n * B + b;
            for (se_int r = 0; r < n; r++)
                xq[r * W + b] = xj[r * B];
            for (se_int rc = 0; rc < n * n; rc++)
                Pq[rc * W + b] = Pj[rc * B];
        }
    }
}

/* P <- P + epsilon I: the inflation of every predicted covariance (Shankar et al. §IV, so that
 * the inverse of P_k|k-1 stays bounded, Assumption 2). P (n, n, W) */
static void inflate(se_int n, se_int W, double *restrict P, double epsilon, se_int width)
{
    for (se_int r = 0; r < n; r++) {
        double *restrict Prr = P + (r * n + r) * W;
        for (se_int b = 0; b < width; b++)
            Prr[b] += epsilon;
    }
}

/* Predict in each lane the filter source[l] of its trial with transition entry[l] and form its
 * innovation.
 *
 * x- = F x + G u, P- = F P F' + Qd + epsilon I (Shankar et al. eqs (6)-(7), §IV) into
 * pred->xs, pred->Ps, then se_innovation of y against (x-, P-) (eq. (8)) into inn: a lane whose
 * innovation covariance fails its factorization has P- repaired, as in the bank's filter.
 * Returns its status. x (L, n, B), P (L, n, n, B); every other lane array W wide.
 */
static se_int hypothesis(const dims *s, const double *x, const double *P, const se_int *source,
                         const double *F, const double *G, const double *Qd,
                         const se_int *entry, const double *u, double epsilon, const double *y,
                         const double *C, const double *R, const double *obs,
                         const double *n_obs, se_int nb, se_int width, const pred_ws *pred,
                         const se_innovation_ws *inn, double *report)
{
    const se_int n = s->n, l = s->l, W = s->W;
    gather_states(n, s->B, W, x, P, source, nb, width, pred->xs, pred->Ps);
    se_gather_matrices(n, n, W, F, entry, width, pred->Fl);
    se_gather_matrices(n, l, W, G, entry, width, pred->Gl);
    se_gather_matrices(n, n, W, Qd, entry, width, pred->Ql);
    se_predict(n, l, W, pred->xs, pred->Ps, pred->Fl, pred->Gl, u, pred->Ql, width, pred->FP,
               pred->xv);
    inflate(n, W, pred->Ps, epsilon, width);
    return se_innovate(n, s->m, W, pred->xs, pred->Ps, y, C, R, obs, n_obs, width, inn, report);
}

/* J of every hypothesis, one per lane (width lanes); use where it accepts the measurement.
 *
 * Lane l holds the switch from source[l] to a destination i at an instant tau, transition
 * entry[l], with C, R those of i and H = C_i F, Gy = C_i G,
 * S0 = C_i (Qd + epsilon I) C_i' + R_i of the transition. J is the likelihood of the
 * measurement given the predecessor's posterior (x_j, P_j) and the switch:
 * log N(y; C_i x-, C_i P- C_i' + R_i), or with printed the paper's literal
 * J_k(tau) = N(y; C_i x-, R_i) (§IV), each -inf where the hypothesis rejects y (its normalized
 * innovation squared is not finite or exceeds gate).
 *
 * It is evaluated without forming the prediction: the innovation of the prediction is
 * (y - C_i G u) - H x_j, with covariance H P_j H' + S0 (eqs (6)-(8) seen through C_i), which
 * is se_innovation of (x_j, P_j) with output matrix H and noise S0: O(m n^2) per hypothesis
 * instead of O(n^3). If a factorization fails there, the hypotheses are predicted in full
 * instead (hypothesis, which repairs P-). Returns a status.
 */
static se_int likelihoods(const dims *s, const double *x, const double *P, se_int nb,
                          se_int width, const double *y, const double *u, const double *obs,
                          const double *n_obs, const double *F, const double *G,
                          const double *Qd, const double *H, const double *Gy,
                          const double *S0, const double *C, const double *R,
                          const se_int *source, const se_int *entry, double epsilon,
                          double gate, int printed, double *zero, double *yh,
                          const pred_ws *pred, const se_innovation_ws *inn, double *report,
                          double *restrict J, uint8_t *restrict use)
{
    const se_int n = s->n, m = s->m, W = s->W;
    double *xw = pred->xs, *Pw = pred->Ps;
    const double *nis = inn->nis, *loglik = inn->loglik;
    se_int status;
    gather_states(n, s->B, W, x, P, source, nb, width, xw, Pw);
    se_residual(s->l, m, W, u, y, Gy, width, yh); /* y less the response to the input, (C G) u */
    int full = se_innovate(n, m, W, xw, Pw, yh, H, S0, obs, n_obs, width, inn, NULL) != SE_OK;
    if (full) { /* the predictions themselves, repaired where needed */
        status = hypothesis(s, x, P, source, F, G, Qd, entry, u, epsilon, y, C, R, obs, n_obs,
                            nb, width, pred, inn, report);
        if (status != SE_OK)
            return status;
    }
    for (se_int b = 0; b < width; b++) {
        use[b] = se_passes_gate(loglik[b], nis[b], gate);
        J[b] = use[b] ? loglik[b] : -INFINITY;
    }
    if (!printed)
        return SE_OK;
    if (full)
        status = se_innovate(n, m, W, xw, zero, y, C, R, obs, n_obs, width, inn, NULL);
    else
        status = se_innovate(n, m, W, xw, zero, yh, H, R, obs, n_obs, width, inn, NULL);
    if (status != SE_OK)
        return status;
    for (se_int b = 0; b < width; b++) /* N(y; C x-, R): -inf where its quadratic form overflows */
        J[b] = use[b] && nis[b] < INFINITY ? loglik[b] : -INFINITY;
    return SE_OK;
}

/* J[j, i, k, b] and use[j, i, k, b] from lane q nb + b of the hypothesis
 * hypotheses[q] = (j, i, k). J_lanes, use_lanes (W,), hypotheses (n_hyp, 3),
 * J, use (L, L, g, B) */
static void by_pair(se_int L, se_int g, se_int B, se_int n_hyp, const double *restrict J_lanes,
                    const uint8_t *restrict use_lanes, const se_int *restrict hypotheses,
                    se_int nb, double *restrict J, uint8_t *restrict use)
{
    for (se_int q = 0; q < n_hyp; q++) {
        se_int j = hypotheses[3 * q], i = hypotheses[3 * q + 1], k = hypotheses[3 * q + 2];
        se_int at = ((j * L + i) * g + k) * B;
        for (se_int b = 0; b < nb; b++) {
            J[at + b] = J_lanes[q * nb + b];
            use[at + b] = use_lanes[q * nb + b];
        }
    }
}

/* Each destination's predecessor and switching instant (Algorithm 1, Ho & Chen).
 *
 * A lane where every hypothesis rejects the measurement is an outlier: there J = 0 and no
 * hypothesis is updated (a missing sample). Per pair (j, i): with "max" the grid maximizer of
 * eq. (23), b_ji = J(tau_k*) (the first on a tie); with marginal, the instant integrated out
 * under a uniform prior on the grid, b_ji = (1/g) sum_k J_k (in the log domain), weights
 * w_k = J_k / sum J and mean instant sum w_k tau_k (a pair whose every hypothesis rejected y
 * gets zero weights and instant, so its merged posterior is zero: it has weight zero). Path
 * weights log a_j + log b_ji (+ log pi_ji); destination i keeps j^ = argmax_j of the path
 * weight (by_path, the extended Viterbi rule) or of b_ji (the printed line
 * "j^ = max_j b_ij"), and gets log a_i = path weight of j^ (unnormalized, into a) and offset =
 * the instant, NaN when j^ == i.
 *
 * J, use, w (L, L, g, B); log_w, chosen, a, offset (L, B); log_transition (L, L); tau (g,);
 * outlier (B,); log_b, best_k, tau_pair (L, L, B).
 */
static void choose(se_int L, se_int g, se_int B, double *restrict J, uint8_t *restrict use,
                   const double *restrict log_w, const double *restrict log_transition,
                   const double *restrict tau, int marginal, int by_path, se_int nb,
                   uint8_t *restrict outlier, double *restrict log_b, se_int *restrict best_k,
                   double *restrict w, double *restrict tau_pair, se_int *restrict chosen,
                   double *restrict a, double *restrict offset)
{
    const double log_g = log((double)g);
#define AT3(j, i, k, b) ((((j) * L + (i)) * g + (k)) * B + (b))
#define AT2(j, i, b) (((j) * L + (i)) * B + (b))
    for (se_int b = 0; b < nb; b++) {
        int out = 1;
        for (se_int j = 0; j < L; j++)
            for (se_int i = 0; i < L; i++)
                for (se_int k = 0; k < (j != i ? g : 1); k++)
                    out &= J[AT3(j, i, k, b)] == -INFINITY;
        outlier[b] = (uint8_t)out;
        for (se_int j = 0; j < L; j++) {
            for (se_int i = 0; i < L; i++) {
                if (out) { /* every hypothesis keeps its prediction, J = 0 */
                    for (se_int k = 0; k < (j != i ? g : 1); k++) {
                        J[AT3(j, i, k, b)] = 0.0;
                        use[AT3(j, i, k, b)] = 0;
                    }
                }
                if (j == i) { /* one hypothesis stands for the g equal ones */
                    log_b[AT2(j, i, b)] = J[AT3(j, i, 0, b)];
                    best_k[AT2(j, i, b)] = 0;
                    for (se_int k = 0; k < g; k++)
                        w[AT3(j, i, k, b)] = k == 0 && J[AT3(j, i, 0, b)] > -INFINITY ? 1.0 : 0.0;
                    continue;
                }
                double top = J[AT3(j, i, 0, b)];
                se_int kt = 0;
                for (se_int k = 1; k < g; k++) {
                    if (J[AT3(j, i, k, b)] > top) {
                        top = J[AT3(j, i, k, b)];
                        kt = k;
                    }
                }
                best_k[AT2(j, i, b)] = kt;
                if (!marginal) {
                    log_b[AT2(j, i, b)] = top;
                    tau_pair[AT2(j, i, b)] = tau[kt];
                    continue;
                }
                if (top == -INFINITY) {
                    for (se_int k = 0; k < g; k++)
                        w[AT3(j, i, k, b)] = 0.0;
                    log_b[AT2(j, i, b)] = -INFINITY;
                    tau_pair[AT2(j, i, b)] = 0.0;
                    continue;
                }
                double acc = 0.0;
                for (se_int k = 0; k < g; k++)
                    acc += exp(J[AT3(j, i, k, b)] - top);
                double log_acc = log(acc);
                double t = 0.0;
                for (se_int k = 0; k < g; k++) {
                    double wk = exp((J[AT3(j, i, k, b)] - top) - log_acc);
                    w[AT3(j, i, k, b)] = wk;
                    t += wk * tau[k];
                }
                tau_pair[AT2(j, i, b)] = t;
                log_b[AT2(j, i, b)] = (top + log_acc) - log_g;
            }
        }
        for (se_int i = 0; i < L; i++) {
            chosen[i * B + b] = 0;
            double best = -INFINITY;
            for (se_int j = 0; j < L; j++) {
                double path = (log_w[j * B + b] + log_b[AT2(j, i, b)]) + log_transition[j * L + i];
                double score = by_path ? path : log_b[AT2(j, i, b)];
                if (j == 0 || score > best) {
                    chosen[i * B + b] = j;
                    best = score;
                    a[i * B + b] = path;
                }
            }
            se_int j = chosen[i * B + b];
            offset[i * B + b] = j == i ? NAN : tau_pair[AT2(j, i, b)];
        }
    }
#undef AT3
#undef AT2
}

/* xo[:, b] = xs[:, first + b], Po[:, :, b] = Ps[:, :, first + b] for the nb trials of one
 * hypothesis. xs (n, W), Ps (n, n, W), xo (n, B), Po (n, n, B) */
static void from_lanes(se_int n, se_int W, se_int B, const double *restrict xs,
                       const double *restrict Ps, se_int first, se_int nb, double *restrict xo,
                       double *restrict Po)
{
    for (se_int r = 0; r < n; r++) {
        for (se_int b = 0; b < nb; b++)
            xo[r * B + b] = xs[r * W + first + b];
        for (se_int c = 0; c < n; c++)
            for (se_int b = 0; b < nb; b++)
                Po[(r * n + c) * B + b] = Ps[(r * n + c) * W + first + b];
    }
}

/* Each destination's posterior from its chosen predecessor (Algorithm 1: "compute
 * x^i_k+1, P^i_k+1 from x^j_k, P^j_k and t^ij_k").
 *
 * "max": the hypothesis of the chosen instant, predicted and updated (eqs (4)-(10));
 * marginal: every grid hypothesis of the chosen pair, merged by moment matching with the
 * weights w of choose (se_moments). A hypothesis that rejected the measurement keeps its
 * prediction. Lane (i per + q) nb + b holds destination i, hypothesis q (of per = g or 1),
 * trial b; C, R are laid out so. Into x_new (L, n, B), P_new (L, n, n, B); returns a status.
 */
static se_int predict_chosen(const dims *s, const double *x, const double *P, se_int d,
                             const se_int *restrict chosen, const se_int *restrict best_k,
                             const uint8_t *restrict use, const double *restrict w,
                             const double *F, const double *G, const double *Qd,
                             const double *u, double epsilon, const double *y, const double *C,
                             const double *R, const double *obs, const double *n_obs,
                             int marginal, se_int nb, se_int *restrict source,
                             se_int *restrict entry, uint8_t *restrict use_lanes,
                             double *restrict w_lanes, const pred_ws *pred,
                             const se_innovation_ws *inn, const se_update_ws *fix,
                             double *report, double *restrict xg, double *restrict Pg,
                             double *restrict x_new, double *restrict P_new)
{
    const se_int n = s->n, m = s->m, L = s->L, g = s->g, B = s->B, W = s->W;
    const se_int per = marginal ? g : 1;
    const se_int width = L * per * nb;
    for (se_int i = 0; i < L; i++) {
        for (se_int q = 0; q < per; q++) {
            for (se_int b = 0; b < nb; b++) {
                se_int lane = (i * per + q) * nb + b, j = chosen[i * B + b];
                se_int k = j == i ? 0 : (marginal ? q : best_k[(j * L + i) * B + b]);
                source[lane] = j;
                entry[lane] = ((d * L + j) * L + i) * g + k;
                use_lanes[lane] = use[((j * L + i) * g + k) * B + b];
            }
        }
    }
    se_int status = hypothesis(s, x, P, source, F, G, Qd, entry, u, epsilon, y, C, R, obs, n_obs,
                               nb, width, pred, inn, report);
    if (status != SE_OK)
        return status;
    double *xs = pred->xs, *Ps = pred->Ps;
    se_update(n, m, W, xs, Ps, C, R, obs, n_obs, use_lanes, width, inn->PCt, inn->chol,
              inn->scale, inn->z, fix, report);
    for (se_int i = 0; i < L; i++) {
        double *xi = x_new + i * n * B, *Pi = P_new + i * n * n * B;
        if (!marginal) {
            from_lanes(n, W, B, xs, Ps, i * nb, nb, xi, Pi);
            continue;
        }
        for (se_int q = 0; q < g; q++) {
            for (se_int b = 0; b < nb; b++)
                w_lanes[q * B + b] = w[((chosen[i * B + b] * L + i) * g + q) * B + b];
            from_lanes(n, W, B, xs, Ps, (i * g + q) * nb, nb, xg + q * n * B,
                       Pg + q * n * n * B);
        }
        se_moments(n, g, B, w_lanes, xg, Pg, nb, xi, Pi);
    }
    return SE_OK;
}

/* A sample without prediction (the first of a record): every mode's filter updated with its
 * prior (Shankar et al. eqs (8)-(10)), log a_j += log N(y; C_j x_j, S_j), -inf where mode j
 * rejects y; where every mode rejects it, nothing is updated and the weights are kept (an
 * outlier). Unnormalized weights into a; returns a status.
 *
 * Every lane array of this pass is read at stride B: x (L, n, B), P (L, n, n, B),
 * log_w, use, a (L, B), y, obs (m, B), Cl (L, m, n, B), Rl (L, m, m, B), and the W-wide
 * scratch of inn and fix as B-wide arrays (see the top of this file).
 */
static se_int update_only(const dims *s, double *x, double *P, const double *restrict log_w,
                          const double *y, const double *Cl, const double *Rl,
                          const double *obs, const double *n_obs, double gate, se_int nb,
                          uint8_t *use, double *restrict a, uint8_t *restrict outlier,
                          const se_innovation_ws *inn, const se_update_ws *fix, double *report)
{
    const se_int n = s->n, m = s->m, L = s->L, B = s->B;
    const double *nis = inn->nis, *loglik = inn->loglik;
    for (se_int j = 0; j < L; j++) {
        double *xj = x + j * n * B, *Pj = P + j * n * n * B;
        const double *Cj = Cl + j * m * n * B, *Rj = Rl + j * m * m * B;
        uint8_t *uj = use + j * B;
        se_int status = se_innovate(n, m, B, xj, Pj, y, Cj, Rj, obs, n_obs, nb, inn, report);
        if (status != SE_OK)
            return status;
        for (se_int b = 0; b < nb; b++) {
            uj[b] = se_passes_gate(loglik[b], nis[b], gate);
            a[j * B + b] = uj[b] ? log_w[j * B + b] + loglik[b] : -INFINITY;
        }
        se_update(n, m, B, xj, Pj, Cj, Rj, obs, n_obs, uj, nb, inn->PCt, inn->chol, inn->scale,
                  inn->z, fix, report);
    }
    for (se_int b = 0; b < nb; b++) {
        int out = 1;
        for (se_int j = 0; j < L; j++)
            out &= !use[j * B + b];
        outlier[b] = (uint8_t)out;
        if (out) /* the sample counts as missing; no mode was updated */
            for (se_int j = 0; j < L; j++)
                a[j * B + b] = log_w[j * B + b];
    }
    return SE_OK;
}

/* ---- the kernel's scratch: one block, carved -------------------------------------------- */

typedef struct {
    double *x, *P, *x_new, *P_new, *log_w, *prob, *total, *offset, *a, *J, *log_b, *w;
    double *tau_pair, *w_lanes, *xg, *Pg, *Cl, *Rl, *yw, *uw, *yh, *obs, *n_obs, *J_lanes;
    double *C1, *R1, *C2, *R2, *H1, *Gy1, *S1, *zero, *xc, *Pc;
    se_int *best, *hypotheses, *chosen, *best_k, *source, *entry, *source2, *entry2;
    uint8_t *outlier, *use, *update_use, *use_lanes;
    pred_ws pred;
    se_innovation_ws inn;
    se_update_ws fix;
} scratch;

static void layout(const dims *s, se_int n_hyp, se_arena *ar, scratch *t)
{
    const size_t n = (size_t)s->n, m = (size_t)s->m, l = (size_t)s->l, L = (size_t)s->L;
    const size_t g = (size_t)s->g, B = (size_t)s->B, W = (size_t)s->W;
    /* xc, Pc: the mixture over the destinations (combined); C1, R1: the likelihood pass's lanes;
     * C2, R2: the update pass's */
    SE_DOUBLES(ar, L * n * B, &t->x, &t->x_new);
    SE_DOUBLES(ar, L * n * n * B, &t->P, &t->P_new);
    SE_DOUBLES(ar, n * B, &t->xc);
    SE_DOUBLES(ar, n * n * B, &t->Pc);
    SE_DOUBLES(ar, L * B, &t->log_w, &t->prob, &t->offset, &t->a);
    SE_DOUBLES(ar, B, &t->total);
    SE_DOUBLES(ar, L * L * g * B, &t->J, &t->w);
    SE_DOUBLES(ar, L * L * B, &t->log_b, &t->tau_pair);
    SE_DOUBLES(ar, g * B, &t->w_lanes);
    SE_DOUBLES(ar, g * n * B, &t->xg);
    SE_DOUBLES(ar, g * n * n * B, &t->Pg);
    SE_DOUBLES(ar, L * m * n * B, &t->Cl);
    SE_DOUBLES(ar, L * m * m * B, &t->Rl);
    SE_DOUBLES(ar, m * W, &t->yw, &t->yh, &t->obs);
    SE_DOUBLES(ar, l * W, &t->uw);
    SE_DOUBLES(ar, W, &t->n_obs, &t->J_lanes);
    SE_DOUBLES(ar, m * n * W, &t->C1, &t->C2, &t->H1);
    SE_DOUBLES(ar, m * m * W, &t->R1, &t->R2, &t->S1);
    SE_DOUBLES(ar, m * l * W, &t->Gy1);
    SE_DOUBLES(ar, n * n * W, &t->zero, &t->pred.Ps, &t->pred.Fl, &t->pred.Ql, &t->pred.FP);
    SE_DOUBLES(ar, n * W, &t->pred.xs, &t->pred.xv);
    SE_DOUBLES(ar, n * l * W, &t->pred.Gl);
    se_carve_innovation(ar, n, m, W, &t->inn);
    se_carve_update(ar, n, m, W, &t->fix);
    SE_INTS(ar, B, &t->best);
    SE_INTS(ar, (size_t)n_hyp * 3, &t->hypotheses);
    SE_INTS(ar, L * B, &t->chosen);
    SE_INTS(ar, L * L * B, &t->best_k);
    SE_INTS(ar, W, &t->source, &t->entry, &t->source2, &t->entry2);
    SE_FLAGS(ar, B, &t->outlier);
    SE_FLAGS(ar, L * L * g * B, &t->use);
    SE_FLAGS(ar, L * B, &t->update_use);
    SE_FLAGS(ar, W, &t->use_lanes);
}

/* Filter N trials over K samples with the IMM-EV1 of Shankar et al., Algorithm 1.
 *
 * Parameters
 * ----------
 * y, u : (N, K, m), (N, K, l) float64
 *     Measurements and inputs, as in the bank's filter_bank.
 * table : (K,) int64
 *     The interval length d into each sample (entry 0 unused unless predict_first).
 * F, G, Qd : (M, n, n), (M, n, l), (M, n, n) float64
 *     Transitions of the hypotheses, M = D L L g: entry ((d L + j) L + i) g + k is the switch
 *     from j to i at tau[d, k] over interval length d (for j == i no switch, read at k = 0).
 * H, Gy, S0 : (M, m, n), (M, m, l), (M, m, m) float64
 *     C_i F, C_i G and C_i (Qd + epsilon I) C_i' + R_i of each entry.
 * tau : (D, g) float64
 *     The grid of switching instants (offsets in the interval) of each interval length.
 * C, R : (L, m, n), (L, m, m) float64
 * log_transition : (L, L) float64
 *     log pi_ji added to the path weights (zeros for none).
 * epsilon : float
 *     The inflation of every predicted covariance (§IV).
 * x_init, P_init, log_w_init, chosen_init, offset_init
 *     State before the first sample: (N, L, n), (N, L, n, n), normalized log weights (N, L),
 *     predecessors (N, L) int64, switch offsets (N, L).
 * predict_first : bool
 *     Whether the first sample is predicted into (a streaming step) or only updated.
 * gate : float
 *     Largest normalized innovation squared a hypothesis accepts.
 * printed, marginal, by_path, combined : bool
 *     likelihood="printed", switch_time="marginal", predecessor="path", estimate="mixture".
 * lanes : int
 *     Trials per block.
 * x_out, P_out, prob_out, mode_out, offset_out, outlier_out
 *     Written: the MAP destination's x (N, K, n), P (N, K, n, n) (with combined, the moments
 *     of the mixture of the destinations' posteriors weighed by their normalized weights, as
 *     the IMM's output, Bar-Shalom, Li & Kirubarajan §11.6.6), normalized weights
 *     (N, K, L), the MAP destination (the first on a tie), its switch offset (NaN without a
 *     switch) and whether every hypothesis rejected the sample (N, K).
 * x_last, P_last, log_w_last, chosen_last, offset_last
 *     Written: the state after the last sample, shaped as the _init arrays.
 * report : (2,) float64
 *     Written: covariances repaired and the smallest eigenvalue one had (as the bank's).
 *
 * Returns
 * -------
 * status : int
 *     SE_OK, or the failure code of the innovation covariance (of a hypothesis, or of a
 *     destination's update) that stopped the kernel (outputs then incomplete); SE_NO_MEMORY if
 *     the scratch could not be allocated.
 *
 * Notes
 * -----
 * Each sample predicted into takes two passes over lanes that hold one hypothesis of one trial
 * each. likelihoods scores the L + L (L - 1) g distinct hypotheses (the no-switch transition
 * is the same at every instant) from the predecessors' posteriors without forming their
 * predictions (an m x n output matrix instead of an n x n transition); choose picks each
 * destination's predecessor and instant; then only the chosen hypotheses are predicted and
 * updated (predict_chosen: L, or L g for "marginal", per trial). The results are those of
 * updating every hypothesis and selecting afterwards, as Algorithm 1 states. Gating and
 * ill-conditioned covariances are handled lane by lane as in the bank's filter.
 *
 * The block of trials is min(lanes, N) lanes wide (se_lanes): lanes beyond N would never be
 * used, so the numbers do not depend on it. Returns SE_OK with only the report written for
 * N = 0.
 */
se_int se_viterbi_bank(SE_VITERBI_BANK_PARAMETERS)
{
    se_report_start(report);
    if (N <= 0)
        return SE_OK;
    const se_int B = se_lanes(lanes, N);
    const se_int per = marginal ? g : 1; /* hypotheses predicted per destination */
    const se_int n_hyp = L + L * (L - 1) * g;
    const se_int W = (n_hyp > L * per ? n_hyp : L * per) * B; /* lanes of the widest pass */
    const dims s = {n, m, l, L, g, B, W};
    scratch t;
    se_arena ar = {NULL, 0};
    do
        layout(&s, n_hyp, &ar, &t);
    while (se_arena_open(&ar));
    if (ar.base == NULL)
        return SE_NO_MEMORY;

    se_int q = 0;
    for (se_int j = 0; j < L; j++) {
        for (se_int i = 0; i < L; i++) {
            for (se_int k = 0; k < (j != i ? g : 1); k++) {
                t.hypotheses[3 * q] = j;
                t.hypotheses[3 * q + 1] = i;
                t.hypotheses[3 * q + 2] = k;
                q++;
            }
        }
    }
    double *x = t.x, *P = t.P, *x_new = t.x_new, *P_new = t.P_new;
    se_int *entry = t.entry, *source = t.source;
    se_int status = SE_OK;
    for (se_int i = 0; i < L; i++) { /* every trial's C_i, R_i, for the update without prediction */
        for (se_int b = 0; b < B; b++)
            entry[b] = i;
        se_gather_matrices(m, n, B, C, entry, B, t.Cl + i * m * n * B);
        se_gather_matrices(m, m, B, R, entry, B, t.Rl + i * m * m * B);
    }
    for (se_int i0 = 0; i0 < N; i0 += B) {
        const se_int nb = se_block_trials(B, N, i0);
        const se_int width1 = n_hyp * nb, width2 = L * per * nb;
        for (q = 0; q < n_hyp; q++) { /* the lanes' predecessors and destinations' C, R */
            for (se_int b = 0; b < nb; b++) {
                source[q * nb + b] = t.hypotheses[3 * q];
                entry[q * nb + b] = t.hypotheses[3 * q + 1];
            }
        }
        se_gather_matrices(m, n, W, C, entry, width1, t.C1);
        se_gather_matrices(m, m, W, R, entry, width1, t.R1);
        for (se_int lane = 0; lane < width2; lane++)
            entry[lane] = lane / (per * nb);
        se_gather_matrices(m, n, W, C, entry, width2, t.C2);
        se_gather_matrices(m, m, W, R, entry, width2, t.R2);
        se_int d_last = -1;
        se_gather_rows(L, B, 1, log_w_init, i0, nb, t.log_w);
        se_gather_rows_int(L, B, 1, chosen_init, i0, nb, t.chosen);
        se_gather_rows(L, B, 1, offset_init, i0, nb, t.offset);
        se_gather_modes(n, L, B, 1, x_init, P_init, i0, nb, x, P);
        for (se_int k = 0; k < K; k++) {
            const int predicted = k > 0 || predict_first;
            if (predicted) {
                const se_int width = width1 > width2 ? width1 : width2;
                se_gather_samples(m, W, K, y, i0, nb, k, t.yw);
                spread(m, W, t.yw, nb, width);
                se_observe(m, W, t.yw, width, t.obs, t.n_obs);
                const se_int d = table[k];
                se_gather_samples(l, W, K, u, i0, nb, k > 0 ? k - 1 : 0, t.uw);
                spread(l, W, t.uw, nb, width);
                if (d != d_last) { /* the hypotheses' transitions as the likelihood pass reads them */
                    for (q = 0; q < n_hyp; q++) {
                        se_int j = t.hypotheses[3 * q], i = t.hypotheses[3 * q + 1];
                        se_int kk = t.hypotheses[3 * q + 2];
                        for (se_int b = 0; b < nb; b++)
                            entry[q * nb + b] = ((d * L + j) * L + i) * g + kk;
                    }
                    se_gather_matrices(m, n, W, H, entry, width1, t.H1);
                    se_gather_matrices(m, l, W, Gy, entry, width1, t.Gy1);
                    se_gather_matrices(m, m, W, S0, entry, width1, t.S1);
                    d_last = d;
                }
                status = likelihoods(&s, x, P, nb, width1, t.yw, t.uw, t.obs, t.n_obs, F, G, Qd,
                                     t.H1, t.Gy1, t.S1, t.C1, t.R1, source, entry, epsilon, gate,
                                     printed, t.zero, t.yh, &t.pred, &t.inn, report, t.J_lanes,
                                     t.use_lanes);
                if (status != SE_OK)
                    goto done;
                by_pair(L, g, B, n_hyp, t.J_lanes, t.use_lanes, t.hypotheses, nb, t.J, t.use);
                choose(L, g, B, t.J, t.use, t.log_w, log_transition, tau + d * g, marginal,
                       by_path, nb, t.outlier, t.log_b, t.best_k, t.w, t.tau_pair, t.chosen,
                       t.a, t.offset);
                status = predict_chosen(&s, x, P, d, t.chosen, t.best_k, t.use, t.w, F, G, Qd,
                                        t.uw, epsilon, t.yw, t.C2, t.R2, t.obs, t.n_obs, marginal,
                                        nb, t.source2, t.entry2, t.use_lanes, t.w_lanes, &t.pred,
                                        &t.inn, &t.fix, report, t.xg, t.Pg, x_new, P_new);
                if (status != SE_OK)
                    goto done;
                double *sw = x;
                x = x_new;
                x_new = sw;
                sw = P;
                P = P_new;
                P_new = sw;
            } else { /* the measurement at stride B: this pass is nb lanes wide */
                se_gather_samples(m, B, K, y, i0, nb, k, t.yw);
                se_observe(m, B, t.yw, nb, t.obs, t.n_obs);
                status = update_only(&s, x, P, t.log_w, t.yw, t.Cl, t.Rl, t.obs, t.n_obs, gate,
                                     nb, t.update_use, t.a, t.outlier, &t.inn, &t.fix, report);
                if (status != SE_OK)
                    goto done;
            }
            se_log_normalize(L, B, t.a, t.prob, t.total, nb); /* a^i = b_ji a^j (pi_ji), normalized */
            for (se_int j = 0; j < L; j++)
                for (se_int b = 0; b < nb; b++)
                    t.log_w[j * B + b] = t.a[j * B + b];
            if (combined)
                se_combine(n, L, B, x, P, t.prob, t.log_w, nb, t.xc, t.Pc, t.best);
            for (se_int b = 0; b < nb; b++) {
                se_int i = i0 + b, best = 0;
                for (se_int j = 1; j < L; j++)
                    if (t.log_w[j * B + b] > t.log_w[best * B + b])
                        best = j;
                mode_out[i * K + k] = best;
                offset_out[i * K + k] = t.offset[best * B + b];
                outlier_out[i * K + k] = t.outlier[b];
                for (se_int j = 0; j < L; j++)
                    prob_out[(i * K + k) * L + j] = t.prob[j * B + b];
                if (combined)
                    se_write_lane(n, B, K, t.xc, t.Pc, b, i, k, x_out, P_out);
                else
                    se_write_lane(n, B, K, x + best * n * B, P + best * n * n * B, b, i, k,
                                  x_out, P_out);
            }
        }
        se_scatter_rows(L, B, 1, t.log_w, i0, nb, log_w_last);
        se_scatter_rows_int(L, B, 1, t.chosen, i0, nb, chosen_last);
        se_scatter_rows(L, B, 1, t.offset, i0, nb, offset_last);
        se_scatter_modes(n, L, B, 1, x, P, i0, nb, x_last, P_last);
    }
done:
    se_arena_close(&ar);
    return status;
}
