# distutils: sources = src/switchest/engine/c/imm_ev1.c
"""Binding of the IMM extended-Viterbi kernel (engine/c/imm_ev1.c): Shankar et al.'s
Algorithm 1 with gridded switching times."""
cimport numpy as cnp
from ._common cimport uint8_t, fptr, iptr, u8ptr, se_int, start_binding
start_binding()

cdef extern from "imm_ev1.h":
    se_int se_viterbi_bank(se_int n, se_int m, se_int l, se_int L, se_int N, se_int K,
                           se_int g, const double *y, const double *u, const se_int *table,
                           const double *F, const double *G, const double *Qd,
                           const double *H, const double *Gy, const double *S0,
                           const double *tau, const double *C, const double *R,
                           const double *log_transition, double epsilon,
                           const double *x_init, const double *P_init,
                           const double *log_w_init, const se_int *chosen_init,
                           const double *offset_init, int predict_first, double gate,
                           int printed, int marginal, int by_path, int combined,
                           se_int lanes,
                           double *x_out, double *P_out, double *prob_out, se_int *mode_out,
                           double *offset_out, uint8_t *outlier_out, double *x_last,
                           double *P_last, double *log_w_last, se_int *chosen_last,
                           double *offset_last, double *report) nogil


def viterbi_bank(cnp.ndarray y, cnp.ndarray u, cnp.ndarray table, cnp.ndarray F,
                 cnp.ndarray G, cnp.ndarray Qd, cnp.ndarray H, cnp.ndarray Gy, cnp.ndarray S0,
                 cnp.ndarray tau, cnp.ndarray C, cnp.ndarray R, cnp.ndarray log_transition,
                 double epsilon, cnp.ndarray x_init, cnp.ndarray P_init,
                 cnp.ndarray log_w_init, cnp.ndarray chosen_init, cnp.ndarray offset_init,
                 bint predict_first, double gate, bint printed, bint marginal, bint by_path,
                 bint combined, se_int lanes, cnp.ndarray x_out, cnp.ndarray P_out, cnp.ndarray prob_out,
                 cnp.ndarray mode_out, cnp.ndarray offset_out, cnp.ndarray outlier_out,
                 cnp.ndarray x_last, cnp.ndarray P_last, cnp.ndarray log_w_last,
                 cnp.ndarray chosen_last, cnp.ndarray offset_last, cnp.ndarray report):
    """The IMM-EV1 over ``N`` trials and ``K`` samples (``se_viterbi_bank``; the shapes and
    argument order are in engine/c/imm_ev1.h, ``outlier_out`` uint8), the arrays checked and
    shaped by :mod:`switchest.engine.imm_ev1`; returns the status."""
    cdef se_int N = y.shape[0], K = y.shape[1], m = y.shape[2]
    cdef se_int L = x_init.shape[1], n = x_init.shape[2]
    cdef se_int l = u.shape[2], g = tau.shape[1]
    cdef se_int status
    with nogil:
        status = se_viterbi_bank(
            n, m, l, L, N, K, g, fptr(y), fptr(u), iptr(table), fptr(F), fptr(G), fptr(Qd),
            fptr(H), fptr(Gy), fptr(S0), fptr(tau), fptr(C), fptr(R), fptr(log_transition),
            epsilon, fptr(x_init), fptr(P_init), fptr(log_w_init), iptr(chosen_init),
            fptr(offset_init), predict_first, gate, printed, marginal, by_path, combined, lanes,
            fptr(x_out), fptr(P_out), fptr(prob_out), iptr(mode_out), fptr(offset_out),
            u8ptr(outlier_out), fptr(x_last), fptr(P_last), fptr(log_w_last),
            iptr(chosen_last), fptr(offset_last), fptr(report))
    return status
