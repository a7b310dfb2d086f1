/* The Kalman and IMM equations over a block of trials laid across SIMD lanes.
 *
 * Provenance: the C engine (the kernels of engine/c, bound by the engine/_NAME.pyx modules)
 * was ported line by line from the numba kernels of switchest/estimators/_compiled (the last
 * commit that holds them is d903876); before those kernels were deleted, the outputs of both
 * were compared on their conformance cases and found bit-identical.
 *
 * Every array here carries a block of trials as its *last* axis, the lanes: x (n, B),
 * P (n, n, B), y (m, B), of which the first nb are in use. Each equation loops over matrix
 * entries outside and over the lanes inside, so the compiler runs the innermost loops on SIMD
 * registers across trials; the matrices of a switched system are a few states across, too
 * short a loop to vectorize along.
 *
 * The functions work in place and allocate nothing (except the scratch of the rare scalar
 * paths se_repair / se_information_form beyond SE_LINALG_STACK states); each is called by the
 * kernels, a block of trials per call, so a call costs little. Only the smallest helpers,
 * called per lane or within an equation (se_write_lane, se_symmetric_sum), are static inline
 * in linalg.h. Divisions follow numpy's error model (no zero-division checks; every divisor is
 * checked positive first).
 *
 * A missing component of y (NaN) is removed exactly by decoupling it: its row of C and its
 * noise are replaced by a unit innovation that is never observed (e_a = 0, S_aa = 1, no
 * correlation), so each lane updates with its observed components only and its likelihood is
 * their marginal. The measurement update is split in two so that a filter decides on gating
 * before it changes anything: se_innovation, then se_correct for the lanes that use the
 * measurement. Where trials share their covariance (the Kalman kernel), those two run once for
 * the shared covariance and se_innovation_mean, se_correct_mean (their per-lane halves, the
 * same operations) finish each trial's mean.
 *
 * Operation order: the order of every loop's operations is fixed on purpose, not to be changed
 * for speed: the numpy oracles of tests/estimators/ depend on it, as did the recorded
 * comparison above (bit-identical on the conformance cases, within 1e-12 on the families).
 * se_repair's eigendecomposition is LAPACK's dsyevd, as numpy.linalg.eigh's, reached through
 * the pointer each binding sets from scipy.linalg.cython_lapack when it is imported
 * (se_use_dsyevd).
 */
