/* The Kalman filter along given transitions: covariances shared by trials (se_kalman_filter),
 * and the fixed-gain filter (se_steady_filter).
 *
 * The covariance recursion of a Kalman filter (Shankar et al. eqs (7)-(10)) does not depend on
 * the measured values: trials that start from the same P, predict through equal F, Qd, update
 * with equal C, R, observe the same components and use (or gate) the measurement alike carry
 * the same P, gain and innovation covariance, to the last bit. se_kalman_filter therefore
 * keeps the trials of a block in *groups* of one covariance each and runs the covariance
 * equations once per group, the mean equations once per trial, all from linalg.c:
 *
 * - per group (the group's covariance in a lane of its own, its mean zero): se_predict,
 *   se_innovation, se_correct, se_joseph_lost with se_information_form, and se_repair;
 * - per trial: se_predict_mean, se_innovation_mean, se_correct_mean (the mean halves of the
 *   same equations), reading a copy of their group's factorization.
 *
 * A group splits when its trials part ways: another transition or output matrix (compared by
 * value, so per-trial copies of one matrix stay together), other observed components, or a
 * measurement some trials gate and others use. Groups never merge. In the common case (every
 * trial in one mode and fully observed) a block is one group, and a trial-step costs a
 * prediction of the mean, a whitened residual and the writing of the outputs; with every trial
 * apart (different transitions, scattered missing components) there is one group per trial,
 * the equations of the bank lane by lane. Either way each trial gets exactly the numbers its
 * own filter would compute: a group runs the same operations on the same operands.
 *
 * A covariance recursion with a fixed sample (the same transition, output matrices, observed
 * components and use of the measurement at every step) reaches a fixed point to the last bit
 * within some tens of samples: P = f(P) in floating point. From the sample after the block's
 * covariances reached it under an unchanged sample, the covariance equations of the next
 * sample with that sample would repeat the last ones operand for operand, so the kernel skips
 * them and keeps their results (P and the factorization of S): the same bits, at the cost of
 * the means alone. Any change (another entry, other observed components, a gated measurement,
 * a new group, a repair) runs the equations again.
 *
 * (A measurement on the JIT-compiled implementation this file was ported from, kept for the
 * record: a block of one group runs the covariance equations on one lane, where each lane loop
 * costs more than its arithmetic; compiling the equations for a literal lane count of 1 ran 10
 * trials over 200 samples of the vehicle (n = 4, m = 2) in 0.80-0.87 of the time but took
 * 5-10 CPU-s more to compile, so it was not done there.)
 *
 * The outputs (N, K, ...) are written through buffers of CHUNK samples, trial by trial, so
 * that each store continues a run of contiguous memory (se_write_out): stored sample by
 * sample, a block's trials write to `lanes` places K samples apart, and the kernel ran 15-20 %
 * slower.
 *
 * Fixed gains (se_steady_filter): x_k|k = x_k|k-1 + K_i (y_k - C_i x_k|k-1) with the gain of
 * the mode i (Zhang & Natarajan eq. (6)); the covariance is read from the tables.
 *
 * Layout: every lane array has the block's lanes as its last axis, of length B = lanes (the
 * lane stride), e.g. P of shape (n, n, B) is addressed P[(r * n + c) * B + b]; a
 * block's scratch is one allocation (an arena carved into the arrays) made at the start of
 * the kernel and freed before it returns.
 */
#include "kalman.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "linalg.h"

#define CHUNK SE_KALMAN_CHUNK

/* rows of a block's group index slot (4, B) */
#define MEMBER 0 /* the lane of a trial in the group (whose sample stands for the group's) */
#define PARENT 1 /* the group it split from, while splits are being made */
#define TRANS 2  /* the entry of F, Qd in the group's lane (-1: to be gathered) */
#define MODE 3   /* the entry of C, R in the group's lane (-1: to be gathered) */

/* ---- shared with the fixed-gain filter ----------------------------------------------------- */

/* held[b] <- index[i0 + b, k] for every lane; return whether one changed (the lanes' matrices
 * are then gathered again). */
static int se_lane_entries(se_int K, const se_int *restrict index, se_int i0, se_int nb, se_int k,
                           se_int *restrict held)
{
    int changed = 0;
    for (se_int b = 0; b < nb; b++) {
        se_int v = index[(i0 + b) * K + k];
        changed |= v != held[b];
        held[b] = v;
    }
    return changed;
}

/* Every trial's mean predicted into sample k, x <- F x + G u (Shankar et al. eq. (6),
 * se_predict_mean), with u[:, k-1] and the transition trans[i0 + b, k] of the table F, G,
 * whose lane matrices Fl, Gl are gathered again where it changed (se_lane_entries); ul, xs are
 * scratch. */
