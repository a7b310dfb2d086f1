/* The compiled Kalman filter with estimated switching times (Shankar et al. §III-§IV).
 *
 * switch_time_run filters every trial over every sample inside compiled code, and so does one
 * call per sample (the streaming step): the kernel se_switch_time_filter holds the one
 * implementation of the filter, built on the equations of linalg.c over blocks of trials laid
 * across SIMD lanes.
 *
 * The mode at each sample is known. When it changes over an interval, from a to b, the
 * switching instant tau is estimated from the likelihood of the new measurement,
 * J_k(tau) = N(y; C x-(tau), C P-(tau) C' + R) (Shankar et al. §IV): the maximizer over the
 * grid tau_i = i T / g - T / (2 g) (eq. (23)), optionally refined by Brent's search over the
 * grid cell around it (refine), or the moment-matched merge of every grid hypothesis
 * (marginal). The filter then predicts with the transition of the estimate (eqs (4)-(5),
 * (6)-(7)) and updates (eqs (8)-(10), Joseph form).
 *
 * J_k needs C F, C G u and C Qd C' of a hypothesis, not its F and Qd: the kernel pulls the
 * output matrix back through the segments of the interval (pull_back, O(m n^2) per segment)
 * and takes the innovation of y against the state of the previous sample, x, P, through C F
 * with the noise C Qd C' + R -- the same Gaussian as the innovation of the prediction. Only the
 * chosen hypothesis is predicted.
 *
 * Tables: one transition table F (M, n, n), G (M, n, l), Qd (M, n, n) holds, for each of the
 * D distinct sampling steps d (D entries of steps) and modes i, j, in four sections:
 *
 * - d L + i: mode i over the step, no switch (switchest.discretize.mode_steps);
 * - D L + ((d L + i) L + j) g + r: switch from i to j at grid instant r
 *   (switchest.discretize.pairwise_grid);
 * - D L (1 + L g) + (d L + i) N1 + c: mode i over c T / N1 (refinement only);
 * - D L (1 + L g + N1) + ((d L + i) L + j) (N0 + 1) + q: a span T / N1 switching from i to j
 *   at q T / (N1 N0) (refinement only).
 *
 * The last two are the switchest.discretize.OffsetTable of the step (N1 = N0 = 2^9). A
 * refinement probe at tau is quantized to (c N0 + q) T / (N1 N0) (3.8e-6 T, under 1/25 of the
 * search's tolerance REFINE_TOLERANCE T) and composed from three flows of the table, i over
 * c T / N1, the span c switching at q, j over (N1 - 1 - c) T / N1: no matrix exponential per
 * probe. The last flow's C_j F, C_j G, C_j Qd C_j' are computed once per table
 * (coarse_outputs), so that a probe pulls the output map back through two flows only.
 *
 * Layout: the scratch arrays, in groups (ws, cs, sw, lw, obsv, flow, gs, pk, hyp), are the
 * fields of one Work, carved from one zeroed allocation at the kernel's start. Lane arrays are
 * addressed with explicit index arithmetic: P of shape (n, n, B) at P[(r * n + c) * B + b];
 * table rows of F (M, n, n) at F[(row * n + r) * n + c].
 */
#include "switch_time.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "linalg.h"

#define GOLDEN_STEP 0.3819660112501051 /* (3 - sqrt(5)) / 2: Brent's golden-section step */
#define SQRT_EPS 1.4901161193847656e-08 /* sqrt(eps): Brent's relative tolerance on the instant */

/* Python's min / max of two floats (the first argument on a tie or a NaN second) */
static inline double py_max(double a, double b) { return b > a ? b : a; }
static inline double py_min(double a, double b) { return b < a ? b : a; }

/* The kernel's scratch (its arrays in named groups) and the sizes and tables it reads. */
typedef struct {
    se_int n, m, l, L, B, g;
    /* tables: the table, the step lengths and grid, the first rows of the grid, coarse and
     * switch sections, and the output map pulled back through the coarse section */
    const double *F, *G, *Qd, *steps, *grid_tau, *CF, *CG, *CQC;
    se_int first, coarse, switch_, n_coarse, n_switch;
    /* opts */
    int printed;
    double gate;
    se_int iterations;
    double tolerance;
    /* ws: se_innovation's (e, PCt, chol, scale, z, nis, loglik, work, bad; linalg.h) */
    se_innovation_ws ws;
    /* cs: se_update's (gain, T, AP, prior, root, lost; linalg.h) */
    se_update_ws cs;
    double *xs;
    /* sw: the compacted switched lanes: x, P, y, u, obs, n_obs, C, R, and the rows of the
     * mode before and after and of the mode pair */
    double *sx, *sP, *sy, *su, *sobs, *sn_obs, *sC, *sR;
    se_int *row_a, *row_b, *pair;
    /* lw: scratch of likelihood; zero (n, n, B) all zeros */
    double *ye, *Re, *zero;
    /* obsv: the output map of pull_back */
    double *E, *Go, *Qo, *EQ;
    /* flow: a grid instant's transition (merge) */
    double *Phi, *Gam, *Q;
    /* gs: grid_maximum's best index, its J_k, J_k, rows; refine's winning probe */
    se_int *best;
    double *best_ll, *J;
    se_int *rows, *win;
    /* pk: one lane's probe in refine */
    double *pE, *pEQ, *pEF, *pGo, *pQo, *pPCt, *pchol, *pscale, *pe, *T1, *T2, *Gt;
    /* hyp: the grid hypotheses of merge */
    double *xh, *Ph, *llh, *wh, *total, *xm, *Pm;
    uint8_t *huse;
    se_int *hindex;
} Work;

/* ---------------------------------------------------------------- lanes */

/* dst[a, c] = src[a, lane[c]]: the compacted lanes lane[:ns] of src (r, B). */
static inline void take_rows(se_int r, se_int B, const double *restrict src,
                             const se_int *restrict lane, se_int ns, double *restrict dst)
{
    for (se_int a = 0; a < r; a++)
        for (se_int c = 0; c < ns; c++)
            dst[a * B + c] = src[a * B + lane[c]];
}

/* dst[a, e, c] = src[a, e, lane[c]]: the compacted lanes of src (r, s, B). */
static inline void take_matrices(se_int r, se_int s, se_int B, const double *restrict src,
                                 const se_int *restrict lane, se_int ns, double *restrict dst)
{
    for (se_int a = 0; a < r; a++)
        take_rows(s, B, src + a * s * B, lane, ns, dst + a * s * B);
}

