/* The compiled Rao-Blackwellized particle filter for jump-Markov linear systems.
 *
 * Each particle carries a mode and the Kalman filter (x, P) conditional on its mode history
 * (Doucet, de Freitas, Murphy & Russell 2000, §3; Doucet, Gordon & Krishnamurthy 2001, §III).
 * The particles of one trial are laid across the SIMD lanes of linalg.c (x (n, Np),
 * P (n, n, Np)), so that the Kalman equations run there, once for all particles; the kernel
 * loops over trials and samples. rbpf_run filters whole records, rbpf_step one sample of every
 * trial (the streaming API); both call se_particle_filter.
 *
 * Randomness is counter-based (Salmon, Moraes, Dror & Shaw 2011, "Parallel random numbers: as
 * easy as 1, 2, 3"): uniform j of sample k of a trial is a pure function of the trial's 64-bit
 * key, k and j (se_uniform), so a trial's result depends on its key alone (not on the batch it
 * ran in), and a streaming step needs nothing but the key and the sample index to continue. At
 * sample k, uniforms 0 .. Np-1 draw the particles' modes and Np .. 2 Np - 1 the resampling
 * positions. The arithmetic is fixed bit for bit (tests/estimators/rbpf_oracle.py reproduces
 * it in numpy): uint64 with wrap-around modulo 2^64, the sample and draw indices (int64)
 * converted to uint64 after the + 1, and the top 53 bits of the result converted exactly to a
 * double before the multiplication by 2^-53.
 *
 * Convention of switchest: transition[i, j] = P(mode j at k+1 | mode i at k). trans[k, r] is
 * mode r's transition over the interval into sample k in the table F, G, Qd; mode r at sample
 * k is updated with C[r], R[r]; the input held over the interval into sample k is u[:, k-1].
 * Which mode's transition a particle takes into sample k is the timing (docs/conventions.rst):
 * with sample_timing its mode at k-1 (the mode of a sample governs the interval after it,
 * x_k = F(r_{k-1}) x_{k-1} + G(r_{k-1}) u_{k-1} + w: the particle is predicted, then its mode
 * at k drawn), else its mode at k (Bar-Shalom's timing, x_k = F(r_k) x_{k-1} + G(r_k) u_{k-1}
 * + w: the mode drawn, then the particle predicted with it).
 *
 * Layout: the arrays keep the shapes and axis order given in rbpf.h, the particles last in the
 * scratch: a lane array of shape (n, n, Np) is addressed P[(r * n + c) * Np + p]. The scratch
 * is carved from one zeroed allocation at the kernel's start (se_arena), freed before every
 * return.
 */
#include "rbpf.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "linalg.h"

/* SplitMix64 (Steele, Lea & Flood 2014, "Fast splittable pseudorandom number generators",
 * OOPSLA, §3): the golden-ratio increment and the two multipliers of its output mix */
#define GOLDEN UINT64_C(0x9E3779B97F4A7C15)
#define MIX1 UINT64_C(0xBF58476D1CE4E5B9)
#define MIX2 UINT64_C(0x94D049BB133111EB)
#define UNIT 0x1p-53 /* 2**-53: a 53-bit integer times this is a float64 in [0, 1) */

/* SplitMix64's output function (Steele, Lea & Flood 2014, §3): a bijection of the 64-bit
 * integers whose every output bit depends on every input bit. */
static inline uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * MIX1;
    z = (z ^ (z >> 27)) * MIX2;
    return z ^ (z >> 31);
}

/* Element index (0-based) of the SplitMix64 sequence started at key:
 * mix64(key + (index + 1) * golden) (Steele, Lea & Flood 2014, §3), modulo 2^64.
 * (The + 1 is taken in uint64, after the conversion: the same bits as converting index + 1,
 * without its signed overflow at INT64_MAX.) */
static inline uint64_t stream(uint64_t key, se_int index)
{
    return mix64(key + ((uint64_t)index + 1u) * GOLDEN);
}

/* Uniform j of sample k of the trial with key, in [0, 1): the top 53 bits of
 * stream(stream(key, k), j), the sample's own SplitMix64 sequence. */