static void se_predict_means(se_int n, se_int l, se_int B, se_int K, const se_int *restrict trans,
                             const double *restrict F, const double *restrict G,
                             const double *restrict u, se_int i0, se_int nb, se_int k,
                             se_int *restrict held, double *restrict Fl, double *restrict Gl,
                             double *restrict ul, double *restrict x, double *restrict xs)
{
    if (se_lane_entries(K, trans, i0, nb, k, held)) {
        se_gather_matrices(n, n, B, F, held, nb, Fl);
        se_gather_matrices(n, l, B, G, held, nb, Gl);
    }
    se_gather_samples(l, B, K, u, i0, nb, k > 0 ? k - 1 : 0, ul);
    se_predict_mean(n, l, B, x, Fl, Gl, ul, nb, xs);
}

/* Write the `count` buffered samples of the block's trials out as samples k0 .. of the
 * outputs, trial by trial (each trial's samples are contiguous there, as in the buffers);
 * P_out holds each covariance as a row of n^2. */
static void se_write_out(se_int n, se_int K, const double *restrict x_buf,
                         const double *restrict P_buf, const se_int *restrict group_buf,
                         const double *restrict loglik_buf, const uint8_t *restrict flag_buf,
                         se_int i0, se_int nb, se_int k0, se_int count, double *restrict x_out,
                         double *restrict P_out, double *restrict loglik_out,
                         uint8_t *restrict flag_out)
{
    const se_int nn = n * n;
    for (se_int b = 0; b < nb; b++) {
        se_int i = i0 + b;
        for (se_int t = 0; t < count; t++) {
            se_int k = k0 + t, at = b * CHUNK + t;
            loglik_out[i * K + k] = loglik_buf[at];
            flag_out[i * K + k] = flag_buf[at];
            double *xo = x_out + (i * K + k) * n;
            const double *xb = x_buf + at * n;
            for (se_int r = 0; r < n; r++)
                xo[r] = xb[r];
            se_int j = group_buf[at];
            double *Po = P_out + (i * K + k) * nn;
            const double *Pb = P_buf + (j * CHUNK + t) * nn;
            for (se_int q = 0; q < nn; q++)
                Po[q] = Pb[q];
        }
    }
}

/* ---- the groups of a block ----------------------------------------------------------------- */

/* Whether entries i and j of table (T, rows, cols) are equal, element by element (NaN is not
 * equal to itself: such entries stay apart). */
static int same_entry(se_int rows, se_int cols, const double *restrict table, se_int i, se_int j)
{
    if (i == j)
        return 1;
    const double *a = table + i * rows * cols, *c = table + j * rows * cols;
    for (se_int q = 0; q < rows * cols; q++)
        if (a[q] != c[q])
            return 0;
    return 1;
}

/* Open group j with lane b as its member, split from `parent`, with the covariance in lane i
 * of source (n, n, B) (its matrices are gathered at the next sample). source may be P. */
static void open_group(se_int n, se_int B, se_int *restrict slot, se_int j, se_int b,
                       se_int parent, const double *source, se_int i, double *P)
{
    slot[MEMBER * B + j] = b;
    slot[PARENT * B + j] = parent;
    slot[TRANS * B + j] = -1;
    slot[MODE * B + j] = -1;
    for (se_int q = 0; q < n * n; q++)
        P[q * B + j] = source[q * B + i];
}

/* out[:, :, j] = table[i]: entry i of a table (T, rows, cols) into lane j of out
 * (rows, cols, B). */
static void copy_entry(se_int rows, se_int cols, se_int B, const double *restrict table,
                       se_int i, double *restrict out, se_int j)
{
    const double *t = table + i * rows * cols;
    for (se_int q = 0; q < rows * cols; q++)
        out[q * B + j] = t[q];
}

/* Group the block's trials by equal initial covariance (each compared with the previous
 * trial's group and with the first group); returns the number of groups. P_init (N, n, n). */
static se_int group_equal(se_int n, se_int B, const double *restrict P_init, se_int i0,
                          se_int nb, se_int *restrict group, se_int *restrict slot,
                          double *restrict P)
{
    se_int n_groups = 0;
    for (se_int b = 0; b < nb; b++) {
        se_int j = -1;
        if (b > 0 && same_entry(n, n, P_init, i0 + b, i0 + slot[MEMBER * B + group[b - 1]]))
            j = group[b - 1];
        else if (b > 0 && same_entry(n, n, P_init, i0 + b, i0 + slot[MEMBER * B + 0]))
            j = 0;
        if (j < 0) {
            j = n_groups;
            n_groups += 1;
            slot[MEMBER * B + j] = b;
            slot[TRANS * B + j] = -1;
            slot[MODE * B + j] = -1;
            copy_entry(n, n, B, P_init, i0 + b, P, j);
        }
        group[b] = j;
    }
    return n_groups;
}

