# Shared by the bindings. The raw data pointer of an array the Python wrapper has already
# checked (C-contiguous, of the kernel's dtype), after a constant-time re-check. The helpers
# run without the GIL (they read the array's header only; a failed check takes the GIL to
# raise), so a binding passes `fptr(y)` straight into its kernel's call in its `with nogil`
# block instead of naming a pointer per array.
cimport numpy as cnp
from libc.stdint cimport int64_t, uint8_t, uint64_t


cdef extern from "se_common.h":
    ctypedef int64_t se_int
    enum:
        SE_NO_MEMORY


cdef inline int _check(bint ok, str what) except -1 nogil:
    if not ok:
        with gil:
            raise TypeError(f"the engine takes C-contiguous {what} arrays")
    return 0


cdef inline double* fptr(cnp.ndarray a) except NULL nogil:
    """A writeable float64 array."""
    _check(cnp.PyArray_TYPE(a) == cnp.NPY_DOUBLE and cnp.PyArray_ISCARRAY(a), "writeable float64")
    return <double*>cnp.PyArray_DATA(a)


cdef inline const double* cfptr(cnp.ndarray a) except NULL nogil:
    """A float64 array only read (it may be read-only)."""
    _check(cnp.PyArray_TYPE(a) == cnp.NPY_DOUBLE and cnp.PyArray_ISCARRAY_RO(a), "float64")
    return <const double*>cnp.PyArray_DATA(a)


cdef inline int64_t* iptr(cnp.ndarray a) except NULL nogil:
    """A writeable int64 index array."""
    _check(cnp.PyArray_TYPE(a) == cnp.NPY_INT64 and cnp.PyArray_ISCARRAY(a),
           "writeable int64 index")
    return <int64_t*>cnp.PyArray_DATA(a)


cdef inline uint8_t* u8ptr(cnp.ndarray a) except NULL nogil:
    """A writeable uint8 flag array."""
    _check(cnp.PyArray_TYPE(a) == cnp.NPY_UINT8 and cnp.PyArray_ISCARRAY(a),
           "writeable uint8 flag")
    return <uint8_t*>cnp.PyArray_DATA(a)


cdef inline uint8_t* bptr(cnp.ndarray a) except NULL nogil:
    """A writeable bool (or uint8) flag array."""
    cdef int t = cnp.PyArray_TYPE(a)
    _check((t == cnp.NPY_BOOL or t == cnp.NPY_UINT8) and cnp.PyArray_ISCARRAY(a),
           "writeable bool flag")
    return <uint8_t*>cnp.PyArray_DATA(a)


cdef inline const uint64_t* kptr(cnp.ndarray a) except NULL nogil:
    """A uint64 key array only read."""
    _check(cnp.PyArray_TYPE(a) == cnp.NPY_UINT64 and cnp.PyArray_ISCARRAY_RO(a), "uint64 key")
    return <const uint64_t*>cnp.PyArray_DATA(a)


cdef inline int no_memory(se_int status, str kernel) except -1:
    """Raise MemoryError for a kernel's SE_NO_MEMORY (its scratch could not be allocated)."""
    if status == SE_NO_MEMORY:
        raise MemoryError(f"{kernel}: the kernel's scratch space could not be allocated")
    return 0


# The outputs of the bank kernels (c/bank.h: se_filter_bank, se_gpb2_bank), gathered for them.
cdef extern from "bank.h":
    ctypedef struct se_bank_out:
        se_int K
        int modes_wanted
        double *x
        double *P
        double *prob
        se_int *mode
        double *loglik
        uint8_t *flag
        double *x_modes
        double *P_modes
        double *x_last
        double *P_last
        double *log_prob_last


# What the bank bindings (_bank.pyx) hand their kernel besides its inputs: the sizes,
# the outputs and the report.
cdef struct bank_call:
    se_int n, m, l, L, N, K
    se_bank_out out
    double *report