/* dst[a, lane[c]] = src[a, c]: compacted lanes back into their places. */
static inline void put_rows(se_int r, se_int B, const double *restrict src,
                            const se_int *restrict lane, se_int ns, double *restrict dst)
{
    for (se_int a = 0; a < r; a++)
        for (se_int c = 0; c < ns; c++)
            dst[a * B + lane[c]] = src[a * B + c];
}

/* dst[a, e, lane[c]] = src[a, e, c]: compacted lanes of (r, s, B) arrays back. */
static inline void put_matrices(se_int r, se_int s, se_int B, const double *restrict src,
                                const se_int *restrict lane, se_int ns, double *restrict dst)
{
    for (se_int a = 0; a < r; a++)
        put_rows(s, B, src + a * s * B, lane, ns, dst + a * s * B);
}

/* Each lane's transition (F, G, Qd)[index[b]] of the table, into Fl, Gl, Ql. */
static inline void gather_transition(const Work *w, const se_int *restrict index, se_int nb,
                                     double *restrict Fl, double *restrict Gl,
                                     double *restrict Ql)
{
    se_gather_matrices(w->n, w->n, w->B, w->F, index, nb, Fl);
    se_gather_matrices(w->n, w->l, w->B, w->G, index, nb, Gl);
    se_gather_matrices(w->n, w->n, w->B, w->Qd, index, nb, Ql);
}

/* ---------------------------------------------------------------- the likelihood J_k(tau) */

/* out[a] = E[a] table[rows[b]] in every lane b: row a of E (r, n, B) times each lane's entry
 * of table (M, n, n). */
static inline void row_times_entries(se_int n, se_int B, const double *restrict E,
                                     const double *restrict table, const se_int *restrict rows,
                                     se_int a, se_int nb, double *restrict out)
{
    for (se_int j = 0; j < n; j++) {
        double *restrict o = out + (a * n + j) * B;
        for (se_int b = 0; b < nb; b++)
            o[b] = 0.0;
        for (se_int i = 0; i < n; i++) {
            const double *restrict Ei = E + (a * n + i) * B;
            for (se_int b = 0; b < nb; b++)
                o[b] += Ei[b] * table[(rows[b] * n + i) * n + j];
        }
    }
}

/* Pull the output map E (r, n, B) back through each lane's segment rows[b] of the table,
 * x+ = Phi x + Gam u + w, w ~ N(0, Qd), in place: Qo <- Qo + E Qd E', Go <- Go + E Gam,
 * E <- E Phi.
 *
 * An interval of segments s = 1..S (in time order) has F = Phi_S ... Phi_1,
 * G = sum_s Phi_S ... Phi_{s+1} Gam_s and Qd = sum_s (Phi_S ... Phi_{s+1}) Qd_s
 * (Phi_S ... Phi_{s+1})' (Shankar et al. eqs (4)-(5) with the exact process noise; the
 * composition of switchest.discretize). Pulled back through s = S..1 from E = C, Go = 0,
 * Qo = 0, the map ends as E = C F, Go = C G, Qo = C Qd C' at O(r n^2) per segment; from E = I
 * it ends as F, G, Qd. Qo comes back exactly symmetric (upper triangle computed, mirrored);
 * EQ (r, n, B) is scratch. Go is (r, l, B), Qo (r, r, B); F, G, Qd the table (M, n, n),
 * (M, n, l), (M, n, n). */
static void pull_back(se_int r, se_int n, se_int l, se_int B, double *restrict E,
                      double *restrict Go, double *restrict Qo, const double *restrict F,
                      const double *restrict G, const double *restrict Qd,
                      const se_int *restrict rows, se_int nb, double *restrict EQ)
{
    for (se_int a = 0; a < r; a++) {
        for (se_int c = 0; c < l; c++) {
            double *restrict go = Go + (a * l + c) * B;
            for (se_int j = 0; j < n; j++) {
                const double *restrict Ej = E + (a * n + j) * B;
                for (se_int b = 0; b < nb; b++)
                    go[b] += Ej[b] * G[(rows[b] * n + j) * l + c];
            }
        }
        row_times_entries(n, B, E, Qd, rows, a, nb, EQ);
    }
    se_symmetric_sum(r, n, B, Qo, EQ, E, nb, Qo);
    for (se_int a = 0; a < r; a++) { /* E <- E Phi, a row at a time through EQ */
        row_times_entries(n, B, E, F, rows, a, nb, EQ);
        for (se_int j = 0; j < n; j++)
            for (se_int b = 0; b < nb; b++)
                E[(a * n + j) * B + b] = EQ[(a * n + j) * B + b];
    }
}

/* E = C, Go = 0, Qo = 0: the output map before pull_back. E (m, n, B), Go (m, l, B),
 * Qo (m, m, B), C (m, n, B). */
static inline void start(se_int m, se_int n, se_int l, se_int B, double *restrict E,
                         double *restrict Go, double *restrict Qo, const double *restrict C,
                         se_int nb)
{
    for (se_int a = 0; a < m; a++) {
        for (se_int j = 0; j < n; j++)
            for (se_int b = 0; b < nb; b++)
                E[(a * n + j) * B + b] = C[(a * n + j) * B + b];
        for (se_int c = 0; c < l; c++)
            for (se_int b = 0; b < nb; b++)
                Go[(a * l + c) * B + b] = 0.0;
        for (se_int c = 0; c < m; c++)
            for (se_int b = 0; b < nb; b++)
                Qo[(a * m + c) * B + b] = 0.0;
    }
}

/* J_k of one hypothesis per lane (Shankar et al. §IV), -inf where it is rejected.
 *
 * From the hypothesis' output map (E = C F, Go = C G, Qo = C Qd C', pull_back):
 * y - C x-(tau) = (y - Go u) - E x and C P-(tau) C' + R = E P E' + (Qo + R), so
 * J = log N(y - Go u; E x, E P E' + Qo + R) is the innovation of y - Go u against x, P through
 * E (se_innovation), rejected (-inf) where its normalized square exceeds gate or the
 * likelihood is not finite. printed: the paper's literal J = N(y; C x-(tau), R) (P- replaced
 * by 0 in the likelihood), rejected where its own normalized square is not finite or, with a
 * finite gate, where the innovation's fails the gate. ye (m, B), Re (m, m, B) are scratch,
 * zero (n, n, B) all zeros; the rest is the workspace of se_innovation, which repairs a
 * failing P as the bank does. */