/* The tables and indices one sample of a block is read from, gathered in one struct. */
typedef struct {
    se_int n, m, B, K;
    const se_int *trans, *mode;
    const double *F, *Qd, *C, *R;
} Sample;

/* Whether lanes b and s take sample k through the same covariance equations: the same
 * observed components, equal C, R and (when `predicting`) F, Qd (the same entry, or entries
 * equal by value). obs (m, B). */
static int same_sample(const Sample *restrict sp, const double *restrict obs, se_int i0,
                       se_int k, int predicting, se_int b, se_int s)
{
    const se_int n = sp->n, m = sp->m, B = sp->B, K = sp->K;
    for (se_int a = 0; a < m; a++)
        if (obs[a * B + b] != obs[a * B + s])
            return 0;
    se_int i = i0 + b, j = i0 + s;
    se_int mi = sp->mode[i * K + k], mj = sp->mode[j * K + k];
    if (mi != mj && !(same_entry(m, n, sp->C, mi, mj) && same_entry(m, m, sp->R, mi, mj)))
        return 0;
    se_int ti = sp->trans[i * K + k], tj = sp->trans[j * K + k];
    return !predicting || ti == tj
           || (same_entry(n, n, sp->F, ti, tj) && same_entry(n, n, sp->Qd, ti, tj));
}

/* Move each trial whose sample differs from its group member's (same_sample) to a new group
 * with a copy of the covariance, shared with the trials that move alike; returns the number
 * of groups. */
static se_int split_samples(const Sample *restrict sp, const double *restrict obs, se_int i0,
                            se_int nb, se_int k, int predicting, se_int *restrict group,
                            se_int n_groups, se_int *restrict slot, double *restrict P)
{
    const se_int m = sp->m, B = sp->B, K = sp->K, first = n_groups;
    const se_int *trans = sp->trans, *mode = sp->mode;
    for (se_int b = 0; b < nb; b++) {
        se_int s = slot[MEMBER * B + group[b]];
        int alike = trans[(i0 + b) * K + k] == trans[(i0 + s) * K + k] || !predicting;
        alike &= mode[(i0 + b) * K + k] == mode[(i0 + s) * K + k];
        for (se_int a = 0; a < m; a++)
            alike &= obs[a * B + b] == obs[a * B + s];
        if (alike) /* the common case, decided without a call */
            continue;
        if (same_sample(sp, obs, i0, k, predicting, b, s))
            continue;
        se_int h = first;
        while (h < n_groups
               && !(slot[PARENT * B + h] == group[b]
                    && same_sample(sp, obs, i0, k, predicting, b, slot[MEMBER * B + h])))
            h += 1;
        if (h == n_groups) {
            n_groups += 1;
            open_group(sp->n, B, slot, h, b, group[b], P, group[b], P);
        }
        group[b] = h;
    }
    return n_groups;
}

/* Each group's sample from its member trial: the observed components, and the matrices of
 * the entries whose index changed. Returns whether any group's sample differs from the one
 * its lane held (other observed components or entries). obs (m, B), n_obs (B,); Fg, Qg
 * (n, n, B), Cg (m, n, B), Rg (m, m, B), obs_g (m, B), n_obs_g (B,). */
static int gather_groups(const Sample *restrict sp, const double *restrict obs,
                         const double *restrict n_obs, se_int i0, se_int k, int predicting,
                         se_int n_groups, se_int *restrict slot, double *restrict Fg,
                         double *restrict Qg, double *restrict Cg, double *restrict Rg,
                         double *restrict obs_g, double *restrict n_obs_g)
{
    const se_int n = sp->n, m = sp->m, B = sp->B, K = sp->K;
    int changed = 0;
    for (se_int j = 0; j < n_groups; j++) {
        se_int b = slot[MEMBER * B + j];
        se_int i = i0 + b;
        for (se_int a = 0; a < m; a++) {
            changed |= obs_g[a * B + j] != obs[a * B + b];
            obs_g[a * B + j] = obs[a * B + b];
        }
        n_obs_g[j] = n_obs[b];
        se_int t = sp->trans[i * K + k], md = sp->mode[i * K + k];
        if (predicting && t != slot[TRANS * B + j]) {
            changed = 1;
            slot[TRANS * B + j] = t;
            copy_entry(n, n, B, sp->F, t, Fg, j);
            copy_entry(n, n, B, sp->Qd, t, Qg, j);
        }
        if (md != slot[MODE * B + j]) {
            changed = 1;
            slot[MODE * B + j] = md;
            copy_entry(m, n, B, sp->C, md, Cg, j);
            copy_entry(m, m, B, sp->R, md, Rg, j);
        }
    }
    return changed;
}

