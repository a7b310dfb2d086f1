# distutils: sources = src/switchest/engine/c/kalman.c
"""Binding of the Kalman kernels (engine/c/kalman.c): the filter along given transitions, whose
trials share their covariance in groups, and the fixed-gain filter.

Each function takes the arguments of its C kernel in the kernel's order (the shapes are in
engine/c/kalman.h), arrays already checked and converted by the wrapper
(:mod:`switchest.engine.kalman`: :func:`~switchest.engine.kalman.kalman_run`,
:func:`~switchest.engine.kalman.kalman_steady_run` and their ``_step`` variants), reads the
sizes from their shapes and runs the kernel without the GIL.
"""
cimport numpy as cnp
from ._common cimport uint8_t, fptr, iptr, u8ptr, se_int, start_binding
start_binding()

cdef extern from "kalman.h":
    enum:
        SE_KALMAN_LANES
        SE_KALMAN_CHUNK
    se_int se_kalman_filter(se_int n, se_int m, se_int l, se_int N, se_int K,
                            const double *y, const double *u, const double *F,
                            const double *G, const double *Qd, const se_int *trans,
                            const double *C, const double *R, const se_int *mode,
                            const double *x_init, const double *P_init, int predict_first,
                            double gate, se_int lanes, double *x_out, double *P_out,
                            double *loglik_out, uint8_t *flag_out, double *report) nogil
    se_int se_steady_filter(se_int n, se_int m, se_int l, se_int L, se_int N, se_int K,
                            const double *y, const double *u, const double *F,
                            const double *G, const se_int *trans, const double *C,
                            const se_int *mode, const double *gain, const double *P_prior,
                            const double *P_post, const double *whiten, const double *x_init,
                            int predict_first, double gate, se_int lanes, double *x_out,
                            double *P_out, double *loglik_out, uint8_t *flag_out) nogil

LANES = SE_KALMAN_LANES  # trials per block: a group's covariance equations serve up to this many
CHUNK = SE_KALMAN_CHUNK  # samples buffered per block before they are written out, trial by trial


def kalman_filter(cnp.ndarray y, cnp.ndarray u, cnp.ndarray F, cnp.ndarray G, cnp.ndarray Qd,
                  cnp.ndarray trans, cnp.ndarray C, cnp.ndarray R, cnp.ndarray mode,
                  cnp.ndarray x_init, cnp.ndarray P_init, bint predict_first, double gate,
                  se_int lanes, cnp.ndarray x_out, cnp.ndarray P_out, cnp.ndarray loglik_out,
                  cnp.ndarray flag_out, cnp.ndarray report):
    """Kalman filter of ``N`` trials over ``K`` samples (se_kalman_filter); returns the
    status. Shapes: y (N, K, m), u (N, K, l), F, G, Qd (M, n, n), (M, n, l), (M, n, n),
    trans, mode (N, K) int64, C (L, m, n), R (L, m, m), x_init (N, n), P_init (N, n, n);
    written: x_out (N, K, n), P_out (N, K, n, n), loglik_out, flag_out (N, K), report (2,)."""
    cdef se_int N = y.shape[0], K = y.shape[1], m = y.shape[2]
    cdef se_int n = x_init.shape[1], l = u.shape[2]
    cdef se_int status
    with nogil:
        status = se_kalman_filter(
            n, m, l, N, K, fptr(y), fptr(u), fptr(F), fptr(G), fptr(Qd), iptr(trans),
            fptr(C), fptr(R), iptr(mode), fptr(x_init), fptr(P_init), predict_first, gate,
            lanes, fptr(x_out), fptr(P_out), fptr(loglik_out), u8ptr(flag_out), fptr(report))
    return status


def steady_filter(cnp.ndarray y, cnp.ndarray u, cnp.ndarray F, cnp.ndarray G,
                  cnp.ndarray trans, cnp.ndarray C, cnp.ndarray mode, cnp.ndarray gain,
                  cnp.ndarray P_prior, cnp.ndarray P_post, cnp.ndarray whiten,
                  cnp.ndarray x_init, bint predict_first, double gate, se_int lanes,
                  cnp.ndarray x_out, cnp.ndarray P_out, cnp.ndarray loglik_out,
                  cnp.ndarray flag_out):
    """Fixed-gain filter of every trial (se_steady_filter); returns the status (``OK``, or
    ``NO_MEMORY`` if its scratch cannot be allocated). Shapes: y (N, K, m), u (N, K, l),
    F (M, n, n), G (M, n, l), trans, mode (N, K) int64, C (L, m, n), gain (L, n, m),
    P_prior, P_post (L, n, n), whiten (L, m, m), x_init (N, n); written: x_out (N, K, n),
    P_out (N, K, n, n), loglik_out (N, K) (NaN), flag_out (N, K)."""
    cdef se_int N = y.shape[0], K = y.shape[1], m = y.shape[2]
    cdef se_int n = x_init.shape[1], l = u.shape[2], L = P_prior.shape[0]
    cdef se_int status
    with nogil:
        status = se_steady_filter(
            n, m, l, L, N, K, fptr(y), fptr(u), fptr(F), fptr(G), iptr(trans), fptr(C),
            iptr(mode), fptr(gain), fptr(P_prior), fptr(P_post), fptr(whiten), fptr(x_init),
            predict_first, gate, lanes, fptr(x_out), fptr(P_out), fptr(loglik_out),
            u8ptr(flag_out))
    return status
