/* The compiled backward pass of the fixed-interval smoother with mode probabilities; the
 * Python side is switchest.engine.smoother.kim_smooth.
 *
 * Kim (1994, J. Econometrics 60, "Dynamic linear models with Markov-switching", §2.2), as
 * applied to collapsed (GPB2 / IMM) filters by Murphy (1998, "Switching Kalman filters", tech.
 * report, §3-4): from the filtered mode-matched posteriors x_j(k|k), P_j(k|k) and
 * probabilities mu_j(k|k), for k = K-2 .. 0 and every pair (mode j at k, mode i at k+1),
 *
 * - the Rauch-Tung-Striebel step (Rauch, Tung & Striebel 1965) of x_j(k|k) towards
 *   x_i(k+1|K), P_i(k+1|K) through the transition of the interval k -> k+1 of the mode that
 *   governs it, the *moving* mode m (table entry trans[k+1, m]):
 *   x_ji = x_j + J (x_i(k+1|K) - x_pred), P_ji = P_j + J (P_i(k+1|K) - P_pred) J',
 *   x_pred = F_m x_j + G_m u_k, P_pred = F_m P_j F_m' + Qd_m, J = P_j F_m' P_pred^-1, with
 *
 *   - m = j in the "sample" timing (switchest's: the mode of sample k governs y_k and the
 *     interval after it, x_{k+1} = F(s_k) x_k + G(s_k) u_k + w_k; Costa, Fragoso & Marques
 *     2005, "Discrete-Time Markov Jump Linear Systems", eq. (3.1)): x_pred, P_pred, its
 *     factorization and J do not depend on i and are computed once per j, L of them per
 *     sample instead of L^2;
 *   - m = i in the "interval" timing (Bar-Shalom, Li & Kirubarajan 2001, §11.6, and Kim's own
 *     model, 1994 §2, where the mode of sample k+1 governs the step into it): once per pair;
 * - the pair's probability mu_ji(k|K) = mu_i(k+1|K) mu_j(k|k) pi_ji / c_i with
 *   c_i = sum_j' mu_j'(k|k) pi_j'i (Kim 1994 §2.2; log domain, a pair whose c_i is zero gets
 *   weight zero);
 * - the merge over i: mu_j(k|K) = sum_i mu_ji, x_j(k|K) = sum_i (mu_ji / mu_j) x_ji,
 *   P_j(k|K) = sum_i (mu_ji / mu_j) (P_ji + (x_ji - x_j)(x_ji - x_j)') (Kim 1994 §2.2;
 *   Murphy 1998 §4), and the combined output, the moments of the mixture over j (se_combine).
 *
 * At k = K-1 the smoothed posterior is the filtered one.
 *
 * Why the moving mode. Kim's step approximates p(x_k | s_k = j, s_{k+1} = i, Y) by
 * conditioning mode j's filtered Gaussian on x_{k+1} and averaging over
 * x_{k+1} ~ N(x_i(k+1|K), P_i(k+1|K)): given x_{k+1} and the modes the later measurements say
 * nothing more of x_k (Kim 1994 §2.2), and the chain is independent of the state, so
 * p(x_k | x_{k+1}, s_k = j, s_{k+1} = i, Y_k) ∝ p(x_{k+1} | x_k, s_k = j, s_{k+1} = i)
 * p(x_k | s_k = j, Y_k). In the "sample" timing x_{k+1} depends on s_k, not on s_{k+1}:
 * p(x_{k+1} | x_k, s_k = j) = N(F_j x_k + G_j u_k, Qd_j), so the step conditions on x_{k+1}
 * through F_j; in the "interval" timing through F_i. The pair probabilities (Kim's
 * P(s_k = j | s_{k+1} = i, Y) ~ P(s_k = j | s_{k+1} = i, y_0..k) = mu_j(k|k) pi_ji / c_i) and
 * the merges do not involve the state equation: they are the same in both timings. With one
 * mode the two timings are one smoother.
 *
 * On request (lagged, "interval" timing or one mode) the pass also reports, for each interval
 * k -> k+1, what the expectation step of maximum-likelihood fitting needs (Shumway & Stoffer
 * 1982, J. Time Series Anal. 3, eqs (9)-(12); Kim 1994 §2.2 for the mode pairs): the pairwise
 * probabilities mu_ji(k|K) = P(r_k = j, r_{k+1} = i | Y) above, and the moments of x_k given
 * r_{k+1} = i (the mode that governs the interval in that timing) and the record: the mixture
 * over j (weights P(r_k = j | r_{k+1} = i, y_0..k), Kim's approximation) of the pairs' x_ji,
 * P_ji, and the lag-one cross-covariance Cov(x_{k+1}, x_k | r_{k+1} = i, Y) = P_i(k+1|K)
 * Jbar_i' with Jbar_i the weighted mean of the pairs' gains (de Jong & MacKinnon 1988,
 * Econometric Theory 4, P_{k+1,k|K} = P_{k+1|K} J_k'; with one mode it is exactly that
 * formula). The weighted covariance of the pairs' means is accumulated by West's incremental
 * rule (West 1979, Comm. ACM 22) so that no second moment is differenced. In the "sample"
 * timing with several modes the interval's mode is r_k, and the moments fitting would need are
 * those given r_k, of x_{k+1} as well as x_k: they are not computed, and lagged is refused
 * there (by the Python wrapper).
 *
 * Each pair's RTS step is taken in its direct form, in two halves: rts_gain, once per moving
 * mode, predicts (P_pred from the filters' se_predict), factors P_pred (its equilibrated
 * Cholesky factor, se_factor) and solves for the rows of J (se_solve_rows); rts_pair, once per
 * pair, forms x_ji = x_j + J e and P_ji = P_j + J (P_i(k+1|K) - P_pred) J' (its upper
 * triangle, mirrored): about half the loops of the form below. The lanes that form cannot
 * take, a P_pred that does not factor or a P_ji that lost its digits (se_joseph_lost against
 * P_j), are redone in the form below, so degenerate cases are handled as they always were: its
 * conditional (rts_joseph) is again taken once per moving mode (in the "sample" timing for the
 * lanes any pair (j, .) needs), and finished per pair by rts_pair. A pair of weight zero in
 * every lane of a block is not computed.
 *
 * That form is a Kalman update of x_j(k|k) by the pseudo-measurement
 * x_{k+1} = F_m x_k + G_m u_k + w, w ~ N(0, Qd_m): conditioned on x_{k+1} the state is
 * Gaussian with mean x_j + J (x_{k+1} - x_pred) and covariance
 * P_j - J P_pred J' = (I - J F_m) P_j (I - J F_m)' + J Qd_m J' (Joseph's form), the same for
 * every value of x_{k+1}; averaging over x_{k+1} ~ N(x_i(k+1|K), P_i(k+1|K)) adds
 * J P_i(k+1|K) J' (Särkkä 2013, "Bayesian Filtering and Smoothing", the derivation of the RTS
 * smoother, Theorem 8.2). So rts_joseph runs the filters' own update, se_innovation and
 * se_correct with C = F_m, R = Qd_m, and rts_pair adds J P_i(k+1|K) J' (its P_pred replaced
 * by zero): the covariance is a sum of two positive semidefinite terms, symmetric by
 * construction; no second Kalman update, no difference of covariances that could turn
 * indefinite.
 *
 * P_pred is factored there by se_innovation as the innovation covariance of a measurement of
 * x_pred (C = I, R = 0: S = P_pred), never inverted. Where it is singular to working precision
 * (Qd_m = 0 with a singular F_m: a state reset, a deterministic component) that function's
 * rule applies: its eigenvalues are raised to its rounding level (se_repair, counted for the
 * caller's warning) and it is factored again. The gain J then annihilates the directions
 * P_pred cannot reach (the columns of P_j F_m' vanish there) up to rounding, as a
 * pseudo-inverse would, and Joseph's form keeps the covariance positive semidefinite for that
 * gain; a conditional covariance that loses its digits (Qd_m = 0 with an invertible F_m: x_k
 * determined by x_{k+1}) is taken in information form or repaired (se_joseph_lost,
 * se_information_or_repair), as in the filters.
 *
 * Trials are processed in blocks of `lanes` laid across SIMD lanes (linalg.h); the results do
 * not depend on the block size.
 *
 * Layout: every block array carries the lanes as its last axis, of stride B = lanes, after the
 * axes of the quantity in C order: x (L, n, B) at x[(j * n + r) * B + b], P (L, n, n, B) at
 * P[((j * n + r) * n + c) * B + b]. The scratch is carved from one zeroed allocation (the
 * arena, below) at the start of se_kim_backward, freed before it returns.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "linalg.h"
#include "smoother.h"

/* The work arrays of rts_gain for n states and B lanes, in its order:
 * F P, xs, chol, scale, work (2, B), root. */
