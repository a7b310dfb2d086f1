/* The compiled backward pass of the two-filter smoother of a bank of mode-matched filters; the
 * Python side is switchest.engine.two_filter.two_filter_run, its documentation (every equation,
 * numbered as here) the module docstring of switchest.estimators.two_filter.
 *
 * For each mode i at sample k the forward filter's posterior N(x_i(k|k), P_i(k|k)) with weight
 * mu_i(k|k) is combined by Bayes' rule with a backward message, the likelihood of the later
 * measurements given the state and the mode, beta_i(k)(x) = p(y_{k+1..K-1} | x_k = x, r_k = i)
 * (Helmick, Blair & Hoffman 1995, IEEE Trans. Inf. Theory 41(6), "Fixed-interval smoothing for
 * Markovian switching systems"; Mayne 1966, Fraser & Potter 1969 for one mode), kept in
 * information form beta(x) = exp(c - x' Omega x / 2 + omega' x). Over the interval k -> k+1 and
 * the mode l of sample k+1 ("interval" timing: l governs the interval into k+1 and y_{k+1}):
 *
 * 1. measurement (measure_): Omega += C_l' R_l^-1 C_l, omega += C_l' R_l^-1 y,
 *    c += log N(y; 0, R_l) over the observed components of y_{k+1} (none in a sample the filter
 *    rejected);
 * 2. dynamics (dynamics_): the Gaussian integral through x' = F_l x + g + w, w ~ N(0, Qd_l),
 *    g = G_l u_k, with M = I + Omega Qd: Omega_d = F' M^-1 Omega F,
 *    omega_d = F' M^-1 (omega - Omega g), c_d = c - log |M| / 2 - g' Omega_t g / 2
 *    + omega_t' g + omega' Qd omega_t / 2 (Omega_t = M^-1 Omega, omega_t = M^-1 omega);
 * 3. the mixture over the next mode collapsed (pool_): w_l ∝ pi_il Z_il, Z_il the evidence of
 *    message l under the reference Gaussian of mode i, Omega = sum_l w_l Omega_l,
 *    omega = sum_l w_l omega_l (log-linear pooling) and c such that the pooled message keeps the
 *    mixture's evidence under that reference: c = log sum_l pi_il Z_il - log Z(pooled, c = 0).
 *
 * In the "interval" timing the reference is mode i's filtered posterior, and the messages
 * pooled are the dynamics' delta_l; in the "sample" timing (the mode of sample k governs the
 * interval after it) the measurement messages alpha_l are pooled at x_{k+1} under mode i's
 * prediction N(F_i x_i + G_i u_k, F_i P_i F_i' + Qd_i), then taken through mode i's dynamics.
 *
 * The posterior of N(x, P) and a message (evidence_): M = I + P Omega, P_s = M^-1 P,
 * x_s = x + P_s r, r = omega - Omega x, and
 * log Z = c - x' Omega x / 2 + omega' x + r' P_s r / 2 - log |M| / 2. At k = K-1 the smoothed
 * posterior is the filtered one (beta = 1). The smoothed mode probabilities of sample k + 1
 * come from the pairs (mode i at k, mode l at k + 1) of step 3,
 * mu_l(k+1|K) ∝ sum_i mu_i(k|k) pi_il Z_il (pool_'s pair: the update with y_{k+1} is then
 * exact given the filter's posteriors at k, not the filter's own mixture at k + 1), but for
 * the last sample, whose smoothed estimate is the filtered one; those of sample 0 are
 * mu_i(0|K) ∝ mu_i(0|0) Z_i, Z_i the pooled message's evidence.
 *
 * The two systems solved, I + P Omega and I + Omega Qd, are not symmetric; both are
 * I + (positive semidefinite)(positive semidefinite), whose eigenvalues are those of
 * I + S' Omega S (P = S S') and so >= 1: regular, with |det| >= 1. They are solved by an LU
 * factorization with partial pivoting per lane (se_lu, se_lu_solve, linalg.c), as
 * numpy.linalg.solve and slogdet do in the oracle; a symmetric square-root form would need a
 * Cholesky factor of P or Qd, which a deterministic component (Qd singular) or a filter
 * certain of a state (P singular) does not have. A pivot of zero (only where the entries are
 * beyond double precision's range of the identity) leaves a result that is not finite, and the
 * kernel stops with SE_NOT_FINITE: the caller's error says the smoother lost its digits.
 *
 * Every message stays exactly symmetric: the measurement adds a mirrored upper triangle
 * (se_symmetric_sum), the dynamics and the posterior symmetrize (A + A') / 2, and a pooled sum
 * of exactly symmetric matrices is one.
 *
 * Trials are processed in blocks of `lanes` laid across SIMD lanes (linalg.h); the results do
 * not depend on the block size. Layout: every block array carries the lanes as its last axis,
 * of stride B, after the axes of the quantity in C order: Omega (L, n, n, B) at
 * Omega[((j * n + r) * n + c) * B + b]. The scratch is carved from one zeroed allocation (the
 * arena) at the start of se_two_filter_backward, freed before it returns.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bank.h"
#include "linalg.h"
#include "two_filter.h"

/* The work arrays of evidence_ and dynamics_ for n states and B lanes: M (n, n, B) and its
 * LU pivots piv (n, B), best, log_det (B,); X (n, n + 1, B) the right-hand sides; T (n, n, B);
 * the vectors v, w, p (n, B); zero (B,) (a message's c = 0). */