static se_int likelihood(const Work *w, const double *restrict x, double *restrict P,
                         const double *restrict y, const double *restrict u,
                         const double *restrict obs, const double *restrict n_obs,
                         const double *restrict R, const double *restrict E,
                         const double *restrict Go, const double *restrict Qo, se_int nb,
                         double *restrict J, double *restrict report)
{
    const se_int n = w->n, m = w->m, l = w->l, B = w->B;
    const double gate = w->gate;
    double *restrict ye = w->ye, *restrict Re = w->Re;
    const double *nis = w->ws.nis, *loglik = w->ws.loglik; /* written by se_innovation */
    se_int status;
    se_residual(l, m, B, u, y, Go, nb, ye); /* y - Go u */
    for (se_int a = 0; a < m; a++)
        for (se_int c = 0; c < m; c++)
            for (se_int b = 0; b < nb; b++)
                Re[(a * m + c) * B + b] = R[(a * m + c) * B + b] + Qo[(a * m + c) * B + b];
    if (!w->printed || gate < INFINITY) {
        status = se_innovate(n, m, B, x, P, ye, E, Re, obs, n_obs, nb, &w->ws, report);
        if (status != SE_OK)
            return status;
        for (se_int b = 0; b < nb; b++)
            J[b] = se_passes_gate(loglik[b], nis[b], gate) ? loglik[b] : -INFINITY;
        if (!w->printed)
            return SE_OK;
    }
    status = se_innovate(n, m, B, x, w->zero, ye, E, R, obs, n_obs, nb, &w->ws, report);
    if (status != SE_OK)
        return status;
    for (se_int b = 0; b < nb; b++) {
        int gated = gate < INFINITY && J[b] == -INFINITY;
        J[b] = nis[b] < INFINITY && !gated ? loglik[b] : -INFINITY;
    }
    return SE_OK;
}

/* ---------------------------------------------------------------- switching instant */

/* Grid maximum of Shankar et al. eq. (23) for the compacted switched lanes; writes the
 * transition of the chosen instant into their lanes of Fl, Gl, Ql and the instant into off,
 * and leaves in gs the grid index best and its J_k, best_ll (inf where uninformed). Returns the
 * status.
 *
 * J_k (likelihood) is evaluated at every grid instant through its exact transition of the
 * table; the first maximum wins. Where the measurement is missing or every instant rejects it,
 * it says nothing of the instant: the middle one, g // 2, is taken. */
static se_int grid_maximum(const Work *w, se_int ns, se_int d, const se_int *restrict lane,
                           double *restrict Fl, double *restrict Gl, double *restrict Ql,
                           double *restrict off, double *restrict report)
{
    const se_int n = w->n, m = w->m, l = w->l, B = w->B, g = w->g;
    const double *restrict F = w->F, *restrict G = w->G, *restrict Qd = w->Qd;
    const se_int *restrict pair = w->pair;
    const double *restrict n_obs = w->sn_obs;
    se_int *restrict best = w->best, *restrict rows = w->rows;
    double *restrict best_ll = w->best_ll, *restrict J = w->J;
    const se_int first = w->first; /* the first row of the grid section */
    for (se_int r = 0; r < g; r++) {
        for (se_int c = 0; c < ns; c++)
            rows[c] = first + pair[c] * g + r;
        start(m, n, l, B, w->E, w->Go, w->Qo, w->sC, ns);
        pull_back(m, n, l, B, w->E, w->Go, w->Qo, F, G, Qd, rows, ns, w->EQ);
        se_int status = likelihood(w, w->sx, w->sP, w->sy, w->su, w->sobs, w->sn_obs, w->sR,
                                   w->E, w->Go, w->Qo, ns, J, report);
        if (status != SE_OK)
            return status;
        for (se_int c = 0; c < ns; c++)
            if (r == 0 || J[c] > best_ll[c]) {
                best[c] = r;
                best_ll[c] = J[c];
            }
    }
    for (se_int c = 0; c < ns; c++) {
        if (n_obs[c] == 0.0 || best_ll[c] == -INFINITY) { /* uninformed: the middle instant, */
            best[c] = g / 2;                              /* which no probe may replace */
            best_ll[c] = INFINITY;
        }
        off[lane[c]] = w->grid_tau[d * g + best[c]];
        rows[c] = first + pair[c] * g + best[c];
    }
    for (se_int i = 0; i < n; i++) {
        for (se_int j = 0; j < n; j++)
            for (se_int c = 0; c < ns; c++) {
                Fl[(i * n + j) * B + lane[c]] = F[(rows[c] * n + i) * n + j];
                Ql[(i * n + j) * B + lane[c]] = Qd[(rows[c] * n + i) * n + j];
            }
        for (se_int j = 0; j < l; j++)
            for (se_int c = 0; c < ns; c++)
                Gl[(i * l + j) * B + lane[c]] = G[(rows[c] * n + i) * l + j];
    }
    return SE_OK;
}