cdef inline bank_call bank_arguments(se_int lanes, cnp.ndarray y, cnp.ndarray u,
                                     cnp.ndarray x_init, tuple outputs) except *:
    """The sizes of a bank kernel's call, read from y (N, K, m), u (N, K, l) and
    x_init (N, L, n), and the arguments after its inputs, ``outputs``: x_out, P_out, prob_out,
    mode_out, loglik_out, flag_out, x_modes_out, P_modes_out, x_last, P_last, log_prob_last
    (se_bank_out's, c/bank.h) and the report (2,), as the C kernels take them. The mode-matched
    posteriors are written if x_modes_out has a row per trial (zero-size arrays otherwise).
    Raises ValueError unless ``lanes`` is positive."""
    if lanes < 1:
        raise ValueError(f"lanes must be a positive int, got {lanes}")
    cdef cnp.ndarray x_out, P_out, prob_out, mode_out, loglik_out, flag_out, x_modes_out
    cdef cnp.ndarray P_modes_out, x_last, P_last, log_prob_last, report
    (x_out, P_out, prob_out, mode_out, loglik_out, flag_out, x_modes_out, P_modes_out, x_last,
     P_last, log_prob_last, report) = outputs
    cdef bank_call c
    c.N, c.K, c.m = y.shape[0], y.shape[1], y.shape[2]
    c.L, c.n, c.l = x_init.shape[1], x_init.shape[2], u.shape[2]
    c.out.K = c.K
    c.out.modes_wanted = x_modes_out.shape[0] == c.N
    c.out.x, c.out.P, c.out.prob = fptr(x_out), fptr(P_out), fptr(prob_out)
    c.out.mode, c.out.loglik, c.out.flag = iptr(mode_out), fptr(loglik_out), u8ptr(flag_out)
    c.out.x_modes, c.out.P_modes = fptr(x_modes_out), fptr(P_modes_out)
    c.out.x_last, c.out.P_last = fptr(x_last), fptr(P_last)
    c.out.log_prob_last, c.report = fptr(log_prob_last), fptr(report)
    return c


# LAPACK for the rare eigendecompositions of a covariance repair (c/linalg.c, se_repair): the
# dsyevd that scipy ships, handed to this module's copy of linalg.c. Every binding calls
# use_lapack() once, at import.
from scipy.linalg.cython_lapack cimport dsyevd as _dsyevd


cdef extern from "linalg.h":
    ctypedef void se_dsyevd_fn(char *jobz, char *uplo, int *n, double *a, int *lda, double *w,
                               double *work, int *lwork, int *iwork, int *liwork,
                               int *info) noexcept nogil
    void se_use_dsyevd(se_dsyevd_fn *dsyevd) noexcept nogil


cdef inline void use_lapack() noexcept:
    se_use_dsyevd(<se_dsyevd_fn *>_dsyevd)


cdef inline int start_binding() except -1:
    """What every binding does once, at import: numpy's C API for this module, and LAPACK for
    its copy of linalg.c (use_lapack)."""
    cnp.import_array()
    use_lapack()
    return 0


cdef inline int shaped(cnp.ndarray a, int ndim, se_int s0, se_int s1, se_int s2, se_int s3,
                       se_int s4, str kernel) except -1:
    """Raise ValueError unless ``a`` has ``ndim`` axes of the sizes given (-1: any), naming
    the ``kernel`` whose arrays disagree."""
    cdef se_int want[5]
    cdef int d
    want[0] = s0
    want[1] = s1
    want[2] = s2
    want[3] = s3
    want[4] = s4
    if cnp.PyArray_NDIM(a) != ndim:
        raise ValueError(f"{kernel}'s arrays do not agree in shape")
    for d in range(ndim):
        if want[d] >= 0 and a.shape[d] != want[d]:
            raise ValueError(f"{kernel}'s arrays do not agree in shape")
    return 0