typedef struct {
    double *M;
    se_int *piv;
    double *best, *log_det, *X, *T, *v, *w, *p, *zero;
} solve_ws;

/* solve_ws carved from the arena */
static void carve_solve(se_arena *a, se_int n, se_int B, solve_ws *s)
{
    SE_DOUBLES(a, n * n * B, &s->M, &s->T);
    SE_INTS(a, n * B, &s->piv);
    SE_DOUBLES(a, B, &s->best, &s->log_det, &s->zero);
    SE_DOUBLES(a, n * (n + 1) * B, &s->X);
    SE_DOUBLES(a, n * B, &s->v, &s->w, &s->p);
}

/* The work arrays of measure_: se_innovation's (inn), its zero state x0 (n, B) and covariance
 * P0 (n, n, B) (S = R), C' over the observed components Ct (n, m, B), its solve V (n, m, B),
 * inv (m, B), and every lane's flag `use` (B,) set. */
typedef struct {
    se_innovation_ws inn;
    double *x0, *P0, *Ct, *V, *inv;
    uint8_t *use;
} measure_ws;

/* measure_ws carved from the arena (its use flags are set once the arena is carved) */
static void carve_measure(se_arena *a, se_int n, se_int m, se_int B, measure_ws *s)
{
    se_carve_innovation(a, n, m, B, &s->inn);
    SE_DOUBLES(a, n * B, &s->x0);
    SE_DOUBLES(a, n * n * B, &s->P0);
    SE_DOUBLES(a, n * m * B, &s->Ct, &s->V);
    SE_DOUBLES(a, m * B, &s->inv);
    SE_FLAGS(a, B, &s->use);
}

/* What measure_ computes of mode l's C_l, R_l alone when every component is observed, the same
 * in every lane and at every sample: R's factorization chol (m, m, B), scale (m, B), its
 * log-determinant in se_innovation_mean's two terms log_det (2, B), Ct = C' and V = R^-1 C
 * (n, m, B). Computed once per call (full_), it leaves a fully observed sample the mean half
 * of the innovation (se_innovation_mean) and the two additions: the same operations on the
 * same operands as the whole of measure_, so the same bits, without a factorization, m + 1
 * logarithms and the products with the zero P0 per mode and sample. */
typedef struct {
    double *chol, *scale, *log_det, *Ct, *V;
} full_ws;

/* full_ws of L modes carved from the arena, each array stacked over the modes */
static void carve_full(se_arena *a, se_int n, se_int m, se_int L, se_int B, full_ws *s)
{
    SE_DOUBLES(a, L * m * m * B, &s->chol);
    SE_DOUBLES(a, L * m * B, &s->scale);
    SE_DOUBLES(a, L * 2 * B, &s->log_det);
    SE_DOUBLES(a, L * n * m * B, &s->Ct, &s->V);
}

/* mode j's full_ws in the stacked one */
static full_ws full_mode(const full_ws *s, se_int n, se_int m, se_int B, se_int j)
{
    full_ws f = {s->chol + j * m * m * B, s->scale + j * m * B, s->log_det + j * 2 * B,
                 s->Ct + j * n * m * B, s->V + j * n * m * B};
    return f;
}

/* Ct = C' with the unobserved columns zero, on lanes 0..nb-1: Ct[i, a] = C[a, i] obs[a]. */
static void observed_transpose(se_int n, se_int m, se_int B, const double *restrict C,
                               const double *restrict obs, se_int nb, double *restrict Ct)
{
    for (se_int i = 0; i < n; i++)
        for (se_int a = 0; a < m; a++) {
            const double *Cai = C + (a * n + i) * B, *oa = obs + a * B;
            double *o = Ct + (i * m + a) * B;
            for (se_int b = 0; b < nb; b++)
                o[b] = Cai[b] * oa[b];
        }
}

/* full_ws of C (m, n, B), R (m, m, B) in all B lanes, with measure_'s own calls (ws scratch:
 * its y, obs and n_obs are set here to a zero sample every component of which is observed).
 * Returns se_innovation's status (where not SE_OK, measure_ is used at every sample). */