/* Whether P[:, :, j] equals Q[:, :, j] bit for bit in every group's lane (NaN is not equal to
 * itself: a covariance with a NaN is never at a fixed point). P, Q (n, n, B). */
static int same_lanes(se_int n, se_int B, const double *restrict P, const double *restrict Q,
                      se_int n_groups)
{
    for (se_int q = 0; q < n * n; q++)
        for (se_int j = 0; j < n_groups; j++)
            if (P[q * B + j] != Q[q * B + j])
                return 0;
    return 1;
}

/* Whether a[j] == b[j] in every group's lane. */
static int same_flags(const uint8_t *restrict a, const uint8_t *restrict b, se_int n_groups)
{
    for (se_int j = 0; j < n_groups; j++)
        if (a[j] != b[j])
            return 0;
    return 1;
}

/* The number of trials in group j. */
static se_int members(const se_int *restrict group, se_int nb, se_int j)
{
    se_int count = 0;
    for (se_int b = 0; b < nb; b++)
        count += group[b] == j;
    return count;
}

/* The number of trials in group j that use the measurement. */
static se_int users(const se_int *restrict group, const uint8_t *restrict use, se_int nb,
                    se_int j)
{
    se_int count = 0;
    for (se_int b = 0; b < nb; b++)
        count += group[b] == j && use[b];
    return count;
}

/* se_repair of group j's covariance, reported once per trial of the group (`trials`), as if
 * each had been repaired; returns whether P changed. */
static int repair_group(se_int n, se_int B, double *restrict P, se_int j, int indefinite_only,
                        se_int trials, double *restrict report)
{
    if (!se_repair(n, B, P, j, indefinite_only, report))
        return 0;
    report[0] += (double)(trials - 1);
    return 1;
}

/* se_innovation of every group, for its covariance (the group's mean and measurement are
 * zero), repairing the covariance of a group whose S fails its factorization and factoring
 * once more; then log det S in its two terms (log_det_g, for se_innovation_mean). Returns the
 * status. */
static se_int factor_groups(se_int n, se_int m, se_int B, const double *restrict xg,
                            double *restrict P, const double *restrict yg,
                            const double *restrict Cg, const double *restrict Rg,
                            const double *restrict obs_g, const double *restrict n_obs_g,
                            se_int n_groups, double *restrict eg, double *restrict PCt_g,
                            double *restrict chol_g, double *restrict scale_g,
                            double *restrict zg, double *restrict nis_g,
                            double *restrict loglik_g, double *restrict work,
                            uint8_t *restrict bad, double *restrict log_det_g,
                            const se_int *restrict group, se_int nb, double *restrict report)
{
    se_int status = se_innovation(n, m, B, xg, P, yg, Cg, Rg, obs_g, n_obs_g, n_groups, eg,
                                  PCt_g, chol_g, scale_g, zg, nis_g, loglik_g, work, bad, NULL);
    if (status == SE_NOT_POSITIVE_DEFINITE) {
        for (se_int j = 0; j < n_groups; j++)
            if (bad[j] && !repair_group(n, B, P, j, 0, members(group, nb, j), report))
                return status;
        status = se_innovation(n, m, B, xg, P, yg, Cg, Rg, obs_g, n_obs_g, n_groups, eg, PCt_g,
                               chol_g, scale_g, zg, nis_g, loglik_g, work, bad, NULL);
    }
    if (status == SE_OK) {
        for (se_int j = 0; j < n_groups; j++) { /* log det S = sum log D + log prod L_aa^2 */
            log_det_g[j] = work[j];
            log_det_g[B + j] = log(work[B + j]);
        }
    }
    return status;
}

/* out[a, b] = source[a, group[b]] for the `rows` rows of source, out (rows, B): each lane's
 * copy of its group's values. */
static void spread(se_int rows, se_int B, const double *restrict source,
                   const se_int *restrict group, se_int nb, se_int n_groups,
                   double *restrict out)
{
    for (se_int a = 0; a < rows; a++) {
        const double *s = source + a * B;
        double *o = out + a * B;
        if (n_groups == 1) { /* one group: a broadcast */
            const double v = s[0];
            for (se_int b = 0; b < nb; b++)
                o[b] = v;
        } else {
            for (se_int b = 0; b < nb; b++)
                o[b] = s[group[b]];
        }
    }
}

/* Move the trials that did not use the measurement out of a group that did (its covariance
 * was updated): to a new group with the covariance before the update (prior). Returns the
 * number of groups. */
