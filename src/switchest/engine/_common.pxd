# Shared by the bindings. The raw data pointer of an array the Python wrapper has already
# checked (C-contiguous, writeable, of the kernel's dtype), after a constant-time re-check.
cimport numpy as cnp
from libc.stdint cimport int64_t, uint8_t


cdef extern from "se_common.h":
    ctypedef int64_t se_int


cdef inline double* fptr(cnp.ndarray a) except NULL:
    if cnp.PyArray_TYPE(a) != cnp.NPY_DOUBLE or not cnp.PyArray_ISCARRAY(a):
        raise TypeError("the engine takes C-contiguous writeable float64 arrays")
    return <double*>cnp.PyArray_DATA(a)


cdef inline int64_t* iptr(cnp.ndarray a) except NULL:
    if cnp.PyArray_TYPE(a) != cnp.NPY_INT64 or not cnp.PyArray_ISCARRAY(a):
        raise TypeError("the engine takes C-contiguous writeable int64 index arrays")
    return <int64_t*>cnp.PyArray_DATA(a)


cdef inline uint8_t* u8ptr(cnp.ndarray a) except NULL:
    if cnp.PyArray_TYPE(a) != cnp.NPY_UINT8 or not cnp.PyArray_ISCARRAY(a):
        raise TypeError("the engine takes C-contiguous writeable uint8 flag arrays")
    return <uint8_t*>cnp.PyArray_DATA(a)


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
