/* The bank of mode-matched Kalman filters with the IMM's or GPB1's interaction. The
 * documentation of the kernel and its helpers (paper and equation citations) is at their
 * definitions in bank.c; here: the prototypes and the shapes.
 *
 * Conventions of linalg.h: sizes first as se_int (n states, m outputs, l inputs, L modes,
 * B the lane stride, then the other extents), then the arrays and scalars in the order of
 * the prototype (the binding, engine/_bank.pyx, keeps it); booleans int,
 * boolean arrays uint8_t, index arrays se_int, the rest double, all C-contiguous. The skeleton
 * below is shared with gpb.c (GPB2), which links bank.c.
 */
#ifndef SE_BANK_H
#define SE_BANK_H

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include "linalg.h"
#include "se_common.h"

/* the interaction of se_filter_bank's mode-matched filters at each sample after the first */
enum {
    SE_MIX = 0,     /* the IMM's: mode j restarts from the mixture with weights mu_{i|j} */
    SE_COLLAPSE = 1 /* GPB1's: every mode restarts from the one Gaussian of all modes' mixture */
};

/* Each lane's exact transition of mode j into sample k, trans[trial, k, j] (se_lane_index) of
 * the table F (M, n, n), G (M, n, l), Qd (M, n, n), into Fl (n, n, B), Gl (n, l, B),
 * Ql (n, n, B). trans (trans_N, trans_K, L) with trans_N, trans_K its first two extents (an
 * axis of length 1 shared); idx (B,) scratch. */
void se_gather_transition(se_int n, se_int l, se_int L, se_int B, se_int trans_N,
                          se_int trans_K, const double *restrict F, const double *restrict G,
                          const double *restrict Qd, const se_int *restrict trans, se_int i0,
                          se_int nb, se_int k, se_int j, se_int *restrict idx,
                          double *restrict Fl, double *restrict Gl, double *restrict Ql);

/* ---- the skeleton of the bank kernels (se_filter_bank, se_gpb2_bank) ------------------------ */

/* Their scratch, B lanes wide. Both: the mode-matched Gaussians x (L, n, B), P (L, n, n, B)
 * with log_prob, prob (L, B); the lanes' transition Fl, Gl, Ql ((n, n, B), (n, l, B),
 * (n, n, B)) and each mode's output matrices Cl (L, m, n, B), Rl (L, m, m, B); the sample yl,
 * obs (m, B), ul (l, B), n_obs (B,); per filter (F of them: L modes, or GPB2's L^2 pairs) the
 * innovation e, z, scale (F, m, B), PCt (F, n, m, B), chol (F, m, m, B), nis, loglik, a
 * (F, B) and use (F, B); se_innovation's work (3, B), bad (B,), se_predict's xs (n, B),
 * se_update's upd; the output's total (B,), xc (n, B), Pc (n, n, B), best (B,), flag (B,);
 * idx (B,). The bank's (pairs 0): log_c (L, B), w (L, L, B), pi, log_pi (L, L, B), xm (L, n, B),
 * Pm (L, n, n, B); GPB2's (pairs 1): the pairs' xp (L, L, n, B), Pp (L, L, n, n, B), prior_w
 * (L, L, B), merge weights w (L, B) and log_mu (L, B). */
typedef struct {
    double *x, *P, *log_prob, *prob, *Fl, *Gl, *Ql, *Cl, *Rl, *yl, *ul, *obs, *n_obs, *e, *z,
        *scale, *PCt, *chol, *nis, *loglik, *a, *work, *xs, *total, *xc, *Pc, *w;
    double *log_c, *pi, *log_pi, *xm, *Pm; /* the bank's */
    double *xp, *Pp, *prior_w, *log_mu;    /* GPB2's */
    se_int *idx, *best;
    uint8_t *use, *flag, *bad;
    se_update_ws upd;
} se_bank_scratch;

/* A bank kernel's start: the report (2,) started and the scratch of se_filter_bank (pairs 0) or
 * se_gpb2_bank (pairs 1) carved from one zeroed block, ar->base; returns 0 if it could not be
 * allocated. */
int se_bank_open(se_arena *ar, se_bank_scratch *s, se_int n, se_int m, se_int l, se_int L,
                 se_int B, int pairs, double *report);