/* Brent's search of J_k over the grid cell around the grid maximum (beyond Shankar et al.),
 * for each compacted switched lane: [tau - T/(2g), tau + T/(2g)] clipped to [0, T], started
 * from the grid instant tau and its J_k. Returns the status.
 *
 * The search is Brent's method (Brent, Algorithms for Minimization without Derivatives, 1973,
 * ch. 5; fmin of Forsythe, Malcolm & Moler, 1977) on -J_k: a parabola through the three best
 * points where it falls inside the bracket and moves less than half the step before last,
 * else a golden-section step into the larger part; no probe nearer than
 * tol1 = sqrt(eps) |tau| + tol / 3 to the best point, with tol = opts[3] T (the tolerance).
 * It stops when the best point lies within 2 tol1 - w / 2 of the middle of the bracket (width
 * w), i.e. the maximizer is bracketed to within about 2 tol, or after iterations probes. An
 * uninformed lane (J_k of its grid maximum inf) is not searched.
 *
 * One step is added to Brent's, for a maximum at an edge of the cell (a switch near a sample,
 * or a likelihood rising beyond the cell): golden-section steps close in on an edge by 0.618
 * per probe, about 17 probes from the middle to within 1e-4 T. So where a golden step is due
 * and the best point and the two before it lie in order toward an edge that still bounds the
 * bracket (x < w < v toward the lower edge), more than 2 tol1 from the best point, the edge is
 * probed instead, once per edge; if it is the best point, the next probe is tol1 inside it,
 * which closes the bracket where it is worse. On the boost converter (1131 searches, Table I's
 * switching) a search then takes 8.1 probes on average instead of 11.0 at g = 1, 6.8 instead
 * of 9.9 at g = 3: about 4 instead of 17-19 for the fifth of searches that end at an edge, as
 * many as before (7-12) for the rest. The instants found agree with Brent's within the
 * tolerance, but for one search in a thousand, where J_k has two maxima of nearly equal height
 * in the cell and the two reached different ones.
 *
 * A probe at tau is quantized to k dt / (N1 N0), k = j N0 + q, and its J_k is exact there: the
 * output map of b over (N1 - 1 - j) dt / N1 (C_b F, C_b G, C_b Qd C_b' of coarse_outputs) is
 * pulled back through the span j switching at q and a over j dt / N1 (Shankar et al. eqs
 * (4)-(5) composed as in pull_back), then J = log N(y - Go u; E x, E P E' + Qo + R) (or the
 * paper's literal N(y; C x-(tau), R)) as in likelihood, a lane at a time: the equations of
 * pull_back and se_innovation (equilibrated Cholesky factor, eq. (8)) written out here, in one
 * body, for one lane at a time: those functions loop over lanes innermost, and a probe has one
 * lane. (Measured on the JIT-compiled (numba) implementation this file was ported from: run on
 * them instead, every switched lane probing in step, the refined filter took 1.9 times as
 * long on the boost converter: about 9 lanes are too few to fill the SIMD registers, and each
 * probe waits for the lane whose search runs longest. Nor did searches side by side pay, each
 * in a slot that takes the next lane when its search ends, the slots' probes evaluated
 * together so that their chains of divisions, roots and logarithms overlap: with the searches'
 * state in arrays and the probe split into inlined parts, the refined filter took 1.5 times as
 * long, with one slot as with four. In that implementation this function was inlined into the
 * kernel: called with its forty arrays, each reference-counted, it cost the refined filter a
 * quarter of its time.) A lane whose factorization fails has its P repaired (se_repair) and is
 * factored once more.
 *
 * The grid instant is kept unless a probe beats it; a winning probe's transition is composed
 * exactly (pulled back from I) into the lane's Fl, Gl, Ql, its instant written into off. */