typedef struct {
    double *FP, *xs, *chol, *scale, *work, *root;
} gain_scratch_t;

/* gain_scratch: carved from the arena; chol starts zero (the arena is zeroed; only its lower
 * triangle is read). */
static void gain_scratch(se_arena *a, se_int n, se_int B, gain_scratch_t *s)
{
    SE_DOUBLES(a, n * n * B, &s->FP, &s->chol);
    SE_DOUBLES(a, n * B, &s->xs, &s->scale, &s->root);
    SE_DOUBLES(a, 2 * B, &s->work);
}

/* The work arrays of rts_pair for n states and B lanes, in its order: e, D, T. */
typedef struct {
    double *e, *D, *T;
} pair_scratch_t;

static void pair_scratch(se_arena *a, se_int n, se_int B, pair_scratch_t *s)
{
    SE_DOUBLES(a, n * B, &s->e);
    SE_DOUBLES(a, n * n * B, &s->D, &s->T);
}

/* The work arrays of rts_joseph for n states and B lanes (carved by joseph_scratch):
 * P_pred, F P, xs (se_predict); inn, se_innovation's workspace (se_carve_innovation);
 * T, AP, prior (se_correct); root, lost (se_joseph_lost); x (the mean
 * se_correct leaves unchanged); the lanes' identity and zero (n, n), obs ones (n, B) and
 * n_obs = n (the pseudo-measurement, every component observed). */
typedef struct {
    double *Pp, *FP, *xs;
    se_innovation_ws inn;
    double *T, *AP, *prior, *root;
    uint8_t *lost;
    double *x, *eye, *zero, *obs, *n_obs;
} joseph_scratch_t;

static void joseph_scratch(se_arena *a, se_int n, se_int B, joseph_scratch_t *s)
{
    SE_DOUBLES(a, n * n * B, &s->Pp, &s->FP, &s->T, &s->AP, &s->prior, &s->eye, &s->zero);
    SE_DOUBLES(a, n * B, &s->xs, &s->root, &s->x, &s->obs);
    se_carve_innovation(a, n, n, B, &s->inn);
    SE_FLAGS(a, B, &s->lost);
    SE_DOUBLES(a, B, &s->n_obs);
}

/* joseph_scratch's constant arrays, once the arena (zeroed) is carved: eye, obs, n_obs. */
static void joseph_constants(se_int n, se_int B, joseph_scratch_t *s)
{
    for (se_int r = 0; r < n; r++)
        for (se_int b = 0; b < B; b++)
            s->eye[(r * n + r) * B + b] = 1.0;
    for (se_int i = 0; i < n * B; i++)
        s->obs[i] = 1.0;
    for (se_int b = 0; b < B; b++)
        s->n_obs[b] = (double)n;
}

