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

#include <stdint.h>
#include <stddef.h>

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

#endif
