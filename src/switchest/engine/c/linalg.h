/* The Kalman and IMM equations over a block of trials laid across SIMD lanes (provenance:
 * linalg.c), and the per-lane index of a trial table (se_lane_index). The full documentation
 * of each equation (paper and equation citations) is at its definition in linalg.c; here: the
 * prototypes and the shapes.
 *
 * Conventions of every prototype
 * ------------------------------
 * - Name: "se_" + the equation's name (se_solve, se_innovation, se_repair ...).
 * - Arguments: first the sizes (the arrays' extents), as se_int, in the order
 *       n, m, l, L, B, then any other extent (K, N, q, p ...),
 *   then the arrays and scalars as each prototype lists them, mostly inputs before outputs
 *   and scratch (nb, i0, k, b, j ... as se_int where they stand). n = states, m = outputs,
 *   l = inputs, L = modes, B = the lane stride, the length of the last axis of EVERY lane
 *   array passed to that call (all lane arrays of one call must have the same last-axis
 *   length B; a lane array of shape (n, n, B) is addressed P[(r * n + c) * B + b]).
 * - Booleans: int (arguments, return values); boolean arrays (use, bad, lost): uint8_t
 *   (0/1); index arrays (index, best): se_int; everything else double.
 * - A sub-array such as mode j's x (n, B) of x (L, n, B) is passed as the pointer
 *   x + j * n * B.
 * - Trial tables read at [i0 + b, ...] (gather / scatter / write): the extents after the
 *   trial axis are passed among the sizes. The gather_rows / scatter_rows / gather_modes /
 *   scatter_modes family also takes a K: the array is (N, K, ...) read at one sample; pass
 *   K = 1 for an (N, ...) array, or, for the sample-k slice data[:, k] of an (N, K, ...) array
 *   (the smoother's x_f[:, k]), the pointer at data[0, k] and that K.
 * - Status codes (SE_OK, SE_NOT_POSITIVE_DEFINITE, SE_NOT_FINITE) and flags come from
 *   se_common.h; the functions returning a status return se_int.
 * - Nothing allocates on the heap except se_repair / se_information_form (via
 *   se_information_or_repair and se_innovation with a report) for n or m beyond
 *   SE_LINALG_STACK (their scratch lives on the stack below that; a failed malloc makes them
 *   return 0, "not done").
 */
#ifndef SE_LINALG_H
#define SE_LINALG_H

#include <math.h>
#include <stdint.h>

#include "se_common.h"

/* LAPACK's dsyevd (symmetric eigendecomposition) with the signature of
 * scipy.linalg.cython_lapack's: every binding hands it over when it is imported, before any
 * kernel runs (_common.pxd, use_lapack), and se_repair calls it. */
typedef void se_dsyevd_fn(char *jobz, char *uplo, int *n, double *a, int *lda, double *w,
                          double *work, int *lwork, int *iwork, int *liwork, int *info);
void se_use_dsyevd(se_dsyevd_fn *dsyevd);

/* the numerical constants of the equations */
#define SE_LOG_2PI 1.8378770664093453           /* math.log(2 pi) = 0x1.d67f1c864beb4p+0 */
#define SE_EPS 2.220446049250313e-16            /* numpy.finfo(float).eps */
#define SE_CORRELATION_BOUND 1.0000000149011612 /* 1 + sqrt(eps) = 0x1.0000004p+0 */
#define SE_TINY_SUM 1e-250 /* below it, a sum of probability products is redone in the log domain */

/* largest n (and m) whose scratch in se_repair / se_information_form / se_cholesky is kept on
 * the stack */
#define SE_LINALG_STACK 24

/* ---- gathering and scattering a block of trials ------------------------------------------ */

/* out[a, b] = data[i0 + b, k, a]: data (N, K, m), out (m, B) (m is l for inputs) */
void se_gather_samples(se_int m, se_int B, se_int K, const double *restrict data, se_int i0,
                       se_int nb, se_int k, double *restrict out);

/* out[:, b] = data[i0 + b]: data (N, K, q) read at [:, 0, :] (see K above), out (q, B) */
void se_gather_rows(se_int q, se_int B, se_int K, const double *restrict data, se_int i0,
                    se_int nb, double *restrict out);