/* Joseph's form (_redo): the conditional's x_pred, covariance and gain, a pair's x, P, and the
 * lanes it is taken in. */
typedef struct {
    double *xp, *P, *J, *x, *Pr;
    uint8_t *use;
} conditional_t;

/* ---- small helpers ------------------------------------------------------------------------ */

/* flag[b] = False for the lanes b < nb. */
static inline void clear_(uint8_t *restrict flag, se_int nb)
{
    for (se_int b = 0; b < nb; b++)
        flag[b] = 0;
}

/* Whether flag[b] is true for a lane b < nb. */
static inline int any_(const uint8_t *restrict flag, se_int nb)
{
    for (se_int b = 0; b < nb; b++)
        if (flag[b])
            return 1;
    return 0;
}

/* Whether the pair's weight log mu_i(k+1|K) + back[i, j] is -inf in every lane. */
static inline int impossible_(const double *restrict log_next, const double *restrict log_back,
                              se_int nb)
{
    for (se_int b = 0; b < nb; b++)
        if (log_next[b] + log_back[b] > -INFINITY)
            return 0;
    return 1;
}

/* A pair of weight zero: x, P get the filtered xj, Pj (finite, so that a zero weight cancels
 * them exactly) and gain zero. xj, x (n, B); Pj, P, gain (n, n, B). */
static void copy_pair(se_int n, se_int B, const double *restrict xj, const double *restrict Pj,
                      se_int nb, double *restrict x, double *restrict P, double *restrict gain)
{
    se_copy_gaussian(n, B, xj, Pj, nb, x, P);
    for (se_int r = 0; r < n; r++)
        for (se_int c = 0; c < n; c++)
            for (se_int b = 0; b < nb; b++)
                gain[(r * n + c) * B + b] = 0.0;
}

/* The lanes b with take[b] of x_from, P_from, gain_from into x, P, gain. */
static void take_lanes(se_int n, se_int B, const double *restrict x_from,
                       const double *restrict P_from, const double *restrict gain_from,
                       const uint8_t *restrict take, se_int nb, double *restrict x,
                       double *restrict P, double *restrict gain)
{
    for (se_int b = 0; b < nb; b++) {
        if (take[b]) {
            for (se_int r = 0; r < n; r++) {
                x[r * B + b] = x_from[r * B + b];
                for (se_int c = 0; c < n; c++) {
                    P[(r * n + c) * B + b] = P_from[(r * n + c) * B + b];
                    gain[(r * n + c) * B + b] = gain_from[(r * n + c) * B + b];
                }
            }
        }
    }
}

/* Add one pair (j, i) of weight exp(log_w) (P(r_k = j | r_{k+1} = i, y_0..k)) to mode i's
 * running moments of x_k: weight, mean and scatter of the means by West's (1979) weighted
 * incremental rule, weighted sums of the covariances P and gains gain.
 * x (n, B), P, gain (n, n, B), log_w (B,); acc_w (B,), acc_x (n, B), acc_M, acc_P,
 * acc_J (n, n, B) updated; delta (n,) scratch. */
static void accumulate(se_int n, se_int B, const double *restrict x, const double *restrict P,
                       const double *restrict gain, const double *restrict log_w, se_int nb,
                       double *restrict acc_w, double *restrict acc_x, double *restrict acc_M,
                       double *restrict acc_P, double *restrict acc_J, double *restrict delta)
{
    for (se_int b = 0; b < nb; b++) {
        if (log_w[b] == -INFINITY)
            continue;
        double w = exp(log_w[b]);
        acc_w[b] += w;
        double share = w / acc_w[b];
        for (se_int r = 0; r < n; r++) {
            delta[r] = x[r * B + b] - acc_x[r * B + b];
            acc_x[r * B + b] += share * delta[r];
        }
        for (se_int r = 0; r < n; r++) {
            for (se_int c = 0; c < n; c++) {
                se_int rc = (r * n + c) * B + b;
                acc_M[rc] += w * delta[r] * (x[c * B + b] - acc_x[c * B + b]);
                acc_P[rc] += w * P[rc];
                acc_J[rc] += w * gain[rc];
            }
        }
    }
}

/* Interval k -> k+1 of the block's trials: mu_ji(k|K) = exp(lpn[i] + back[i, j]), the moments
 * of x_k given r_{k+1} = i and Cov(x_{k+1}, x_k | i) = P_i(k+1|K) Jbar_i' (module comment).
 * The weights over j sum to one (back[i] is normalized; a mode i no pair reaches gets zeros).
 * lpn (L, B), back (L, L, B), Pn (L, n, n, B), acc_x (L, n, B), acc_M, acc_P, acc_J
 * (L, n, n, B); written at [i0 + b, k]: pair_out (N, J, L, L), lag_x (N, J, L, n),
 * lag_P, lag_cross (N, J, L, n, n). */
