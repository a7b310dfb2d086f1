# Shared by the bindings: the raw data pointer of an array the Python wrapper has already
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
