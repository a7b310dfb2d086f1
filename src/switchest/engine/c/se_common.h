/* The conventions every kernel of switchest's engine keeps.
 *
 * Arrays are C-contiguous float64 (int64 indices, uint8 flags) of the shapes the Python
 * wrappers (the modules of src/switchest/engine) document; a block of trials lies across the *last*
 * axis, the lanes, so that the innermost loops run over trials on SIMD registers. Sizes and
 * indices are 64-bit (32-bit indices ran the lane-blocked prediction twice as slow).
 *
 * Kernels never raise: they return a status code (SE_OK or the failure that stopped them) and
 * the binding raises the package's error for it. A kernel that repairs covariances adds to a
 * report {count, smallest eigenvalue seen} that the caller turns into a warning.
 */
#ifndef SE_COMMON_H
#define SE_COMMON_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#if defined(__unix__) || defined(__APPLE__)
#include <sys/mman.h>
#define SE_HAVE_MMAP 1
#endif

typedef int64_t se_int;

/* status codes a kernel returns */
enum {
    SE_OK = 0,
    SE_NOT_POSITIVE_DEFINITE = 1, /* an innovation covariance failed its Cholesky factorization */
    SE_NOT_FINITE = 2,            /* an innovation covariance holds an infinity or NaN */
    SE_NO_MEMORY = 3              /* the kernel's scratch space could not be allocated */
};

/* per-sample flags a kernel writes */
enum {
    SE_ACCEPTED = 0,    /* updated (or nothing observed) */
    SE_GATED = 1,       /* an outlier or a gated measurement: treated as missing */
    SE_PARTLY_GATED = 2 /* multiple-model filters: some modes gated the measurement */
};

/* The lane-block iteration of every kernel: N trials in blocks of B = se_lanes(lanes, N) lanes
 * (min(lanes, N), at least 1: one block either way when lanes >= N; the results do not depend
 * on it), the block at trial i0 being nb = se_block_trials(B, N, i0) trials wide:
 *
 *     for (se_int i0 = 0; i0 < N; i0 += B) {
 *         const se_int nb = se_block_trials(B, N, i0);
 */
static inline se_int se_lanes(se_int lanes, se_int N)
{
    return lanes < 1 ? 1 : (lanes < N ? lanes : (N > 0 ? N : 1));
}

static inline se_int se_block_trials(se_int B, se_int N, se_int i0)
{
    return B < N - i0 ? B : N - i0;
}

/* A kernel's report of covariance repairs {count, smallest eigenvalue seen}, before any. */
static inline void se_report_start(double *report)
{
    report[0] = 0.0;
    report[1] = INFINITY;
}

/* A kernel's scratch: ONE zeroed block of memory carved into its arrays, each rounded up to
 * 64 bytes so that every array starts on a cache line. A kernel carves its arrays twice with
 * the same calls: a first pass with base NULL only adds up the size (se_carve returns NULL),
 * se_arena_open then allocates a zeroed block of that size and asks for the second pass, which
 * carves it; the kernel closes the arena before it returns:
 *
 *     se_arena ar = {NULL, 0};
 *     do {
 *         SE_DOUBLES(&ar, n * B, &x, &xs);
 *         ...
 *     } while (se_arena_open(&ar));
 *     if (ar.base == NULL)
 *         return SE_NO_MEMORY;
 *     ...
 *     se_arena_close(&ar);
 *
 * A block of SE_MAPPED_BYTES or more is mapped from the system (mmap, zeroed pages) and
 * unmapped at the close, not taken from malloc's heap: glibc raises its mmap threshold to the
 * size of the largest block freed, so later blocks of that size came from the heap, between
 * the Python objects allocated from call to call, and the freed blocks were not reused (a fit
 * that filters hundreds of candidate models, each call's scratch a few hundred KiB, grew by
 * about 1 MiB per call to 450 MiB). */
typedef struct {
    char *base;
    size_t used;
    size_t mapped; /* the size of a mapped block, 0 for one from aligned_alloc */
} se_arena;

#define SE_MAPPED_BYTES ((size_t)1 << 18)

static inline void *se_carve(se_arena *arena, se_int count, size_t size)
{
    size_t bytes = ((size_t)count * size + 63) & ~(size_t)63;
    void *p = arena->base ? (void *)(arena->base + arena->used) : NULL;
    arena->used += bytes;
    return p;
}

/* Carve several arrays of one size: SE_DOUBLES(&ar, n * B, &x, &xs) points x and xs at arrays
 * of n * B doubles, in that order (SE_INTS and SE_FLAGS likewise). */
#define SE_CARVE_EACH(type, arena, count, ...)                                                \
    do {                                                                                      \
        type *restrict *const se_out_[] = {__VA_ARGS__};                                      \
        for (size_t se_i_ = 0; se_i_ < sizeof se_out_ / sizeof se_out_[0]; se_i_++)           \
            *se_out_[se_i_] = (type *)se_carve((arena), (count), sizeof(type));               \
    } while (0)
#define SE_DOUBLES(arena, count, ...) SE_CARVE_EACH(double, arena, count, __VA_ARGS__)
#define SE_INTS(arena, count, ...) SE_CARVE_EACH(se_int, arena, count, __VA_ARGS__)
#define SE_FLAGS(arena, count, ...) SE_CARVE_EACH(uint8_t, arena, count, __VA_ARGS__)

/* After the counting pass: allocate the zeroed block and return 1 (carve it now); after the
 * carving pass, or if the allocation failed (ar.base stays NULL), return 0. */
static inline int se_arena_open(se_arena *arena)
{
    if (arena->base != NULL)
        return 0;
    size_t bytes = arena->used ? arena->used : 64;
    arena->used = 0;
#ifdef SE_HAVE_MMAP
    if (bytes >= SE_MAPPED_BYTES) {
        void *block = mmap(NULL, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (block == MAP_FAILED)
            return 0;
        arena->base = (char *)block; /* page aligned, zeroed by the system */
        arena->mapped = bytes;
        return 1;
    }
#endif
    arena->base = (char *)aligned_alloc(64, bytes);
    if (arena->base == NULL)
        return 0;
    memset(arena->base, 0, bytes);
    return 1;
}

/* Release the arena's block (either kind; nothing if none was allocated). */
static inline void se_arena_close(se_arena *arena)
{
#ifdef SE_HAVE_MMAP
    if (arena->mapped) {
        munmap(arena->base, arena->mapped);
        arena->mapped = 0;
        arena->base = NULL;
        return;
    }
#endif
    free(arena->base);
    arena->base = NULL;
}

#endif