static inline double uniform(uint64_t key, se_int k, se_int j)
{
    return (double)(stream(stream(key, k), j) >> 11) * UNIT;
}

double se_uniform(uint64_t key, se_int k, se_int j) { return uniform(key, k, j); }

/* The keys of trials 0 .. count-1 derived from a root key (uint64): element i of the
 * SplitMix64 sequence started at root (Steele, Lea & Flood 2014, §3). */
void se_trial_keys(se_int count, uint64_t root, uint64_t *restrict keys)
{
    for (se_int i = 0; i < count; i++)
        keys[i] = stream(root, i);
}

/* The index j drawn with probability weights[j] / sum(weights) by inversion of the cumulative
 * sum: the first j whose running sum exceeds u * sum(weights), else the last positive weight
 * (u * sum rounded up to the sum). A zero weight is never drawn. weights (L,) */
static se_int pick(se_int L, const double *restrict weights, double u)
{
    double total = 0.0;
    for (se_int j = 0; j < L; j++)
        total += weights[j];
    double target = u * total, acc = 0.0;
    se_int last = 0;
    for (se_int j = 0; j < L; j++) {
        if (weights[j] > 0.0) {
            last = j;
            acc += weights[j];
            if (acc > target)
                return j;
        }
    }
    return last;
}

/* a[0 .. n-1] sorted ascending in place (the multinomial positions: any correct sort gives the
 * same array, the uniforms holding no NaN): quicksort with a
 * median-of-three pivot, recursing into the smaller part, insertion sort below 17 entries. */
static void sort_doubles(double *a, se_int n)
{
    while (n > 16) {
        se_int mid = (n - 1) / 2, last = n - 1;
        double t;
        if (a[mid] < a[0]) { t = a[0]; a[0] = a[mid]; a[mid] = t; }
        if (a[last] < a[mid]) {
            t = a[mid]; a[mid] = a[last]; a[last] = t;
            if (a[mid] < a[0]) { t = a[0]; a[0] = a[mid]; a[mid] = t; }
        }
        double pivot = a[mid];
        se_int i = -1, j = n; /* Hoare's partition: a[0 .. j] <= pivot <= a[j+1 .. n-1] */
        for (;;) {
            do i++; while (a[i] < pivot);
            do j--; while (a[j] > pivot);
            if (i >= j)
                break;
            t = a[i]; a[i] = a[j]; a[j] = t;
        }
        se_int left = j + 1; /* 1 <= left <= n - 1 */
        if (left < n - left) {
            sort_doubles(a, left);
            a += left;
            n -= left;
        } else {
            sort_doubles(a + left, n - left);
            n = left;
        }
    }
    for (se_int i = 1; i < n; i++) {
        double v = a[i];
        se_int j = i - 1;
        while (j >= 0 && a[j] > v) {
            a[j + 1] = a[j];
            j--;
        }
        a[j + 1] = v;
    }
}

/* The nb sorted positions in [0, 1] of a resampling at sample k, from uniforms nb .. 2 nb - 1
 * (Douc, Cappé & Moulines 2005, "Comparison of resampling schemes for particle filtering",
 * §2): systematic (p + U) / nb with one U; stratified (p + U_p) / nb; multinomial the U_p
 * sorted. pos (nb,) */
void se_resampling_positions(uint64_t key, se_int k, se_int scheme, se_int nb,
                             double *restrict pos)
{
    if (scheme == SE_SYSTEMATIC) {
        double shift = uniform(key, k, nb);
        for (se_int p = 0; p < nb; p++)
            pos[p] = ((double)p + shift) / (double)nb;
    } else if (scheme == SE_STRATIFIED) {
        for (se_int p = 0; p < nb; p++)
            pos[p] = ((double)p + uniform(key, k, nb + p)) / (double)nb;
    } else {
        for (se_int p = 0; p < nb; p++)
            pos[p] = uniform(key, k, nb + p);
        sort_doubles(pos, nb);
    }
}

/* out[p]: the particle whose cumulative-weight interval holds position pos[p] (sorted, in
 * [0, 1]), the first j with w_0 + .. + w_j > pos[p] sum(w), at most the last positive weight:
 * the inversion every resampling scheme shares (Douc, Cappé & Moulines 2005, §2), merged in one
 * pass over the sorted positions. w, pos, out (nb,). Nothing is read or written for nb = 0. */