static se_int split_gated(se_int n, se_int B, const uint8_t *restrict use,
                          const uint8_t *restrict use_g, se_int *restrict group, se_int nb,
                          se_int n_groups, se_int *restrict slot, double *restrict P,
                          const double *restrict prior)
{
    const se_int first = n_groups;
    for (se_int b = 0; b < nb; b++) {
        se_int j = group[b];
        if (use[b] || !use_g[j])
            continue;
        se_int h = first;
        while (h < n_groups && slot[PARENT * B + h] != j)
            h += 1;
        if (h == n_groups) {
            n_groups += 1;
            open_group(n, B, slot, h, b, j, prior, j, P);
        }
        group[b] = h;
    }
    for (se_int j = 0; j < first; j++) { /* a group that used the measurement keeps a member that used it */
        if (use_g[j] && !use[slot[MEMBER * B + j]]) {
            se_int b = 0;
            while (group[b] != j)
                b += 1;
            slot[MEMBER * B + j] = b;
        }
    }
    return n_groups;
}

/* Keep the block's posterior as sample t of the buffers (each trial's, and each group's,
 * samples contiguous): the trials' means, the groups' covariances (as rows of n^2) and each
 * trial's group, its log-likelihood (0 where nothing was used) and its flag.
 * x (n, B), P (n, n, B); x_buf (B, CHUNK, n), P_buf (B, CHUNK, n * n), group_buf,
 * loglik_buf, flag_buf (B, CHUNK). */
static void record(se_int n, se_int B, const double *restrict x, const double *restrict P,
                   const se_int *restrict group, const uint8_t *restrict use,
                   const double *restrict n_obs, const double *restrict loglik, se_int nb,
                   se_int n_groups, se_int t, double *restrict x_buf, double *restrict P_buf,
                   se_int *restrict group_buf, double *restrict loglik_buf,
                   uint8_t *restrict flag_buf)
{
    const se_int nn = n * n;
    for (se_int b = 0; b < nb; b++)
        for (se_int r = 0; r < n; r++)
            x_buf[(b * CHUNK + t) * n + r] = x[r * B + b];
    for (se_int j = 0; j < n_groups; j++)
        for (se_int q = 0; q < nn; q++)
            P_buf[(j * CHUNK + t) * nn + q] = P[q * B + j];
    for (se_int b = 0; b < nb; b++) {
        group_buf[b * CHUNK + t] = group[b];
        loglik_buf[b * CHUNK + t] = use[b] && n_obs[b] > 0.0 ? loglik[b] : 0.0;
        flag_buf[b * CHUNK + t] = use[b] ? SE_ACCEPTED : SE_GATED;
    }
}

/* ---- the kernel ---------------------------------------------------------------------------- */

/* Kalman filter of N trials over K samples, in blocks of `lanes` trials.
 *
 * Parameters
 * ----------
 * y (N, K, m): measurements; NaN components are missing (each trial updates with its
 *     observed ones).
 * u (N, K, l): inputs; u[:, k-1] is held over the interval into sample k, u[:, 0] over the
 *     interval into sample 0 when predict_first.
 * F, G, Qd (M, n, n), (M, n, l), (M, n, n): table of exact transitions x+ = F x + G u + w,
 *     w ~ N(0, Qd).
 * trans (N, K): transition into sample k of each trial.
 * C, R (L, m, n), (L, m, m): table of output matrices and measurement-noise covariances.
 * mode (N, K): which C, R sample k of each trial uses.
 * x_init, P_init (N, n), (N, n, n): state of every trial before the first sample.
 * predict_first: whether the first sample is predicted into (a streaming step) or only
 *     updated.
 * gate: largest normalized innovation squared accepted.
 * lanes: trials per block.
 * x_out, P_out, loglik_out, flag_out: written: posterior (N, K, n), (N, K, n, n),
 *     log-likelihood (0 when nothing was observed or the sample was gated) and flag
 *     (SE_ACCEPTED or SE_GATED) (N, K).
 * report (2,): written: the number of covariances repaired (a group's repair counts once per
 *     trial of the group) and the smallest eigenvalue one had before its repair (inf if none).
 *
 * Returns SE_OK or the failure code that stopped the kernel (outputs then incomplete);
 * SE_NO_MEMORY if the scratch could not be allocated.
 *
 * A measurement whose normalized innovation squared exceeds gate, or whose likelihood is not
 * finite, is treated as missing (flag SE_GATED). Ill-conditioned covariances as in the bank's
 * filter: the information form where Joseph's form loses its digits, a repair where neither
 * resolves it or where the innovation covariance fails its factorization; only a covariance
 * that needs no repair and still fails stops the kernel.
 */