static se_int full_(se_int n, se_int m, se_int B, const double *restrict C,
                    const double *restrict R, double *restrict y, double *restrict obs,
                    double *restrict n_obs, const measure_ws *ws, const full_ws *f)
{
    const se_innovation_ws *inn = &ws->inn;
    for (se_int b = 0; b < B; b++) {
        n_obs[b] = (double)m;
        for (se_int a = 0; a < m; a++) {
            y[a * B + b] = 0.0;
            obs[a * B + b] = 1.0;
        }
    }
    se_int status = se_innovate(n, m, B, ws->x0, ws->P0, y, C, R, obs, n_obs, B, inn, NULL);
    if (status != SE_OK)
        return status;
    se_copy_lanes(m, m, B, inn->chol, B, f->chol);
    se_copy_lanes(m, 1, B, inn->scale, B, f->scale);
    for (se_int b = 0; b < B; b++) { /* se_innovation's log det S, in its two terms */
        f->log_det[b] = inn->work[b];
        f->log_det[B + b] = log(inn->work[B + b]);
    }
    observed_transpose(n, m, B, C, obs, B, f->Ct); /* every column observed: C' times 1 */
    se_copy_lanes(n, m, B, f->Ct, B, f->V);
    se_solve_rows(m, B, n, f->chol, f->scale, f->V, B, ws->inv);
    return SE_OK;
}

/* The work arrays of pool_: the log-weights a (L, B) of one mode i, the weights w (L, L, B) of
 * every mode (row i, normalized), a total (B,), s (L, B) the log of each mode's share, and the
 * next modes rows (L,) that mode i can move to (pi_il > 0). */
typedef struct {
    double *a, *w, *total, *s;
    se_int *rows;
} pool_ws;

/* out (size, B) = sum_t wt[rows[t]] M[rows[t]] per lane: the messages M (L, size, B) of the
 * next modes a mode can move to, weighed by wt (L, B); the same sums, bit for bit, as over
 * every next mode with the others' weights 0. */
static void pooled_(se_int count, const se_int *restrict rows, se_int B, se_int size,
                    const double *restrict wt, const double *restrict M, se_int nb,
                    double *restrict out)
{
    for (se_int e = 0; e < size; e++)
        se_lane_accumulate_rows(count, rows, NULL, 0, wt, B, M + e * B, size * B, nb,
                                out + e * B);
}

/* M = I + X Y per lane, X, Y (n, n, B) row-major. */
static void identity_plus(se_int n, se_int B, const double *restrict X, const double *restrict Y,
                          se_int nb, double *restrict M)
{
    se_lane_product(n, n, n, B, X, n, 1, Y, n, 1, nb, M);
    for (se_int r = 0; r < n; r++)
        for (se_int b = 0; b < nb; b++)
            M[(r * n + r) * B + b] += 1.0;
}

/* out = (A + A') / 2 per lane: A's leading (n, n) block, its rows q entries apart (A (n, q, B),
 * q >= n), out (n, n, B). */
static void symmetrize_(se_int n, se_int q, se_int B, const double *restrict A, se_int nb,
                        double *restrict out)
{
    for (se_int r = 0; r < n; r++)
        for (se_int c = 0; c < n; c++) {
            const double *Arc = A + (r * q + c) * B, *Acr = A + (c * q + r) * B;
            double *o = out + (r * n + c) * B;
            for (se_int b = 0; b < nb; b++)
                o[b] = 0.5 * (Arc[b] + Acr[b]);
        }
}

/* o[b] = sum_i X[i, b] Y[i, b] per lane: X, Y (n, B). */
static void dot_(se_int n, se_int B, const double *restrict X, const double *restrict Y,
                 se_int nb, double *restrict o)
{
    se_lane_product(1, n, 1, B, X, 0, 1, Y, 1, 1, nb, o);
}

/* Step 1 (measurement): the message beta_l (Omega (n, n, B), omega (n, B), c (B,)) times
 * N(y; C x, R) over each lane's observed components (obs (m, B), n_obs (B,)), in place:
 * Omega += C' R^-1 C, omega += C' R^-1 y, c += log N(y; 0, R). The factorization of R over the
 * observed components (an unobserved one decoupled with a unit variance) is se_innovation's for
 * x = 0, P = 0 (S = R, e = y, loglik = log N(y; 0, R)); V = R^-1 C by its solves
 * (se_solve_rows on the rows of C'), C' V added as a mirrored upper triangle
 * (se_symmetric_sum), C' R^-1 y added as a Kalman mean update would add it (se_correct_mean,
 * gain C'). With `full` (not NULL: every lane observes every component) R's factorization,
 * C' and V are full's, and only the mean half of the innovation is computed. Returns
 * se_innovation's status. */
