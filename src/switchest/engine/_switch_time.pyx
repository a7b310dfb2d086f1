# distutils: sources = src/switchest/engine/c/switch_time.c
"""Binding of the switch-time Kalman kernel (engine/c/switch_time.c)."""
cimport numpy as cnp
from ._common cimport uint8_t, fptr, iptr, u8ptr, se_int, start_binding
start_binding()

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
    """The switch-time filter of N trials over K samples (``se_switch_time_filter``, the
    arguments in the order of engine/c/switch_time.h, ``outputs`` being the tuple
    ``(CF, CG, CQC)`` of :func:`switchest.engine.switch_time.coarse_outputs`), called by
    :func:`switchest.engine.switch_time.switch_time_run`; returns the status."""
    cdef cnp.ndarray CF = outputs[0], CG = outputs[1], CQC = outputs[2]
    cdef se_int N = y.shape[0], K = y.shape[1], m = y.shape[2]
    cdef se_int n = x_init.shape[1], l = u.shape[2], L = C.shape[0]
    cdef se_int D = grid_tau.shape[0], g = grid_tau.shape[1]
    if lanes < 1:
        raise ValueError(f"lanes must be at least 1, got {lanes}")
    cdef se_int status
    with nogil:
        status = se_switch_time_filter(
            n, m, l, L, N, K, D, g, fptr(y), fptr(u), iptr(which), iptr(mode), iptr(prev),
            fptr(C), fptr(R), fptr(F), fptr(G), fptr(Qd), fptr(steps), fptr(grid_tau),
            n_coarse, n_switch, fptr(x_init), fptr(P_init), predict_first, marginal, printed,
            gate, iterations, tolerance, fptr(CF), fptr(CG), fptr(CQC), lanes, fptr(x_out),
            fptr(P_out), fptr(loglik_out), fptr(offset_out), u8ptr(flag_out), fptr(report))
    return status