se_int se_kalman_filter(SE_KALMAN_FILTER_PARAMETERS)
{
    se_report_start(report);
    if (N <= 0 || K <= 0 || lanes <= 0)
        return SE_OK; /* nothing to filter: SE_OK with only the report written */
    const se_int B = se_lanes(lanes, N), nn = n * n;
    double *restrict x, *restrict xs, *restrict Fl, *restrict Gl, *restrict Cl, *restrict yl,
        *restrict ul, *restrict obs, *restrict n_obs, *restrict e, *restrict z, *restrict nis,
        *restrict loglik, *restrict PCt, *restrict chol, *restrict scale, *restrict log_det,
        *restrict P, *restrict Fg, *restrict Qg, *restrict Cg, *restrict Rg, *restrict obs_g,
        *restrict n_obs_g, *restrict xg, *restrict Gg, *restrict ug, *restrict yg, *restrict eg,
        *restrict zg, *restrict PCt_g, *restrict chol_g, *restrict scale_g, *restrict nis_g,
        *restrict loglik_g, *restrict work, *restrict log_det_g, *restrict gain, *restrict T,
        *restrict FP, *restrict prior, *restrict root, *restrict P_last, *restrict x_buf, *restrict
        P_buf, *restrict loglik_buf;
    se_int *restrict held, *restrict group, *restrict slot, *restrict group_buf;
    uint8_t *restrict use, *restrict use_g, *restrict bad, *restrict lost, *restrict use_last,
        *restrict flag_buf;
    se_arena ar = {NULL, 0};
    do { /* size the arena, then carve it (zeroed: xg, Gg, ug, yg and bad start at 0) */
        SE_DOUBLES(&ar, n * B, &x, &xs, &xg, &root);
        SE_DOUBLES(&ar, nn * B, &Fl, &P, &Fg, &Qg, &FP, &prior, &P_last);
        SE_DOUBLES(&ar, n * l * B, &Gl, &Gg);
        SE_DOUBLES(&ar, m * n * B, &Cl, &Cg);
        SE_DOUBLES(&ar, m * B, &yl, &obs, &e, &z, &scale, &obs_g, &yg, &eg, &zg, &scale_g);
        SE_DOUBLES(&ar, l * B, &ul, &ug);
        SE_DOUBLES(&ar, B, &n_obs, &nis, &loglik, &n_obs_g, &nis_g, &loglik_g);
        SE_DOUBLES(&ar, n * m * B, &PCt, &PCt_g, &gain, &T);
        SE_DOUBLES(&ar, m * m * B, &chol, &Rg, &chol_g);
        SE_DOUBLES(&ar, 2 * B, &log_det, &log_det_g);
        SE_DOUBLES(&ar, 3 * B, &work);
        SE_DOUBLES(&ar, B * CHUNK * n, &x_buf);
        SE_DOUBLES(&ar, B * CHUNK * nn, &P_buf);
        SE_DOUBLES(&ar, B * CHUNK, &loglik_buf);
        SE_INTS(&ar, 2 * B, &held);
        SE_INTS(&ar, B, &group);
        SE_INTS(&ar, 4 * B, &slot);
        SE_INTS(&ar, B * CHUNK, &group_buf);
        SE_FLAGS(&ar, B, &use, &use_g, &bad, &lost, &use_last);
        SE_FLAGS(&ar, B * CHUNK, &flag_buf);
    } while (se_arena_open(&ar));
    if (ar.base == NULL)
        return SE_NO_MEMORY;
    const Sample sp = {n, m, B, K, trans, mode, F, Qd, C, R};
    se_int status = SE_OK;
    for (se_int i0 = 0; i0 < N; i0 += B) {
        const se_int nb = se_block_trials(B, N, i0);
        se_gather_rows(n, B, 1, x_init, i0, nb, x);
        for (se_int q = 0; q < 2 * B; q++) /* no entry held: each lane gathers its matrices at its first sample */
            held[q] = -1;
        se_int n_groups = group_equal(n, B, P_init, i0, nb, group, slot, P);
        int fixed = 0; /* the groups' covariances are at a fixed point of the last sample's map */
        for (se_int k = 0; k < K; k++) {
            se_gather_samples(m, B, K, y, i0, nb, k, yl);
            se_observe(m, B, yl, nb, obs, n_obs);
            const int predicting = k > 0 || predict_first;
            const se_int before = n_groups;
            const double repairs = report[0];
            n_groups = split_samples(&sp, obs, i0, nb, k, predicting, group, n_groups, slot, P);
            const int changed = gather_groups(&sp, obs, n_obs, i0, k, predicting, n_groups, slot,
                                              Fg, Qg, Cg, Rg, obs_g, n_obs_g);
            /* the same covariances through the same equations: the last sample's results, kept
             * in P, prior, PCt_g, chol_g, scale_g and log_det_g, to the last bit */
            const int repeat = fixed && predicting && n_groups == before && !changed;
            if (predicting) { /* Shankar et al. eqs (6)-(7) */
                se_predict_means(n, l, B, K, trans, F, G, u, i0, nb, k, held, Fl, Gl, ul, x, xs);
                if (!repeat)
                    se_predict(n, l, B, xg, P, Fg, Gg, ug, Qg, n_groups, FP, xs);
            }
            if (se_lane_entries(K, mode, i0, nb, k, held + B))
                se_gather_matrices(m, n, B, C, held + B, nb, Cl);
            if (!repeat) {
                status = factor_groups(n, m, B, xg, P, yg, Cg, Rg, obs_g, n_obs_g, n_groups, eg,
                                       PCt_g, chol_g, scale_g, zg, nis_g, loglik_g, work, bad,
                                       log_det_g, group, nb, report); /* eq. (8) */
                if (status != SE_OK)
                    goto done;
            }
            spread(n * m, B, PCt_g, group, nb, n_groups, PCt);
            spread(m * m, B, chol_g, group, nb, n_groups, chol);
            spread(m, B, scale_g, group, nb, n_groups, scale);
            spread(2, B, log_det_g, group, nb, n_groups, log_det);
            se_innovation_mean(n, m, B, x, yl, Cl, obs, n_obs, chol, scale, log_det, nb, e, z,
                               nis, loglik);
            for (se_int j = 0; j < n_groups; j++)
                use_g[j] = 0;
            for (se_int b = 0; b < nb; b++) { /* the gate, then the update (eqs (9)-(10)) where it passed */
                use[b] = se_passes_gate(loglik[b], nis[b], gate);
                use_g[group[b]] |= use[b];
            }
            int lost_any = 0;
            if (!(repeat && same_flags(use_g, use_last, n_groups))) {
                if (repeat) /* the prediction skipped above: the prior, as the last sample's */
                    se_copy_lanes(n, n, B, prior, n_groups, P);
                se_correct(n, m, B, xg, P, Cg, Rg, use_g, n_groups, PCt_g, chol_g, scale_g, zg,
                           gain, T, FP, prior);
                lost_any = se_joseph_lost(n, B, P, prior, use_g, n_groups, root, lost);
                if (lost_any) { /* rare */
                    for (se_int j = 0; j < n_groups; j++)
                        if (lost[j] && n_obs_g[j] > 0.0
                            && !se_information_form(n, m, B, P, prior, Cg, Rg, obs_g, j))
                            repair_group(n, B, P, j, 1, users(group, use, nb, j), report);
                }
            }
            se_correct_mean(n, m, B, x, z, PCt, chol, scale, use, nb);
            for (se_int j = 0; j < n_groups; j++)
                use_last[j] = use_g[j];
            n_groups = split_gated(n, B, use, use_g, group, nb, n_groups, slot, P, prior);
            /* P = f(P) for this sample's map f: the next sample, with the same map, repeats it */
            fixed = k > 0 && predicting && n_groups == before && !lost_any
                    && report[0] == repairs && same_lanes(n, B, P, P_last, n_groups);
            se_copy_lanes(n, n, B, P, n_groups, P_last);
            const se_int t = k % CHUNK;
            record(n, B, x, P, group, use, n_obs, loglik, nb, n_groups, t, x_buf, P_buf,
                   group_buf, loglik_buf, flag_buf);
            if (t == CHUNK - 1 || k == K - 1)
                se_write_out(n, K, x_buf, P_buf, group_buf, loglik_buf, flag_buf, i0, nb, k - t,
                             t + 1, x_out, P_out, loglik_out, flag_out);
        }
    }
done:
    se_arena_close(&ar);
    return status;
}