#include "linalg.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The Kalman kernel runs the covariance equations once per group of trials that share their
 * covariance (kalman.c): one lane, nb = 1, in the common case of a block in one group. Each of
 * those equations (se_predict, se_innovation, se_correct, se_joseph_lost) is therefore written
 * once, as a static body of its lane count nb, and compiled twice by its public function:
 * for nb == 1 apart, with every call inlined (gcc's flatten), where each lane loop becomes
 * straight-line code, and for any nb. The same operations in the same order either way (the
 * same bits); on 10 trials of the vehicle (n = 4, m = 2), whose covariances reach their
 * fixed point only after 116 of 200 samples, the one-lane loops' set-up had cost more than
 * their arithmetic. */
#define SE_ONE_LANE_APART __attribute__((flatten))

/* ---- gathering and scattering a block of trials ------------------------------------------ */

/* out[a, b] = data[i0 + b, k, a]: sample k of trials i0 .. i0 + nb - 1. */
void se_gather_samples(se_int m, se_int B, se_int K, const double *restrict data, se_int i0,
                       se_int nb, se_int k, double *restrict out)
{
    for (se_int a = 0; a < m; a++)
        for (se_int b = 0; b < nb; b++)
            out[a * B + b] = data[((i0 + b) * K + k) * m + a];
}

/* out[:, b] = data[i0 + b] for the nb lanes of a block (a trial's initial state). */
void se_gather_rows(se_int q, se_int B, se_int K, const double *restrict data, se_int i0,
                    se_int nb, double *restrict out)
{
    for (se_int r = 0; r < q; r++)
        for (se_int b = 0; b < nb; b++)
            out[r * B + b] = data[(i0 + b) * K * q + r];
}

void se_gather_rows_int(se_int q, se_int B, se_int K, const se_int *restrict data, se_int i0,
                        se_int nb, se_int *restrict out)
{
    for (se_int r = 0; r < q; r++)
        for (se_int b = 0; b < nb; b++)
            out[r * B + b] = data[(i0 + b) * K * q + r];
}

/* data[i0 + b] = src[:, b] for the nb lanes of a block: se_gather_rows back. */
void se_scatter_rows(se_int q, se_int B, se_int K, const double *restrict src, se_int i0,
                     se_int nb, double *restrict data)
{
    for (se_int r = 0; r < q; r++)
        for (se_int b = 0; b < nb; b++)
            data[(i0 + b) * K * q + r] = src[r * B + b];
}

void se_scatter_rows_int(se_int q, se_int B, se_int K, const se_int *restrict src, se_int i0,
                         se_int nb, se_int *restrict data)
{
    for (se_int r = 0; r < q; r++)
        for (se_int b = 0; b < nb; b++)
            data[(i0 + b) * K * q + r] = src[r * B + b];
}

/* x[j, :, b] = x_init[i0 + b, j], P[j, :, :, b] = P_init[i0 + b, j]: the mode-matched means
 * (N, L, n) and covariances (N, L, n, n) of the block's trials into their lanes. */
void se_gather_modes(se_int n, se_int L, se_int B, se_int K, const double *restrict x_init,
                     const double *restrict P_init, se_int i0, se_int nb, double *restrict x,
                     double *restrict P)
{
    for (se_int j = 0; j < L; j++) {
        for (se_int r = 0; r < n; r++) {
            for (se_int b = 0; b < nb; b++)
                x[(j * n + r) * B + b] = x_init[((i0 + b) * K * L + j) * n + r];
            for (se_int c = 0; c < n; c++)
                for (se_int b = 0; b < nb; b++)
                    P[((j * n + r) * n + c) * B + b] =
                        P_init[(((i0 + b) * K * L + j) * n + r) * n + c];
        }
    }
}

/* x_last[i0 + b, j] = x[j, :, b], P_last[i0 + b, j] = P[j, :, :, b]: se_gather_modes back. */
void se_scatter_modes(se_int n, se_int L, se_int B, se_int K, const double *restrict x,
                      const double *restrict P, se_int i0, se_int nb, double *restrict x_last,
                      double *restrict P_last)
{
    for (se_int b = 0; b < nb; b++)
        for (se_int j = 0; j < L; j++)
            for (se_int r = 0; r < n; r++) {
                x_last[((i0 + b) * K * L + j) * n + r] = x[(j * n + r) * B + b];
                for (se_int c = 0; c < n; c++)
                    P_last[(((i0 + b) * K * L + j) * n + r) * n + c] =
                        P[((j * n + r) * n + c) * B + b];
            }
}

/* out[r, c, b] = table[index[b], r, c]: each lane's matrix from a table. When every lane reads
 * the same matrix (trials sampled at the same times: the usual case) it is broadcast over the
 * lanes by vector stores instead of being gathered entry by entry per lane. */
void se_gather_matrices(se_int p, se_int q, se_int B, const double *restrict table,
                        const se_int *restrict index, se_int nb, double *restrict out)
{
    const se_int first = nb > 0 ? index[0] : 0;
    se_int differ = 0;
    for (se_int b = 0; b < nb; b++)
        differ |= index[b] ^ first;
    if (!differ) {
        const double *t = table + first * p * q;
        for (se_int e = 0; e < p * q; e++) {
            const double v = t[e];
            for (se_int b = 0; b < nb; b++)
                out[e * B + b] = v;
        }
        return;
    }
    for (se_int r = 0; r < p; r++)
        for (se_int c = 0; c < q; c++)
            for (se_int b = 0; b < nb; b++)
                out[(r * q + c) * B + b] = table[(index[b] * p + r) * q + c];
}

/* obs[a, b] = 1 where y[a, b] is observed (not NaN), else 0; n_obs[b] counts them. */
void se_observe(se_int m, se_int B, const double *restrict y, se_int nb, double *restrict obs,
                double *restrict n_obs)
{
    for (se_int b = 0; b < nb; b++)
        n_obs[b] = 0.0;
    for (se_int a = 0; a < m; a++)
        for (se_int b = 0; b < nb; b++) {
            double seen = isnan(y[a * B + b]) ? 0.0 : 1.0;
            obs[a * B + b] = seen;
            n_obs[b] += seen;
        }
}

/* o[b] = sum_k X_k[b] Y_k[b] per lane, k = 0 .. q-1, X_k = X + k sx and Y_k = Y + k sy being
 * lane rows (.., B) (strides in doubles): one entry of a product of lane matrices (F P, P C',
 * K R, a mixture's mean), from 0, its terms added in the order of k (se_lane_accumulate,
 * linalg.h). */
static inline void se_lane_dot(se_int q, const double *restrict X, se_int sx,
                               const double *restrict Y, se_int sy, se_int nb, double *restrict o)
{
    se_lane_accumulate(q, NULL, 0, X, sx, Y, sy, nb, o);
}

/* ---- time update --------------------------------------------------------------------------- */

/* Mean time update x <- F x + G u (Shankar et al. eq. (6)); xs (n, B) is scratch. */
void se_predict_mean(se_int n, se_int l, se_int B, double *restrict x, const double *restrict F,
                     const double *restrict G, const double *restrict u, se_int nb,
                     double *restrict xs)
{
    for (se_int i = 0; i < n; i++) {
        double *xi = xs + i * B;
        se_lane_accumulate(n, NULL, 0, F + i * n * B, B, x, B, nb, xi);
        se_lane_accumulate(l, xi, 0, G + i * l * B, B, u, B, nb, xi);
    }
    for (se_int i = 0; i < n; i++)
        for (se_int b = 0; b < nb; b++)
            x[i * B + b] = xs[i * B + b];
}

/* Time update x <- F x + G u, P <- F P F' + Qd (Shankar et al. eqs (6)-(7)).
 *
 * Qd is the process-noise covariance of the exact discretization (symmetric; its upper
 * triangle is read). P comes back exactly symmetric: its upper triangle is computed and
 * mirrored. FP (n, n, B) and xs (n, B) are scratch. */
static inline void predict_(se_int n, se_int l, se_int B, double *restrict x, double *restrict P,
                            const double *restrict F, const double *restrict G,
                            const double *restrict u, const double *restrict Qd, se_int nb,
                            double *restrict FP, double *restrict xs)
{
    se_predict_mean(n, l, B, x, F, G, u, nb, xs);
    for (se_int i = 0; i < n; i++) /* FP = F P */
        for (se_int j = 0; j < n; j++)
            se_lane_dot(n, F + i * n * B, B, P + j * B, n * B, nb, FP + (i * n + j) * B);
    se_symmetric_sum(n, n, B, Qd, FP, F, nb, P);
}

SE_ONE_LANE_APART void se_predict(se_int n, se_int l, se_int B, double *restrict x,
                                  double *restrict P, const double *restrict F,
                                  const double *restrict G, const double *restrict u,
                                  const double *restrict Qd, se_int nb, double *restrict FP,
                                  double *restrict xs)
{
    if (nb == 1)
        predict_(n, l, B, x, P, F, G, u, Qd, 1, FP, xs);
    else
        predict_(n, l, B, x, P, F, G, u, Qd, nb, FP, xs);
}

/* out[:, :, b] = source[:, :, b] in the first nb lanes of (p, q, B) arrays. */
void se_copy_lanes(se_int p, se_int q, se_int B, const double *restrict source, se_int nb,
                   double *restrict out)
{
    for (se_int r = 0; r < p; r++)
        for (se_int c = 0; c < q; c++)
            for (se_int b = 0; b < nb; b++)
                out[(r * q + c) * B + b] = source[(r * q + c) * B + b];
}

/* ---- measurement update -------------------------------------------------------------------- */

/* e = y - C x in every lane, C (m, n, B): the innovation before missing components are
 * removed, or y less the response to an input x. */
void se_residual(se_int n, se_int m, se_int B, const double *restrict x,
                 const double *restrict y, const double *restrict C, se_int nb,
                 double *restrict e)
{
    for (se_int a = 0; a < m; a++) {
        se_lane_accumulate(n, y + a * B, 1, C + a * n * B, B, x, B, nb, e + a * B);
    }
}

/* e = y - C x (Shankar et al. eq. (8)) with each lane's unobserved components zeroed. */
static void se_observed_residual(se_int n, se_int m, se_int B, const double *restrict x,
                                 const double *restrict y, const double *restrict C,
                                 const double *restrict obs, se_int nb, double *restrict e)
{
    se_residual(n, m, B, x, y, C, nb, e);
    for (se_int a = 0; a < m; a++)
        for (se_int b = 0; b < nb; b++)
            e[a * B + b] = obs[a * B + b] > 0.0 ? e[a * B + b] : 0.0;
}

/* va <- va / L_aa, or va * inv_a with the reciprocals inv (m, B) taken beforehand */
static inline void se_divide_by_pivot(se_int m, se_int B, const double *restrict chol,
                                      const double *restrict inv, se_int a, double *restrict va,
                                      se_int nb)
{
    if (inv) {
        const double *ia = inv + a * B;
        for (se_int b = 0; b < nb; b++)
            va[b] *= ia[b];
    } else {
        const double *Laa = chol + (a * m + a) * B;
        for (se_int b = 0; b < nb; b++)
            va[b] /= Laa[b];
    }
}

/* The triangular solves with S = D^1/2 L L' D^1/2 as se_factor leaves it (chol (m, m, B),
 * scale = D^-1/2 (m, B)), in place on v (m, B) per lane (Golub & Van Loan, "Matrix
 * Computations", 4th ed., §3.1): forward, v <- L^-1 D^-1/2 v, and back, v <- D^-1/2 L'^-1 v.
 * Each divides by L's diagonal, or with inv (m, B) multiplies by its reciprocals (se_solve_rows
 * takes them once for many right-hand sides: a division costs several multiplications). The
 * one shared implementation of the lane solves. */
static inline void se_forward_lanes(se_int m, se_int B, const double *restrict chol,
                                    const double *restrict scale, const double *restrict inv,
                                    double *restrict v, se_int nb)
{
    for (se_int a = 0; a < m; a++) {
        double *va = v + a * B;
        const double *sa = scale + a * B;
        for (se_int b = 0; b < nb; b++)
            va[b] *= sa[b];
        se_lane_accumulate(a, va, 1, chol + a * m * B, B, v, B, nb, va);
        se_divide_by_pivot(m, B, chol, inv, a, va, nb);
    }
}

static inline void se_backward_lanes(se_int m, se_int B, const double *restrict chol,
                                     const double *restrict scale, const double *restrict inv,
                                     double *restrict v, se_int nb)
{
    for (se_int a = m - 1; a >= 0; a--) {
        double *va = v + a * B;
        se_lane_accumulate(m - 1 - a, va, 1, chol + ((a + 1) * m + a) * B, m * B,
                           v + (a + 1) * B, B, nb, va);
        se_divide_by_pivot(m, B, chol, inv, a, va, nb);
    }
    for (se_int a = 0; a < m; a++)
        for (se_int b = 0; b < nb; b++)
            v[a * B + b] *= scale[a * B + b];
}

/* z = L^-1 D^-1/2 e by forward substitution and nis = |z|^2 = e' S^-1 e, per lane, for
 * S = D^1/2 L L' D^1/2 as se_innovation factors it. */
static void se_whiten(se_int m, se_int B, const double *restrict e, const double *restrict chol,
                      const double *restrict scale, se_int nb, double *restrict z,
                      double *restrict nis)
{
    se_copy_lanes(m, 1, B, e, nb, z);
    se_forward_lanes(m, B, chol, scale, NULL, z, nb);
    se_lane_accumulate(m, NULL, 0, z, B, z, B, nb, nis);
}

/* Innovation of y against (x, P) over each lane's observed components.
 *
 * e = y - C x, P C' and S = C P C' + R (Shankar et al. eq. (8)), with every unobserved
 * component decoupled (e_a = 0, row and column a of S those of the identity). S is
 * equilibrated by its diagonal D before its Cholesky factorization, D^-1/2 S D^-1/2 = L L',
 * so entries of 1e300 or 1e-300 neither overflow nor underflow;
 * log det S = sum log D + log prod L_aa^2 (the product lies in (0, 1]: it underflows only for
 * a condition number beyond 1e300, which the factorization refuses). Written per lane:
 * nis = e' S^-1 e = |L^-1 D^-1/2 e|^2 and
 * loglik = log N(e; 0, S) = -(e' S^-1 e + log det S + m_o log 2 pi) / 2 (0 with nothing
 * observed). work (3, B) is scratch; e, PCt, chol, scale, z keep what se_correct needs.
 *
 * With report ([count, smallest eigenvalue] of se_repair; NULL: no repair), the lanes
 * whose factorization fails have their P repaired and every lane is factored once more: the
 * rule of the filters here. Without it the caller decides (a group's repair in the Kalman
 * kernel, a full prediction in imm_ev1).
 *
 * Returns SE_OK; SE_NOT_FINITE if a lane's S has a non-finite diagonal; else
 * SE_NOT_POSITIVE_DEFINITE if a lane's factorization failed (with report: again, or where its
 * P needed no repair), bad (B,) then marking those lanes (the others are complete). */
static inline se_int innovation_(SE_INNOVATION_PARAMETERS)
{
    double *log_det = work, *det = work + B, *pivot = work + 2 * B;
    int repaired = 0;
    for (;;) { /* once; with report, again after the failing lanes' P are repaired */
        se_observed_residual(n, m, B, x, y, C, obs, nb, e);
        for (se_int a = 0; a < m; a++) {
            const double *oa = obs + a * B;
            for (se_int i = 0; i < n; i++) {
                double *o = PCt + (i * m + a) * B;
                se_lane_dot(n, P + i * n * B, B, C + a * n * B, B, nb, o);
                for (se_int b = 0; b < nb; b++)
                    o[b] *= oa[b];
            }
        }
        for (se_int a = 0; a < m; a++) { /* S, lower triangle, into chol */
            const double *oa = obs + a * B;
            for (se_int c = 0; c <= a; c++) {
                double *o = chol + (a * m + c) * B;
                const double *Rac = R + (a * m + c) * B, *oc = obs + c * B;
                for (se_int b = 0; b < nb; b++)
                    o[b] = Rac[b] * oc[b];
                se_lane_accumulate(n, o, 0, C + a * n * B, B, PCt + c * B, m * B, nb, o);
                double unit = a == c ? 1.0 : 0.0;
                for (se_int b = 0; b < nb; b++)
                    o[b] = o[b] * oa[b] + unit * (1.0 - oa[b]);
            }
        }
        for (se_int b = 0; b < nb; b++)
            log_det[b] = 0.0;
        for (se_int a = 0; a < m; a++) /* log det D, before the factorization overwrites it */
            for (se_int b = 0; b < nb; b++)
                log_det[b] += log(chol[(a * m + a) * B + b]);
        int positive;
        int finite = se_factor(m, B, chol, scale, nb, det, pivot, &positive);
        if (!finite)
            return SE_NOT_FINITE;
        se_whiten(m, B, e, chol, scale, nb, z, nis);
        for (se_int b = 0; b < nb; b++)
            loglik[b] = -0.5 * (nis[b] + log_det[b] + log(det[b]) + n_obs[b] * SE_LOG_2PI);
        if (positive)
            return SE_OK;
        for (se_int b = 0; b < nb; b++) /* a failed pivot leaves NaN (or 0) in det */
            bad[b] = !(det[b] > 0.0);
        if (report == NULL)
            return SE_NOT_POSITIVE_DEFINITE;
        if (repaired)
            return SE_NOT_POSITIVE_DEFINITE;
        for (se_int b = 0; b < nb; b++)
            if (bad[b] && !se_repair(n, B, P, b, 0, report))
                return SE_NOT_POSITIVE_DEFINITE;
        repaired = 1;
    }
}

SE_ONE_LANE_APART se_int se_innovation(SE_INNOVATION_PARAMETERS)
{
    if (nb == 1)
        return innovation_(n, m, B, x, P, y, C, R, obs, n_obs, 1, e, PCt, chol, scale, z, nis,
                           loglik, work, bad, report);
    return innovation_(n, m, B, x, P, y, C, R, obs, n_obs, nb, e, PCt, chol, scale, z, nis,
                       loglik, work, bad, report);
}

/* Equilibrated Cholesky factorization, in place, of each lane's symmetric S (m, m) held in
 * the lower triangle of chol (m, m, B) (the factorization of se_innovation).
 *
 * S is equilibrated by its diagonal D, D^-1/2 S D^-1/2 = L L' (Golub & Van Loan, "Matrix
 * Computations", 4th ed., Algorithm 4.2.2, column by column), so entries of 1e300 or 1e-300
 * neither overflow nor underflow (|S_ac| <= sqrt(S_aa S_cc)). Written: L in the lower
 * triangle of chol (the upper one is not read), scale = D^-1/2 (m, B) and
 * det (B,) = prod L_aa^2, in (0, 1] for a positive definite S and NaN or 0 where a lane's
 * factorization failed; pivot (B,) is scratch.
 *
 * Returns `finite`, whether every lane's diagonal of S is finite (if not, nothing else is
 * done), and sets *positive: whether every lane's S is positive definite (its diagonal and
 * pivots positive). */
int se_factor(se_int m, se_int B, double *restrict chol, double *restrict scale, se_int nb,
              double *restrict det, double *restrict pivot, int *positive)
{
    int finite = 1, pos = 1;
    for (se_int a = 0; a < m; a++) {
        const double *d = chol + (a * m + a) * B;
        double *s = scale + a * B;
        for (se_int b = 0; b < nb; b++) {
            finite &= isfinite(d[b]) != 0;
            pos &= d[b] > 0.0;
            s[b] = 1.0 / sqrt(d[b]);
        }
    }
    if (!finite) {
        *positive = pos;
        return finite;
    }
    for (se_int b = 0; b < nb; b++)
        det[b] = 1.0;
    for (se_int a = 0; a < m; a++) /* D^-1/2 S D^-1/2: |S_ac| <= sqrt(S_aa S_cc) */
        for (se_int c = 0; c <= a; c++) {
            double *o = chol + (a * m + c) * B;
            const double *sa = scale + a * B, *sc = scale + c * B;
            for (se_int b = 0; b < nb; b++)
                o[b] = o[b] * sa[b] * sc[b];
        }
    for (se_int j = 0; j < m; j++) { /* Cholesky, column by column */
        double *Ljj = chol + (j * m + j) * B;
        se_lane_accumulate(j, Ljj, 1, chol + j * m * B, B, chol + j * m * B, B, nb, pivot);
        for (se_int b = 0; b < nb; b++) {
            pos &= pivot[b] > 0.0;
            double root = sqrt(pivot[b]);
            Ljj[b] = root;
            det[b] *= pivot[b];
        }
        for (se_int i = j + 1; i < m; i++) {
            double *Lij = chol + (i * m + j) * B;
            se_lane_accumulate(j, Lij, 1, chol + i * m * B, B, chol + j * m * B, B, nb, Lij);
            for (se_int b = 0; b < nb; b++)
                Lij[b] /= Ljj[b];
        }
    }
    *positive = pos;
    return finite;
}

/* The per-lane half of se_innovation, from a factorization of S computed elsewhere.
 *
 * Where lanes share their covariance (the same P, C, R and observed components: the same S),
 * se_innovation factors S once and this function finishes each lane: e = y - C x (Shankar et
 * al. eq. (8)) with the unobserved components zeroed, z = L^-1 D^-1/2 e,
 * nis = |z|^2 = e' S^-1 e and loglik = -(e' S^-1 e + log det S + m_o log 2 pi) / 2. chol,
 * scale are the factorization se_innovation leaves, and log_det (2, B) its log det S in two
 * terms, sum log D and log prod L_aa^2 (work[0] and the logarithm of work[1] there), each
 * lane's copy of its covariance's. The operations are those of se_innovation, in its order: a
 * lane gets the same bits either way. */
void se_innovation_mean(se_int n, se_int m, se_int B, const double *restrict x,
                        const double *restrict y, const double *restrict C,
                        const double *restrict obs, const double *restrict n_obs,
                        const double *restrict chol, const double *restrict scale,
                        const double *restrict log_det, se_int nb, double *restrict e,
                        double *restrict z, double *restrict nis, double *restrict loglik)
{
    se_observed_residual(n, m, B, x, y, C, obs, nb, e);
    se_whiten(m, B, e, chol, scale, nb, z, nis);
    for (se_int b = 0; b < nb; b++)
        loglik[b] = -0.5 * (nis[b] + log_det[b] + log_det[B + b] + n_obs[b] * SE_LOG_2PI);
}

/* v <- S^-1 v per lane, with S = D^1/2 L L' D^1/2 as se_innovation left it. */
static void se_solve(se_int m, se_int B, const double *restrict chol, const double *restrict scale,
                     double *restrict v, se_int nb)
{
    se_forward_lanes(m, B, chol, scale, NULL, v, nb);
    se_backward_lanes(m, B, chol, scale, NULL, v, nb);
}

/* V[r] <- S^-1 V[r] per lane for every row r of V (q, m, B), with S = D^1/2 L L' D^1/2 as
 * se_factor left it: forward and back substitution (Golub & Van Loan, "Matrix Computations",
 * 4th ed., §3.1) as se_solve's, multiplying by the reciprocals of L's diagonal, inv (m, B)
 * (written), taken once for all q rows (a division costs several multiplications). */
void se_solve_rows(se_int m, se_int B, se_int q, const double *restrict chol,
                   const double *restrict scale, double *restrict V, se_int nb,
                   double *restrict inv)
{
    for (se_int a = 0; a < m; a++)
        for (se_int b = 0; b < nb; b++)
            inv[a * B + b] = 1.0 / chol[(a * m + a) * B + b];
    for (se_int r = 0; r < q; r++) {
        se_forward_lanes(m, B, chol, scale, inv, V + r * m * B, nb);
        se_backward_lanes(m, B, chol, scale, inv, V + r * m * B, nb);
    }
}

/* v <- D^-1/2 L'^-1 v per lane: the second half of se_solve (S^-1 e from z = L^-1 D^-1/2 e). */
static void se_back_substitute(se_int m, se_int B, const double *restrict chol,
                               const double *restrict scale, double *restrict v, se_int nb)
{
    se_backward_lanes(m, B, chol, scale, NULL, v, nb);
}

/* Measurement update, in the lanes where use is true (Shankar et al. eqs (9)-(10)).
 *
 * From what se_innovation left: K = P C' S^-1 by Cholesky solves (no inverse), x <- x + K e
 * computed as x + P C' (S^-1 e), and the covariance in Joseph form
 * P <- (I - K C) P (I - K C)' + K R K', valid for any gain. It is evaluated through
 * A = I - K C without forming A: A P = P - K (P C')', then
 * A P A' + K R K' = A P + (K R - A P C') K' (O(n^2 m) instead of O(n^3)); the upper triangle
 * is computed and mirrored, so P is exactly symmetric. The other lanes get K = 0, which leaves
 * x and P exactly as they were. z is overwritten; prior (n, n, B) gets the covariance before
 * the update (for se_joseph_lost). */
static inline void correct_(se_int n, se_int m, se_int B, double *restrict x,
                            double *restrict P, const double *restrict C,
                            const double *restrict R, const uint8_t *restrict use, se_int nb,
                            const double *restrict PCt, const double *restrict chol,
                            const double *restrict scale, double *restrict z, double *restrict K,
                            double *restrict T, double *restrict AP, double *restrict prior)
{
    for (se_int i = 0; i < n; i++)
        for (se_int j = 0; j < n; j++)
            for (se_int b = 0; b < nb; b++)
                prior[(i * n + j) * B + b] = P[(i * n + j) * B + b];
    se_correct_mean(n, m, B, x, z, PCt, chol, scale, use, nb); /* x <- x + P C' S^-1 e, (9) */
    for (se_int i = 0; i < n; i++) {
        double *Ki = K + i * m * B;
        for (se_int a = 0; a < m; a++)
            for (se_int b = 0; b < nb; b++)
                Ki[a * B + b] = PCt[(i * m + a) * B + b];
        se_solve(m, B, chol, scale, Ki, nb); /* row i of K is S^-1 (row i of P C') */
        for (se_int a = 0; a < m; a++)
            for (se_int b = 0; b < nb; b++)
                Ki[a * B + b] = use[b] ? Ki[a * B + b] : 0.0;
    }
    for (se_int i = 0; i < n; i++) /* A P = P - K (C P), with C P = (P C')' as P is symmetric */
        for (se_int j = 0; j < n; j++) {
            double *o = AP + (i * n + j) * B;
            const double *Pij = P + (i * n + j) * B;
            se_lane_accumulate(m, Pij, 1, K + i * m * B, B, PCt + j * m * B, B, nb, o);
        }
    for (se_int i = 0; i < n; i++) /* T = K R - A P C' */
        for (se_int c = 0; c < m; c++) {
            double *o = T + (i * m + c) * B;
            se_lane_dot(m, K + i * m * B, B, R + c * B, m * B, nb, o);
            se_lane_accumulate(n, o, 1, AP + i * n * B, B, C + c * n * B, B, nb, o);
        }
    se_symmetric_sum(n, m, B, AP, T, K, nb, P); /* P = A P + T K' */
}

SE_ONE_LANE_APART void se_correct(se_int n, se_int m, se_int B, double *restrict x,
                                  double *restrict P, const double *restrict C,
                                  const double *restrict R, const uint8_t *restrict use,
                                  se_int nb, const double *restrict PCt,
                                  const double *restrict chol, const double *restrict scale,
                                  double *restrict z, double *restrict K, double *restrict T,
                                  double *restrict AP, double *restrict prior)
{
    if (nb == 1)
        correct_(n, m, B, x, P, C, R, use, 1, PCt, chol, scale, z, K, T, AP, prior);
    else
        correct_(n, m, B, x, P, C, R, use, nb, PCt, chol, scale, z, K, T, AP, prior);
}

/* The per-lane half of se_correct: x <- x + P C' S^-1 e in the lanes where use is true
 * (Shankar et al. eq. (9)), from z as se_innovation_mean left it and a factorization of S with
 * its P C' computed elsewhere (each lane's copy of its covariance's); z is overwritten with
 * S^-1 e. se_correct updates x with it too, so a lane gets the same bits either way. */
void se_correct_mean(se_int n, se_int m, se_int B, double *restrict x, double *restrict z,
                     const double *restrict PCt, const double *restrict chol,
                     const double *restrict scale, const uint8_t *restrict use, se_int nb)
{
    se_back_substitute(m, B, chol, scale, z, nb); /* S^-1 e = D^-1/2 L'^-1 z */
    se_add_gain(n, m, B, x, PCt, z, use, nb);
}

/* Mark the lanes where Joseph's form has lost its digits; return whether there is one.
 *
 * Joseph's A = I - K C is accurate to eps |K C| only, so A P A' carries an error of about
 * eps^2 |K C|^2 P. Where the update removes nearly all the prior variance of a state
 * (P+_ii < eps P_ii: a diffuse prior, a nearly noise-free measurement) or the result is no
 * longer a covariance (a correlation beyond 1 + sqrt(eps), or a NaN), that error has swamped
 * P+: lost[b] is set there, among the lanes that use the measurement, for
 * se_information_form. root (n, B) is scratch. */
static inline int joseph_lost_(se_int n, se_int B, const double *restrict P,
                               const double *restrict prior, const uint8_t *restrict use,
                               se_int nb, double *restrict root, uint8_t *restrict lost)
{
    for (se_int b = 0; b < nb; b++)
        lost[b] = 0;
    for (se_int i = 0; i < n; i++) {
        const double *Pii = P + (i * n + i) * B, *Qii = prior + (i * n + i) * B;
        for (se_int b = 0; b < nb; b++) {
            lost[b] |= !(Pii[b] >= SE_EPS * Qii[b]);
            root[i * B + b] = sqrt(fabs(Pii[b]));
        }
    }
    for (se_int i = 0; i < n; i++)
        for (se_int j = i + 1; j < n; j++) {
            const double *Pij = P + (i * n + j) * B, *ri = root + i * B, *rj = root + j * B;
            for (se_int b = 0; b < nb; b++)
                lost[b] |= !(fabs(Pij[b]) <= SE_CORRELATION_BOUND * ri[b] * rj[b]);
        }
    int found = 0;
    for (se_int b = 0; b < nb; b++) {
        lost[b] &= use[b] != 0;
        found |= lost[b];
    }
    return found;
}

SE_ONE_LANE_APART int se_joseph_lost(se_int n, se_int B, const double *restrict P,
                                     const double *restrict prior, const uint8_t *restrict use,
                                     se_int nb, double *restrict root, uint8_t *restrict lost)
{
    return nb == 1 ? joseph_lost_(n, B, P, prior, use, 1, root, lost)
                   : joseph_lost_(n, B, P, prior, use, nb, root, lost);
}

/* The posterior of each lost lane (se_joseph_lost) that observed something, in information
 * form (se_information_form), or where that fails, repaired if indefinite (se_repair, counted
 * in report): the rule of the filters here, after se_correct (a group's repair in the Kalman
 * kernel counts its trials). */
static void se_information_or_repair(se_int n, se_int m, se_int B, double *restrict P,
                                     const double *restrict prior, const double *restrict C,
                                     const double *restrict R, const double *restrict obs,
                                     const double *restrict n_obs, const uint8_t *restrict lost,
                                     se_int nb, double *restrict report)
{
    for (se_int b = 0; b < nb; b++)
        if (lost[b] && n_obs[b] > 0.0 && !se_information_form(n, m, B, P, prior, C, R, obs, b))
            se_repair(n, B, P, b, 1, report);
}

/* The measurement update with the covariance rule of every filter (see linalg.h). */
void se_update(se_int n, se_int m, se_int B, double *restrict x, double *restrict P,
               const double *restrict C, const double *restrict R, const double *restrict obs,
               const double *restrict n_obs, const uint8_t *restrict use, se_int nb,
               const double *restrict PCt, const double *restrict chol,
               const double *restrict scale, double *restrict z, const se_update_ws *ws,
               double *restrict report)
{
    se_correct(n, m, B, x, P, C, R, use, nb, PCt, chol, scale, z, ws->gain, ws->T, ws->AP,
               ws->prior);
    if (se_joseph_lost(n, B, P, ws->prior, use, nb, ws->root, ws->lost)) /* rare: lane by lane */
        se_information_or_repair(n, m, B, P, ws->prior, C, R, obs, n_obs, ws->lost, nb, report);
}

/* The gating decision of a multiple-model filter, before anything changes (see linalg.h). */
void se_gate(se_int rows, se_int cols, se_int stride, se_int B, const double *restrict prior,
             const double *restrict loglik, const double *restrict nis, double gate, se_int nb,
             uint8_t *restrict use, double *restrict a, uint8_t *restrict flag)
{
    for (se_int b = 0; b < nb; b++) {
        double top = -INFINITY;
        for (se_int j = 0; j < rows; j++)
            for (se_int i = 0; i < cols; i++) {
                const se_int at = (j * stride + i) * B + b;
                const int used = se_passes_gate(loglik[at], nis[at], gate);
                use[at] = (uint8_t)used;
                a[at] = used ? prior[at] + loglik[at] : -INFINITY;
                if (a[at] > top)
                    top = a[at];
            }
        flag[b] = SE_ACCEPTED;
        for (se_int j = 0; j < rows; j++)
            for (se_int i = 0; i < cols; i++) {
                const se_int at = (j * stride + i) * B + b;
                if (top == -INFINITY) { /* no filter can use it: the sample counts as missing */
                    flag[b] = SE_GATED;
                    use[at] = 0;
                    a[at] = prior[at];
                } else if (!use[at]) {
                    flag[b] = SE_PARTLY_GATED;
                }
            }
    }
}

/* Scratch of the scalar paths: on the stack up to SE_LINALG_STACK states, else the heap. */
#define SE_SCRATCH(name, count, small)                                                       \
    double name##_stack[small];                                                               \
    double *name = (count) <= (se_int)(small) ? name##_stack                                  \
                                              : (double *)malloc((size_t)(count) * sizeof(double))
#define SE_SCRATCH_FREE(name)                                                                 \
    do {                                                                                      \
        if (name != name##_stack)                                                             \
            free(name);                                                                       \
    } while (0)

/* Python's floor division by 2 of an int (frexp's exponent may be negative). */
static inline int se_floor_half(int e)
{
    return e >= 0 ? e / 2 : -((-e + 1) / 2);
}

static int se_cholesky_into(se_int n, const double *restrict A, double *restrict out,
                            double *restrict d)
{
    for (se_int i = 0; i < n; i++) {
        double Aii = A[i * n + i];
        if (!(Aii > 0.0 && isfinite(Aii)))
            return 0;
        int e;
        frexp(Aii, &e);
        d[i] = ldexp(1.0, se_floor_half(e));
    }
    for (se_int j = 0; j < n; j++) {
        for (se_int i = 0; i < j; i++)
            out[i * n + j] = 0.0;
        double pivot = A[j * n + j] / d[j] / d[j];
        for (se_int p = 0; p < j; p++)
            pivot -= out[j * n + p] * out[j * n + p];
        if (!(pivot > 0.0 && isfinite(pivot)))
            return 0;
        out[j * n + j] = sqrt(pivot);
        for (se_int i = j + 1; i < n; i++) {
            double v = A[i * n + j] / d[i] / d[j];
            for (se_int p = 0; p < j; p++)
                v -= out[i * n + p] * out[j * n + p];
            out[i * n + j] = v / out[j * n + j];
        }
    }
    for (se_int i = 0; i < n; i++)
        for (se_int j = 0; j <= i; j++)
            out[i * n + j] *= d[i];
    return 1;
}

/* Bm <- Lo^-1 Bm for a lower-triangular Lo (m, m) and Bm (m, q), both row-major. */
static void se_forward(se_int m, se_int q, const double *restrict Lo, double *restrict Bm)
{
    for (se_int a = 0; a < m; a++) {
        for (se_int c = 0; c < a; c++)
            for (se_int r = 0; r < q; r++)
                Bm[a * q + r] -= Lo[a * m + c] * Bm[c * q + r];
        for (se_int r = 0; r < q; r++)
            Bm[a * q + r] /= Lo[a * m + a];
    }
}

/* Lane b of P <- (M + M') / 2 for a row-major M (n, n). */
static void se_store_symmetric(se_int n, se_int B, const double *restrict M, double *restrict P,
                               se_int b)
{
    for (se_int i = 0; i < n; i++)
        for (se_int j = i; j < n; j++) {
            double v = 0.5 * (M[i * n + j] + M[j * n + i]);
            P[(i * n + j) * B + b] = v;
            P[(j * n + i) * B + b] = v;
        }
}

/* Lane b of the posterior in information form, where Joseph's has lost its digits.
 *
 * P+ = (P^-1 + C' R^-1 C)^-1 = L (I + L' C' R^-1 C L)^-1 L' with P = L L' the prior (prior),
 * over the observed components of y (obs); computed as the Gram matrix Z' Z, Z = N^-1 L',
 * N N' = I + W' W, W = R^-1/2 C L: accurate to the conditioning of C' R^-1 C however diffuse
 * the prior. A scalar path for one lane (rare). Returns 0, leaving P alone, if P or R is not
 * positive definite. */
int se_information_form(se_int n, se_int m, se_int B, double *restrict P,
                        const double *restrict prior, const double *restrict C,
                        const double *restrict R, const double *restrict obs, se_int b)
{
    enum { S = SE_LINALG_STACK };
    SE_SCRATCH(buf, 4 * n * n + 2 * m * m + m * n + n + m, 7 * S * S + 2 * S);
    if (buf == NULL)
        return 0;
    /* A, Lp, Ln, Z (n, n), Rd, Lr (m, m), W (m, n) and the Cholesky scratch d (n or m) */
    double *A = buf, *Lp = A + n * n, *Ln = Lp + n * n, *Z = Ln + n * n;
    double *Rd = Z + n * n, *Lr = Rd + m * m, *W = Lr + m * m, *d = W + m * n;
    int ok = 0;
    for (se_int i = 0; i < n; i++)
        for (se_int j = 0; j < n; j++)
            A[i * n + j] = prior[(i * n + j) * B + b];
    if (!se_cholesky_into(n, A, Lp, d))
        goto done;
    for (se_int a = 0; a < m; a++)
        for (se_int c = 0; c < m; c++) {
            double oa = obs[a * B + b];
            double unit = a == c ? 1.0 - oa : 0.0;
            Rd[a * m + c] = R[(a * m + c) * B + b] * oa * obs[c * B + b] + unit;
        }
    if (!se_cholesky_into(m, Rd, Lr, d))
        goto done;
    for (se_int q = 0; q < m * n; q++) /* R^-1/2 C L, the unobserved rows zero */
        W[q] = 0.0;
    for (se_int a = 0; a < m; a++)
        for (se_int j = 0; j < n; j++)
            for (se_int i = j; i < n; i++)
                W[a * n + j] += C[(a * n + i) * B + b] * obs[a * B + b] * Lp[i * n + j];
    se_forward(m, n, Lr, W);
    for (se_int i = 0; i < n; i++)
        for (se_int j = 0; j < n; j++) {
            A[i * n + j] = i == j ? 1.0 : 0.0;
            for (se_int a = 0; a < m; a++)
                A[i * n + j] += W[a * n + i] * W[a * n + j];
        }
    if (!se_cholesky_into(n, A, Ln, d))
        goto done;
    for (se_int i = 0; i < n; i++)
        for (se_int j = 0; j < n; j++)
            Z[i * n + j] = Lp[j * n + i];
    se_forward(n, n, Ln, Z);
    for (se_int i = 0; i < n; i++) /* A <- Z' Z, symmetric to the last bit */
        for (se_int j = 0; j < n; j++) {
            A[i * n + j] = 0.0;
            for (se_int q = 0; q < n; q++)
                A[i * n + j] += Z[q * n + i] * Z[q * n + j];
        }
    se_store_symmetric(n, B, A, P, b);
    ok = 1;
done:
    SE_SCRATCH_FREE(buf);
    return ok;
}

static se_dsyevd_fn *se_dsyevd = NULL; /* set by se_use_dsyevd */

void se_use_dsyevd(se_dsyevd_fn *dsyevd)
{
    se_dsyevd = dsyevd;
}

/* Eigenvalues w (ascending) and eigenvectors V (column q: V[i * n + q]) of the symmetric
 * A (n, n), by LAPACK's dsyevd (what numpy.linalg.eigh calls) on its lower triangle: A holds
 * the eigenvectors column-major afterwards. Returns whether LAPACK succeeded. */
static int se_eigh(se_int n, double *restrict A, double *restrict w, double *restrict V)
{
    enum { S = SE_LINALG_STACK };
    int nn = (int)n, lwork = 1 + 6 * nn + 2 * nn * nn, liwork = 3 + 5 * nn, info = -1;
    SE_SCRATCH(work, lwork, 1 + 6 * S + 2 * S * S);
    int iwork_small[3 + 5 * S];
    int *iwork = n <= S ? iwork_small : malloc(sizeof(int) * (size_t)liwork);
    if (work != NULL && iwork != NULL && se_dsyevd != NULL)
        se_dsyevd("V", "L", &nn, A, &nn, w, work, &lwork, iwork, &liwork, &info);
    if (iwork != iwork_small)
        free(iwork);
    SE_SCRATCH_FREE(work);
    if (info != 0)
        return 0;
    for (se_int i = 0; i < n; i++)
        for (se_int q = 0; q < n; q++)
            V[i * n + q] = A[q * n + i];
    return 1;
}

/* Raise lane b's covariance's eigenvalues to its rounding level n eps max|eig|.
 *
 * A covariance whose condition number exceeds 1/eps (a prior of 1e300 on a state seen only
 * through the dynamics, a mixture of estimates 1e50 apart) cannot be told from a singular or
 * indefinite one: its eigenvalues below that level (with indefinite_only, below minus that
 * level: negative beyond rounding) are raised to it, as much as is known about them. Returns
 * whether P was changed; report [count, smallest eigenvalue] records it for the caller's
 * RuntimeWarning. A non-finite P is left alone. */
int se_repair(se_int n, se_int B, double *restrict P, se_int b, int indefinite_only,
              double *restrict report)
{
    SE_SCRATCH(buf, 3 * n * n + n, 3 * SE_LINALG_STACK * SE_LINALG_STACK + SE_LINALG_STACK);
    if (buf == NULL)
        return 0;
    double *A = buf, *V = A + n * n, *M = V + n * n, *w = M + n * n;
    int changed = 0;
    for (se_int i = 0; i < n; i++)
        for (se_int j = 0; j < n; j++) {
            A[i * n + j] = 0.5 * (P[(i * n + j) * B + b] + P[(j * n + i) * B + b]);
            if (!isfinite(A[i * n + j]))
                goto done;
        }
    if (!se_eigh(n, A, w, V))
        goto done;
    double top = 0.0;
    for (se_int i = 0; i < n; i++)
        top = fabs(w[i]) > top ? fabs(w[i]) : top;
    double level = (double)n * SE_EPS * top;
    if (!(w[0] < (indefinite_only ? -level : level)))
        goto done;
    report[0] += 1.0;
    report[1] = w[0] < report[1] ? w[0] : report[1];
    for (se_int i = 0; i < n; i++)
        w[i] = level > w[i] ? level : w[i];
    for (se_int i = 0; i < n; i++)
        for (se_int j = 0; j < n; j++) {
            M[i * n + j] = 0.0;
            for (se_int q = 0; q < n; q++)
                M[i * n + j] += V[i * n + q] * w[q] * V[j * n + q];
        }
    se_store_symmetric(n, B, M, P, b);
    changed = 1;
done:
    SE_SCRATCH_FREE(buf);
    return changed;
}

/* ---- multiple models ----------------------------------------------------------------------- */

/* Normalize log-weights a (L, B) over the modes by log-sum-exp, per lane.
 *
 * a <- (a - max) - log sum exp(a - max), prob <- exp(a) computed as
 * exp(a - max) / sum exp(a - max) and total <- log sum exp(a). A lane whose weights are all
 * -inf keeps them, with probabilities 0 and total -inf. */
void se_log_normalize(se_int L, se_int B, double *restrict a, double *restrict prob,
                      double *restrict total, se_int nb)
{
    se_log_normalize_rows(B, NULL, L, a, prob, total, nb);
}

/* se_log_normalize over the count rows rows[0 .. count-1] of a and prob (their order), the
 * others' -inf left out (they are neither read nor written: their probabilities are 0 where
 * the caller keeps them so); rows NULL: the rows 0 .. count-1. Without the rows of -inf the
 * result is the same, bit for bit: exp(-inf) = 0 adds nothing to the sum. */
void se_log_normalize_rows(se_int B, const se_int *restrict rows, se_int count,
                           double *restrict a, double *restrict prob, double *restrict total,
                           se_int nb)
{
    enum { W = 64 }; /* lanes at a time, each row's lanes innermost: the maximum, the sum and
                      * the division over contiguous lanes (the same operations per lane, in the
                      * same order, as lane by lane) */
    double top[W], acc[W], log_acc[W];
    for (se_int b0 = 0; b0 < nb; b0 += W) {
        const se_int w = nb - b0 < W ? nb - b0 : W;
        for (se_int b = 0; b < w; b++) {
            top[b] = -INFINITY;
            acc[b] = 0.0;
        }
        for (se_int t = 0; t < count; t++) {
            const double *restrict at = a + (rows ? rows[t] : t) * B + b0;
            for (se_int b = 0; b < w; b++)
                top[b] = at[b] > top[b] ? at[b] : top[b];
        }
        for (se_int t = 0; t < count; t++) {
            const se_int j = rows ? rows[t] : t;
            const double *restrict at = a + j * B + b0;
            double *restrict pt = prob + j * B + b0;
            for (se_int b = 0; b < w; b++) {
                pt[b] = top[b] == -INFINITY ? 0.0 : exp(at[b] - top[b]);
                acc[b] += pt[b];
            }
        }
        for (se_int b = 0; b < w; b++) {
            log_acc[b] = top[b] == -INFINITY ? 0.0 : log(acc[b]);
            total[b0 + b] = top[b] + log_acc[b];
        }
        for (se_int t = 0; t < count; t++) {
            const se_int j = rows ? rows[t] : t;
            double *restrict at = a + j * B + b0, *restrict pt = prob + j * B + b0;
            for (se_int b = 0; b < w; b++)
                if (top[b] != -INFINITY) {
                    at[b] = (at[b] - top[b]) - log_acc[b];
                    pt[b] /= acc[b];
                }
        }
    }
}

/* Lane b of mixture j in the log domain: w[i, b] = exp(log mu_i + log pi_ij - lse),
 * returning lse = logsumexp_i(log mu_i + log pi_ij); zero weights and -inf when every term is
 * -inf. w (L, B) is mixture j's rows, the pointer w + j L B of the caller's w (L, L, B). */
static double se_log_weights(se_int L, se_int B, const double *restrict log_prob,
                             const double *restrict log_transition, se_int j, se_int b,
                             double *restrict w)
{
    double top = -INFINITY;
    for (se_int i = 0; i < L; i++) {
        w[i * B + b] = log_prob[i * B + b] + log_transition[(i * L + j) * B + b];
        top = w[i * B + b] > top ? w[i * B + b] : top;
    }
    if (top == -INFINITY) {
        for (se_int i = 0; i < L; i++)
            w[i * B + b] = 0.0;
        return -INFINITY;
    }
    double acc = 0.0;
    for (se_int i = 0; i < L; i++)
        acc += exp(w[i * B + b] - top);
    double lse = top + log(acc);
    for (se_int i = 0; i < L; i++)
        w[i * B + b] = exp(w[i * B + b] - lse);
    return lse;
}

/* Predicted mode probabilities log c_j = log sum_i pi_ij mu_i and the IMM's mixing weights
 * w[j][i] = mu_{i|j} = pi_ij mu_i / c_j (Blom & Bar-Shalom, 1988; Bar-Shalom, Li &
 * Kirubarajan §11.6.6), per lane, for L modes of probabilities prob (L, B) (and their
 * logarithms log_prob) and the lane's transition matrix transition (L, L, B) (and its
 * logarithm): the first half of se_mix, shared with se_collapse.
 *
 * The sums are taken over the probabilities themselves; one below 1e-250 is redone in the log
 * domain (see se_mix). A mode no predecessor reaches gets log c_j = -inf and zero weights.
 * log_c (L, B) and w (L, L, B) are written. */
static void se_predicted_mode_probabilities(se_int L, se_int B, const double *restrict prob,
                                            const double *restrict log_prob,
                                            const double *restrict transition,
                                            const double *restrict log_transition, se_int nb,
                                            double *restrict log_c, double *restrict w)
{
    for (se_int j = 0; j < L; j++) {
        double *wj = w + j * L * B, *cj = log_c + j * B;
        for (se_int b = 0; b < nb; b++)
            cj[b] = 0.0;
        for (se_int i = 0; i < L; i++) {
            const double *tij = transition + (i * L + j) * B, *pi = prob + i * B;
            double *wji = wj + i * B;
            for (se_int b = 0; b < nb; b++) {
                wji[b] = tij[b] * pi[b];
                cj[b] += wji[b];
            }
        }
        for (se_int b = 0; b < nb; b++) {
            if (cj[b] > SE_TINY_SUM) {
                for (se_int i = 0; i < L; i++)
                    wj[i * B + b] /= cj[b];
                cj[b] = log(cj[b]);
            } else {
                cj[b] = se_log_weights(L, B, log_prob, log_transition, j, b, wj);
            }
        }
    }
}

/* IMM interaction, in place on the mode-matched x (L, n, B), P (L, n, n, B).
 *
 * Predicted mode probabilities log c_j = logsumexp_i(log mu_i + log pi_ij), mixing weights
 * mu_{i|j} = exp(log mu_i + log pi_ij - log c_j), mixed means x0_j = sum_i mu_{i|j} x_i and
 * covariances P0_j = sum_i mu_{i|j} (P_i + (x_i - x0_j)(x_i - x0_j)'), the deviations taken
 * from each mixture's own mean (Blom & Bar-Shalom, 1988; Bar-Shalom, Li & Kirubarajan
 * §11.6.6). A mode no predecessor reaches gets log c_j = -inf and zero weights.
 *
 * The sums are taken over the probabilities prob = exp(log_prob) themselves (their largest is
 * at least 1/L, so they need no shift): c_j = sum_i pi_ij mu_i, without an exponential. A sum
 * below 1e-250 (a mode all but unreachable, where the products may underflow) is redone in
 * the log domain. transition (L, L, B) is each lane's transition matrix, exp(log_transition);
 * w (L, L, B) (w[j]: the weights of mixture j), xm (L, n, B) and Pm (L, n, n, B) are scratch;
 * log_c (L, B) is written. */
void se_mix(se_int n, se_int L, se_int B, double *restrict x, double *restrict P,
            const double *restrict prob, const double *restrict log_prob,
            const double *restrict transition, const double *restrict log_transition, se_int nb,
            double *restrict log_c, double *restrict w, double *restrict xm,
            double *restrict Pm)
{
    se_predicted_mode_probabilities(L, B, prob, log_prob, transition, log_transition, nb,
                                    log_c, w);
    for (se_int j = 0; j < L; j++)
        se_moments(n, L, B, w + j * L * B, x, P, nb, xm + j * n * B, Pm + j * n * n * B);
    for (se_int j = 0; j < L; j++)
        for (se_int r = 0; r < n; r++) {
            for (se_int b = 0; b < nb; b++)
                x[(j * n + r) * B + b] = xm[(j * n + r) * B + b];
            for (se_int c = 0; c < n; c++)
                for (se_int b = 0; b < nb; b++)
                    P[((j * n + r) * n + c) * B + b] = Pm[((j * n + r) * n + c) * B + b];
        }
}

/* GPB1 interaction, in place on the mode-matched x (L, n, B), P (L, n, n, B).
 *
 * Every mode-matched filter restarts from one Gaussian, the moments of the mixture of all of
 * them, x0 = sum_i mu_i x_i, P0 = sum_i mu_i (P_i + (x_i - x0)(x_i - x0)') (the mixing
 * weights mu_{i|j} = mu_i for every j); the predicted mode probabilities are the IMM's,
 * c_j = sum_i pi_ij mu_i (Bar-Shalom, Li & Kirubarajan §11.6.4, "GPB1"). Arguments as
 * se_mix, whose scratch w, xm, Pm it uses (w gets the IMM's mixing weights, unused here). */
void se_collapse(se_int n, se_int L, se_int B, double *restrict x, double *restrict P,
                 const double *restrict prob, const double *restrict log_prob,
                 const double *restrict transition, const double *restrict log_transition,
                 se_int nb, double *restrict log_c, double *restrict w, double *restrict xm,
                 double *restrict Pm)
{
    se_predicted_mode_probabilities(L, B, prob, log_prob, transition, log_transition, nb,
                                    log_c, w);
    se_moments(n, L, B, prob, x, P, nb, xm, Pm);
    for (se_int j = 0; j < L; j++)
        for (se_int r = 0; r < n; r++) {
            for (se_int b = 0; b < nb; b++)
                x[(j * n + r) * B + b] = xm[r * B + b];
            for (se_int c = 0; c < n; c++)
                for (se_int b = 0; b < nb; b++)
                    P[((j * n + r) * n + c) * B + b] = Pm[(r * n + c) * B + b];
        }
}

/* Moments of the mixture sum_i w_i N(x_i, P_i) per lane, w (L, B) summing to one:
 * xm = sum_i w_i x_i, Pm = sum_i w_i (P_i + (x_i - xm)(x_i - xm)') (xm (n, B), Pm (n, n, B),
 * exactly symmetric): the merging of Gaussians of GPB2 (Bar-Shalom, Li & Kirubarajan
 * §11.6.5), the computation se_mix and se_combine make. */
void se_merge(se_int n, se_int L, se_int B, const double *restrict w, const double *restrict x,
              const double *restrict P, se_int nb, double *restrict xm, double *restrict Pm)
{
    se_moments(n, L, B, w, x, P, nb, xm, Pm);
}

/* o[c] = sum_i w_i[c] (P_i[c] + (xr_i[c] - mr[c]) (xc_i[c] - mc[c])) for the w lanes c < w,
 * i = 0 .. L-1 (w_i = w + i B, P_i = P + i sP, xr_i = xr + i sx, xc_i = xc + i sx), its terms
 * added in the order of i, the w sums in registers (SE_LANE_CHUNKS) */
static inline void moment_chunk_(se_int w, se_int L, se_int B, const double *restrict wt,
                                 const double *restrict P, se_int sP, const double *restrict xr,
                                 const double *restrict xc, se_int sx, const double *restrict mr,
                                 const double *restrict mc, double *restrict o)
{
    double acc[16];
    for (se_int c = 0; c < w; c++)
        acc[c] = 0.0;
    for (se_int i = 0; i < L; i++) {
        const double *wi = wt + i * B, *Pi = P + i * sP, *xri = xr + i * sx, *xci = xc + i * sx;
        for (se_int c = 0; c < w; c++)
            acc[c] += wi[c] * (Pi[c] + (xri[c] - mr[c]) * (xci[c] - mc[c]));
    }
    for (se_int c = 0; c < w; c++)
        o[c] = acc[c];
}

/* Mean xm (n, B) and covariance Pm (n, n, B) of the mixture sum_i w_i N(x_i, P_i) per lane,
 * the deviations taken from its mean; upper triangle computed, then mirrored. */
void se_moments(se_int n, se_int L, se_int B, const double *restrict w, const double *restrict x,
                const double *restrict P, se_int nb, double *restrict xm, double *restrict Pm)
{
    for (se_int r = 0; r < n; r++)
        se_lane_dot(L, w, B, x + r * B, n * B, nb, xm + r * B);
    for (se_int r = 0; r < n; r++)
        for (se_int c = r; c < n; c++) {
            double *o = Pm + (r * n + c) * B;
            const double *mr = xm + r * B, *mc = xm + c * B, *Prc = P + (r * n + c) * B;
            const double *xr = x + r * B, *xc = x + c * B;
            se_int b = 0;
#define SE_MOMENT_CHUNK(width)                                                                   \
    moment_chunk_((width), L, B, w + b, Prc + b, n * n * B, xr + b, xc + b, n * B, mr + b,       \
                  mc + b, o + b)
            SE_LANE_CHUNKS(b, nb, SE_MOMENT_CHUNK);
#undef SE_MOMENT_CHUNK
            double *t = Pm + (c * n + r) * B;
            for (b = 0; b < nb; b++)
                t[b] = o[b];
        }
}

/* IMM output x = sum_j mu_j x_j, P = sum_j mu_j (P_j + (x_j - x)(x_j - x)') (Bar-Shalom, Li &
 * Kirubarajan §11.6.6) with mu = prob, into xc (n, B), Pc (n, n, B); best (B,) gets the most
 * probable mode (the first on a tie). */
void se_combine(se_int n, se_int L, se_int B, const double *restrict x, const double *restrict P,
                const double *restrict prob, const double *restrict log_prob, se_int nb,
                double *restrict xc, double *restrict Pc, se_int *restrict best)
{
    for (se_int b = 0; b < nb; b++) {
        best[b] = 0;
        for (se_int j = 1; j < L; j++)
            if (log_prob[j * B + b] > log_prob[best[b] * B + b])
                best[b] = j;
    }
    se_moments(n, L, B, prob, x, P, nb, xc, Pc);
}

/* ---- general lane products and solves (the two-filter smoother) ---------------------------- */

/* out = X Y per lane, each entry one se_lane_dot over the strided operands (see linalg.h): the
 * products of the two-filter smoother's messages, F' Omega F, I + P Omega, I + Omega Qd. */
void se_lane_product(se_int p, se_int q, se_int r, se_int B, const double *restrict X,
                     se_int xi, se_int xk, const double *restrict Y, se_int yk, se_int yj,
                     se_int nb, double *restrict out)
{
    for (se_int i = 0; i < p; i++)
        for (se_int j = 0; j < r; j++)
            se_lane_dot(q, X + i * xi * B, xk * B, Y + j * yj * B, yk * B, nb,
                        out + (i * r + j) * B);
}

/* The rows j and piv[j, b] of each lane's X (n, q, B) exchanged, in the lanes that chose another
 * row than j: nothing where no lane did (I + P Omega is often dominated by its diagonal: one
 * pass finds it), else for each row r below j up to the last one chosen, a pass over every
 * lane that swaps where piv[j, b] = r and keeps the others (a blend over contiguous lanes). */
static void se_swap_rows(se_int q, se_int B, se_int j, const se_int *restrict piv,
                         double *restrict X, se_int nb)
{
    const se_int *restrict pj = piv + j * B;
    se_int moved = 0;
    for (se_int b = 0; b < nb; b++)
        moved |= pj[b] ^ j;
    if (!moved)
        return;
    se_int last = j;
    for (se_int b = 0; b < nb; b++)
        last = pj[b] > last ? pj[b] : last;
    for (se_int r = j + 1; r <= last; r++)
        for (se_int c = 0; c < q; c++) {
            double *restrict Xj = X + (j * q + c) * B, *restrict Xr = X + (r * q + c) * B;
            for (se_int b = 0; b < nb; b++) {
                const double a = Xj[b], z = Xr[b];
                const int swap = pj[b] == r;
                Xj[b] = swap ? z : a;
                Xr[b] = swap ? a : z;
            }
        }
}

/* LU factorization with partial pivoting of each lane's A (n, n), in place (Golub & Van Loan,
 * "Matrix Computations", 4th ed., Algorithm 3.4.1; the pivot of column j the first entry of
 * largest modulus on or below the diagonal, LAPACK dgetrf's rule, what numpy.linalg.solve and
 * slogdet factor with): P A = L U with L unit lower triangular in the strict lower triangle of
 * A and U in its upper triangle, whole rows exchanged. piv[j, b] is the row exchanged with row j
 * at step j; log_det = log |det A| = log prod_j |U_jj|, one logarithm of the product, or
 * sum_j log |U_jj| in a lane whose product leaves the normal range (over- or underflow: the
 * logarithms of the pivots there cost n times as much; the two agree to rounding). A zero
 * pivot leaves infinities or NaN (no check: the caller's result is then not finite).
 * best (B,) is scratch. */
void se_lu(se_int n, se_int B, double *restrict A, se_int *restrict piv, se_int nb,
           double *restrict log_det, double *restrict best)
{
    for (se_int j = 0; j < n; j++) {
        se_int *pj = piv + j * B;
        const double *Ajj = A + (j * n + j) * B;
        for (se_int b = 0; b < nb; b++) {
            pj[b] = j;
            best[b] = fabs(Ajj[b]);
        }
        for (se_int r = j + 1; r < n; r++) {
            const double *Arj = A + (r * n + j) * B;
            for (se_int b = 0; b < nb; b++) {
                const double v = fabs(Arj[b]);
                const int larger = v > best[b];
                best[b] = larger ? v : best[b];
                pj[b] = larger ? r : pj[b];
            }
        }
        se_swap_rows(n, B, j, piv, A, nb);
        for (se_int r = j + 1; r < n; r++) {
            double *Arj = A + (r * n + j) * B;
            for (se_int b = 0; b < nb; b++)
                Arj[b] /= Ajj[b];
            for (se_int c = j + 1; c < n; c++) {
                double *Arc = A + (r * n + c) * B;
                const double *Ajc = A + (j * n + c) * B;
                for (se_int b = 0; b < nb; b++)
                    Arc[b] -= Arj[b] * Ajc[b];
            }
        }
    }
    for (se_int b = 0; b < nb; b++) /* |det A| = prod_j |U_jj| (row j of U is final) */
        best[b] = 1.0;
    for (se_int j = 0; j < n; j++)
        for (se_int b = 0; b < nb; b++)
            best[b] *= fabs(A[(j * n + j) * B + b]);
    for (se_int b = 0; b < nb; b++) {
        if (isnormal(best[b])) {
            log_det[b] = log(best[b]);
            continue;
        }
        log_det[b] = 0.0;
        for (se_int j = 0; j < n; j++)
            log_det[b] += log(fabs(A[(j * n + j) * B + b]));
    }
}

/* X <- A^-1 X per lane for the q columns of X (n, q, B), from se_lu's P A = L U: the rows
 * exchanged as piv says, then forward substitution with L (unit diagonal) and back
 * substitution with U (Golub & Van Loan, "Matrix Computations", 4th ed., §3.1 and §3.4.4). */
void se_lu_solve(se_int n, se_int q, se_int B, const double *restrict LU,
                 const se_int *restrict piv, double *restrict X, se_int nb)
{
    for (se_int j = 0; j < n; j++)
        se_swap_rows(q, B, j, piv, X, nb);
    for (se_int r = 1; r < n; r++) /* X_r -= sum_{p < r} L_rp X_p, in the order of p */
        for (se_int c = 0; c < q; c++) {
            double *Xr = X + (r * q + c) * B;
            se_lane_accumulate(r, Xr, 1, LU + r * n * B, B, X + c * B, q * B, nb, Xr);
        }
    for (se_int r = n - 1; r >= 0; r--) { /* X_r = (X_r - sum_{p > r} U_rp X_p) / U_rr */
        for (se_int c = 0; c < q; c++) {
            double *Xr = X + (r * q + c) * B;
            se_lane_accumulate(n - 1 - r, Xr, 1, LU + (r * n + r + 1) * B, B,
                               X + ((r + 1) * q + c) * B, q * B, nb, Xr);
        }
        const double *Urr = LU + (r * n + r) * B;
        for (se_int c = 0; c < q; c++) {
            double *Xr = X + (r * q + c) * B;
            for (se_int b = 0; b < nb; b++)
                Xr[b] /= Urr[b];
        }
    }
}

/* ---- the per-lane index of a trial table --------------------------------------------------- */

/* out[b]: entry [trial, k, j] of index (N or 1, K or 1, L) for trial i0 + b; an axis of length
 * 1 is shared by all trials (or samples). */
void se_lane_index(se_int L, se_int N, se_int K, const se_int *restrict index, se_int i0,
                   se_int nb, se_int k, se_int j, se_int *restrict out)
{
    for (se_int b = 0; b < nb; b++) {
        se_int i = N > 1 ? i0 + b : 0;
        out[b] = index[(i * K + (K > 1 ? k : 0)) * L + j];
    }
}
