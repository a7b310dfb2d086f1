# distutils: sources = src/switchest/engine/c/gpb.c src/switchest/engine/c/bank.c src/switchest/engine/c/linalg.c
"""Binding of GPB2 (engine/c/gpb.c): :func:`gpb2_bank`, with the arguments of the numba kernel
it replaces (``switchest.estimators._compiled.gpb.gpb2_bank``)."""
cimport numpy as cnp
from libc.stdint cimport uint8_t
from ._common cimport fptr, iptr, u8ptr, se_int, use_lapack
cnp.import_array()
use_lapack()

cdef extern from "gpb.h":
    se_int se_gpb2_bank(se_int n, se_int m, se_int l, se_int L, se_int N, se_int K,
                        se_int trans_N, se_int trans_K, se_int modes_N, const double *y,
                        const double *u, const double *F, const double *G, const double *Qd,
                        const se_int *trans, const double *C, const double *R,
                        const double *log_transition, const double *x_init,
                        const double *P_init, const double *log_prob_init, int sample_timing,
                        int predict_first, double gate, se_int lanes, double *x_out,
                        double *P_out, double *prob_out, se_int *mode_out,
                        double *loglik_out, uint8_t *flag_out, double *x_modes_out,
                        double *P_modes_out, double *x_last, double *P_last,
                        double *log_prob_last, double *report) nogil

cdef enum:
    SE_NO_MEMORY = 3


def gpb2_bank(cnp.ndarray y, cnp.ndarray u, cnp.ndarray F, cnp.ndarray G, cnp.ndarray Qd,
              cnp.ndarray trans, cnp.ndarray C, cnp.ndarray R, cnp.ndarray log_transition,
              cnp.ndarray x_init, cnp.ndarray P_init, cnp.ndarray log_prob_init,
              bint sample_timing, bint predict_first, double gate, se_int lanes,
              cnp.ndarray x_out, cnp.ndarray P_out, cnp.ndarray prob_out,
              cnp.ndarray mode_out, cnp.ndarray loglik_out, cnp.ndarray flag_out,
              cnp.ndarray x_modes_out, cnp.ndarray P_modes_out, cnp.ndarray x_last,
              cnp.ndarray P_last, cnp.ndarray log_prob_last, cnp.ndarray report):
    """:func:`switchest.estimators._compiled.gpb.gpb2_bank` in C: the same arguments (checked
    by the caller), the same outputs written, the same status returned."""
    if lanes < 1:
        raise ValueError(f"lanes must be a positive int, got {lanes}")
    cdef se_int N = y.shape[0], K = y.shape[1], m = y.shape[2]
    cdef se_int L = x_init.shape[1], n = x_init.shape[2], l = u.shape[2]
    cdef se_int trans_N = trans.shape[0], trans_K = trans.shape[1]
    cdef se_int modes_N = x_modes_out.shape[0]
    cdef const double *py = fptr(y)
    cdef const double *pu = fptr(u)
    cdef const double *pF = fptr(F)
    cdef const double *pG = fptr(G)
    cdef const double *pQd = fptr(Qd)
    cdef const se_int *ptrans = iptr(trans)
    cdef const double *pC = fptr(C)
    cdef const double *pR = fptr(R)
    cdef const double *plt = fptr(log_transition)
    cdef const double *px0 = fptr(x_init)
    cdef const double *pP0 = fptr(P_init)
    cdef const double *plp0 = fptr(log_prob_init)
    cdef double *px = fptr(x_out)
    cdef double *pP = fptr(P_out)
    cdef double *pprob = fptr(prob_out)
    cdef se_int *pmode = iptr(mode_out)
    cdef double *pll = fptr(loglik_out)
    cdef uint8_t *pflag = u8ptr(flag_out)
    cdef double *pxm = fptr(x_modes_out)
    cdef double *pPm = fptr(P_modes_out)
    cdef double *pxl = fptr(x_last)
    cdef double *pPl = fptr(P_last)
    cdef double *plpl = fptr(log_prob_last)
    cdef double *prep = fptr(report)
    cdef se_int status
    cdef int st = sample_timing, pf = predict_first
    with nogil:
        status = se_gpb2_bank(n, m, l, L, N, K, trans_N, trans_K, modes_N, py, pu, pF, pG,
                              pQd, ptrans, pC, pR, plt, px0, pP0, plp0, st, pf, gate, lanes,
                              px, pP, pprob, pmode, pll, pflag, pxm, pPm, pxl, pPl, plpl,
                              prep)
    if status == SE_NO_MEMORY:
        raise MemoryError("the GPB2 kernel's scratch space could not be allocated")
    return status