static se_int refine(const Work *w, se_int ns, se_int d, const se_int *restrict lane,
                     double *restrict Fl, double *restrict Gl, double *restrict Ql,
                     double *restrict off, double *restrict report)
{
    const se_int n = w->n, m = w->m, n_in = w->l, B = w->B, g = w->g;
    const double *restrict x = w->sx, *restrict y = w->sy, *restrict u = w->su;
    double *restrict P = w->sP;
    const double *restrict obs = w->sobs, *restrict n_obs = w->sn_obs, *restrict Rs = w->sR;
    const se_int *restrict row_a = w->row_a, *restrict row_b = w->row_b,
                 *restrict pair = w->pair;
    const double *restrict F = w->F, *restrict G = w->G, *restrict Qd = w->Qd;
    const double *restrict CF = w->CF, *restrict CG = w->CG, *restrict CQC = w->CQC;
    const se_int coarse = w->coarse, switch_ = w->switch_, n_coarse = w->n_coarse,
                 n_switch = w->n_switch;
    const int printed = w->printed;
    const double gate = w->gate;
    const se_int iterations = w->iterations;
    const se_int *restrict best = w->best;
    const double *restrict best_ll = w->best_ll;
    se_int *restrict win = w->win;
    double *E = w->pE, *EF = w->pEF; /* swapped: no restrict */
    double *restrict EQ = w->pEQ, *restrict Go = w->pGo, *restrict Qo = w->pQo;
    double *restrict PCt = w->pPCt, *restrict chol = w->pchol, *restrict scale = w->pscale;
    double *restrict e = w->pe, *restrict T1 = w->T1, *restrict T2 = w->T2, *restrict Gt = w->Gt;
    const double dt = w->steps[d];
    const se_int N0 = n_switch - 1;
    const se_int total = n_coarse * N0;
    const double half = dt / (double)(2 * g);
    const double tol = w->tolerance * dt;
    const int first = !printed || gate < INFINITY ? 0 : 1; /* 0: the innovation's J, 1: printed */
    for (se_int c = 0; c < ns; c++) {
        win[c] = -1;
        if (best_ll[c] == INFINITY) /* uninformed: no probe may replace the middle instant */
            continue;
        double top = best_ll[c];
        const double tau = w->grid_tau[d * g + best[c]];
        double lo = py_min(py_max(tau - half, 0.0), dt), hi = py_min(py_max(tau + half, 0.0), dt);
        double edge_lo = lo, edge_hi = hi; /* the cell's edges (NaN once probed: an edge step) */
        double x_b = tau, wb = tau, v = tau; /* minimize f = -J: x_b the best point, wb (Brent's
                                                w) the second, v the last w */
        double fx = -top, fw = -top, fv = -top;
        double e_old = 0.0, step = 0.0; /* the step before last, the last step */
        double inward = 0.0; /* after an edge that won: the direction into the cell */
        for (se_int it = 0; it < iterations; it++) {
            const double xm = 0.5 * (lo + hi);
            const double tol1 = SQRT_EPS * fabs(x_b) + tol / 3.0;
            const double tol2 = 2.0 * tol1;
            if (fabs(x_b - xm) <= tol2 - 0.5 * (hi - lo))
                break;
            double edge = 0.0; /* 1 / -1: this probe is the edge step toward lo / hi */
            double at;
            if (inward != 0.0) { /* tol1 inside the edge that won: if worse, the bracket closes */
                at = x_b + inward * tol1;
                inward = 0.0;
            } else {
                int golden = 1;
                if (fabs(e_old) > tol1) { /* a parabola through x_b, w, v */
                    double r = (x_b - wb) * (fx - fv);
                    double q = (x_b - v) * (fx - fw);
                    double p = (x_b - v) * q - (x_b - wb) * r;
                    q = 2.0 * (q - r);
                    if (q > 0.0)
                        p = -p;
                    q = fabs(q);
                    r = e_old;
                    e_old = step;
                    if (fabs(p) < fabs(0.5 * q * r) && p > q * (lo - x_b) && p < q * (hi - x_b)) {
                        golden = 0;
                        step = p / q;
                        if ((x_b + step) - lo < tol2 || hi - (x_b + step) < tol2)
                            step = xm - x_b >= 0.0 ? tol1 : -tol1;
                    }
                }
                if (golden && lo == edge_lo && x_b < wb && wb < v && x_b - lo > tol2) {
                    at = lo; /* heading for lo: probe it */
                    edge = 1.0;
                    edge_lo = NAN;
                } else if (golden && hi == edge_hi && x_b > wb && wb > v && hi - x_b > tol2) {
                    at = hi; /* heading for hi: probe it */
                    edge = -1.0;
                    edge_hi = NAN;
                } else {
                    if (golden) { /* into the larger part of the bracket */
                        e_old = x_b >= xm ? lo - x_b : hi - x_b;
                        step = GOLDEN_STEP * e_old;
                    }
                    if (fabs(step) >= tol1)
                        at = x_b + step;
                    else
                        at = x_b + (step >= 0.0 ? tol1 : -tol1);
                }
            }
            /* ---- the probe: J_k at the table instant k (Shankar et al. §IV) */
            se_int k = (se_int)floor(at / dt * (double)total + 0.5);
            k = k < 0 ? 0 : k;
            k = k > total ? total : k;
            se_int j = k / N0;
            se_int s = k - j * N0;
            if (j == n_coarse) { /* at the end of the interval: the last span, switching at its end */
                j = n_coarse - 1;
                s = N0;
            }
            const se_int ra = coarse + row_a[c] * n_coarse + j;
            const se_int rb = row_b[c] * n_coarse + n_coarse - 1 - j;
            for (se_int a = 0; a < m; a++) { /* C b over (N1 - 1 - j) dt / N1: E, Go, Qo from the table */
                for (se_int i = 0; i < n; i++)
                    E[a * n + i] = CF[(rb * m + a) * n + i];
                for (se_int i = 0; i < n_in; i++)
                    Go[a * n_in + i] = CG[(rb * m + a) * n_in + i];
                for (se_int i = 0; i < m; i++)
                    Qo[a * m + i] = CQC[(rb * m + a) * m + i];
            }
            for (int flow = 0; flow < 2; flow++) { /* pulled back through the span, then a (see pull_back) */
                const se_int row = flow == 0 ? switch_ + pair[c] * n_switch + s : ra;
                const double *restrict Fr = F + row * n * n, *restrict Gr = G + row * n * n_in,
                                       *restrict Qr = Qd + row * n * n;
                for (se_int a = 0; a < m; a++) { /* Go <- Go + E Gam; EQ = E Qd, EF = E Phi */
                    for (se_int i = 0; i < n_in; i++) {
                        double acc = Go[a * n_in + i];
                        for (se_int h = 0; h < n; h++)
                            acc += E[a * n + h] * Gr[h * n_in + i];
                        Go[a * n_in + i] = acc;
                    }
                    for (se_int i = 0; i < n; i++) {
                        double acc = 0.0, acc_f = 0.0;
                        for (se_int h = 0; h < n; h++) {
                            acc += E[a * n + h] * Qr[h * n + i];
                            acc_f += E[a * n + h] * Fr[h * n + i];
                        }
                        EQ[a * n + i] = acc;
                        EF[a * n + i] = acc_f;
                    }
                }
                for (se_int a = 0; a < m; a++) /* Qo <- Qo + E Qd E', symmetric */
                    for (se_int i = a; i < m; i++) {
                        double acc = Qo[a * m + i];
                        for (se_int h = 0; h < n; h++)
                            acc += EQ[a * n + h] * E[i * n + h];
                        Qo[a * m + i] = acc;
                        Qo[i * m + a] = acc;
                    }
                double *swap = E; /* E <- E Phi */
                E = EF;
                EF = swap;
            }
            double J = -INFINITY;
            int kind = first, repaired = 0;
            while (kind < 2) { /* the innovation of y - Go u through E (kind 0: with P; 1: without) */
                for (se_int a = 0; a < m; a++) { /* e = y - Go u - E x, P E' over the observed components */
                    const double oa = obs[a * B + c];
                    double acc = y[a * B + c];
                    for (se_int i = 0; i < n_in; i++)
                        acc -= Go[a * n_in + i] * u[i * B + c];
                    for (se_int h = 0; h < n; h++)
                        acc -= E[a * n + h] * x[h * B + c];
                    e[a] = oa > 0.0 ? acc : 0.0;
                    for (se_int i = 0; i < n; i++) {
                        acc = 0.0;
                        if (kind == 0)
                            for (se_int h = 0; h < n; h++)
                                acc += P[(i * n + h) * B + c] * E[a * n + h];
                        PCt[i * m + a] = acc * oa;
                    }
                }
                int finite = 1, positive = 1;
                double log_det = 0.0, det = 1.0;
                for (se_int a = 0; a < m; a++) { /* S = E P E' + Qo + R (kind 1: R), lower triangle; D */
                    const double oa = obs[a * B + c];
                    for (se_int i = 0; i <= a; i++) {
                        double acc = (kind == 0 ? Rs[(a * m + i) * B + c] + Qo[a * m + i]
                                                : Rs[(a * m + i) * B + c]) * obs[i * B + c];
                        for (se_int h = 0; h < n; h++)
                            acc += E[a * n + h] * PCt[h * m + i];
                        const double unit = a == i ? 1.0 : 0.0;
                        chol[a * m + i] = acc * oa + unit * (1.0 - oa);
                    }
                    const double diag = chol[a * m + a];
                    finite &= isfinite(diag) != 0;
                    positive &= diag > 0.0;
                    scale[a] = 1.0 / sqrt(diag);
                    log_det += log(diag);
                }
                if (!finite)
                    return SE_NOT_FINITE;
                for (se_int h = 0; h < m; h++) { /* D^-1/2 S D^-1/2 = L L', column by column */
                    double pivot = chol[h * m + h] * scale[h] * scale[h];
                    for (se_int i = 0; i < h; i++)
                        pivot -= chol[h * m + i] * chol[h * m + i];
                    positive &= pivot > 0.0;
                    chol[h * m + h] = sqrt(pivot);
                    det *= pivot;
                    for (se_int a = h + 1; a < m; a++) {
                        double acc = chol[a * m + h] * scale[a] * scale[h];
                        for (se_int i = 0; i < h; i++)
                            acc -= chol[a * m + i] * chol[h * m + i];
                        chol[a * m + h] = acc / chol[h * m + h];
                    }
                }
                if (!positive) {
                    if (kind == 0 && !repaired && se_repair(n, B, P, c, 0, report)) {
                        repaired = 1;
                        continue;
                    }
                    return SE_NOT_POSITIVE_DEFINITE;
                }
                double nis = 0.0;
                for (se_int a = 0; a < m; a++) { /* z = L^-1 D^-1/2 e (into e), nis = |z|^2 */
                    double acc = scale[a] * e[a];
                    for (se_int i = 0; i < a; i++)
                        acc -= chol[a * m + i] * e[i];
                    acc /= chol[a * m + a];
                    e[a] = acc;
                    nis += acc * acc;
                }
                const double loglik = -0.5 * (nis + log_det + log(det) + n_obs[c] * SE_LOG_2PI);
                if (kind == 0) { /* rejected beyond the gate or where not finite */
                    J = se_passes_gate(loglik, nis, gate) ? loglik : -INFINITY;
                    if (!printed)
                        break;
                } else { /* printed: rejected where its own nis is not finite, or gated */
                    const int gated = gate < INFINITY && J == -INFINITY;
                    J = nis < INFINITY && !gated ? loglik : -INFINITY;
                }
                kind += 1;
            }
            /* ---- Brent's bookkeeping */
            if (J > top) {
                top = J;
                win[c] = k;
            }
            const double fu = -J;
            if (fu <= fx) {
                inward = edge;
                if (at >= x_b)
                    lo = x_b;
                else
                    hi = x_b;
                v = wb;
                fv = fw;
                wb = x_b;
                fw = fx;
                x_b = at;
                fx = fu;
            } else {
                if (at < x_b)
                    lo = at;
                else
                    hi = at;
                if (fu <= fw || wb == x_b) {
                    v = wb;
                    fv = fw;
                    wb = at;
                    fw = fu;
                } else if (fu <= fv || v == x_b || v == wb) {
                    v = at;
                    fv = fu;
                }
            }
        }
        if (win[c] < 0)
            continue;
        /* ---- a probe won: its instant, and its transition composed in time order */
        const se_int b = lane[c];
        off[b] = (double)win[c] * (dt / (double)total);
        se_int j = win[c] / N0, s = win[c] % N0;
        if (j == n_coarse) {
            j = n_coarse - 1;
            s = N0;
        }
        for (int flow = 0; flow < 3; flow++) { /* a over j dt / N1, the span, b over the rest */
            se_int row;
            if (flow == 0)
                row = coarse + row_a[c] * n_coarse + j;
            else if (flow == 1)
                row = switch_ + pair[c] * n_switch + s;
            else
                row = coarse + row_b[c] * n_coarse + n_coarse - 1 - j;
            const double *restrict Fr = F + row * n * n, *restrict Gr = G + row * n * n_in,
                                   *restrict Qr = Qd + row * n * n;
            if (flow == 0) {
                for (se_int h = 0; h < n; h++) {
                    for (se_int i = 0; i < n; i++) {
                        Fl[(h * n + i) * B + b] = Fr[h * n + i];
                        Ql[(h * n + i) * B + b] = Qr[h * n + i];
                    }
                    for (se_int i = 0; i < n_in; i++)
                        Gl[(h * n_in + i) * B + b] = Gr[h * n_in + i];
                }
                continue;
            }
            for (se_int h = 0; h < n; h++) { /* T1 = Phi F, T2 = Phi Qd, Gt = Phi G + Gam */
                for (se_int i = 0; i < n; i++) {
                    double acc = 0.0, acc_q = 0.0;
                    for (se_int k2 = 0; k2 < n; k2++) {
                        acc += Fr[h * n + k2] * Fl[(k2 * n + i) * B + b];
                        acc_q += Fr[h * n + k2] * Ql[(k2 * n + i) * B + b];
                    }
                    T1[h * n + i] = acc;
                    T2[h * n + i] = acc_q;
                }
                for (se_int i = 0; i < n_in; i++) {
                    double acc = Gr[h * n_in + i];
                    for (se_int k2 = 0; k2 < n; k2++)
                        acc += Fr[h * n + k2] * Gl[(k2 * n_in + i) * B + b];
                    Gt[h * n_in + i] = acc;
                }
            }
            for (se_int h = 0; h < n; h++) { /* F <- Phi F, G <- Phi G + Gam, Qd <- Phi Qd Phi' + Qd_s */
                for (se_int i = 0; i < n; i++)
                    Fl[(h * n + i) * B + b] = T1[h * n + i];
                for (se_int i = 0; i < n_in; i++)
                    Gl[(h * n_in + i) * B + b] = Gt[h * n_in + i];
                for (se_int i = h; i < n; i++) {
                    double acc = Qr[h * n + i];
                    for (se_int k2 = 0; k2 < n; k2++)
                        acc += T2[h * n + k2] * Fr[i * n + k2];
                    Ql[(h * n + i) * B + b] = acc;
                }
            }
            for (se_int h = 0; h < n; h++)
                for (se_int i = 0; i < h; i++)
                    Ql[(h * n + i) * B + b] = Ql[(i * n + h) * B + b];
        }
    }
    return SE_OK;
}

