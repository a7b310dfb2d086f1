/* The bank of mode-matched Kalman filters with the IMM's or GPB1's interaction: the port of
 * switchest/estimators/_compiled/bank.py. The documentation of the kernel and its helpers
 * (paper and equation citations) is at their definitions in bank.c; here: the prototypes and
 * the shapes.
 *
 * Conventions of linalg.h: sizes first as se_int (n states, m outputs, l inputs, L modes,
 * B the lane stride, then the other extents), then the arguments of the Python function in
 * its order; booleans int, boolean arrays uint8_t, index arrays se_int, the rest double, all
 * C-contiguous. The helpers below are shared with gpb.c (GPB2), which links bank.c.
 */
#ifndef SE_BANK_H
#define SE_BANK_H

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include "se_common.h"

/* A kernel's scratch: ONE block, carved into its arrays (each rounded up to 64 bytes, so that
 * every array starts on a cache line). A kernel carves its arrays twice with the same calls:
 * first with base NULL, which only adds up the size, then from the block allocated of that
 * size (se_arena_alloc). */
typedef struct {
    char *base;
    size_t used;
} se_arena;

static inline void *se_carve(se_arena *arena, se_int count, size_t size)
{
    size_t bytes = ((size_t)count * size + 63) & ~(size_t)63;
    void *p = arena->base ? (void *)(arena->base + arena->used) : NULL;
    arena->used += bytes;
    return p;
}

/* allocate the block a counting pass sized (NULL on failure); release it with free() */
static inline char *se_arena_alloc(const se_arena *counted)
{
    size_t bytes = counted->used ? counted->used : 64;
    return (char *)aligned_alloc(64, bytes);
}

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

/* Each lane's transition matrix and its logarithm: transition, log_transition
 * (transition_N, L, L) (transition_N = N or 1, shared) into pi, log_pi (L, L, B). */
void se_gather_transitions(se_int L, se_int B, se_int transition_N,
                           const double *restrict transition,
                           const double *restrict log_transition, se_int i0, se_int nb,
                           double *restrict pi, double *restrict log_pi);

/* dst[:, :nb] = src[:, :nb] for src, dst (L, B) (L: src.shape[0], any row count). */
void se_copy_rows(se_int L, se_int B, const double *restrict src, double *restrict dst,
                  se_int nb);

/* Write sample k of the block's trials: combined output of x (L, n, B), P (L, n, n, B) with
 * probabilities prob, log_prob (L, B), the most probable mode, the log-likelihood total (B,),
 * the flag (B,) uint8, n_obs (B,), and if modes_wanted the mode-matched Gaussians.
 * Scratch xc (n, B), Pc (n, n, B), best (B,). Outputs: x_out (N, K, n), P_out (N, K, n, n),
 * prob_out (N, K, L), mode_out (N, K) se_int, loglik_out (N, K), flag_out (N, K) uint8,
 * x_modes_out (N, K, L, n), P_modes_out (N, K, L, n, n) (read only if modes_wanted). */
void se_report_sample(se_int n, se_int L, se_int B, se_int K, const double *restrict x,
                      const double *restrict P, const double *restrict prob,
                      const double *restrict log_prob, const double *restrict total,
                      const uint8_t *restrict flag, const double *restrict n_obs, se_int i0,
                      se_int nb, se_int k, int modes_wanted, double *restrict xc,
                      double *restrict Pc, se_int *restrict best, double *restrict x_out,
                      double *restrict P_out, double *restrict prob_out,
                      se_int *restrict mode_out, double *restrict loglik_out,
                      uint8_t *restrict flag_out, double *restrict x_modes_out,
                      double *restrict P_modes_out);

/* Filter N trials over K samples with L interacting mode-matched filters (bank.c documents
 * it). Shapes: y (N, K, m), u (N, K, l), F, G, Qd (M, n, n), (M, n, l), (M, n, n),
 * trans (trans_N, trans_K, L) se_int, C, R (M', m, n), (M', m, m),
 * out_index (out_N, out_K, L) se_int, transition, log_transition (transition_N, L, L),
 * x_init (N, L, n), P_init (N, L, n, n), log_prob_init (N, L); written: x_out (N, K, n),
 * P_out (N, K, n, n), prob_out (N, K, L), mode_out (N, K) se_int, loglik_out (N, K),
 * flag_out (N, K) uint8, x_modes_out, P_modes_out (modes_N, K, L, n), (modes_N, K, L, n, n)
 * (written if modes_N == N), x_last, P_last, log_prob_last as the _init arrays, report (2,).
 * Returns SE_OK, SE_NOT_POSITIVE_DEFINITE, SE_NOT_FINITE or SE_NO_MEMORY. */
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
                      double *restrict log_prob_last, double *restrict report);

#endif