static void write_lagged(se_int n, se_int L, se_int B, se_int J, const double *restrict lpn,
                         const double *restrict back, const double *restrict Pn,
                         const double *restrict acc_x, const double *restrict acc_M,
                         const double *restrict acc_P, const double *restrict acc_J, se_int i0,
                         se_int nb, se_int k, double *restrict pair_out,
                         double *restrict lag_x, double *restrict lag_P,
                         double *restrict lag_cross)
{
    for (se_int b = 0; b < nb; b++) {
        se_int t = i0 + b;
        double *po = pair_out + (t * J + k) * L * L;
        for (se_int i = 0; i < L; i++) {
            for (se_int j = 0; j < L; j++)
                po[j * L + i] = exp(lpn[i * B + b] + back[(i * L + j) * B + b]);
            double *lx = lag_x + ((t * J + k) * L + i) * n;
            double *lP = lag_P + ((t * J + k) * L + i) * n * n;
            double *lc = lag_cross + ((t * J + k) * L + i) * n * n;
            const double *ax = acc_x + i * n * B;
            const double *aM = acc_M + i * n * n * B;
            const double *aP = acc_P + i * n * n * B;
            const double *aJ = acc_J + i * n * n * B;
            const double *Pi = Pn + i * n * n * B;
            for (se_int r = 0; r < n; r++) {
                lx[r] = ax[r * B + b];
                for (se_int c = 0; c < n; c++) { /* symmetric part of the scatter: rounding only */
                    lP[r * n + c] = aP[(r * n + c) * B + b]
                                    + 0.5 * (aM[(r * n + c) * B + b] + aM[(c * n + r) * B + b]);
                    double s = 0.0;
                    for (se_int a = 0; a < n; a++)
                        s += Pi[(r * n + a) * B + b] * aJ[(c * n + a) * B + b];
                    lc[r * n + c] = s;
                }
            }
        }
    }
}

/* Lane b of x (n, B), P (n, n, B) into x_to, P_to. */
static inline void copy_lane(se_int n, se_int B, const double *restrict x,
                             const double *restrict P, se_int b, double *restrict x_to,
                             double *restrict P_to)
{
    for (se_int r = 0; r < n; r++) {
        x_to[r * B + b] = x[r * B + b];
        for (se_int c = 0; c < n; c++)
            P_to[(r * n + c) * B + b] = P[(r * n + c) * B + b];
    }
}

/* Sample k of the block's trials: the mode-matched x (L, n, B), P, their probabilities and
 * the combined moments (se_combine) into the outputs. prob, log_prob (L, B); xc (n, B),
 * Pc (n, n, B), best (B,) scratch; x_out (N, K, n), P_out (N, K, n, n), prob_out (N, K, L),
 * mode_out (N, K), x_s (Ns, K, L, n), P_s (Ns, K, L, n, n) (Ns = 0: not written). */
static void write_(se_int n, se_int L, se_int B, se_int K, se_int Ns, const double *restrict x,
                   const double *restrict P, const double *restrict prob,
                   const double *restrict log_prob, se_int i0, se_int nb, se_int k,
                   double *restrict xc, double *restrict Pc, se_int *restrict best,
                   double *restrict x_out, double *restrict P_out, double *restrict prob_out,
                   se_int *restrict mode_out, double *restrict x_s, double *restrict P_s)
{
    if (Ns > 0) /* the mode-matched outputs, where asked for */
        se_scatter_modes(n, L, B, K, x, P, i0, nb, x_s + k * L * n, P_s + k * L * n * n);
    se_scatter_rows(L, B, K, prob, i0, nb, prob_out + k * L);
    se_combine(n, L, B, x, P, prob, log_prob, nb, xc, Pc, best);
    for (se_int b = 0; b < nb; b++) {
        mode_out[(i0 + b) * K + k] = best[b];
        se_write_lane(n, B, K, xc, Pc, b, i0 + b, k, x_out, P_out);
    }
}

/* ---- the two halves of an RTS step -------------------------------------------------------- */

/* The half of an RTS step in its direct form that does not depend on the smoothed posterior at
 * k + 1, per lane (Rauch, Tung & Striebel 1965; Särkkä 2013, Theorem 8.2): mode j's filtered
 * xj, Pj predicted through the transition F, G, Qd (with input u) into xp = x_pred,
 * Pp = P_pred (se_predict), and the gain J = P_j F' P_pred^-1 into gain.
 *
 * P_pred is factored as the filters factor an innovation covariance (se_factor) and each row
 * of J, P_pred^-1 times a column of F P_j, is two triangular solves (se_solve_rows). failed
 * marks the lanes whose P_pred is not positive definite to working precision (their gain is
 * not usable: rts_joseph takes them). s holds the work arrays (gain_scratch). Returns SE_OK,
 * or SE_NOT_FINITE if a lane's P_pred has a non-finite diagonal (it overflowed).
 * xj, xp (n, B); Pj, Pp, F, Qd, gain (n, n, B); G (n, l, B); u (l, B); failed (B,). */
static se_int rts_gain(se_int n, se_int l, se_int B, const double *restrict xj,
                       const double *restrict Pj, const double *restrict F,
                       const double *restrict G, const double *restrict u,
                       const double *restrict Qd, se_int nb, double *restrict xp,
                       double *restrict Pp, double *restrict gain, uint8_t *restrict failed,
                       const gain_scratch_t *s)
{
    double *restrict FP = s->FP, *restrict chol = s->chol, *restrict work = s->work;
    se_copy_gaussian(n, B, xj, Pj, nb, xp, Pp);
    se_predict(n, l, B, xp, Pp, F, G, u, Qd, nb, FP, s->xs); /* x_pred, P_pred; FP = F P_j */
    for (se_int r = 0; r < n; r++) /* P_pred's lower triangle, factored in place */
        for (se_int c = 0; c <= r; c++)
            for (se_int b = 0; b < nb; b++)
                chol[(r * n + c) * B + b] = Pp[(r * n + c) * B + b];
    int positive;
    int finite = se_factor(n, B, chol, s->scale, nb, work, work + B, &positive);
    if (!finite)
        return SE_NOT_FINITE;
    for (se_int b = 0; b < nb; b++) /* a failed pivot leaves NaN or 0 in the product of the pivots */
        failed[b] = !(work[b] > 0.0);
    for (se_int r = 0; r < n; r++) /* row r of J: P_pred^-1 (column r of F P_j), P_pred symmetric */
        for (se_int a = 0; a < n; a++)
            for (se_int b = 0; b < nb; b++)
                gain[(r * n + a) * B + b] = FP[(a * n + r) * B + b];
    se_solve_rows(n, B, n, chol, s->scale, gain, nb, s->root);
    return SE_OK;
}