void se_ancestors(const double *restrict w, const double *restrict pos, se_int nb,
                  se_int *restrict out)
{
    if (nb <= 0)
        return;
    double total = 0.0;
    se_int last = 0;
    for (se_int j = 0; j < nb; j++) {
        total += w[j];
        if (w[j] > 0.0)
            last = j;
    }
    se_int j = 0;
    double acc = w[0];
    for (se_int p = 0; p < nb; p++) {
        double target = pos[p] * total;
        while (j < last && acc <= target) {
            j++;
            acc += w[j];
        }
        out[p] = j;
    }
}

/* out[a, b] = vector[a] in every lane: a trial's measurement or input for each of its
 * particles. vector (q,), out (q, B) */
static void fill_lanes(se_int q, se_int B, const double *restrict vector, se_int nb,
                       double *restrict out)
{
    for (se_int a = 0; a < q; a++)
        for (se_int b = 0; b < nb; b++)
            out[a * B + b] = vector[a];
}

/* out[b] = value in every lane. */
static void fill_index(se_int value, se_int nb, se_int *restrict out)
{
    for (se_int b = 0; b < nb; b++)
        out[b] = value;
}

/* The scratch arrays of the kernel, in two groups (the lanes' matrices, mats_t, with the
 * entries idx they are gathered from, and the measurement update's workspace, work_t), every
 * lane array with the lane stride Np. */
typedef struct {
    double *Fl, *Gl, *Ql, *Cl, *Rl, *AP, *xs; /* (n,n,B) (n,l,B) (n,n,B) (m,n,B) (m,m,B) (n,n,B) (n,B) */
    se_int *idx;                              /* (B,) */
} mats_t;

typedef struct {
    se_innovation_ws inn; /* se_innovation's (linalg.h); bad zeroed */
    se_update_ws upd;     /* se_update's (linalg.h) */
} work_t;

/* What a proposal reads at sample k of a trial: the sizes (B = Np lanes, nb of them in use),
 * the sample in every lane, yl (m, B), ul (l, B), obs (m, B), n_obs (B,), the tables F, G, Qd,
 * C, R and the row trans_row = trans[k] (L,), the mode chain's transition, log_transition
 * (L, L) and prob0, log_prob0 (L,), the trial's key and the sample's index k in its record
 * (for the uniforms), whether the sample is predicted into, and the timing. */
typedef struct {
    se_int n, m, l, L, B, nb;
    const double *yl, *ul, *obs, *n_obs;
    const double *F, *G, *Qd, *C, *R;
    const se_int *trans_row;
    const double *transition, *log_transition, *prob0, *log_prob0;
    uint64_t key;
    se_int k;
    int predicting, sample_timing;
} sample_t;

/* The Kalman measurement update of every lane p with the output matrices of entry index[p] of
 * C, R, with its predictive log-likelihood.
 *
 * loglik = log N(y; C x, C P C' + R) over the observed components (0 with none), by
 * se_innovation (Shankar et al. eq. (8)); the lanes whose likelihood is finite (use) are
 * corrected in Joseph form (se_correct, Shankar et al. eqs (9)-(10)), in information form where
 * that loses its digits, as the bank of filters does (bank.c). mats and work hold the scratch
 * arrays. Returns the status of the innovation.
 * x (n, B), P (n, n, B), index (B,); written loglik (B,) (work's own, or a candidate's row),
 * use (B,). */
static se_int filter_lanes(const sample_t *restrict s, double *restrict x, double *restrict P,
                           const se_int *restrict index, double *restrict loglik,
                           uint8_t *restrict use, const mats_t *restrict mats,
                           const work_t *restrict work, double *restrict report)
{
    const se_int n = s->n, m = s->m, B = s->B, nb = s->nb;
    const se_innovation_ws *inn = &work->inn;
    se_gather_matrices(m, n, B, s->C, index, nb, mats->Cl);
    se_gather_matrices(m, m, B, s->R, index, nb, mats->Rl);
    se_int status = se_innovation(n, m, B, x, P, s->yl, mats->Cl, mats->Rl, s->obs, s->n_obs, nb,
                                  inn->e, inn->PCt, inn->chol, inn->scale, inn->z, inn->nis,
                                  loglik, inn->work, inn->bad, report);
    if (status != SE_OK)
        return status;
    for (se_int b = 0; b < nb; b++)
        use[b] = isfinite(loglik[b]) ? 1 : 0;
    se_update(n, m, B, x, P, mats->Cl, mats->Rl, s->obs, s->n_obs, use, nb, inn->PCt, inn->chol,
              inn->scale, inn->z, &work->upd, report);
    return SE_OK;
}