static se_int measure_(se_int n, se_int m, se_int B, double *restrict Omega,
                       double *restrict omega, double *restrict c, const double *restrict y,
                       const double *restrict obs, const double *restrict n_obs,
                       const double *restrict C, const double *restrict R, se_int nb,
                       const measure_ws *ws, const full_ws *full)
{
    const se_innovation_ws *inn = &ws->inn;
    if (full) {
        se_innovation_mean(n, m, B, ws->x0, y, C, obs, n_obs, full->chol, full->scale,
                           full->log_det, nb, inn->e, inn->z, inn->nis, inn->loglik);
        se_symmetric_sum(n, m, B, Omega, full->Ct, full->V, nb, Omega);
        se_correct_mean(n, m, B, omega, inn->z, full->Ct, full->chol, full->scale, ws->use, nb);
        for (se_int b = 0; b < nb; b++)
            c[b] += inn->loglik[b];
        return SE_OK;
    }
    se_int status = se_innovate(n, m, B, ws->x0, ws->P0, y, C, R, obs, n_obs, nb, inn, NULL);
    if (status != SE_OK)
        return status;
    observed_transpose(n, m, B, C, obs, nb, ws->Ct);
    se_copy_lanes(n, m, B, ws->Ct, nb, ws->V);
    se_solve_rows(m, B, n, inn->chol, inn->scale, ws->V, nb, ws->inv); /* V[i] = R^-1 C[:, i] */
    se_symmetric_sum(n, m, B, Omega, ws->Ct, ws->V, nb, Omega);       /* Omega += C' R^-1 C */
    se_correct_mean(n, m, B, omega, inn->z, ws->Ct, inn->chol, inn->scale, ws->use, nb);
    for (se_int b = 0; b < nb; b++) /* c += log N(y; 0, R) */
        c[b] += inn->loglik[b];
    return SE_OK;
}

/* Step 2 (dynamics): the message (Omega, omega, c) on x_{k+1} taken back through
 * x_{k+1} = F x_k + g + w, w ~ N(0, Qd) (F, Qd (n, n, B), g (n, B)), the Gaussian integral
 * delta(x) = ∫ N(x'; F x + g, Qd) beta(x') dx', into (Od (n, n, B), od (n, B), cd (B,)):
 * M = I + Omega Qd (LU, log |M|), Omega_t = sym(M^-1 Omega), omega_t = M^-1 omega (one solve
 * of both), Og = Omega_t g,
 * cd = c - log |M| / 2 - g' Og / 2 + omega_t' g + omega' Qd omega_t / 2,
 * Od = sym(F' Omega_t F), od = F' (omega_t - Og). */
static void dynamics_(se_int n, se_int B, const double *restrict Omega,
                      const double *restrict omega, const double *restrict c,
                      const double *restrict F, const double *restrict g,
                      const double *restrict Qd, se_int nb, double *restrict Od,
                      double *restrict od, double *restrict cd, const solve_ws *ws)
{
    const se_int q = n + 1;
    identity_plus(n, B, Omega, Qd, nb, ws->M);
    se_lu(n, B, ws->M, ws->piv, nb, ws->log_det, ws->best);
    for (se_int r = 0; r < n; r++) { /* X = [Omega | omega] */
        for (se_int s = 0; s < n; s++)
            for (se_int b = 0; b < nb; b++)
                ws->X[(r * q + s) * B + b] = Omega[(r * n + s) * B + b];
        for (se_int b = 0; b < nb; b++)
            ws->X[(r * q + n) * B + b] = omega[r * B + b];
    }
    se_lu_solve(n, q, B, ws->M, ws->piv, ws->X, nb);
    symmetrize_(n, q, B, ws->X, nb, ws->T); /* Omega_t */
    for (se_int r = 0; r < n; r++)           /* omega_t */
        for (se_int b = 0; b < nb; b++)
            ws->v[r * B + b] = ws->X[(r * q + n) * B + b];
    se_lane_product(n, n, 1, B, ws->T, n, 1, g, 1, 1, nb, ws->w);      /* Og */
    se_lane_product(n, n, 1, B, Qd, n, 1, ws->v, 1, 1, nb, ws->p);     /* Qd omega_t */
    double *gOg = ws->best, *tg = ws->X, *quad = ws->X + B;            /* (X is free now) */
    dot_(n, B, g, ws->w, nb, gOg);
    dot_(n, B, ws->v, g, nb, tg);
    dot_(n, B, omega, ws->p, nb, quad);
    for (se_int b = 0; b < nb; b++)
        cd[b] = c[b] - 0.5 * ws->log_det[b] - 0.5 * gOg[b] + tg[b] + 0.5 * quad[b];
    se_lane_product(n, n, n, B, ws->T, n, 1, F, n, 1, nb, ws->X);      /* Omega_t F */
    se_lane_product(n, n, n, B, F, 1, n, ws->X, n, 1, nb, ws->M);      /* F' Omega_t F */
    symmetrize_(n, n, B, ws->M, nb, Od);
    for (se_int r = 0; r < n; r++) /* omega_t - Og */
        for (se_int b = 0; b < nb; b++)
            ws->v[r * B + b] -= ws->w[r * B + b];
    se_lane_product(n, n, 1, B, F, 1, n, ws->v, 1, 1, nb, od);
}

