/* The Rao-Blackwellized particle filter for jump-Markov linear systems. The documentation of
 * each function is at its definition in rbpf.c; here: the prototypes and the shapes.
 *
 * Conventions as linalg.h: sizes first (se_int), then the arrays and scalars in the order of
 * the prototype (the binding, engine/_rbpf.pyx, keeps it); booleans int, boolean arrays
 * uint8_t, index arrays se_int, keys uint64_t, the rest double; every array C-contiguous of
 * the shape given. The particles of one trial lie across the lanes: the lane stride B is the
 * particle count Np.
 */
#ifndef SE_RBPF_H
#define SE_RBPF_H

#include <stdint.h>

#include "se_common.h"

/* resampling schemes (RESAMPLING of the Python wrapper) */
enum { SE_SYSTEMATIC = 0, SE_STRATIFIED = 1, SE_MULTINOMIAL = 2 };

/* Uniform j of sample k of the trial with key, in [0, 1). */
double se_uniform(uint64_t key, se_int k, se_int j);

/* keys[i] = element i of the SplitMix64 sequence started at root, i = 0 .. count-1;
 * keys (count,) */
void se_trial_keys(se_int count, uint64_t root, uint64_t *restrict keys);

/* The nb sorted resampling positions of sample k in [0, 1]: pos (nb,) */
void se_resampling_positions(uint64_t key, se_int k, se_int scheme, se_int nb,
                             double *restrict pos);

/* out[p]: the particle whose cumulative-weight interval holds pos[p]; w, pos, out (nb,) */
void se_ancestors(const double *restrict w, const double *restrict pos, se_int nb,
                  se_int *restrict out);

/* RBPF of N trials over K samples with Np particles each.
 * Sizes: n states, m outputs, l inputs, L modes, Np particles, N trials, K samples, S the first
 * axis of the initial particles (1: shared by every trial, or N), T the first axis of the last
 * particles (0: not written, or N).
 * y (N, K, m), u (N, K, l), F (M, n, n), G (M, n, l), Qd (M, n, n), trans (K, L),
 * C (L, m, n), R (L, m, m), transition, log_transition (L, L), prob0, log_prob0 (L,),
 * keys (N,), x_init (S, Np, n), P_init (S, Np, n, n), mode_init (S, Np), logw_init (S, Np);
 * written: x_out (N, K, n), P_out (N, K, n, n), prob_out (N, K, L), mode_out (N, K),
 * loglik_out (N, K), flag_out (N, K), ess_out (N, K), x_last (T, Np, n),
 * P_last (T, Np, n, n), mode_last (T, Np), logw_last (T, Np), report (2,).
 * Returns SE_OK, the failure code of an innovation covariance, or SE_NO_MEMORY. */
/* the parameter list, written once for the prototype and the definition (rbpf.c) */
#define SE_PARTICLE_FILTER_PARAMETERS                                                             \
    se_int n, se_int m, se_int l, se_int L, se_int Np, se_int N, se_int K, se_int S, se_int T,    \
    const double *restrict y, const double *restrict u, const double *restrict F,                 \
    const double *restrict G, const double *restrict Qd, const se_int *restrict trans,            \
    const double *restrict C, const double *restrict R, const double *restrict transition,        \
    const double *restrict log_transition, const double *restrict prob0,                          \
    const double *restrict log_prob0, const uint64_t *restrict keys, se_int k0,                   \
    int predict_first, int sample_timing, int optimal, se_int scheme, double threshold,           \
    const double *restrict x_init, const double *restrict P_init,                                 \
    const se_int *restrict mode_init, const double *restrict logw_init,                           \
    double *restrict x_out, double *restrict P_out, double *restrict prob_out,                    \
    se_int *restrict mode_out, double *restrict loglik_out, uint8_t *restrict flag_out,           \
    double *restrict ess_out, double *restrict x_last, double *restrict P_last,                   \
    se_int *restrict mode_last, double *restrict logw_last, double *restrict report
se_int se_particle_filter(SE_PARTICLE_FILTER_PARAMETERS);

#endif