/* ---------------------------------------------------------------- measurement update */

/* Measurement update of every lane, as the bank does for one mode (se_bank_measure, bank.c):
 * innovation (se_innovation, repairing), the gate (use: the normalized innovation squared
 * within gate and a finite likelihood), the Joseph-form correction of the lanes that use it
 * (Shankar et al. eqs (8)-(10)), and the information form where Joseph's loses its digits, a
 * repair where neither resolves P (se_information_or_repair). The workspace is Work's group
 * ws (e, PCt, chol, scale, z, nis, loglik, work, bad) and cs (gain, T, AP, prior, root, lost).
 * Returns the status. */
static se_int update(const Work *w, double *restrict x, double *restrict P,
                     const double *restrict y, const double *restrict C,
                     const double *restrict R, const double *restrict obs,
                     const double *restrict n_obs, double gate, se_int nb,
                     uint8_t *restrict use, double *restrict report)
{
    const se_int n = w->n, m = w->m, B = w->B;
    const double *nis = w->ws.nis, *loglik = w->ws.loglik; /* written by se_innovation */
    se_int status = se_innovate(n, m, B, x, P, y, C, R, obs, n_obs, nb, &w->ws, report);
    if (status != SE_OK)
        return status;
    for (se_int b = 0; b < nb; b++)
        use[b] = se_passes_gate(loglik[b], nis[b], gate);
    se_update(n, m, B, x, P, C, R, obs, n_obs, use, nb, w->ws.PCt, w->ws.chol, w->ws.scale,
              w->ws.z, &w->cs, report);
    return SE_OK;
}

/* The switching instant marginalized over the grid (beyond Shankar et al.), for the compacted
 * switched lanes: every grid instant tau_i is predicted (eqs (6)-(7)) and updated (update),
 * the hypotheses get the posterior weights w_i = p(y | tau_i) / sum_k p(y | tau_k) of a
 * uniform prior (log-sum-exp) and are merged by moment matching (se_moments); the likelihood
 * is the grid mean (1/g) sum_i p(y | tau_i) and the instant the posterior mean
 * sum_i w_i tau_i. Where every instant rejects the measurement, the predictions are weighed
 * equally and the sample is flagged GATED. Writes the lanes' x, P, lik, flg, off; returns the
 * status. */