/* Kalman prediction of every lane p through the entry mats->idx[p] of the table F, G, Qd
 * (Shankar et al. eqs (6)-(7), se_predict), with the input ul. x (n, B), P (n, n, B); mats'
 * matrices scratch. */
static void predict_entries(const sample_t *restrict s, double *restrict x, double *restrict P,
                            const mats_t *restrict mats)
{
    const se_int n = s->n, l = s->l, B = s->B, nb = s->nb;
    se_gather_matrices(n, n, B, s->F, mats->idx, nb, mats->Fl);
    se_gather_matrices(n, l, B, s->G, mats->idx, nb, mats->Gl);
    se_gather_matrices(n, n, B, s->Qd, mats->idx, nb, mats->Ql);
    se_predict(n, l, B, x, P, mats->Fl, mats->Gl, s->ul, mats->Ql, nb, mats->AP, mats->xs);
}

/* Kalman prediction of every lane p through the transition trans_row[mode[p]] of its mode
 * (predict_entries). mode (B,). */
static void predict_lanes(const sample_t *restrict s, double *restrict x, double *restrict P,
                          const se_int *restrict mode, const mats_t *restrict mats)
{
    for (se_int p = 0; p < s->nb; p++)
        mats->idx[p] = s->trans_row[mode[p]];
    predict_entries(s, x, P, mats);
}

/* Sample each particle's mode from its prior and update its filter; inc gets the incremental
 * log-weights.
 *
 * r_k ~ pi(r_{k-1}, .) (prob0 at the first sample), Kalman prediction through r_{k-1}'s
 * transition before the draw (sample_timing) or through r_k's after it,
 * inc = log N(y_k; C_{r_k} x-, C_{r_k} P- C_{r_k}' + R_{r_k}) (-inf where not finite) and the
 * Joseph update (Doucet, Gordon & Krishnamurthy 2001, §III, with the prior as importance
 * distribution; Doucet, de Freitas, Murphy & Russell 2000, §3). In either timing the weight is
 * the likelihood of y_k given the particle's history up to r_k, the target-to-proposal ratio
 * when the proposal is the prior.
 * x (n, B), P (n, n, B), mode (B,); written use (B,), the particles' likelihoods in
 * work->inn.loglik, inc (B,). */
static se_int prior_proposal(const sample_t *restrict s, double *restrict x, double *restrict P,
                             se_int *restrict mode, const mats_t *restrict mats,
                             uint8_t *restrict use, double *restrict inc,
                             const work_t *restrict work, double *restrict report)
{
    const se_int L = s->L, nb = s->nb;
    double *ll = work->inn.loglik;
    if (s->predicting && s->sample_timing)
        predict_lanes(s, x, P, mode, mats);
    for (se_int p = 0; p < nb; p++) {
        const double *row = s->predicting ? s->transition + mode[p] * L : s->prob0;
        mode[p] = pick(L, row, uniform(s->key, s->k, p));
    }
    if (s->predicting && !s->sample_timing)
        predict_lanes(s, x, P, mode, mats);
    se_int status = filter_lanes(s, x, P, mode, ll, use, mats, work, report);
    for (se_int p = 0; p < nb; p++)
        inc[p] = use[p] ? ll[p] : -INFINITY;
    return status;
}