/* The posterior of the Gaussian N(x, P) (x (n, B), P (n, n, B)) times the message
 * (Omega, omega, c) (module docstring): M = I + P Omega (LU, log |M|), r = omega - Omega x,
 * log_z (B,) = c - x' Omega x / 2 + omega' x + r' P_s r / 2 - log |M| / 2 with P_s = M^-1 P.
 * With x_s (n, B) and P_s (n, n, B) (not NULL) the posterior too: P_s = sym(M^-1 P),
 * x_s = x + P_s r; without, only P_s r = M^-1 (P r) is solved (the evidence of a pair). */
static void evidence_(se_int n, se_int B, const double *restrict x, const double *restrict P,
                      const double *restrict Omega, const double *restrict omega,
                      const double *restrict c, se_int nb, double *restrict log_z,
                      double *restrict x_s, double *restrict P_s, const solve_ws *ws)
{
    identity_plus(n, B, P, Omega, nb, ws->M);
    se_lu(n, B, ws->M, ws->piv, nb, ws->log_det, ws->best);
    se_lane_product(n, n, 1, B, Omega, n, 1, x, 1, 1, nb, ws->w); /* Omega x */
    for (se_int r = 0; r < n; r++)                                 /* r = omega - Omega x */
        for (se_int b = 0; b < nb; b++)
            ws->v[r * B + b] = omega[r * B + b] - ws->w[r * B + b];
    if (x_s) {
        se_copy_lanes(n, n, B, P, nb, ws->X);
        se_lu_solve(n, n, B, ws->M, ws->piv, ws->X, nb);
        symmetrize_(n, n, B, ws->X, nb, P_s);
        se_lane_product(n, n, 1, B, P_s, n, 1, ws->v, 1, 1, nb, ws->p); /* P_s r */
        for (se_int r = 0; r < n; r++)
            for (se_int b = 0; b < nb; b++)
                x_s[r * B + b] = x[r * B + b] + ws->p[r * B + b];
    } else {
        se_lane_product(n, n, 1, B, P, n, 1, ws->v, 1, 1, nb, ws->p); /* P r */
        se_lu_solve(n, 1, B, ws->M, ws->piv, ws->p, nb);
    }
    double *xOx = ws->best, *ox = ws->X, *rPr = ws->X + B; /* (free now) */
    dot_(n, B, x, ws->w, nb, xOx);
    dot_(n, B, omega, x, nb, ox);
    dot_(n, B, ws->v, ws->p, nb, rPr);
    for (se_int b = 0; b < nb; b++)
        log_z[b] = c[b] - 0.5 * xOx[b] + ox[b] + 0.5 * rPr[b] - 0.5 * ws->log_det[b];
}

/* Step 3 (the mixture over the next mode): for every mode i, the messages l (Omega (L, n, n, B),
 * omega (L, n, B), c (L, B)) weighed under the reference N(x_ref[i], P_ref[i]) (x_ref (L, n, B),
 * P_ref (L, n, n, B)): a_l = log pi_il + log Z_il (evidence_), w = exp(a - logsumexp(a))
 * (zero if every a_l is -inf), pooled Op[i] = sum_l w_l Omega_l, op[i] = sum_l w_l omega_l
 * (the sums over the l of pi_il > 0 only: a pair of pi_il = 0 has a_l = -inf and w_l = 0, and
 * is neither computed nor summed; a chain of switching instants has half its pairs so), and
 * cp[i] = logsumexp(a) - base[i], base[i] = log Z of the pooled message with c = 0 under the
 * reference. base (L, B) is written; with x_s, P_s (L, ..) not NULL the posterior of that
 * evidence too (the "interval" timing's smoothed posterior, whose reference is the filtered
 * one).
 * pair (L, B) is written with the smoothed log probabilities of the next mode from the pairs,
 * pair[l] = log sum_i mu_i(k|k) pi_il Z_il (lmu (L, B) = log mu_i(k|k); the evidence of
 * message l under mode i's reference is the pair's, Z_il = p(y_{k+1..} | r_k = i, r_{k+1} = l,
 * y_{0..k}) up to a constant of k), up to one constant over l: from the weights already
 * normalized, pi_il Z_il = w_il exp(t_i), t_i = logsumexp_l a_l, so
 * pair[l] = log sum_i exp(s_i) w_il with s_i = log mu_i(k|k) + t_i. */