/* ---- the fixed-gain filter ----------------------------------------------------------------- */

/* nis[b] = |W e|^2 (= e' S^-1 e for S^-1 = W' W) in every lane; NaN where a component of e is
 * missing. e (m, B), W (m, m, B) lower triangular, v (B,) scratch, nis (B,). */
static void whitened_norm(se_int m, se_int B, const double *restrict e,
                          const double *restrict W, se_int nb, double *restrict v,
                          double *restrict nis)
{
    for (se_int b = 0; b < nb; b++)
        nis[b] = 0.0;
    for (se_int a = 0; a < m; a++) {
        se_lane_accumulate(a + 1, NULL, 0, W + a * m * B, B, e, B, nb, v); /* W lower */
        for (se_int b = 0; b < nb; b++)
            nis[b] += v[b] * v[b];
    }
}

/* Fixed-gain filter of every trial from x_init[i], in blocks of `lanes` trials:
 * x <- F x + G u (se_predict_means), then x <- x + K (y - C x) in the lanes where every
 * component of y is observed and its normalized innovation squared |W e|^2 passes gate
 * (Zhang & Natarajan eq. (6)); P is copied from the tables, loglik is NaN. A lane's matrices
 * are gathered when its entry changes; the outputs are buffered and written trial by trial
 * (se_write_out). Returns SE_OK, or SE_NO_MEMORY. */