/* The half of an RTS step that takes the smoothed x_next, P_next at k + 1, per lane, into x,
 * P: x = x_j + J (x_next - x_pred) and P = base + J (P_next - sub) J' with J = gain,
 * x_pred = xp. In the direct form (rts_gain) base = P_j, sub = P_pred; after rts_joseph, base
 * its conditional covariance and sub zero. P is exactly symmetric (se_symmetric_sum); s holds
 * the work arrays (pair_scratch). xj, xp, x_next, x (n, B); base, sub, gain, P_next, P
 * (n, n, B). */
static void rts_pair(se_int n, se_int B, const double *restrict xj, const double *restrict xp,
                     const double *restrict base, const double *restrict sub,
                     const double *restrict gain, const double *restrict x_next,
                     const double *restrict P_next, se_int nb, double *restrict x,
                     double *restrict P, const pair_scratch_t *s)
{
    double *restrict e = s->e, *restrict D = s->D, *restrict T = s->T;
    for (se_int a = 0; a < n; a++)
        for (se_int b = 0; b < nb; b++)
            e[a * B + b] = x_next[a * B + b] - xp[a * B + b];
    for (se_int r = 0; r < n; r++) { /* x = x_j + J (x_next - x_pred) */
        se_lane_accumulate(n, xj + r * B, 0, gain + r * n * B, B, e, B, nb, x + r * B);
    }
    for (se_int r = 0; r < n; r++) /* D = P_next - sub */
        for (se_int c = 0; c < n; c++)
            for (se_int b = 0; b < nb; b++)
                D[(r * n + c) * B + b] = P_next[(r * n + c) * B + b] - sub[(r * n + c) * B + b];
    se_lane_product(n, n, n, B, gain, n, 1, D, n, 1, nb, T); /* T = J D */
    se_symmetric_sum(n, n, B, base, T, gain, nb, P); /* P = base + J D J' */
}

/* The conditional of an RTS step in Joseph's form, in the lanes where use is true: mode j's
 * filtered xj, Pj at k given x_{k+1} through the transition F, G, Qd (with input u), whatever
 * its value (module comment): xp = x_pred, the covariance
 * P = (I - J F) P_j (I - J F)' + J Qd J' and the gain J = P_j F' P_pred^-1 into gain, by the
 * filters' update with the pseudo-measurement x_{k+1} = F x_k + G u + w, w ~ N(0, Qd), set to
 * its prediction (rts_pair then adds J P_next J'). A P_pred singular to working precision is
 * repaired (se_innovation), a conditional covariance that lost its digits is taken in
 * information form or repaired (se_information_or_repair), both counted in report. s holds
 * the work arrays (joseph_scratch). Returns SE_OK or the failure code of se_innovation on
 * P_pred. xj, xp (n, B); Pj, F, Qd, P, gain (n, n, B); G (n, l, B); u (l, B); use (B,). */
static se_int rts_joseph(se_int n, se_int l, se_int B, const double *restrict xj,
                         const double *restrict Pj, const double *restrict F,
                         const double *restrict G, const double *restrict u,
                         const double *restrict Qd, const uint8_t *restrict use, se_int nb,
                         double *restrict xp, double *restrict P, double *restrict gain,
                         double *restrict report, const joseph_scratch_t *s)
{
    double *restrict Pp = s->Pp, *restrict FP = s->FP, *restrict PCt = s->inn.PCt;
    se_copy_gaussian(n, B, xj, Pj, nb, xp, Pp);
    se_predict(n, l, B, xp, Pp, F, G, u, Qd, nb, FP, s->xs); /* x_pred, P_pred; FP = F P_j */
    /* S = P_pred factored (repaired where singular); the measurement x_pred: e = z = 0 */
    se_int status = se_innovate(n, n, B, xp, Pp, xp, s->eye, s->zero, s->obs, s->n_obs, nb,
                                &s->inn, report);
    if (status != SE_OK)
        return status;
    for (se_int r = 0; r < n; r++) /* the pseudo-measurement's P C' = P_j F' = (F P_j)' */
        for (se_int a = 0; a < n; a++)
            for (se_int b = 0; b < nb; b++)
                PCt[(r * n + a) * B + b] = FP[(a * n + r) * B + b];
    se_copy_gaussian(n, B, xj, Pj, nb, s->x, P);
    /* P = (I - J F) P_j (I - J F)' + J Qd J', gain = J = P_j F' P_pred^-1 (x: unchanged) */
    const se_update_ws ws = {gain, s->T, s->AP, s->prior, s->root, s->lost};
    se_update(n, n, B, s->x, P, F, Qd, s->obs, s->n_obs, use, nb, PCt, s->inn.chol,
              s->inn.scale, s->inn.z, &ws, report);
    return SE_OK;
}

/* The pairs (j, i), first <= i < last, in Joseph's form, in their lanes marked in redo[i]
 * (module comment): mode j's conditional through F, G, Qd (rts_joseph), once, for every lane
 * one of them marks, then each pair's step (rts_pair) into x_pair[i], P_pair[i], gain_pair[i]
 * where marked. Nothing is done where no lane is marked. cond holds x_pred, the conditional
 * covariance and gain, a pair's x, P and the lanes used; js the work arrays of rts_joseph
 * (joseph_scratch), ps those of rts_pair. Returns SE_OK or the failure code of rts_joseph.
 * x_next (L, n, B), P_next (L, n, n, B), redo (L, B), x_pair (L, n, B), P_pair, gain_pair
 * (L, n, n, B). */