static void pool_(se_int n, se_int L, se_int B, const double *restrict x_ref,
                  const double *restrict P_ref, const double *restrict Omega,
                  const double *restrict omega, const double *restrict c,
                  const double *restrict log_transition, const double *restrict lmu, se_int nb,
                  double *restrict Op, double *restrict op, double *restrict cp,
                  double *restrict base, double *restrict x_s, double *restrict P_s,
                  double *restrict pair, const pool_ws *pw, const solve_ws *ws)
{
    const se_int nn = n * n;
    for (se_int i = 0; i < L; i++) {
        const double *xi = x_ref + i * n * B, *Pi = P_ref + i * nn * B;
        double *wi = pw->w + i * L * B;
        se_int count = 0; /* the next modes of pi_il > 0; the others have weight 0 */
        for (se_int j = 0; j < L; j++) {
            const double lt = log_transition[i * L + j];
            if (lt == -INFINITY) {
                for (se_int b = 0; b < nb; b++)
                    wi[j * B + b] = 0.0;
                continue;
            }
            double *aj = pw->a + j * B;
            pw->rows[count++] = j;
            evidence_(n, B, xi, Pi, Omega + j * nn * B, omega + j * n * B, c + j * B, nb, aj,
                      NULL, NULL, ws);
            for (se_int b = 0; b < nb; b++)
                aj[b] += lt;
        }
        se_log_normalize_rows(B, pw->rows, count, pw->a, wi, pw->total, nb);
        for (se_int b = 0; b < nb; b++)
            pw->s[i * B + b] = lmu[i * B + b] + pw->total[b];
        double *Opi = Op + i * nn * B, *opi = op + i * n * B;
        pooled_(count, pw->rows, B, nn, wi, Omega, nb, Opi);
        pooled_(count, pw->rows, B, n, wi, omega, nb, opi);
        evidence_(n, B, xi, Pi, Opi, opi, ws->zero, nb, base + i * B,
                  x_s ? x_s + i * n * B : NULL, P_s ? P_s + i * nn * B : NULL, ws);
        for (se_int b = 0; b < nb; b++)
            cp[i * B + b] = pw->total[b] - base[i * B + b];
    }
    double *top = pw->total; /* pair[l] = top + log sum_i exp(s_i - top) w_il */
    for (se_int b = 0; b < nb; b++)
        top[b] = -INFINITY;
    for (se_int i = 0; i < L; i++)
        for (se_int b = 0; b < nb; b++)
            top[b] = pw->s[i * B + b] > top[b] ? pw->s[i * B + b] : top[b];
    for (se_int i = 0; i < L; i++)
        for (se_int b = 0; b < nb; b++)
            pw->s[i * B + b] = top[b] == -INFINITY ? 0.0 : exp(pw->s[i * B + b] - top[b]);
    se_lane_product(1, L, L, B, pw->s, 0, 1, pw->w, L, 1, nb, pair); /* sum_i e_i w_il */
    for (se_int l = 0; l < L; l++)
        for (se_int b = 0; b < nb; b++)
            pair[l * B + b] = top[b] == -INFINITY ? -INFINITY : top[b] + log(pair[l * B + b]);
}

/* The combined moments of a sample's smoothed mixture (se_combine): x (n, B), P (n, n, B),
 * best (B,). */
typedef struct {
    double *x, *P;
    se_int *best;
} combine_ws;

/* Sample k of the block's smoothed outputs: log_s (L, B) normalized over the modes into prob
 * (L, B) (total (B,) scratch), x (L, n, B), P (L, n, n, B) and prob written at sample k of
 * x_s, P_s (where Ns > 0: the mode-matched outputs were asked for), prob_s, and the mixture's
 * moments (cw scratch) and most probable mode at sample k of x_c, P_c, mode_c. Returns whether
 * every lane's x, P and prob are finite (nothing is written otherwise). */
static int write_(se_int n, se_int L, se_int B, se_int K, se_int Ns, const double *restrict x,
                  const double *restrict P, double *restrict log_s, double *restrict prob,
                  double *restrict total, se_int i0, se_int nb, se_int k, double *restrict x_s,
                  double *restrict P_s, double *restrict prob_s, const combine_ws *cw,
                  double *restrict x_c, double *restrict P_c, se_int *restrict mode_c)
{
    se_log_normalize(L, B, log_s, prob, total, nb);
    int finite = 1;
    for (se_int b = 0; b < nb; b++) /* a lane whose every mode has evidence 0 is not a result */
        finite &= isfinite(total[b]) != 0;
    for (se_int j = 0; j < L; j++) {
        for (se_int e = 0; e < n; e++)
            for (se_int b = 0; b < nb; b++)
                finite &= isfinite(x[(j * n + e) * B + b]) != 0;
        for (se_int e = 0; e < n * n; e++)
            for (se_int b = 0; b < nb; b++)
                finite &= isfinite(P[(j * n * n + e) * B + b]) != 0;
        for (se_int b = 0; b < nb; b++)
            finite &= isfinite(prob[j * B + b]) != 0;
    }
    if (!finite)
        return 0;
    if (Ns > 0)
        se_scatter_modes(n, L, B, K, x, P, i0, nb, x_s + k * L * n, P_s + k * L * n * n);
    se_scatter_rows(L, B, K, prob, i0, nb, prob_s + k * L);
    se_combine(n, L, B, x, P, prob, log_s, nb, cw->x, cw->P, cw->best);
    for (se_int b = 0; b < nb; b++) {
        mode_c[(i0 + b) * K + k] = cw->best[b];
        se_write_lane(n, B, K, cw->x, cw->P, b, i0 + b, k, x_c, P_c);
    }
    return 1;
}

