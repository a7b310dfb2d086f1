# distutils: sources = src/switchest/engine/c/smoother.c src/switchest/engine/c/two_filter.c
"""Binding of the smoothers' backward passes: Kim's and the covariance screen
(engine/c/smoother.c), the two-filter smoother's (engine/c/two_filter.c)."""
cimport numpy as cnp
from ._common cimport uint8_t, fptr, cfptr, iptr, bptr, se_int, no_memory, shaped, start_binding
start_binding()

cdef extern from "smoother.h":
    se_int se_kim_backward(se_int n, se_int l, se_int L, se_int N, se_int K, se_int T,
                           se_int TK, se_int Ns, se_int J, const double *x_f,
                           const double *P_f, const double *log_prob_f, const double *u,
                           const double *F, const double *G, const double *Qd,
                           const se_int *trans, const double *log_transition, se_int lanes,
                           int sample_timing, double *x_out, double *P_out, double *prob_out,
                           se_int *mode_out, double *x_s, double *P_s, double *report,
                           int lagged, double *pair_out, double *lag_x, double *lag_P,
                           double *lag_cross) nogil
    se_int se_screen_psd(se_int M, se_int n, const double *A, double relative_shift,
                         double *sym, uint8_t *failed, double *scale, double *asym) nogil

cdef extern from "two_filter.h":
    se_int se_two_filter_backward(se_int n, se_int m, se_int l, se_int L, se_int N, se_int K,
                                  se_int T, se_int TK, se_int Ns, const double *x_f,
                                  const double *P_f, const double *log_prob_f, const double *y,
                                  const double *u, const uint8_t *outlier, const double *F,
                                  const double *G, const double *Qd, const se_int *trans,
                                  const double *log_transition, const double *C,
                                  const double *R, se_int lanes, int sample_timing,
                                  double *x_s, double *P_s, double *prob_s, double *x_c,
                                  double *P_c, se_int *mode_c, double *report) nogil


_KIM = "the smoother"  # named when its arrays disagree in shape
_TWO_FILTER = "the two-filter smoother"  # likewise


cdef tuple forward_shapes(cnp.ndarray x_f, cnp.ndarray P_f, cnp.ndarray log_prob_f,
                          cnp.ndarray u, cnp.ndarray F, cnp.ndarray G, cnp.ndarray Qd,
                          cnp.ndarray trans, cnp.ndarray log_transition, str what):
    """Check what both backward passes read of the forward filter and the model: the filtered
    posteriors x_f (N, K, L, n), P_f, log_prob_f, the inputs u (N, K, l), the transitions F, G,
    Qd (M, ...), their table trans (T, TK, L) and log_transition (L, L); returns
    ``(N, K, L, n, l, M, T, TK)``."""
    shaped(x_f, 4, -1, -1, -1, -1, -1, what)
    cdef se_int N = x_f.shape[0], K = x_f.shape[1], L = x_f.shape[2], n = x_f.shape[3]
    shaped(P_f, 5, N, K, L, n, n, what)
    shaped(log_prob_f, 3, N, K, L, -1, -1, what)
    shaped(u, 3, N, K, -1, -1, -1, what)
    shaped(F, 3, -1, n, n, -1, -1, what)
    cdef se_int l = u.shape[2], M = F.shape[0]
    shaped(G, 3, M, n, l, -1, -1, what)
    shaped(Qd, 3, M, n, n, -1, -1, what)
    shaped(trans, 3, -1, K, L, -1, -1, what)
    shaped(log_transition, 2, L, L, -1, -1, -1, what)
    return N, K, L, n, l, M, trans.shape[0], trans.shape[1]


def kim_backward(cnp.ndarray x_f, cnp.ndarray P_f, cnp.ndarray log_prob_f, cnp.ndarray u,
                 cnp.ndarray F, cnp.ndarray G, cnp.ndarray Qd, cnp.ndarray trans,
                 cnp.ndarray log_transition, se_int lanes, bint sample_timing,
                 cnp.ndarray x_out, cnp.ndarray P_out, cnp.ndarray prob_out,
                 cnp.ndarray mode_out, cnp.ndarray x_s, cnp.ndarray P_s, cnp.ndarray report,
                 bint lagged, cnp.ndarray pair_out, cnp.ndarray lag_x, cnp.ndarray lag_P,
                 cnp.ndarray lag_cross):
    """The backward recursion over every trial, in blocks of ``lanes`` trials (the arguments of
    ``se_kim_backward``, engine/c/smoother.h, checked by
    :func:`switchest.engine.smoother.kim_smooth`); returns the status code (``MemoryError`` if
    the scratch cannot be allocated)."""
    cdef se_int N, K, L, n, l, M, T, TK
    N, K, L, n, l, M, T, TK = forward_shapes(x_f, P_f, log_prob_f, u, F, G, Qd, trans,
                                             log_transition, _KIM)
    shaped(x_s, 4, -1, K, L, n, -1, _KIM)
    cdef se_int Ns = x_s.shape[0]
    shaped(pair_out, 4, N, -1, L, L, -1, _KIM)
    cdef se_int J = pair_out.shape[1]
    shaped(x_out, 3, N, K, n, -1, -1, _KIM)
    shaped(P_out, 4, N, K, n, n, -1, _KIM)
    shaped(prob_out, 3, N, K, L, -1, -1, _KIM)
    shaped(mode_out, 2, N, K, -1, -1, -1, _KIM)
    shaped(P_s, 5, Ns, K, L, n, n, _KIM)
    shaped(report, 1, 2, -1, -1, -1, -1, _KIM)
    shaped(lag_x, 4, N, J, L, n, -1, _KIM)
    shaped(lag_P, 5, N, J, L, n, n, _KIM)
    shaped(lag_cross, 5, N, J, L, n, n, _KIM)
    if (T != 1 and T != N) or (Ns != 0 and Ns != N) or (lagged and J != K - 1) or lanes < 1:
        raise ValueError("the smoother's arrays do not agree in shape")
    cdef se_int status
    with nogil:
        status = se_kim_backward(
            n, l, L, N, K, T, TK, Ns, J, fptr(x_f), fptr(P_f), fptr(log_prob_f), fptr(u),
            fptr(F), fptr(G), fptr(Qd), iptr(trans), fptr(log_transition), lanes,
            sample_timing, fptr(x_out), fptr(P_out), fptr(prob_out), iptr(mode_out),
            fptr(x_s), fptr(P_s), fptr(report), lagged, fptr(pair_out), fptr(lag_x),
            fptr(lag_P), fptr(lag_cross))
    no_memory(status, "kim_backward")  # SE_NO_MEMORY (no scratch) raises MemoryError
    return status


