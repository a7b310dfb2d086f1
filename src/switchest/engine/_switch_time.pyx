# distutils: sources = src/switchest/engine/c/switch_time.c src/switchest/engine/c/linalg.c
"""Binding of the switch-time Kalman kernel (engine/c/switch_time.c)."""
cimport numpy as cnp
from libc.stdint cimport uint8_t
from ._common cimport fptr, iptr, u8ptr, se_int, use_lapack
cnp.import_array()
use_lapack()

cdef extern from "switch_time.h":
    se_int se_switch_time_filter(se_int n, se_int m, se_int l, se_int L, se_int N, se_int K,
                                 se_int D, se_int g, const double *y, const double *u,
                                 const se_int *which, const se_int *mode, const se_int *prev,
                                 const double *C, const double *R, const double *F,
                                 const double *G, const double *Qd, const double *steps,
                                 const double *grid_tau, se_int n_coarse, se_int n_switch,
                                 const double *x_init, const double *P_init, int predict_first,
                                 int marginal, int printed, double gate, se_int iterations,
                                 double tolerance, const double *CF, const double *CG,
                                 const double *CQC, se_int lanes, double *x_out, double *P_out,
                                 double *loglik_out, double *offset_out, uint8_t *flag_out,
                                 double *report) nogil


def switch_time_filter(cnp.ndarray y, cnp.ndarray u, cnp.ndarray which, cnp.ndarray mode,
                       cnp.ndarray prev, cnp.ndarray C, cnp.ndarray R, cnp.ndarray F,
                       cnp.ndarray G, cnp.ndarray Qd, cnp.ndarray steps, cnp.ndarray grid_tau,
                       se_int n_coarse, se_int n_switch, cnp.ndarray x_init, cnp.ndarray P_init,
                       bint predict_first, bint marginal, bint printed, double gate,
                       se_int iterations, double tolerance, tuple outputs, se_int lanes,
                       cnp.ndarray x_out, cnp.ndarray P_out, cnp.ndarray loglik_out,
                       cnp.ndarray offset_out, cnp.ndarray flag_out, cnp.ndarray report):
    """The switch-time filter of N trials over K samples (the numba kernel
    ``switch_time_filter`` of ``_compiled/switch_time.py``, same arguments); returns the
    status."""
    cdef cnp.ndarray CF = outputs[0], CG = outputs[1], CQC = outputs[2]
    cdef se_int N = y.shape[0], K = y.shape[1], m = y.shape[2]
    cdef se_int n = x_init.shape[1], l = u.shape[2], L = C.shape[0]
    cdef se_int D = grid_tau.shape[0], g = grid_tau.shape[1]
    cdef const double* py = fptr(y)
    cdef const double* pu = fptr(u)
    cdef const se_int* pwhich = iptr(which)
    cdef const se_int* pmode = iptr(mode)
    cdef const se_int* pprev = iptr(prev)
    cdef const double* pC = fptr(C)
    cdef const double* pR = fptr(R)
    cdef const double* pF = fptr(F)
    cdef const double* pG = fptr(G)
    cdef const double* pQd = fptr(Qd)
    cdef const double* psteps = fptr(steps)
    cdef const double* pgrid = fptr(grid_tau)
    cdef const double* px0 = fptr(x_init)
    cdef const double* pP0 = fptr(P_init)
    cdef const double* pCF = fptr(CF)
    cdef const double* pCG = fptr(CG)
    cdef const double* pCQC = fptr(CQC)
    cdef double* px = fptr(x_out)
    cdef double* pP = fptr(P_out)
    cdef double* pll = fptr(loglik_out)
    cdef double* poff = fptr(offset_out)
    cdef uint8_t* pflag = u8ptr(flag_out)
    cdef double* prep = fptr(report)
    cdef se_int status
    if lanes < 1:
        raise ValueError(f"lanes must be at least 1, got {lanes}")
    with nogil:
        status = se_switch_time_filter(n, m, l, L, N, K, D, g, py, pu, pwhich, pmode, pprev,
                                       pC, pR, pF, pG, pQd, psteps, pgrid, n_coarse, n_switch,
                                       px0, pP0, predict_first, marginal, printed, gate,
                                       iterations, tolerance, pCF, pCG, pCQC, lanes, px, pP,
                                       pll, poff, pflag, prep)
    return status