/* the same for int64 rows (imm_ev1's chosen) */
void se_gather_rows_int(se_int q, se_int B, se_int K, const se_int *restrict data, se_int i0,
                        se_int nb, se_int *restrict out);

/* data[i0 + b] = src[:, b]: src (q, B), data (N, K, q) written at [:, 0, :] */
void se_scatter_rows(se_int q, se_int B, se_int K, const double *restrict src, se_int i0,
                     se_int nb, double *restrict data);
void se_scatter_rows_int(se_int q, se_int B, se_int K, const se_int *restrict src, se_int i0,
                         se_int nb, se_int *restrict data);

/* x[j, :, b] = x_init[i0 + b, j], P[j, :, :, b] = P_init[i0 + b, j]:
 * x_init (N, K, L, n), P_init (N, K, L, n, n) read at [:, 0] (K = 1: (N, L, n), (N, L, n, n));
 * x (L, n, B), P (L, n, n, B) */
void se_gather_modes(se_int n, se_int L, se_int B, se_int K, const double *restrict x_init,
                     const double *restrict P_init, se_int i0, se_int nb, double *restrict x,
                     double *restrict P);

/* x_last[i0 + b, j] = x[j, :, b], P_last[i0 + b, j] = P[j, :, :, b]: se_gather_modes back;
 * x (L, n, B), P (L, n, n, B), x_last (N, K, L, n), P_last (N, K, L, n, n) at [:, 0] */
void se_scatter_modes(se_int n, se_int L, se_int B, se_int K, const double *restrict x,
                      const double *restrict P, se_int i0, se_int nb, double *restrict x_last,
                      double *restrict P_last);

/* Lane b of x (n, B) and P (n, n, B) as sample k of trial i of the outputs
 * x_out (N, K, n), P_out (N, K, n, n). */
static inline void se_write_lane(se_int n, se_int B, se_int K, const double *restrict x,
                                 const double *restrict P, se_int b, se_int i, se_int k,
                                 double *restrict x_out, double *restrict P_out)
{
    double *xo = x_out + (i * K + k) * n;
    double *Po = P_out + (i * K + k) * n * n;
    for (se_int r = 0; r < n; r++) {
        xo[r] = x[r * B + b];
        for (se_int c = 0; c < n; c++)
            Po[r * n + c] = P[(r * n + c) * B + b];
    }
}

/* out[r, c, b] = table[index[b], r, c]: table (M, p, q), index (B,), out (p, q, B) */
void se_gather_matrices(se_int p, se_int q, se_int B, const double *restrict table,
                        const se_int *restrict index, se_int nb, double *restrict out);

/* obs[a, b] = 1 where y[a, b] is observed (not NaN), else 0; n_obs[b] counts them.
 * y (m, B), obs (m, B), n_obs (B,) */
void se_observe(se_int m, se_int B, const double *restrict y, se_int nb, double *restrict obs,
                double *restrict n_obs);

/* ---- time update --------------------------------------------------------------------------- */

/* x <- F x + G u: x (n, B), F (n, n, B), G (n, l, B), u (l, B), xs (n, B) scratch */
void se_predict_mean(se_int n, se_int l, se_int B, double *restrict x, const double *restrict F,
                     const double *restrict G, const double *restrict u, se_int nb,
                     double *restrict xs);

/* x <- F x + G u, P <- F P F' + Qd (exactly symmetric): x (n, B), P (n, n, B), F (n, n, B),
 * G (n, l, B), u (l, B), Qd (n, n, B); FP (n, n, B), xs (n, B) scratch */
void se_predict(se_int n, se_int l, se_int B, double *restrict x, double *restrict P,
                const double *restrict F, const double *restrict G, const double *restrict u,
                const double *restrict Qd, se_int nb, double *restrict FP, double *restrict xs);

/* x_to = x, P_to = P in the first nb lanes: x, x_to (n, B), P, P_to (n, n, B) */
static inline void se_copy_gaussian(se_int n, se_int B, const double *restrict x,
                                    const double *restrict P, se_int nb, double *restrict x_to,
                                    double *restrict P_to)
{
    for (se_int r = 0; r < n; r++) {
        for (se_int b = 0; b < nb; b++)
            x_to[r * B + b] = x[r * B + b];
        for (se_int c = 0; c < n; c++)
            for (se_int b = 0; b < nb; b++)
                P_to[(r * n + c) * B + b] = P[(r * n + c) * B + b];
    }
}