static se_int redo_(se_int n, se_int l, se_int B, const double *restrict xj,
                    const double *restrict Pj, const double *restrict F,
                    const double *restrict G, const double *restrict u,
                    const double *restrict Qd, const double *restrict x_next,
                    const double *restrict P_next, const uint8_t *restrict redo, se_int first,
                    se_int last, se_int nb, double *restrict x_pair, double *restrict P_pair,
                    double *restrict gain_pair, double *restrict report,
                    const conditional_t *cond, const joseph_scratch_t *js,
                    const pair_scratch_t *ps)
{
    uint8_t *restrict use = cond->use;
    const double *zero = js->zero;
    for (se_int b = 0; b < nb; b++)
        use[b] = 0;
    for (se_int i = first; i < last; i++)
        for (se_int b = 0; b < nb; b++)
            use[b] |= redo[i * B + b];
    if (!any_(use, nb))
        return SE_OK;
    se_int status = rts_joseph(n, l, B, xj, Pj, F, G, u, Qd, use, nb, cond->xp, cond->P,
                               cond->J, report, js);
    if (status != SE_OK)
        return status;
    for (se_int i = first; i < last; i++) {
        if (any_(redo + i * B, nb)) {
            rts_pair(n, B, xj, cond->xp, cond->P, zero, cond->J, x_next + i * n * B,
                     P_next + i * n * n * B, nb, cond->x, cond->Pr, ps);
            take_lanes(n, B, cond->x, cond->Pr, cond->J, redo + i * B, nb, x_pair + i * n * B,
                       P_pair + i * n * n * B, gain_pair + i * n * n * B);
        }
    }
    return SE_OK;
}

/* ---- the kernel --------------------------------------------------------------------------- */

/* The backward recursion over every trial, in blocks of `lanes` trials.
 *
 * Arguments as switchest.engine.smoother.kim_smooth (checked there; shapes in smoother.h;
 * sample_timing true for the "sample" timing); written: the combined x_out, P_out, prob_out,
 * mode_out and the mode-matched x_s, P_s (shapes of KimOutput), report [repairs, smallest
 * eigenvalue] and, when lagged, pair_out, lag_x, lag_P, lag_cross (KimOutput). Returns SE_OK
 * or the failure code of a predicted covariance that could not be factored even repaired
 * (SE_NO_MEMORY if the scratch could not be allocated). */