/* Sample each particle's mode from the optimal importance distribution and keep that
 * candidate's filter; inc gets the incremental log-weights.
 *
 * For every candidate mode r each particle's filter is predicted and updated with C_r, R_r,
 * with predictive likelihood Lambda_r = N(y_k; C_r x-_r, C_r P-_r C_r' + R_r). The prediction
 * goes through r_{k-1}'s transition with sample_timing (once per particle, the same x-, P- for
 * every candidate), else through the candidate r's own; then
 * r_k ~ pi(r_{k-1}, r) Lambda_r / sum_r pi(r_{k-1}, r) Lambda_r and
 * inc = log sum_r pi(r_{k-1}, r) Lambda_r, the ratio of target to proposal (Doucet, Gordon &
 * Krishnamurthy 2001, §III); prob0 replaces pi(r_{k-1}, .) at the first sample. A candidate
 * whose likelihood is not finite gets Lambda_r = 0; a particle with no candidate left
 * (inc = -inf) draws from pi(r_{k-1}, .) alone and keeps its predicted filter.
 * x (n, B), P (n, n, B), mode (B,); xc (L, n, B), Pc (L, n, n, B), ll, use, terms (L, B),
 * pick_w (L,) (one draw's weights), inc (B,). */
static se_int optimal_proposal(const sample_t *restrict s, double *restrict x, double *restrict P,
                               se_int *restrict mode, const mats_t *restrict mats,
                               double *restrict xc, double *restrict Pc, double *restrict ll,
                               uint8_t *restrict use, double *restrict terms,
                               double *restrict pick_w, double *restrict inc,
                               const work_t *restrict work, double *restrict report)
{
    const se_int n = s->n, L = s->L, B = s->B, nb = s->nb;
    const double *log_transition = s->log_transition, *log_prob0 = s->log_prob0;
    if (s->predicting && s->sample_timing)
        predict_lanes(s, x, P, mode, mats);
    for (se_int r = 0; r < L; r++) {
        double *xr = xc + r * n * B, *Pr = Pc + r * n * n * B;
        se_copy_gaussian(n, B, x, P, nb, xr, Pr);
        if (s->predicting && !s->sample_timing) {
            fill_index(s->trans_row[r], nb, mats->idx);
            predict_entries(s, xr, Pr, mats);
        }
        fill_index(r, nb, mats->idx);
        se_int status = filter_lanes(s, xr, Pr, mats->idx, ll + r * B, use + r * B, mats, work,
                                     report);
        if (status != SE_OK)
            return status;
    }
    for (se_int p = 0; p < nb; p++) { /* log pi(r_{k-1}, r) + log Lambda_r and their log-sum-exp */
        const double *prev = s->predicting ? log_transition + mode[p] * L : log_prob0;
        double top = -INFINITY;
        for (se_int r = 0; r < L; r++) {
            double t = use[r * B + p] ? prev[r] + ll[r * B + p] : -INFINITY;
            terms[r * B + p] = t;
            top = t > top ? t : top; /* max(top, t): no NaN here */
        }
        double acc = 0.0;
        for (se_int r = 0; r < L; r++)
            acc += top > -INFINITY ? exp(terms[r * B + p] - top) : 0.0;
        inc[p] = top > -INFINITY ? top + log(acc) : -INFINITY;
    }
    for (se_int p = 0; p < nb; p++) {
        const double *prev = s->predicting ? log_transition + mode[p] * L : log_prob0;
        for (se_int r = 0; r < L; r++) /* weights relative to the largest, or the prior's alone */
            pick_w[r] = inc[p] > -INFINITY ? exp(terms[r * B + p] - inc[p]) : exp(prev[r]);
        se_int chosen = pick(L, pick_w, uniform(s->key, s->k, p));
        mode[p] = chosen;
        const double *xs = xc + chosen * n * B, *Ps = Pc + chosen * n * n * B;
        for (se_int a = 0; a < n; a++) {
            x[a * B + p] = xs[a * B + p];
            for (se_int c = 0; c < n; c++)
                P[(a * n + c) * B + p] = Ps[(a * n + c) * B + p];
        }
    }
    return SE_OK;
}

/* Mean xm = sum_b w_b x_b and covariance Pm = sum_b w_b (P_b + (x_b - xm)(x_b - xm)') of the
 * mixture of the lanes' Gaussians with weights w: the RBPF's output (Doucet, Gordon &
 * Krishnamurthy 2001, §III), a sum across lanes. Upper triangle computed, then mirrored.
 * w (B,), x (n, B), P (n, n, B); xm (n,), Pm (n, n). */