/* out[:, :, b] = source[:, :, b] in the first nb lanes: source, out (p, q, B) */
void se_copy_lanes(se_int p, se_int q, se_int B, const double *restrict source, se_int nb,
                   double *restrict out);

/* o[c] = start[c] + sum_k X_k[c] Y_k[c] (minus: start[c] - ...; start NULL: from 0) for the w
 * lanes c < w, k = rows[t] for t = 0 .. q-1 (rows NULL: k = t), X_k = X + k sx, Y_k = Y + k sy,
 * its terms added in the order of t (w a constant where it is inlined: the w sums stay in
 * registers over t). o may be start. */
static inline void se_chunk_accumulate(se_int w, se_int q, const se_int *restrict rows,
                                       const double *start, int minus, const double *restrict X,
                                       se_int sx, const double *restrict Y, se_int sy, double *o)
{
    double acc[16];
    for (se_int c = 0; c < w; c++)
        acc[c] = start ? start[c] : 0.0;
    for (se_int t = 0; t < q; t++) {
        const se_int k = rows ? rows[t] : t;
        const double *Xk = X + k * sx, *Yk = Y + k * sy;
        if (minus)
            for (se_int c = 0; c < w; c++)
                acc[c] -= Xk[c] * Yk[c];
        else
            for (se_int c = 0; c < w; c++)
                acc[c] += Xk[c] * Yk[c];
    }
    for (se_int c = 0; c < w; c++)
        o[c] = acc[c];
}

/* The lanes b .. nb-1 in chunks of 16, then 8, 4, 2 and 1 (b advanced): STEP(w) is called with
 * the chunk's width w, a constant, at each chunk's first lane b, so that a chunk's w sums can
 * stay in registers (se_chunk_accumulate). */
#define SE_LANE_CHUNKS(b, nb, STEP)                                                              \
    do {                                                                                         \
        for (; (b) + 16 <= (nb); (b) += 16)                                                      \
            STEP(16);                                                                            \
        for (; (b) + 8 <= (nb); (b) += 8)                                                        \
            STEP(8);                                                                             \
        for (; (b) + 4 <= (nb); (b) += 4)                                                        \
            STEP(4);                                                                             \
        for (; (b) + 2 <= (nb); (b) += 2)                                                        \
            STEP(2);                                                                             \
        for (; (b) < (nb); (b)++)                                                                \
            STEP(1);                                                                             \
    } while (0)

/* o[b] = start[b] + sum_k X_k[b] Y_k[b] per lane (minus: start[b] - ...; start NULL: from 0),
 * k = rows[t] for t = 0 .. q-1 (rows NULL: k = t), X_k = X + k sx and Y_k = Y + k sy being lane
 * rows (.., B) (strides in doubles), its terms added in the order of t: the same additions in
 * the same order in every lane as o[b] += X_k[b] Y_k[b] over t in memory, but each chunk's sums
 * (SE_LANE_CHUNKS) stay in registers over t (in memory every term is loaded and stored again:
 * 1.5-2x the time on n = 4). o may be start. Always inlined: each call site's rows, start and
 * minus are then constants (as a shared copy it ran 3 % more instructions in the two-filter
 * pass). */
__attribute__((always_inline)) static inline void
se_lane_accumulate_rows(se_int q, const se_int *restrict rows, const double *start, int minus,
                        const double *restrict X, se_int sx, const double *restrict Y, se_int sy,
                        se_int nb, double *o)
{
    se_int b = 0;
#define SE_ACCUMULATE_CHUNK(w)                                                                   \
    se_chunk_accumulate((w), q, rows, start ? start + b : NULL, minus, X + b, sx, Y + b, sy,    \
                        o + b)
    SE_LANE_CHUNKS(b, nb, SE_ACCUMULATE_CHUNK);
#undef SE_ACCUMULATE_CHUNK
}