def screen_psd(cnp.ndarray A, double relative_shift, cnp.ndarray sym, cnp.ndarray failed):
    """Symmetrize a stack ``A (M, n, n)`` into ``sym`` and mark in ``failed (M,)`` the
    matrices whose Cholesky factorization shifted by ``relative_shift max |A|`` fails (engine
    C; :func:`switchest.engine.smoother.screen_psd`); returns ``(scale, max |A - A'|)``."""
    shaped(A, 3, -1, -1, -1, -1, -1, _KIM)
    cdef se_int M = A.shape[0], n = A.shape[1]
    shaped(A, 3, M, n, n, -1, -1, _KIM)
    shaped(sym, 3, M, n, n, -1, -1, _KIM)
    shaped(failed, 1, M, -1, -1, -1, -1, _KIM)
    cdef double scale = 0.0, asym = 0.0
    cdef se_int status
    with nogil:
        status = se_screen_psd(M, n, cfptr(A), relative_shift, fptr(sym), bptr(failed), &scale,
                               &asym)
    no_memory(status, "screen_psd")
    return scale, asym


def two_filter_backward(cnp.ndarray x_f, cnp.ndarray P_f, cnp.ndarray log_prob_f,
                        cnp.ndarray y, cnp.ndarray u, cnp.ndarray outlier, cnp.ndarray F,
                        cnp.ndarray G, cnp.ndarray Qd, cnp.ndarray trans,
                        cnp.ndarray log_transition, cnp.ndarray C, cnp.ndarray R,
                        se_int lanes, bint sample_timing, cnp.ndarray x_s, cnp.ndarray P_s,
                        cnp.ndarray prob_s, cnp.ndarray x_c, cnp.ndarray P_c,
                        cnp.ndarray mode_c, cnp.ndarray report):
    """The backward recursion over every trial, in blocks of ``lanes`` trials (the arguments of
    ``se_two_filter_backward``, engine/c/two_filter.h, checked by
    :func:`switchest.engine.two_filter.two_filter_run`); returns the status code
    (``MemoryError`` if the scratch cannot be allocated)."""
    cdef se_int N, K, L, n, l, M, T, TK
    N, K, L, n, l, M, T, TK = forward_shapes(x_f, P_f, log_prob_f, u, F, G, Qd, trans,
                                             log_transition, _TWO_FILTER)
    shaped(y, 3, N, K, -1, -1, -1, _TWO_FILTER)
    cdef se_int m = y.shape[2]
    shaped(outlier, 2, N, K, -1, -1, -1, _TWO_FILTER)
    shaped(C, 3, L, m, n, -1, -1, _TWO_FILTER)
    shaped(R, 3, L, m, m, -1, -1, _TWO_FILTER)
    shaped(x_s, 4, -1, K, L, n, -1, _TWO_FILTER)
    cdef se_int Ns = x_s.shape[0]
    shaped(P_s, 5, Ns, K, L, n, n, _TWO_FILTER)
    shaped(prob_s, 3, N, K, L, -1, -1, _TWO_FILTER)
    shaped(x_c, 3, N, K, n, -1, -1, _TWO_FILTER)
    shaped(P_c, 4, N, K, n, n, -1, _TWO_FILTER)
    shaped(mode_c, 2, N, K, -1, -1, -1, _TWO_FILTER)
    shaped(report, 1, 2, -1, -1, -1, -1, _TWO_FILTER)
    if (T != 1 and T != N) or (Ns != 0 and Ns != N) or lanes < 1:
        raise ValueError("the two-filter smoother's arrays do not agree in shape")
    cdef se_int status
    with nogil:
        status = se_two_filter_backward(
            n, m, l, L, N, K, T, TK, Ns, cfptr(x_f), cfptr(P_f), cfptr(log_prob_f), cfptr(y),
            cfptr(u), bptr(outlier), cfptr(F), cfptr(G), cfptr(Qd), iptr(trans),
            cfptr(log_transition), cfptr(C), cfptr(R), lanes, sample_timing, fptr(x_s),
            fptr(P_s), fptr(prob_s), fptr(x_c), fptr(P_c), iptr(mode_c), fptr(report))
    no_memory(status, "two_filter_backward")  # SE_NO_MEMORY (no scratch) raises MemoryError
    return status