static void particle_moments(se_int n, se_int B, const double *restrict w,
                             const double *restrict x, const double *restrict P, se_int nb,
                             double *restrict xm, double *restrict Pm)
{
    for (se_int r = 0; r < n; r++) {
        xm[r] = 0.0;
        for (se_int b = 0; b < nb; b++)
            xm[r] += w[b] * x[r * B + b];
    }
    for (se_int r = 0; r < n; r++) {
        for (se_int c = r; c < n; c++) {
            double acc = 0.0;
            const double *Prc = P + (r * n + c) * B, *xr = x + r * B, *xcol = x + c * B;
            for (se_int b = 0; b < nb; b++)
                acc += w[b] * (Prc[b] + (xr[b] - xm[r]) * (xcol[b] - xm[c]));
            Pm[r * n + c] = acc;
            Pm[c * n + r] = acc;
        }
    }
}

/* x_to[:, p] = x[:, anc[p]] and likewise P, mode: each particle replaced by its ancestor, mode
 * and filter. x, x_to (n, B), P, P_to (n, n, B), mode, anc, mode_to (B,) */
static void resample(se_int n, se_int B, const double *restrict x, const double *restrict P,
                     const se_int *restrict mode, const se_int *restrict anc, se_int nb,
                     double *restrict x_to, double *restrict P_to, se_int *restrict mode_to)
{
    for (se_int r = 0; r < n; r++) {
        for (se_int p = 0; p < nb; p++)
            x_to[r * B + p] = x[r * B + anc[p]];
        for (se_int c = 0; c < n; c++)
            for (se_int p = 0; p < nb; p++)
                P_to[(r * n + c) * B + p] = P[(r * n + c) * B + anc[p]];
    }
    for (se_int p = 0; p < nb; p++)
        mode_to[p] = mode[anc[p]];
}

/* Filter N trials over K samples with Np particles each.
 *
 * Parameters
 * ----------
 * y : (N, K, m) float64
 *     Measurements; NaN components are missing.
 * u : (N, K, l) float64
 *     Inputs; u[:, k-1] is held over the interval into sample k (u[:, 0] into sample 0 when
 *     predict_first).
 * F, G, Qd : (M, n, n), (M, n, l), (M, n, n) float64
 *     Table of exact transitions.
 * trans : (K, L) int64
 *     trans[k, r]: the transition of mode r into sample k.
 * C, R : (L, m, n), (L, m, m) float64
 *     Output matrix and measurement-noise covariance of each mode.
 * transition, log_transition : (L, L) float64
 *     transition[i, j] = P(mode j at k+1 | mode i at k), and its logarithm.
 * prob0, log_prob0 : (L,) float64
 *     Mode probabilities at the first sample, and their logarithms.
 * keys : (N,) uint64
 *     Each trial's random key (se_uniform).
 * k0 : int
 *     Index of the first sample of this call in its trials' records (for the uniforms).
 * predict_first : bool
 *     Whether the first sample is predicted into (a streaming step after the first) or is the
 *     first of the record (modes drawn from prob0, update only).
 * sample_timing : bool
 *     Whether a particle predicts into sample k through its mode at k-1 (the "sample" timing:
 *     predicted, then its new mode drawn) or through its mode at k (the "interval" timing:
 *     mode drawn, then predicted with it).
 * optimal : bool
 *     The optimal importance distribution (optimal_proposal) or the prior (prior_proposal).
 * scheme : int
 *     Resampling scheme (RESAMPLING).
 * threshold : float
 *     Resample when ESS < threshold Np (always when threshold >= 1).
 * x_init, P_init, mode_init, logw_init : (S, Np, n), (S, Np, n, n), (S, Np), (S, Np), S = N or 1
 *     Particles before the first sample (shared by every trial when the first axis is 1):
 *     filters, modes and normalized log-weights.
 * x_out, P_out, prob_out, mode_out, loglik_out, flag_out, ess_out
 *     Written, per trial and sample: x = sum_p w_p x_p, its covariance
 *     sum_p w_p (P_p + (x_p - x)(x_p - x)'), mode probabilities sum_{p: r_p = j} w_p, the most
 *     probable mode (first on a tie), the log-likelihood of the measurement given the past (0
 *     when nothing was observed or no particle could use it), the flag (GATED when no
 *     particle's likelihood was finite: the sample was treated as missing) and the effective
 *     sample size 1 / sum_p w_p^2 before resampling.
 * x_last, P_last, mode_last, logw_last : (T, Np, ...), T = N or 0
 *     Written when their first axis is N: the particles after the last sample.
 * report : (2,) float64
 *     Written: the number of covariances repaired (se_repair) and the smallest eigenvalue one
 *     had (inf if none).
 *
 * Returns
 * -------
 * status : int
 *     SE_OK, or the failure code of an innovation covariance that stopped the kernel
 *     (SE_NO_MEMORY if the scratch space could not be allocated).
 *
 * Notes
 * -----
 * After the proposal (which samples the modes and updates the filters), the weights are
 * w_p ∝ w_{p,k-1} exp(inc_p) in the log domain and the log-likelihood is
 * log sum_p w_{p,k-1} exp(inc_p), the unbiased particle estimate of p(y_k | y_{0:k-1})
 * (Doucet & Johansen 2011, "A tutorial on particle filtering and smoothing: fifteen years
 * later", §4). A fully missing sample does not reweight. The outputs are taken, then the
 * particles resampled when the effective sample size 1 / sum_p w_p^2 (Kong, Liu & Wong 1994)
 * is below threshold Np, each copying its ancestor's mode and filter, with weights 1 / Np.
 */