/* se_lane_accumulate_rows over every k = 0 .. q-1 */
__attribute__((always_inline)) static inline void
se_lane_accumulate(se_int q, const double *start, int minus, const double *restrict X, se_int sx,
                   const double *restrict Y, se_int sy, se_int nb, double *o)
{
    se_lane_accumulate_rows(q, NULL, start, minus, X, sx, Y, sy, nb, o);
}

/* out = base + X Y' per lane, for X, Y (n, q, B) whose sum is symmetric (Qd + (F P) F',
 * A P + T K'): the upper triangle is computed, base's read, and mirrored, so out (n, n, B) is
 * exactly symmetric. out may be base (hence no restrict on those two). */
static inline void se_symmetric_sum(se_int n, se_int q, se_int B, const double *base,
                                    const double *restrict X, const double *restrict Y,
                                    se_int nb, double *out)
{
    for (se_int i = 0; i < n; i++) {
        for (se_int j = i; j < n; j++) {
            double *o = out + (i * n + j) * B;
            se_lane_accumulate(q, base + (i * n + j) * B, 0, X + i * q * B, B, Y + j * q * B, B,
                               nb, o);
            double *t = out + (j * n + i) * B;
            for (se_int b = 0; b < nb; b++)
                t[b] = o[b];
        }
    }
}

/* ---- measurement update -------------------------------------------------------------------- */

/* e = y - C x in every lane: x (n, B), y (m, B), C (m, n, B), e (m, B) (n is l for an input) */
void se_residual(se_int n, se_int m, se_int B, const double *restrict x,
                 const double *restrict y, const double *restrict C, se_int nb,
                 double *restrict e);

/* Innovation of y against (x, P) over each lane's observed components, and S's factorization.
 * x (n, B), P (n, n, B), y (m, B), C (m, n, B), R (m, m, B), obs (m, B), n_obs (B,);
 * written: e (m, B), PCt (n, m, B), chol (m, m, B), scale (m, B), z (m, B), nis (B,),
 * loglik (B,), work (3, B) scratch, bad (B,) uint8; report (2,) or NULL (NULL: no
 * repair). Returns SE_OK, SE_NOT_FINITE or SE_NOT_POSITIVE_DEFINITE (bad marks the lanes). */
/* the parameter list, written once for the prototype and the definition (linalg.c) */
#define SE_INNOVATION_PARAMETERS                                                                  \
    se_int n, se_int m, se_int B, const double *restrict x, double *restrict P,                   \
    const double *restrict y, const double *restrict C, const double *restrict R,                 \
    const double *restrict obs, const double *restrict n_obs, se_int nb, double *restrict e,      \
    double *restrict PCt, double *restrict chol, double *restrict scale, double *restrict z,      \
    double *restrict nis, double *restrict loglik, double *restrict work, uint8_t *restrict bad,  \
    double *restrict report
se_int se_innovation(SE_INNOVATION_PARAMETERS);

/* The workspace of se_innovation (W lanes wide for W-lane calls): e, scale, z (m, B),
 * PCt (n, m, B), chol (m, m, B), nis, loglik (B,), work (3, B), bad (B,) (zeroed, as the
 * arena is) */
typedef struct {
    double *e, *PCt, *chol, *scale, *z, *nis, *loglik, *work;
    uint8_t *bad;
} se_innovation_ws;

static inline void se_carve_innovation(se_arena *arena, se_int n, se_int m, se_int B,
                                       se_innovation_ws *ws)
{
    SE_DOUBLES(arena, m * B, &ws->e, &ws->scale, &ws->z);
    SE_DOUBLES(arena, n * m * B, &ws->PCt);
    SE_DOUBLES(arena, m * m * B, &ws->chol);
    SE_DOUBLES(arena, B, &ws->nis, &ws->loglik);
    SE_DOUBLES(arena, 3 * B, &ws->work);
    SE_FLAGS(arena, B, &ws->bad);
}

/* se_innovation (Shankar et al. eq. (8)) with its workspace ws, whose nis and loglik get the
 * lanes' results */
static inline se_int se_innovate(se_int n, se_int m, se_int B, const double *restrict x,
                                 double *restrict P, const double *restrict y,
                                 const double *restrict C, const double *restrict R,
                                 const double *restrict obs, const double *restrict n_obs,
                                 se_int nb, const se_innovation_ws *ws, double *restrict report)
{
    return se_innovation(n, m, B, x, P, y, C, R, obs, n_obs, nb, ws->e, ws->PCt, ws->chol,
                         ws->scale, ws->z, ws->nis, ws->loglik, ws->work, ws->bad, report);
}