static se_int merge(const Work *w, double gate, se_int ns, se_int d, const se_int *restrict lane,
                    double *restrict x, double *restrict P, double *restrict lik,
                    uint8_t *restrict flg, double *restrict off, double *restrict report)
{
    const se_int n = w->n, B = w->B, g = w->g;
    const double *restrict xc = w->sx, *restrict Pc = w->sP;
    const se_int *restrict pair = w->pair;
    double *restrict xh = w->xh, *restrict Ph = w->Ph, *restrict llh = w->llh,
                     *restrict wh = w->wh, *restrict total = w->total;
    se_int *restrict index = w->hindex;
    const uint8_t *use = w->huse;        /* written by update */
    const double *loglik = w->ws.loglik; /* written by update */
    for (se_int r = 0; r < g; r++) {
        for (se_int c = 0; c < ns; c++)
            index[c] = w->first + pair[c] * g + r;
        gather_transition(w, index, ns, w->Phi, w->Gam, w->Q);
        double *restrict xr = xh + r * n * B, *restrict Pr = Ph + r * n * n * B;
        se_copy_gaussian(n, B, xc, Pc, ns, xr, Pr);
        se_predict(n, w->l, B, xr, Pr, w->Phi, w->Gam, w->su, w->Q, ns, w->cs.AP, w->xs);
        se_int status = update(w, xr, Pr, w->sy, w->sC, w->sR, w->sobs, w->sn_obs, gate, ns,
                               w->huse, report);
        if (status != SE_OK)
            return status;
        for (se_int c = 0; c < ns; c++)
            llh[r * B + c] = use[c] ? loglik[c] : -INFINITY;
    }
    for (se_int c = 0; c < ns; c++) {
        int rejected = 1;
        for (se_int r = 0; r < g; r++)
            rejected &= llh[r * B + c] == -INFINITY;
        if (rejected) /* weigh the predictions equally */
            for (se_int r = 0; r < g; r++)
                llh[r * B + c] = 0.0;
        flg[lane[c]] = rejected ? SE_GATED : SE_ACCEPTED;
    }
    se_log_normalize(g, B, llh, wh, total, ns); /* w_i = p(y | tau_i) / sum_k p(y | tau_k) */
    se_moments(n, g, B, wh, xh, Ph, ns, w->xm, w->Pm);
    put_rows(n, B, w->xm, lane, ns, x);
    put_matrices(n, n, B, w->Pm, lane, ns, P);
    const double log_g = log((double)g);
    for (se_int c = 0; c < ns; c++) {
        double tau = 0.0;
        for (se_int r = 0; r < g; r++)
            tau += wh[r * B + c] * w->grid_tau[d * g + r];
        off[lane[c]] = tau;
        lik[lane[c]] = flg[lane[c]] == SE_ACCEPTED ? total[c] - log_g : 0.0;
    }
    return SE_OK;
}

/* ---------------------------------------------------------------- the kernel */

/* Filter N trials over K samples, estimating the switching instant of every interval whose
 * mode changes (Shankar et al. §IV).
 *
 * Parameters
 * ----------
 * y, u, which, mode, prev, C, R, F, G, Qd, steps, grid_tau
 *     As in switch_time_run (the table's layout at the top of this file).
 * n_coarse, n_switch
 *     N1 and N0 + 1: the refinement sections' lengths per mode and per mode pair (0 without).
 * x_init, P_init : (N, n), (N, n, n)
 *     Each trial's state before the first sample.
 * predict_first
 *     Whether the first sample is predicted into (a streaming step) or only updated.
 * marginal, printed, gate
 * iterations
 *     The most probes of the refinement's search per switched lane (0: no refinement).
 * tolerance
 *     The refinement's tolerance on the switching instant, in units of the sampling step.
 * CF, CG, CQC
 *     C F, C G, C Qd C' of the coarse section, (H, m, n), (H, m, l), (H, m, m) with
 *     H = D L N1 (switchest.engine.switch_time.coarse_outputs).
 * lanes
 *     Trials per block.
 * x_out, P_out, loglik_out, offset_out, flag_out
 *     Written: the posterior (N, K, n), (N, K, n, n), the log-likelihood, the estimated
 *     switching offset (NaN without a switch) and the flag (N, K).
 * report : (2,)
 *     Written: repairs and the smallest eigenvalue before one (se_repair).
 *
 * Returns
 * -------
 * status
 *     SE_OK, or the failure code of the innovation covariance (of a grid instant, a
 *     refinement probe or the update) that stopped the kernel (outputs then incomplete), or
 *     SE_NO_MEMORY.
 *
 * Notes
 * -----
 * At each sample the kernel compacts the lanes whose mode changed, estimates their switching
 * instant (grid_maximum, refine; every lane's transition is otherwise the no-switch one of the
 * mode before the interval), predicts every lane (eqs (6)-(7)) and updates it (update); with
 * marginal the switched lanes' posteriors are then replaced by the merge of their grid
 * hypotheses (merge). The predicted state of a lane whose measurement is rejected is its
 * posterior, as for a missing measurement. */