se_int se_kim_backward(SE_KIM_BACKWARD_PARAMETERS)
{
    /* the lane stride: a block never holds more than N trials, and every lane's operations are
     * the same whatever the stride, so B = min(lanes, N) rather than `lanes` gives the same
     * numbers with no more scratch than the trials need (nor an overflow of its size for a
     * huge `lanes`) */
    const se_int B = se_lanes(lanes, N);
    double *xf, *Pf, *xn, *Pn, *xk, *Pk, *lpf, *lpn, *lpk, *prob, *back, *x_pair, *P_pair;
    double *gain_pair, *log_w, *w, *total, *xc, *Pc, *ul, *Fl, *Gl, *Ql, *xp, *Pp, *gain;
    double *acc_w, *acc_x, *acc_M, *acc_P, *acc_J, *delta;
    se_int *best, *idx;
    uint8_t *redo, *failed, *use;
    gain_scratch_t scratch;
    joseph_scratch_t joseph;
    pair_scratch_t pair;
    conditional_t conditional;
    se_arena arena = {NULL, 0};
    se_report_start(report);
    if (N == 0 || K == 0)
        return SE_OK; /* nothing to smooth: SE_OK with only the report written */
    do { /* size the arena, then carve it */
        /* per mode: filtered at k (xf, Pf, lpf), smoothed at k + 1 (xn, Pn, lpn) and at k (xk,
         * Pk, lpk), its transition (Fl, Gl, Ql); per pair: x_pair, P_pair and the pair's J,
         * gain_pair (read when lagged); back[i, j] = log P(r_k = j | r_{k+1} = i, y_0..k);
         * redo[i]: the lanes of pair (j, i) for Joseph's form */
        SE_DOUBLES(&arena, L * n * B, &xf, &xn, &xk, &x_pair);
        SE_DOUBLES(&arena, L * n * n * B, &Pf, &Pn, &Pk, &P_pair, &gain_pair, &Fl, &Ql);
        SE_DOUBLES(&arena, L * n * l * B, &Gl);
        SE_DOUBLES(&arena, L * B, &lpf, &lpn, &lpk, &prob, &log_w, &w);
        SE_DOUBLES(&arena, L * L * B, &back);
        SE_FLAGS(&arena, L * B, &redo);
        SE_DOUBLES(&arena, B, &total);
        SE_INTS(&arena, B, &best, &idx);
        SE_DOUBLES(&arena, n * B, &xc);
        SE_DOUBLES(&arena, n * n * B, &Pc);
        SE_DOUBLES(&arena, l * B, &ul);
        /* the direct form's prediction and gain of the moving mode (rts_gain) */
        SE_DOUBLES(&arena, n * B, &xp);
        SE_DOUBLES(&arena, n * n * B, &Pp, &gain);
        SE_FLAGS(&arena, B, &failed, &use); /* use: all lanes (set to 1 below) */
        gain_scratch(&arena, n, B, &scratch);
        joseph_scratch(&arena, n, B, &joseph);
        pair_scratch(&arena, n, B, &pair);
        /* Joseph's form (redo_): the conditional's x_pred, covariance and gain, a pair's x, P,
         * and the lanes it is taken in */
        SE_DOUBLES(&arena, n * B, &conditional.xp, &conditional.x);
        SE_DOUBLES(&arena, n * n * B, &conditional.P, &conditional.J, &conditional.Pr);
        SE_FLAGS(&arena, B, &conditional.use);
        /* per mode i at k + 1: weight, mean, scatter of the pairs' x_ji, mean P_ji and gain */
        SE_DOUBLES(&arena, L * B, &acc_w);
        SE_DOUBLES(&arena, L * n * B, &acc_x);
        SE_DOUBLES(&arena, L * n * n * B, &acc_M, &acc_P, &acc_J);
        SE_DOUBLES(&arena, n, &delta);
    } while (se_arena_open(&arena));
    if (arena.base == NULL)
        return SE_NO_MEMORY;
    for (se_int b = 0; b < B; b++)
        use[b] = 1;
    joseph_constants(n, B, &joseph);
    double *root = scratch.root; /* shared: rts_gain's root also serves se_joseph_lost here */
    uint8_t *lost = joseph.lost;
    se_int status = SE_OK;

    for (se_int i0 = 0; i0 < N; i0 += B) {
        const se_int nb = se_block_trials(B, N, i0);
        /* smoothed = filtered */
        se_gather_modes(n, L, B, K, x_f + (K - 1) * L * n, P_f + (K - 1) * L * n * n, i0, nb, xn,
                        Pn);
        se_gather_rows(L, B, K, log_prob_f + (K - 1) * L, i0, nb, lpn);
        se_log_normalize(L, B, lpn, prob, total, nb);
        write_(n, L, B, K, Ns, xn, Pn, prob, lpn, i0, nb, K - 1, xc, Pc, best, x_out, P_out,
               prob_out, mode_out, x_s, P_s);
        for (se_int k = K - 2; k >= 0; k--) {
            se_gather_modes(n, L, B, K, x_f + k * L * n, P_f + k * L * n * n, i0, nb, xf, Pf);
            se_gather_rows(L, B, K, log_prob_f + k * L, i0, nb, lpf);
            se_log_normalize(L, B, lpf, prob, total, nb);
            se_gather_samples(l, B, K, u, i0, nb, k, ul);
            for (se_int i = 0; i < L; i++) { /* log mu_j(k|k) pi_ji - log c_i, normalized over j */
                for (se_int j = 0; j < L; j++) {
                    double lt = log_transition[j * L + i];
                    double *restrict bij = back + (i * L + j) * B;
                    const double *restrict lj = lpf + j * B;
                    for (se_int b = 0; b < nb; b++)
                        bij[b] = lj[b] + lt;
                }
                se_log_normalize(L, B, back + i * L * B, prob, total, nb);
            }
            if (lagged) {
                memset(acc_w, 0, sizeof(double) * (size_t)(L * B));
                memset(acc_x, 0, sizeof(double) * (size_t)(L * n * B));
                memset(acc_M, 0, sizeof(double) * (size_t)(L * n * n * B));
                memset(acc_P, 0, sizeof(double) * (size_t)(L * n * n * B));
                memset(acc_J, 0, sizeof(double) * (size_t)(L * n * n * B));
            }
            for (se_int m = 0; m < L; m++) { /* each mode's transition into k + 1 */
                se_lane_index(L, T, TK, trans, i0, nb, k + 1, m, idx);
                se_gather_matrices(n, n, B, F, idx, nb, Fl + m * n * n * B);
                se_gather_matrices(n, l, B, G, idx, nb, Gl + m * n * l * B);
                se_gather_matrices(n, n, B, Qd, idx, nb, Ql + m * n * n * B);
            }
            for (se_int j = 0; j < L; j++) {
                const double *xfj = xf + j * n * B, *Pfj = Pf + j * n * n * B;
                int ready = 0; /* "sample": mode j's prediction and gain, shared by the pairs (j, .) */
                for (se_int i = 0; i < L; i++) {
                    const double *lni = lpn + i * B, *bij = back + (i * L + j) * B;
                    double *lwi = log_w + i * B;
                    uint8_t *redo_i = redo + i * B;
                    double *xpi = x_pair + i * n * B, *Ppi = P_pair + i * n * n * B;
                    double *gpi = gain_pair + i * n * n * B;
                    for (se_int b = 0; b < nb; b++) /* log mu_ji(k|K) = log mu_i(k+1|K) + back[i, j] */
                        lwi[b] = lni[b] + bij[b];
                    if (impossible_(lni, bij, nb)) { /* weight 0 in every lane */
                        copy_pair(n, B, xfj, Pfj, nb, xpi, Ppi, gpi);
                        clear_(redo_i, nb);
                        continue;
                    }
                    if (!ready) {
                        se_int m = sample_timing ? j : i; /* the mode that governs k -> k+1 */
                        status = rts_gain(n, l, B, xfj, Pfj, Fl + m * n * n * B,
                                          Gl + m * n * l * B, ul, Ql + m * n * n * B, nb, xp, Pp,
                                          gain, failed, &scratch);
                        if (status != SE_OK)
                            goto done;
                        ready = sample_timing;
                    }
                    rts_pair(n, B, xfj, xp, Pfj, Pp, gain, xn + i * n * B, Pn + i * n * n * B,
                             nb, xpi, Ppi, &pair);
                    se_joseph_lost(n, B, Ppi, Pfj, use, nb, root, lost);
                    for (se_int b = 0; b < nb; b++) /* P_pred not factored, or P_ji lost its digits */
                        redo_i[b] = failed[b] || lost[b];
                    if (lagged)
                        se_copy_lanes(n, n, B, gain, nb, gpi);
                    if (!sample_timing && any_(redo_i, nb)) { /* Joseph's form, through F_i */
                        status = redo_(n, l, B, xfj, Pfj, Fl + i * n * n * B, Gl + i * n * l * B,
                                       ul, Ql + i * n * n * B, xn, Pn, redo, i, i + 1, nb,
                                       x_pair, P_pair, gain_pair, report, &conditional, &joseph,
                                       &pair);
                        if (status != SE_OK)
                            goto done;
                    }
                }
                if (sample_timing) { /* Joseph's form through F_j, once for every pair (j, .) */
                    status = redo_(n, l, B, xfj, Pfj, Fl + j * n * n * B, Gl + j * n * l * B, ul,
                                   Ql + j * n * n * B, xn, Pn, redo, 0, L, nb, x_pair, P_pair,
                                   gain_pair, report, &conditional, &joseph, &pair);
                    if (status != SE_OK)
                        goto done;
                }
                if (lagged)
                    for (se_int i = 0; i < L; i++)
                        accumulate(n, B, x_pair + i * n * B, P_pair + i * n * n * B,
                                   gain_pair + i * n * n * B, back + (i * L + j) * B, nb,
                                   acc_w + i * B, acc_x + i * n * B, acc_M + i * n * n * B,
                                   acc_P + i * n * n * B, acc_J + i * n * n * B, delta);
                se_log_normalize(L, B, log_w, w, total, nb); /* total: log mu_j(k|K) */
                double *xkj = xk + j * n * B, *Pkj = Pk + j * n * n * B;
                se_combine(n, L, B, x_pair, P_pair, w, log_w, nb, xkj, Pkj, best);
                for (se_int b = 0; b < nb; b++) {
                    lpk[j * B + b] = total[b];
                    if (total[b] == -INFINITY) /* mode j impossible: keep its filtered posterior */
                        copy_lane(n, B, xfj, Pfj, b, xkj, Pkj);
                }
            }
            se_log_normalize(L, B, lpk, prob, total, nb);
            write_(n, L, B, K, Ns, xk, Pk, prob, lpk, i0, nb, k, xc, Pc, best, x_out, P_out,
                   prob_out, mode_out, x_s, P_s);
            if (lagged)
                write_lagged(n, L, B, J, lpn, back, Pn, acc_x, acc_M, acc_P, acc_J, i0, nb, k,
                             pair_out, lag_x, lag_P, lag_cross);
            double *t;
            t = xn; xn = xk; xk = t;
            t = Pn; Pn = Pk; Pk = t;
            t = lpn; lpn = lpk; lpk = t;
        }
    }
done:
    se_arena_close(&arena);
    return status;
}