/* Equilibrated Cholesky factorization in place of each lane's S in the lower triangle of
 * chol (m, m, B); scale (m, B), det (B,) written, pivot (B,) scratch. Returns whether every
 * lane's diagonal of S is finite; *positive gets whether every lane's S is positive definite. */
int se_factor(se_int m, se_int B, double *restrict chol, double *restrict scale, se_int nb,
              double *restrict det, double *restrict pivot, int *positive);

/* The per-lane half of se_innovation: x (n, B), y (m, B), C (m, n, B), obs (m, B), n_obs (B,),
 * chol (m, m, B), scale (m, B), log_det (2, B); written e (m, B), z (m, B), nis, loglik (B,) */
void se_innovation_mean(se_int n, se_int m, se_int B, const double *restrict x,
                        const double *restrict y, const double *restrict C,
                        const double *restrict obs, const double *restrict n_obs,
                        const double *restrict chol, const double *restrict scale,
                        const double *restrict log_det, se_int nb, double *restrict e,
                        double *restrict z, double *restrict nis, double *restrict loglik);

/* V[r] <- S^-1 V[r] for every row r of V (q, m, B); inv (m, B) written. (The smoother passes
 * its gain (n, m, B): q = n.) */
void se_solve_rows(se_int m, se_int B, se_int q, const double *restrict chol,
                   const double *restrict scale, double *restrict V, se_int nb,
                   double *restrict inv);

/* Measurement update (Joseph form) in the lanes where use[b]: x (n, B), P (n, n, B),
 * C (m, n, B), R (m, m, B), use (B,) uint8, PCt (n, m, B), chol (m, m, B), scale (m, B),
 * z (m, B) (overwritten); K (n, m, B), T (n, m, B), AP (n, n, B) scratch; prior (n, n, B)
 * written (P before the update). */
void se_correct(se_int n, se_int m, se_int B, double *restrict x, double *restrict P,
                const double *restrict C, const double *restrict R,
                const uint8_t *restrict use, se_int nb, const double *restrict PCt,
                const double *restrict chol, const double *restrict scale, double *restrict z,
                double *restrict K, double *restrict T, double *restrict AP,
                double *restrict prior);

/* x <- x + K v in the lanes where use[b], the others left as they are: x (n, B),
 * K (n, m, B), v (m, B), use (B,) uint8 (the mean update of se_correct_mean, K = P C' and
 * v = S^-1 e, and of the fixed-gain filter) */
static inline void se_add_gain(se_int n, se_int m, se_int B, double *restrict x,
                               const double *restrict K, const double *restrict v,
                               const uint8_t *restrict use, se_int nb)
{
    for (se_int i = 0; i < n; i++) {
        double *xi = x + i * B;
        for (se_int a = 0; a < m; a++) {
            const double *Kia = K + (i * m + a) * B, *va = v + a * B;
            for (se_int b = 0; b < nb; b++)
                xi[b] += use[b] ? Kia[b] * va[b] : 0.0;
        }
    }
}

/* x <- x + P C' S^-1 e where use[b]: x (n, B), z (m, B) (overwritten with S^-1 e),
 * PCt (n, m, B), chol (m, m, B), scale (m, B), use (B,) uint8 */
void se_correct_mean(se_int n, se_int m, se_int B, double *restrict x, double *restrict z,
                     const double *restrict PCt, const double *restrict chol,
                     const double *restrict scale, const uint8_t *restrict use, se_int nb);

/* The gating rule of every filter: a lane uses its measurement only if its likelihood is
 * finite (an outlier such as 1e300 overflows it) and its normalized innovation squared is
 * within the gate. */
static inline int se_passes_gate(double loglik, double nis, double gate)
{
    return isfinite(loglik) && nis <= gate;
}