se_int se_switch_time_filter(SE_SWITCH_TIME_FILTER_PARAMETERS)
{
    const se_int B = se_lanes(lanes, N);
    const se_int G_h = marginal ? g : 0;
    se_report_start(report);

    double *restrict x, *restrict P, *restrict yl, *restrict ul, *restrict obs, *restrict n_obs,
        *restrict Fl, *restrict Gl, *restrict Ql, *restrict Cl, *restrict Rl, *restrict lik,
        *restrict off;
    se_int *restrict index, *restrict lane, *restrict mode_c;
    uint8_t *restrict use, *restrict flg;
    Work w;
    w.n = n;
    w.m = m;
    w.l = l;
    w.L = L;
    w.B = B;
    w.g = g;
    w.F = F;
    w.G = G;
    w.Qd = Qd;
    w.steps = steps;
    w.grid_tau = grid_tau;
    w.CF = CF;
    w.CG = CG;
    w.CQC = CQC;
    w.first = D * L; /* the first rows of the grid, coarse and switch sections */
    w.coarse = D * L * (1 + L * g);
    w.switch_ = w.coarse + D * L * n_coarse;
    w.n_coarse = n_coarse;
    w.n_switch = n_switch;
    w.printed = printed;
    w.gate = gate;
    w.iterations = iterations;
    w.tolerance = tolerance;
    se_arena ar = {NULL, 0};
    do { /* size the arena, then carve it (zeroed: zero and bad must start at 0) */
        SE_DOUBLES(&ar, n * B, &x);
        SE_DOUBLES(&ar, n * n * B, &P, &Fl, &Ql);
        SE_DOUBLES(&ar, m * B, &yl, &obs);
        SE_DOUBLES(&ar, l * B, &ul);
        SE_DOUBLES(&ar, B, &n_obs, &lik, &off);
        SE_DOUBLES(&ar, n * l * B, &Gl);
        SE_DOUBLES(&ar, m * n * B, &Cl);
        SE_DOUBLES(&ar, m * m * B, &Rl);
        SE_INTS(&ar, B, &index, &lane, &mode_c);
        SE_FLAGS(&ar, B, &use, &flg);
        se_carve_innovation(&ar, n, m, B, &w.ws);
        se_carve_update(&ar, n, m, B, &w.cs);
        SE_DOUBLES(&ar, n * B, &w.xs, &w.sx, &w.xm);
        SE_DOUBLES(&ar, n * n * B, &w.sP, &w.zero, &w.Phi, &w.Q, &w.Pm);
        SE_DOUBLES(&ar, m * B, &w.sy, &w.sobs, &w.ye);
        SE_DOUBLES(&ar, l * B, &w.su);
        SE_DOUBLES(&ar, B, &w.sn_obs, &w.best_ll, &w.J, &w.total);
        SE_DOUBLES(&ar, m * n * B, &w.sC, &w.E, &w.EQ);
        SE_DOUBLES(&ar, m * m * B, &w.sR, &w.Re, &w.Qo);
        SE_INTS(&ar, B, &w.row_a, &w.row_b, &w.pair, &w.best, &w.rows, &w.win, &w.hindex);
        SE_DOUBLES(&ar, m * l * B, &w.Go);
        SE_DOUBLES(&ar, n * l * B, &w.Gam);
        SE_DOUBLES(&ar, m * n, &w.pE, &w.pEQ, &w.pEF);
        SE_DOUBLES(&ar, m * l, &w.pGo);
        SE_DOUBLES(&ar, m * m, &w.pQo, &w.pchol);
        SE_DOUBLES(&ar, n * m, &w.pPCt);
        SE_DOUBLES(&ar, m, &w.pscale, &w.pe);
        SE_DOUBLES(&ar, n * n, &w.T1, &w.T2);
        SE_DOUBLES(&ar, n * l, &w.Gt);
        SE_DOUBLES(&ar, G_h * n * B, &w.xh);
        SE_DOUBLES(&ar, G_h * n * n * B, &w.Ph);
        SE_DOUBLES(&ar, G_h * B, &w.llh, &w.wh);
        SE_FLAGS(&ar, B, &w.huse);
    } while (se_arena_open(&ar));
    if (ar.base == NULL)
        return SE_NO_MEMORY;

    se_int status = SE_OK;
    for (se_int i0 = 0; i0 < N; i0 += B) {
        const se_int nb = se_block_trials(B, N, i0);
        se_gather_rows(n, B, 1, x_init, i0, nb, x);
        for (se_int r = 0; r < n; r++)
            for (se_int c = 0; c < n; c++)
                for (se_int b = 0; b < nb; b++)
                    P[(r * n + c) * B + b] = P_init[((i0 + b) * n + r) * n + c];
        for (se_int k = 0; k < K; k++) {
            se_gather_samples(m, B, K, y, i0, nb, k, yl);
            se_observe(m, B, yl, nb, obs, n_obs);
            se_int ns = 0, d = 0;
            for (se_int b = 0; b < nb; b++)
                off[b] = NAN;
            if (k > 0 || predict_first) {
                d = which[k];
                se_gather_samples(l, B, K, u, i0, nb, k, ul);
                for (se_int b = 0; b < nb; b++) {
                    const se_int before = prev[(i0 + b) * K + k], after = mode[(i0 + b) * K + k];
                    index[b] = d * L + before; /* no switch: the mode before the interval */
                    if (before != after) {
                        lane[ns] = b;
                        mode_c[ns] = after;
                        w.row_a[ns] = d * L + before;
                        w.row_b[ns] = d * L + after;
                        w.pair[ns] = (d * L + before) * L + after;
                        ns++;
                    }
                }
                gather_transition(&w, index, nb, Fl, Gl, Ql);
                if (ns) {
                    take_rows(n, B, x, lane, ns, w.sx);
                    take_matrices(n, n, B, P, lane, ns, w.sP);
                    take_rows(m, B, yl, lane, ns, w.sy);
                    take_rows(l, B, ul, lane, ns, w.su);
                    take_rows(m, B, obs, lane, ns, w.sobs);
                    for (se_int c = 0; c < ns; c++)
                        w.sn_obs[c] = n_obs[lane[c]];
                    se_gather_matrices(m, n, B, C, mode_c, ns, w.sC);
                    se_gather_matrices(m, m, B, R, mode_c, ns, w.sR);
                }
                if (ns && !marginal) {
                    status = grid_maximum(&w, ns, d, lane, Fl, Gl, Ql, off, report);
                    if (status == SE_OK && iterations)
                        status = refine(&w, ns, d, lane, Fl, Gl, Ql, off, report);
                    if (status != SE_OK)
                        goto done;
                }
                se_predict(n, l, B, x, P, Fl, Gl, ul, Ql, nb, w.cs.AP, w.xs);
            }
            for (se_int b = 0; b < nb; b++)
                index[b] = mode[(i0 + b) * K + k];
            se_gather_matrices(m, n, B, C, index, nb, Cl);
            se_gather_matrices(m, m, B, R, index, nb, Rl);
            status = update(&w, x, P, yl, Cl, Rl, obs, n_obs, gate, nb, use, report);
            if (status != SE_OK)
                goto done;
            for (se_int b = 0; b < nb; b++) {
                lik[b] = use[b] ? w.ws.loglik[b] : 0.0;
                flg[b] = use[b] ? SE_ACCEPTED : SE_GATED;
            }
            if (ns && marginal) {
                status = merge(&w, gate, ns, d, lane, x, P, lik, flg, off, report);
                if (status != SE_OK)
                    goto done;
            }
            for (se_int b = 0; b < nb; b++) {
                const se_int i = i0 + b;
                loglik_out[i * K + k] = lik[b];
                offset_out[i * K + k] = off[b];
                flag_out[i * K + k] = flg[b];
                se_write_lane(n, B, K, x, P, b, i, k, x_out, P_out);
            }
        }
    }
done:
    se_arena_close(&ar);
    return status;
}