se_int se_steady_filter(SE_STEADY_FILTER_PARAMETERS)
{
    if (N <= 0 || K <= 0 || lanes <= 0)
        return SE_OK; /* nothing to filter: SE_OK with nothing written */
    const se_int B = se_lanes(lanes, N), nn = n * n;
    double *restrict x, *restrict xs, *restrict yl, *restrict ul, *restrict Fl, *restrict Gl,
        *restrict Cl, *restrict Kl, *restrict Wl, *restrict e, *restrict obs, *restrict n_obs,
        *restrict v, *restrict nis, *restrict x_buf, *restrict P_buf, *restrict loglik_buf;
    se_int *restrict held, *restrict entry_buf;
    uint8_t *restrict use, *restrict flag_buf;
    se_arena ar = {NULL, 0};
    do { /* size the arena, then carve it (zeroed) */
        SE_DOUBLES(&ar, n * B, &x, &xs);
        SE_DOUBLES(&ar, m * B, &yl, &e, &obs);
        SE_DOUBLES(&ar, l * B, &ul);
        SE_DOUBLES(&ar, nn * B, &Fl);
        SE_DOUBLES(&ar, n * l * B, &Gl);
        SE_DOUBLES(&ar, m * n * B, &Cl);
        SE_DOUBLES(&ar, n * m * B, &Kl);
        SE_DOUBLES(&ar, m * m * B, &Wl);
        SE_DOUBLES(&ar, B, &n_obs, &v, &nis);
        SE_DOUBLES(&ar, B * CHUNK * n, &x_buf);
        SE_DOUBLES(&ar, 2 * L * CHUNK * nn, &P_buf);
        SE_DOUBLES(&ar, B * CHUNK, &loglik_buf);
        SE_INTS(&ar, 2 * B, &held);
        SE_INTS(&ar, B * CHUNK, &entry_buf);
        SE_FLAGS(&ar, B, &use);
        SE_FLAGS(&ar, B * CHUNK, &flag_buf);
    } while (se_arena_open(&ar));
    if (ar.base == NULL)
        return SE_NO_MEMORY;
    for (se_int q = 0; q < B * CHUNK; q++)
        loglik_buf[q] = NAN;
    for (se_int i = 0; i < L; i++)
        for (se_int t = 0; t < CHUNK; t++)
            for (se_int q = 0; q < nn; q++) {
                P_buf[(i * CHUNK + t) * nn + q] = P_prior[i * nn + q];
                P_buf[((L + i) * CHUNK + t) * nn + q] = P_post[i * nn + q];
            }
    for (se_int i0 = 0; i0 < N; i0 += B) {
        const se_int nb = se_block_trials(B, N, i0);
        se_gather_rows(n, B, 1, x_init, i0, nb, x);
        for (se_int q = 0; q < 2 * B; q++) /* no entry held: each lane gathers its matrices at its first sample */
            held[q] = -1;
        for (se_int k = 0; k < K; k++) {
            if (k > 0 || predict_first)
                se_predict_means(n, l, B, K, trans, F, G, u, i0, nb, k, held, Fl, Gl, ul, x, xs);
            if (se_lane_entries(K, mode, i0, nb, k, held + B)) {
                se_gather_matrices(m, n, B, C, held + B, nb, Cl);
                se_gather_matrices(n, m, B, gain, held + B, nb, Kl);
                se_gather_matrices(m, m, B, whiten, held + B, nb, Wl);
            }
            se_gather_samples(m, B, K, y, i0, nb, k, yl);
            se_observe(m, B, yl, nb, obs, n_obs);
            se_residual(n, m, B, x, yl, Cl, nb, e);
            whitened_norm(m, B, e, Wl, nb, v, nis);
            const se_int t = k % CHUNK;
            for (se_int b = 0; b < nb; b++) {
                const int seen = n_obs[b] == (double)m;
                use[b] = seen && isfinite(nis[b]) && nis[b] <= gate;
                flag_buf[b * CHUNK + t] = seen && !use[b] ? SE_GATED : SE_ACCEPTED;
                entry_buf[b * CHUNK + t] = held[B + b] + (use[b] ? L : 0);
            }
            se_add_gain(n, m, B, x, Kl, e, use, nb); /* Zhang & Natarajan eq. (6) */
            for (se_int b = 0; b < nb; b++)
                for (se_int r = 0; r < n; r++)
                    x_buf[(b * CHUNK + t) * n + r] = x[r * B + b];
            if (t == CHUNK - 1 || k == K - 1)
                se_write_out(n, K, x_buf, P_buf, entry_buf, loglik_buf, flag_buf, i0, nb, k - t,
                             t + 1, x_out, P_out, loglik_out, flag_out);
        }
    }
    se_arena_close(&ar);
    return SE_OK;
}