/* The gating decision of a multiple-model filter over its filters, lane by lane, before
 * anything changes: filter (j, i), for j < rows and i < cols, stands at (j * stride + i) * B of
 * the (.., B) arrays prior, loglik, nis, use, a (stride 1, cols 1: the bank's modes; stride L:
 * GPB2's pairs). use = se_passes_gate; a = prior + loglik where used, -inf where not (prior:
 * the filter's log-weight before the measurement). If no filter has a finite a the sample
 * counts as missing: none is used, a = prior, flag SE_GATED; else the flag is SE_PARTLY_GATED
 * where a filter is not used, SE_ACCEPTED where all are. flag (B,) uint8. */
void se_gate(se_int rows, se_int cols, se_int stride, se_int B, const double *restrict prior,
             const double *restrict loglik, const double *restrict nis, double gate, se_int nb,
             uint8_t *restrict use, double *restrict a, uint8_t *restrict flag);

/* The scratch of se_update (W lanes wide for W-lane calls): gain, T (n, m, B),
 * AP, prior (n, n, B), root (n, B), lost (B,) */
typedef struct {
    double *gain, *T, *AP, *prior, *root;
    uint8_t *lost;
} se_update_ws;

static inline void se_carve_update(se_arena *arena, se_int n, se_int m, se_int B,
                                   se_update_ws *ws)
{
    SE_DOUBLES(arena, n * m * B, &ws->gain, &ws->T);
    SE_DOUBLES(arena, n * n * B, &ws->AP, &ws->prior);
    SE_DOUBLES(arena, n * B, &ws->root);
    SE_FLAGS(arena, B, &ws->lost);
}

/* The measurement update of every filter, in the lanes where use[b], with its covariance rule:
 * se_correct (Joseph form), then each lane where Joseph's form lost its digits (se_joseph_lost)
 * in information form, or repaired (se_information_or_repair, counted in report (2,)).
 * Arguments as se_correct's, with obs (m, B), n_obs (B,) as se_innovation read them. */
void se_update(se_int n, se_int m, se_int B, double *restrict x, double *restrict P,
               const double *restrict C, const double *restrict R, const double *restrict obs,
               const double *restrict n_obs, const uint8_t *restrict use, se_int nb,
               const double *restrict PCt, const double *restrict chol,
               const double *restrict scale, double *restrict z, const se_update_ws *ws,
               double *restrict report);

/* Mark in lost (B,) uint8 the lanes where Joseph's form lost its digits; returns whether there
 * is one. P, prior (n, n, B), use (B,) uint8, root (n, B) scratch. */
int se_joseph_lost(se_int n, se_int B, const double *restrict P, const double *restrict prior,
                   const uint8_t *restrict use, se_int nb, double *restrict root,
                   uint8_t *restrict lost);

/* Lane b of the posterior in information form: P, prior (n, n, B), C (m, n, B), R (m, m, B),
 * obs (m, B); returns 0, leaving P alone, if prior or R is not positive definite. */
int se_information_form(se_int n, se_int m, se_int B, double *restrict P,
                        const double *restrict prior, const double *restrict C,
                        const double *restrict R, const double *restrict obs, se_int b);

/* Raise lane b's covariance's eigenvalues to n eps max|eig|: P (n, n, B), report (2,);
 * returns whether P was changed. */
int se_repair(se_int n, se_int B, double *restrict P, se_int b, int indefinite_only,
              double *restrict report);

/* ---- multiple models ----------------------------------------------------------------------- */

/* log-sum-exp normalization over the modes per lane: a (L, B), prob (L, B), total (B,) */
void se_log_normalize(se_int L, se_int B, double *restrict a, double *restrict prob,
                      double *restrict total, se_int nb);

/* the same over the rows rows[0 .. count-1] of a and prob only (rows NULL: 0 .. count-1);
 * the others are neither read nor written */
void se_log_normalize_rows(se_int B, const se_int *restrict rows, se_int count,
                           double *restrict a, double *restrict prob, double *restrict total,
                           se_int nb);

/* IMM interaction in place: x (L, n, B), P (L, n, n, B), prob, log_prob (L, B),
 * transition, log_transition (L, L, B); log_c (L, B) written; w (L, L, B), xm (L, n, B),
 * Pm (L, n, n, B) scratch */