/* The backward recursion over every trial (see the top of this file and two_filter.h). */
se_int se_two_filter_backward(SE_TWO_FILTER_PARAMETERS)
{
    se_report_start(report); /* nothing is repaired here */
    if (N == 0 || K == 0)
        return SE_OK;
    const se_int B = se_lanes(lanes, N), nn = n * n;
    double *Om, *om, *c, *Od, *od, *cd, *Fl, *Gl, *Ql, *g, *ul, *yk, *obs;
    double *n_obs, *Cl, *Rl, *xf, *Pf, *lmu, *xp, *Pp, *FP, *xs, *xo, *Po, *lz, *xq, *Pq, *lq;
    double *pair, *base, *prob, *total;
    se_int *idx;
    solve_ws sw;
    measure_ws mw;
    full_ws fw;
    pool_ws pw;
    combine_ws cw;
    se_arena arena = {NULL, 0};
    do {
        /* per mode: the information triples (matrix, vector, constant) Om, om, c of
         * beta_l(k+1), alpha_l (step 1), then beta_i(k), and Od, od, cd of delta_l ("interval")
         * or the pooled one ("sample"); each mode's transition into k + 1, Fl, Gl, Ql, g; the
         * filtered posteriors at k, xf, Pf, lmu; "sample"'s predictions into k + 1, xp, Pp; the
         * smoothed posteriors at k, xo, Po, lz, and at k + 1 (written once pair is known), xq,
         * Pq, lq */
        SE_DOUBLES(&arena, L * nn * B, &Om, &Od, &Fl, &Ql, &Pf, &Pp, &Po, &Pq);
        SE_DOUBLES(&arena, L * n * B, &om, &od, &g, &xf, &xp, &xo, &xq);
        SE_DOUBLES(&arena, L * B, &c, &cd, &lmu, &lz, &lq, &pair, &base, &prob, &pw.a, &pw.s);
        SE_DOUBLES(&arena, L * n * l * B, &Gl);
        SE_DOUBLES(&arena, L * m * n * B, &Cl);
        SE_DOUBLES(&arena, L * m * m * B, &Rl);
        SE_DOUBLES(&arena, l * B, &ul);
        SE_DOUBLES(&arena, m * B, &yk, &obs);
        SE_DOUBLES(&arena, B, &n_obs, &total, &pw.total);
        SE_DOUBLES(&arena, nn * B, &FP, &cw.P);
        SE_DOUBLES(&arena, n * B, &xs, &cw.x);
        SE_INTS(&arena, B, &idx, &cw.best);
        SE_DOUBLES(&arena, L * L * B, &pw.w);
        SE_INTS(&arena, L, &pw.rows);
        carve_solve(&arena, n, B, &sw);
        carve_measure(&arena, n, m, B, &mw);
        carve_full(&arena, n, m, L, B, &fw);
    } while (se_arena_open(&arena));
    if (arena.base == NULL)
        return SE_NO_MEMORY;
    for (se_int b = 0; b < B; b++) /* constants: every lane's C_l, R_l; every lane used */
        idx[b] = 0;
    for (se_int j = 0; j < L; j++) {
        se_gather_matrices(m, n, B, C + j * m * n, idx, B, Cl + j * m * n * B);
        se_gather_matrices(m, m, B, R + j * m * m, idx, B, Rl + j * m * m * B);
    }
    for (se_int b = 0; b < B; b++)
        mw.use[b] = 1;
    int fully = 1; /* whether full_ holds every mode's fully observed measurement */
    for (se_int j = 0; j < L; j++) {
        const full_ws fj = full_mode(&fw, n, m, B, j);
        fully &= full_(n, m, B, Cl + j * m * n * B, Rl + j * m * m * B, yk, obs, n_obs, &mw,
                       &fj) == SE_OK;
    }
    se_int status = SE_OK;

    for (se_int i0 = 0; i0 < N; i0 += B) {
        const se_int nb = se_block_trials(B, N, i0);
        memset(Om, 0, sizeof(double) * (size_t)(L * nn * B)); /* beta(K-1) = 1 */
        memset(om, 0, sizeof(double) * (size_t)(L * n * B));
        memset(c, 0, sizeof(double) * (size_t)(L * B));
        /* k = K-1: the smoothed posteriors are the filtered ones (beta = 1), held (xq, Pq, lq)
         * until the pairs of step K-2 give their mode probabilities */
        se_gather_modes(n, L, B, K, x_f + (K - 1) * L * n, P_f + (K - 1) * L * nn, i0, nb, xq,
                        Pq);
        se_gather_rows(L, B, K, log_prob_f + (K - 1) * L, i0, nb, lq);
        for (se_int k = K - 2; k >= 0; k--) {
            for (se_int j = 0; j < L; j++) /* mode j's transition into k + 1, g_j = G_j u_k */
                se_gather_transition(n, l, L, B, T, TK, F, G, Qd, trans, i0, nb, k + 1, j, idx,
                                     Fl + j * nn * B, Gl + j * n * l * B, Ql + j * nn * B);
            se_gather_samples(l, B, K, u, i0, nb, k, ul);
            for (se_int j = 0; j < L; j++)
                se_lane_product(n, l, 1, B, Gl + j * n * l * B, l, 1, ul, 1, 1, nb,
                                g + j * n * B);
            se_gather_samples(m, B, K, y, i0, nb, k + 1, yk); /* y_{k+1}, its observed part */
            se_observe(m, B, yk, nb, obs, n_obs);
            for (se_int b = 0; b < nb; b++)
                if (outlier[(i0 + b) * K + k + 1]) { /* rejected by the filter: missing */
                    n_obs[b] = 0.0;
                    for (se_int a = 0; a < m; a++)
                        obs[a * B + b] = 0.0;
                }
            int all = fully; /* every lane observes every component of y_{k+1} */
            for (se_int b = 0; b < nb; b++)
                all &= n_obs[b] == (double)m;
            for (se_int j = 0; j < L; j++) { /* step 1, in place: alpha_l */
                const full_ws fj = full_mode(&fw, n, m, B, j);
                status = measure_(n, m, B, Om + j * nn * B, om + j * n * B, c + j * B, yk,
                                  obs, n_obs, Cl + j * m * n * B, Rl + j * m * m * B, nb, &mw,
                                  all ? &fj : NULL);
                if (status != SE_OK)
                    goto done;
            }
            se_gather_modes(n, L, B, K, x_f + k * L * n, P_f + k * L * nn, i0, nb, xf, Pf);
            se_gather_rows(L, B, K, log_prob_f + k * L, i0, nb, lmu);
            if (!sample_timing) {
                for (se_int j = 0; j < L; j++) /* step 2 through mode j's transition */
                    dynamics_(n, B, Om + j * nn * B, om + j * n * B, c + j * B,
                              Fl + j * nn * B, g + j * n * B, Ql + j * nn * B, nb,
                              Od + j * nn * B, od + j * n * B, cd + j * B, &sw);
                /* step 3 under the filtered posteriors, whose pooled evidence is the smoothed
                 * posterior's: log Z_i = c_i + base_i */
                pool_(n, L, B, xf, Pf, Od, od, cd, log_transition, lmu, nb, Om, om, c, base,
                      xo, Po, pair, &pw, &sw);
                for (se_int e = 0; e < L * B; e++)
                    lz[e] = c[e] + base[e];
            } else {
                for (se_int i = 0; i < L; i++) { /* mode i's prediction into k + 1 */
                    se_copy_gaussian(n, B, xf + i * n * B, Pf + i * nn * B, nb, xp + i * n * B,
                                     Pp + i * nn * B);
                    se_predict(n, l, B, xp + i * n * B, Pp + i * nn * B, Fl + i * nn * B,
                               Gl + i * n * l * B, ul, Ql + i * nn * B, nb, FP, xs);
                }
                /* step 3 at x_{k+1} under the predictions, then step 2 through mode i's
                 * transition, then the posterior of the filtered Gaussian */
                pool_(n, L, B, xp, Pp, Om, om, c, log_transition, lmu, nb, Od, od, cd, base,
                      NULL, NULL, pair, &pw, &sw);
                for (se_int i = 0; i < L; i++) {
                    dynamics_(n, B, Od + i * nn * B, od + i * n * B, cd + i * B,
                              Fl + i * nn * B, g + i * n * B, Ql + i * nn * B, nb,
                              Om + i * nn * B, om + i * n * B, c + i * B, &sw);
                    evidence_(n, B, xf + i * n * B, Pf + i * nn * B, Om + i * nn * B,
                              om + i * n * B, c + i * B, nb, lz + i * B, xo + i * n * B,
                              Po + i * nn * B, &sw);
                }
            }
            /* sample k + 1 with the mode probabilities of the pairs (k, k + 1); the last
             * sample keeps the filtered ones: its smoothed estimate is the filtered estimate */
            if (!write_(n, L, B, K, Ns, xq, Pq, k == K - 2 ? lq : pair, prob, total, i0, nb,
                        k + 1, x_s, P_s, prob_s, &cw, x_c, P_c, mode_c)) {
                status = SE_NOT_FINITE;
                goto done;
            }
            for (se_int e = 0; e < L * B; e++) /* log mu_i(k|K) = log mu_i(k|k) + log Z_i + const */
                lq[e] = lz[e] + lmu[e];
            double *swap = xq; /* sample k is held next */
            xq = xo;
            xo = swap;
            swap = Pq;
            Pq = Po;
            Po = swap;
        }
        /* sample 0 (or the only one) with the probabilities of its own combination */
        if (!write_(n, L, B, K, Ns, xq, Pq, lq, prob, total, i0, nb, 0, x_s, P_s, prob_s, &cw,
                    x_c, P_c, mode_c)) {
            status = SE_NOT_FINITE;
            goto done;
        }
    }
done:
    se_arena_close(&arena);
    return status;
}