/* ---- screening covariances ---------------------------------------------------------------- */

/* Symmetrize a stack A (M, n, n) and certify its matrices positive semidefinite to within a
 * shift, as far as a Cholesky factorization can, without eigenvalues.
 *
 * scale = max |A| (at least the smallest normal float), sym = (A + A') / 2, and failed[s] set
 * where the Cholesky factorization of sym[s] + relative_shift scale I (Golub & Van Loan,
 * "Matrix Computations", 4th ed., Algorithm 4.2.2) meets a pivot that is not positive. Where
 * it succeeds, the computed factor is the exact one of sym[s] + shift I + E with
 * |E| <= gamma_{n+1} |R'| |R| (Higham, "Accuracy and Stability of Numerical Algorithms", 2nd
 * ed., Theorem 10.3), so the smallest eigenvalue of sym[s] is at least
 * -shift - n gamma_{n+1} (scale + shift). Returns (scale, max |A - A'|) in *scale, *asym.
 *
 * (Each running maximum is taken as v if v > a else a, as Python's max(a, v) does: a NaN v
 * leaves it unchanged.)
 */
se_int se_screen_psd(se_int M, se_int n, const double *restrict A, double relative_shift,
                     double *restrict sym, uint8_t *restrict failed, double *restrict scale_out,
                     double *restrict asym_out)
{
    double stack[SE_SCREEN_STACK * SE_SCREEN_STACK];
    double *R = stack;
    if (n > SE_SCREEN_STACK) {
        R = malloc(sizeof(double) * (size_t)(n * n));
        if (!R)
            return SE_NO_MEMORY;
    }
    double scale = 2.2250738585072014e-308; /* numpy.finfo(float).tiny */
    for (se_int s = 0; s < M; s++)
        for (se_int i = 0; i < n * n; i++) {
            double v = fabs(A[s * n * n + i]);
            if (v > scale)
                scale = v;
        }
    double shift = relative_shift * scale;
    double asym = 0.0;
    for (se_int s = 0; s < M; s++) {
        const double *As = A + s * n * n;
        double *Ss = sym + s * n * n;
        for (se_int i = 0; i < n; i++)
            for (se_int j = 0; j < n; j++) {
                double d = fabs(As[i * n + j] - As[j * n + i]);
                if (d > asym)
                    asym = d;
                Ss[i * n + j] = 0.5 * (As[i * n + j] + As[j * n + i]);
            }
        failed[s] = 0;
        for (se_int j = 0; j < n; j++) {
            double pivot = Ss[j * n + j] + shift;
            for (se_int p = 0; p < j; p++)
                pivot -= R[j * n + p] * R[j * n + p];
            if (!(pivot > 0.0)) {
                failed[s] = 1;
                break;
            }
            R[j * n + j] = sqrt(pivot);
            for (se_int i = j + 1; i < n; i++) {
                double v = Ss[i * n + j];
                for (se_int p = 0; p < j; p++)
                    v -= R[i * n + p] * R[j * n + p];
                R[i * n + j] = v / R[j * n + j];
            }
        }
    }
    if (R != stack)
        free(R);
    *scale_out = scale;
    *asym_out = asym;
    return SE_OK;
}