/* Their outputs: sample k of trial i written at [i, k] of x (N, K, n), P (N, K, n, n),
 * prob (N, K, L), mode, loglik, flag (N, K) and, if modes_wanted, x_modes (N, K, L, n),
 * P_modes (N, K, L, n, n); the state after the last sample, x_last (N, L, n),
 * P_last (N, L, n, n), log_prob_last (N, L). */
typedef struct {
    se_int K;
    int modes_wanted;
    double *x, *P, *prob;
    se_int *mode;
    double *loglik;
    uint8_t *flag;
    double *x_modes, *P_modes, *x_last, *P_last, *log_prob_last;
} se_bank_out;

/* A block's start: each trial's mode-matched state before the first sample, x_init (N, L, n),
 * P_init (N, L, n, n), log_prob_init (N, L), into s->x, s->P, s->log_prob. */
void se_bank_open_block(se_int n, se_int L, se_int B, const double *restrict x_init,
                        const double *restrict P_init, const double *restrict log_prob_init,
                        se_int i0, se_int nb, se_bank_scratch *s);

/* Sample k of y (N, K, m) into s->yl, its observed components into s->obs, s->n_obs. */
void se_bank_observe(se_int m, se_int B, se_int K, const double *restrict y, se_int i0,
                     se_int nb, se_int k, se_bank_scratch *s);

/* The measurement update of the bank's filters (bank.c documents it): filter (j, i), j < rows,
 * i < cols, is x, P at q = j * stride + i of x (.., n, B), P (.., n, n, B) with mode j's
 * output matrices and log-weight prior[q] (.., B). Returns the status of the innovations. */
se_int se_bank_measure(se_int n, se_int m, se_int B, se_int rows, se_int cols, se_int stride,
                       double *x, double *P, const double *prior, double gate, se_int nb,
                       se_bank_scratch *s, double *report);

/* A sample's end: the log-weights log_w (L, B) of the modes normalized into s->prob,
 * s->log_prob, s->total, and sample k written (bank.c). */
void se_bank_close_sample(se_int n, se_int L, se_int B, double *log_w, se_int i0, se_int nb,
                          se_int k, se_bank_scratch *s, const se_bank_out *out);

/* A block's end: the mode-matched state after the last sample into out's _last arrays. */
void se_bank_close_block(se_int n, se_int L, se_int B, se_int i0, se_int nb,
                         const se_bank_scratch *s, const se_bank_out *out);

/* Filter N trials over K samples with L interacting mode-matched filters (bank.c documents
 * it). Shapes: y (N, K, m), u (N, K, l), F, G, Qd (M, n, n), (M, n, l), (M, n, n),
 * trans (trans_N, trans_K, L) se_int, C, R (M', m, n), (M', m, m),
 * out_index (out_N, out_K, L) se_int, transition, log_transition (transition_N, L, L),
 * x_init (N, L, n), P_init (N, L, n, n), log_prob_init (N, L); written: out (se_bank_out),
 * report (2,).
 * Returns SE_OK, SE_NOT_POSITIVE_DEFINITE, SE_NOT_FINITE or SE_NO_MEMORY. */
/* the parameter list, written once for the prototype and the definition (bank.c) */
#define SE_FILTER_BANK_PARAMETERS                                                                 \
    se_int n, se_int m, se_int l, se_int L, se_int N, se_int K, se_int trans_N,                   \
    se_int trans_K, se_int out_N, se_int out_K, se_int transition_N, const double *restrict y,    \
    const double *restrict u, const double *restrict F, const double *restrict G,                 \
    const double *restrict Qd, const se_int *restrict trans, const double *restrict C,            \
    const double *restrict R, const se_int *restrict out_index,                                   \
    const double *restrict transition, const double *restrict log_transition,                     \
    const double *restrict x_init, const double *restrict P_init,                                 \
    const double *restrict log_prob_init, se_int interaction, int sample_timing,                  \
    int predict_first, double gate, se_int lanes, const se_bank_out *out,                         \
    double *restrict report
se_int se_filter_bank(SE_FILTER_BANK_PARAMETERS);

#endif