void se_mix(se_int n, se_int L, se_int B, double *restrict x, double *restrict P,
            const double *restrict prob, const double *restrict log_prob,
            const double *restrict transition, const double *restrict log_transition, se_int nb,
            double *restrict log_c, double *restrict w, double *restrict xm,
            double *restrict Pm);

/* GPB1 interaction in place; arguments as se_mix */
void se_collapse(se_int n, se_int L, se_int B, double *restrict x, double *restrict P,
                 const double *restrict prob, const double *restrict log_prob,
                 const double *restrict transition, const double *restrict log_transition,
                 se_int nb, double *restrict log_c, double *restrict w, double *restrict xm,
                 double *restrict Pm);

/* Moments of a mixture: w (L, B), x (L, n, B), P (L, n, n, B); xm (n, B), Pm (n, n, B) */
void se_merge(se_int n, se_int L, se_int B, const double *restrict w, const double *restrict x,
              const double *restrict P, se_int nb, double *restrict xm, double *restrict Pm);

/* Lane b of the mode-matched x (L, n, B), P (L, n, n, B) as sample k of trial i of
 * x_out (N, K, L, n), P_out (N, K, L, n, n). */
static inline void se_write_modes(se_int n, se_int L, se_int B, se_int K,
                                  const double *restrict x, const double *restrict P, se_int b,
                                  se_int i, se_int k, double *restrict x_out,
                                  double *restrict P_out)
{
    for (se_int j = 0; j < L; j++) {
        double *xo = x_out + ((i * K + k) * L + j) * n;
        double *Po = P_out + ((i * K + k) * L + j) * n * n;
        for (se_int r = 0; r < n; r++) {
            xo[r] = x[(j * n + r) * B + b];
            for (se_int c = 0; c < n; c++)
                Po[r * n + c] = P[((j * n + r) * n + c) * B + b];
        }
    }
}

/* Mixture moments: w (L, B), x (L, n, B), P (L, n, n, B); xm (n, B), Pm (n, n, B) */
void se_moments(se_int n, se_int L, se_int B, const double *restrict w, const double *restrict x,
                const double *restrict P, se_int nb, double *restrict xm, double *restrict Pm);

/* IMM output: x (L, n, B), P (L, n, n, B), prob, log_prob (L, B); xc (n, B), Pc (n, n, B),
 * best (B,) se_int written */
void se_combine(se_int n, se_int L, se_int B, const double *restrict x, const double *restrict P,
                const double *restrict prob, const double *restrict log_prob, se_int nb,
                double *restrict xc, double *restrict Pc, se_int *restrict best);

/* ---- general lane products and solves (the two-filter smoother) ---------------------------- */

/* out = X Y per lane: X (p, q), Y (q, r), out (p, r, B) at out[(i * r + j) * B + b]; X's entry
 * (i, k) stands at X + (i * xi + k * xk) * B and Y's (k, j) at Y + (k * yk + j * yj) * B
 * (strides in lane rows: a transposed operand passes its two strides swapped) */
void se_lane_product(se_int p, se_int q, se_int r, se_int B, const double *restrict X,
                     se_int xi, se_int xk, const double *restrict Y, se_int yk, se_int yj,
                     se_int nb, double *restrict out);

/* LU factorization with partial pivoting, in place, of each lane's A (n, n, B): piv (n, B)
 * se_int written (the row swapped with row j at step j), log_det (B,) = log |det A|, best (B,)
 * scratch */
void se_lu(se_int n, se_int B, double *restrict A, se_int *restrict piv, se_int nb,
           double *restrict log_det, double *restrict best);

/* X <- A^-1 X per lane from se_lu's factors: LU (n, n, B), piv (n, B), X (n, q, B) */
void se_lu_solve(se_int n, se_int q, se_int B, const double *restrict LU,
                 const se_int *restrict piv, double *restrict X, se_int nb);

/* ---- the per-lane index of a trial table --------------------------------------------------- */

/* out[b]: entry [trial, k, j] of index (N or 1, K or 1, L) for trial i0 + b; an axis of length
 * 1 is shared. N, K: index.shape[0], index.shape[1]; out (B,) */
void se_lane_index(se_int L, se_int N, se_int K, const se_int *restrict index, se_int i0,
                   se_int nb, se_int k, se_int j, se_int *restrict out);

#endif