se_int se_particle_filter(SE_PARTICLE_FILTER_PARAMETERS)
{
    const se_int B = Np;
    const se_int n_cand = optimal ? L : 1;   /* filters updated per particle: candidates, or one */
    const se_int n_copies = optimal ? L : 0; /* candidates' filters and likelihoods, until a draw */

    double *x, *P, *x_to, *P_to, *logw, *w, *total, *yl, *ul, *obs, *n_obs, *pos, *ll, *xc, *Pc;
    double *terms, *pick_w, *inc, *prob, *xm, *Pm;
    se_int *mode, *mode_to, *anc;
    uint8_t *use;
    mats_t mats;
    work_t work;
    se_arena ar = {NULL, 0};
    do { /* size the arena, then carve it (zeroed: work.inn.bad must start at 0) */
        SE_DOUBLES(&ar, n * B, &x, &x_to, &mats.xs);
        SE_DOUBLES(&ar, n * n * B, &P, &P_to, &mats.Fl, &mats.Ql, &mats.AP);
        SE_DOUBLES(&ar, B, &logw, &w, &n_obs, &pos, &inc);
        SE_DOUBLES(&ar, 1, &total);
        SE_DOUBLES(&ar, m * B, &yl, &obs);
        SE_DOUBLES(&ar, l * B, &ul);
        SE_DOUBLES(&ar, n * l * B, &mats.Gl);
        SE_DOUBLES(&ar, m * n * B, &mats.Cl);
        SE_DOUBLES(&ar, m * m * B, &mats.Rl);
        se_carve_innovation(&ar, n, m, B, &work.inn);
        se_carve_update(&ar, n, m, B, &work.upd);
        SE_DOUBLES(&ar, n_copies * B, &ll);
        SE_DOUBLES(&ar, n_copies * n * B, &xc);
        SE_DOUBLES(&ar, n_copies * n * n * B, &Pc);
        SE_DOUBLES(&ar, n_cand * B, &terms);
        SE_DOUBLES(&ar, L, &pick_w, &prob);
        SE_DOUBLES(&ar, n, &xm);
        SE_DOUBLES(&ar, n * n, &Pm);
        SE_INTS(&ar, B, &mode, &mode_to, &mats.idx, &anc);
        SE_FLAGS(&ar, n_cand * B, &use);
    } while (se_arena_open(&ar));
    if (ar.base == NULL)
        return SE_NO_MEMORY;

    se_int status = SE_OK;
    se_report_start(report);
    const double uniform_log_weight = -log((double)Np);
    sample_t sp = {n, m, l, L, B, Np, yl, ul, obs, n_obs, F, G, Qd, C, R, NULL, transition,
                   log_transition, prob0, log_prob0, 0, 0, 0, sample_timing};
    for (se_int i = 0; i < N; i++) {
        se_int s = S > 1 ? i : 0;
        for (se_int p = 0; p < Np; p++) {
            mode[p] = mode_init[s * Np + p];
            logw[p] = logw_init[s * Np + p];
            const double *xi = x_init + (s * Np + p) * n, *Pi = P_init + (s * Np + p) * n * n;
            for (se_int r = 0; r < n; r++) {
                x[r * B + p] = xi[r];
                for (se_int c = 0; c < n; c++)
                    P[(r * n + c) * B + p] = Pi[r * n + c];
            }
        }
        for (se_int k = 0; k < K; k++) {
            const se_int ik = i * K + k;
            fill_lanes(m, B, y + ik * m, Np, yl);
            se_observe(m, B, yl, Np, obs, n_obs);
            fill_lanes(l, B, u + (i * K + (k > 0 ? k - 1 : 0)) * l, Np, ul);
            sp.trans_row = trans + k * L;
            sp.key = keys[i];
            sp.k = k0 + k;
            sp.predicting = k > 0 || predict_first;
            if (optimal)
                status = optimal_proposal(&sp, x, P, mode, &mats, xc, Pc, ll, use, terms, pick_w,
                                          inc, &work, report);
            else
                status = prior_proposal(&sp, x, P, mode, &mats, use, inc, &work, report);
            if (status != SE_OK)
                goto done;
            /* without particles (Np = 0) nothing counts as seen, and n_obs is not read */
            const int seen = Np > 0 && n_obs[0] > 0.0;
            int alive = 0;
            for (se_int p = 0; p < Np; p++)
                alive |= inc[p] > -INFINITY;
            /* else no reweighting: nothing observed, or nothing usable */
            const int usable = seen && alive;
            for (se_int p = 0; p < Np; p++)
                logw[p] += usable ? inc[p] : 0.0;
            se_log_normalize(Np, 1, logw, w, total, 1); /* w_p ∝ w_{p,k-1} exp(inc_p); total = loglik */
            se_int best = 0;
            double sq = 0.0;
            for (se_int j = 0; j < L; j++)
                prob[j] = 0.0;
            for (se_int p = 0; p < Np; p++) {
                prob[mode[p]] += w[p];
                sq += w[p] * w[p];
            }
            for (se_int j = 0; j < L; j++) {
                prob_out[ik * L + j] = prob[j];
                if (prob[j] > prob[best])
                    best = j;
            }
            mode_out[ik] = best;
            particle_moments(n, B, w, x, P, Np, xm, Pm);
            for (se_int r = 0; r < n; r++) {
                x_out[ik * n + r] = xm[r];
                for (se_int c = 0; c < n; c++)
                    P_out[(ik * n + r) * n + c] = Pm[r * n + c];
            }
            loglik_out[ik] = usable ? total[0] : 0.0;
            flag_out[ik] = seen && !alive ? SE_GATED : SE_ACCEPTED;
            const double ess = 1.0 / sq;
            ess_out[ik] = ess;
            if (threshold >= 1.0 || ess < threshold * (double)Np) {
                se_resampling_positions(keys[i], k0 + k, scheme, Np, pos);
                se_ancestors(w, pos, Np, anc);
                resample(n, B, x, P, mode, anc, Np, x_to, P_to, mode_to);
                double *t;
                se_int *ti;
                t = x; x = x_to; x_to = t;
                t = P; P = P_to; P_to = t;
                ti = mode; mode = mode_to; mode_to = ti;
                for (se_int p = 0; p < Np; p++)
                    logw[p] = uniform_log_weight;
            }
        }
        if (T > 0) {
            for (se_int p = 0; p < Np; p++) {
                mode_last[i * Np + p] = mode[p];
                logw_last[i * Np + p] = logw[p];
                double *xo = x_last + (i * Np + p) * n, *Po = P_last + (i * Np + p) * n * n;
                for (se_int r = 0; r < n; r++) {
                    xo[r] = x[r * B + p];
                    for (se_int c = 0; c < n; c++)
                        Po[r * n + c] = P[(r * n + c) * B + p];
                }
            }
        }
    }
done:
    se_arena_close(&ar);
    return status;
}
