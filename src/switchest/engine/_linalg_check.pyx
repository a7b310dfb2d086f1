# distutils: sources = src/switchest/engine/c/linalg.c
"""TEMPORARY binding of engine/c/linalg.c, function by function, for
tests/engine/test_linalg_against_numba.py (compared against _compiled/linalg.py). Each wrapper
takes the numba function's arguments and reads the sizes from the arrays' shapes; boolean
arrays are passed as uint8 views. Deleted with the numba code."""
cimport numpy as cnp
from libc.stdint cimport uint8_t
from ._common cimport fptr, iptr, u8ptr, se_int, use_lapack
cnp.import_array()
use_lapack()

cdef extern from "linalg.h":
    void se_gather_samples(se_int m, se_int B, se_int K, const double *data, se_int i0, se_int nb, se_int k, double *out) nogil
    void se_gather_rows(se_int q, se_int B, se_int K, const double *data, se_int i0, se_int nb, double *out) nogil
    void se_gather_rows_int(se_int q, se_int B, se_int K, const se_int *data, se_int i0, se_int nb, se_int *out) nogil
    void se_scatter_rows(se_int q, se_int B, se_int K, const double *src, se_int i0, se_int nb, double *data) nogil
    void se_scatter_rows_int(se_int q, se_int B, se_int K, const se_int *src, se_int i0, se_int nb, se_int *data) nogil
    void se_gather_modes(se_int n, se_int L, se_int B, se_int K, const double *x_init, const double *P_init, se_int i0, se_int nb, double *x, double *P) nogil
    void se_scatter_modes(se_int n, se_int L, se_int B, se_int K, const double *x, const double *P, se_int i0, se_int nb, double *x_last, double *P_last) nogil
    void se_write_lane(se_int n, se_int B, se_int K, const double *x, const double *P, se_int b, se_int i, se_int k, double *x_out, double *P_out) nogil
    void se_gather_matrices(se_int p, se_int q, se_int B, const double *table, const se_int *index, se_int nb, double *out) nogil
    void se_observe(se_int m, se_int B, const double *y, se_int nb, double *obs, double *n_obs) nogil
    void se_predict_mean(se_int n, se_int l, se_int B, double *x, const double *F, const double *G, const double *u, se_int nb, double *xs) nogil
    void se_predict(se_int n, se_int l, se_int B, double *x, double *P, const double *F, const double *G, const double *u, const double *Qd, se_int nb, double *FP, double *xs) nogil
    void se_copy_gaussian(se_int n, se_int B, const double *x, const double *P, se_int nb, double *x_to, double *P_to) nogil
    void se_copy_lanes(se_int p, se_int q, se_int B, const double *source, se_int nb, double *out) nogil
    void se_symmetric_sum(se_int n, se_int q, se_int B, const double *base, const double *X, const double *Y, se_int nb, double *out) nogil
    void se_residual(se_int n, se_int m, se_int B, const double *x, const double *y, const double *C, se_int nb, double *e) nogil
    void se_observed_residual(se_int n, se_int m, se_int B, const double *x, const double *y, const double *C, const double *obs, se_int nb, double *e) nogil
    void se_whiten(se_int m, se_int B, const double *e, const double *chol, const double *scale, se_int nb, double *z, double *nis) nogil
    se_int se_innovation(se_int n, se_int m, se_int B, const double *x, double *P, const double *y, const double *C, const double *R, const double *obs, const double *n_obs, se_int nb, double *e, double *PCt, double *chol, double *scale, double *z, double *nis, double *loglik, double *work, uint8_t *bad, double *report) nogil
    int se_factor(se_int m, se_int B, double *chol, double *scale, se_int nb, double *det, double *pivot, int *positive) nogil
    void se_innovation_mean(se_int n, se_int m, se_int B, const double *x, const double *y, const double *C, const double *obs, const double *n_obs, const double *chol, const double *scale, const double *log_det, se_int nb, double *e, double *z, double *nis, double *loglik) nogil
    void se_solve(se_int m, se_int B, const double *chol, const double *scale, double *v, se_int nb) nogil
    void se_solve_rows(se_int m, se_int B, se_int q, const double *chol, const double *scale, double *V, se_int nb, double *inv) nogil
    void se_back_substitute(se_int m, se_int B, const double *chol, const double *scale, double *v, se_int nb) nogil
    void se_correct(se_int n, se_int m, se_int B, double *x, double *P, const double *C, const double *R, const uint8_t *use, se_int nb, const double *PCt, const double *chol, const double *scale, double *z, double *K, double *T, double *AP, double *prior) nogil
    void se_correct_mean(se_int n, se_int m, se_int B, double *x, double *z, const double *PCt, const double *chol, const double *scale, const uint8_t *use, se_int nb) nogil
    int se_joseph_lost(se_int n, se_int B, const double *P, const double *prior, const uint8_t *use, se_int nb, double *root, uint8_t *lost) nogil
    void se_information_or_repair(se_int n, se_int m, se_int B, double *P, const double *prior, const double *C, const double *R, const double *obs, const double *n_obs, const uint8_t *lost, se_int nb, double *report) nogil
    int se_cholesky(se_int n, const double *A, double *out) nogil
    void se_forward(se_int m, se_int q, const double *Lo, double *Bm) nogil
    int se_information_form(se_int n, se_int m, se_int B, double *P, const double *prior, const double *C, const double *R, const double *obs, se_int b) nogil
    int se_repair(se_int n, se_int B, double *P, se_int b, int indefinite_only, double *report) nogil
    void se_log_normalize(se_int L, se_int B, double *a, double *prob, double *total, se_int nb) nogil
    void se_mix(se_int n, se_int L, se_int B, double *x, double *P, const double *prob, const double *log_prob, const double *transition, const double *log_transition, se_int nb, double *log_c, double *w, double *xm, double *Pm) nogil
    void se_predicted_mode_probabilities(se_int L, se_int B, const double *prob, const double *log_prob, const double *transition, const double *log_transition, se_int nb, double *log_c, double *w) nogil
    void se_collapse(se_int n, se_int L, se_int B, double *x, double *P, const double *prob, const double *log_prob, const double *transition, const double *log_transition, se_int nb, double *log_c, double *w, double *xm, double *Pm) nogil
    void se_merge(se_int n, se_int L, se_int B, const double *w, const double *x, const double *P, se_int nb, double *xm, double *Pm) nogil
    void se_write_modes(se_int n, se_int L, se_int B, se_int K, const double *x, const double *P, se_int b, se_int i, se_int k, double *x_out, double *P_out) nogil
    double se_log_weights(se_int L, se_int B, const double *log_prob, const double *log_transition, se_int j, se_int b, double *w) nogil
    void se_moments(se_int n, se_int L, se_int B, const double *w, const double *x, const double *P, se_int nb, double *xm, double *Pm) nogil
    void se_combine(se_int n, se_int L, se_int B, const double *x, const double *P, const double *prob, const double *log_prob, se_int nb, double *xc, double *Pc, se_int *best) nogil
    void se_lane_index(se_int L, se_int N, se_int K, const se_int *index, se_int i0, se_int nb, se_int k, se_int j, se_int *out) nogil


def gather_samples(cnp.ndarray data, se_int i0, se_int nb, se_int k, cnp.ndarray out):
    se_gather_samples(out.shape[0], out.shape[1], data.shape[1], fptr(data), i0, nb, k, fptr(out))

def gather_rows(cnp.ndarray data, se_int i0, se_int nb, cnp.ndarray out):
    se_gather_rows(data.shape[1], out.shape[1], 1, fptr(data), i0, nb, fptr(out))

def gather_rows_at(cnp.ndarray data, se_int k, se_int i0, se_int nb, cnp.ndarray out):
    """gather_rows(data[:, k], ...) of data (N, K, q)"""
    se_gather_rows(data.shape[2], out.shape[1], data.shape[1], fptr(data) + k * data.shape[2], i0, nb, fptr(out))

def gather_rows_int(cnp.ndarray data, se_int i0, se_int nb, cnp.ndarray out):
    se_gather_rows_int(data.shape[1], out.shape[1], 1, iptr(data), i0, nb, iptr(out))

def scatter_rows(cnp.ndarray src, se_int i0, se_int nb, cnp.ndarray data):
    se_scatter_rows(data.shape[1], src.shape[1], 1, fptr(src), i0, nb, fptr(data))

def scatter_rows_at(cnp.ndarray src, se_int i0, se_int nb, cnp.ndarray data, se_int k):
    """scatter_rows(src, ..., data[:, k]) of data (N, K, q)"""
    se_scatter_rows(data.shape[2], src.shape[1], data.shape[1], fptr(src), i0, nb, fptr(data) + k * data.shape[2])

def scatter_rows_int(cnp.ndarray src, se_int i0, se_int nb, cnp.ndarray data):
    se_scatter_rows_int(data.shape[1], src.shape[1], 1, iptr(src), i0, nb, iptr(data))

def gather_modes(cnp.ndarray x_init, cnp.ndarray P_init, se_int i0, se_int nb, cnp.ndarray x, cnp.ndarray P):
    se_gather_modes(x.shape[1], x.shape[0], x.shape[2], 1, fptr(x_init), fptr(P_init), i0, nb, fptr(x), fptr(P))

def gather_modes_at(cnp.ndarray x_f, cnp.ndarray P_f, se_int k, se_int i0, se_int nb, cnp.ndarray x, cnp.ndarray P):
    """gather_modes(x_f[:, k], P_f[:, k], ...) of x_f (N, K, L, n)"""
    cdef se_int L = x.shape[0], n = x.shape[1]
    se_gather_modes(n, L, x.shape[2], x_f.shape[1], fptr(x_f) + k * L * n, fptr(P_f) + k * L * n * n, i0, nb, fptr(x), fptr(P))

def scatter_modes(cnp.ndarray x, cnp.ndarray P, se_int i0, se_int nb, cnp.ndarray x_last, cnp.ndarray P_last):
    se_scatter_modes(x.shape[1], x.shape[0], x.shape[2], 1, fptr(x), fptr(P), i0, nb, fptr(x_last), fptr(P_last))

def scatter_modes_at(cnp.ndarray x, cnp.ndarray P, se_int i0, se_int nb, cnp.ndarray x_s, cnp.ndarray P_s, se_int k):
    cdef se_int L = x.shape[0], n = x.shape[1]
    se_scatter_modes(n, L, x.shape[2], x_s.shape[1], fptr(x), fptr(P), i0, nb, fptr(x_s) + k * L * n, fptr(P_s) + k * L * n * n)

def write_lane(cnp.ndarray x, cnp.ndarray P, se_int b, se_int i, se_int k, cnp.ndarray x_out, cnp.ndarray P_out):
    se_write_lane(x.shape[0], x.shape[1], x_out.shape[1], fptr(x), fptr(P), b, i, k, fptr(x_out), fptr(P_out))

def gather_matrices(cnp.ndarray table, cnp.ndarray index, se_int nb, cnp.ndarray out):
    se_gather_matrices(out.shape[0], out.shape[1], out.shape[2], fptr(table), iptr(index), nb, fptr(out))

def observe(cnp.ndarray y, se_int nb, cnp.ndarray obs, cnp.ndarray n_obs):
    se_observe(y.shape[0], y.shape[1], fptr(y), nb, fptr(obs), fptr(n_obs))

def predict_mean(cnp.ndarray x, cnp.ndarray F, cnp.ndarray G, cnp.ndarray u, se_int nb, cnp.ndarray xs):
    se_predict_mean(x.shape[0], u.shape[0], x.shape[1], fptr(x), fptr(F), fptr(G), fptr(u), nb, fptr(xs))

def predict(cnp.ndarray x, cnp.ndarray P, cnp.ndarray F, cnp.ndarray G, cnp.ndarray u, cnp.ndarray Qd, se_int nb, cnp.ndarray FP, cnp.ndarray xs):
    se_predict(x.shape[0], u.shape[0], x.shape[1], fptr(x), fptr(P), fptr(F), fptr(G), fptr(u), fptr(Qd), nb, fptr(FP), fptr(xs))

def copy_gaussian(cnp.ndarray x, cnp.ndarray P, se_int nb, cnp.ndarray x_to, cnp.ndarray P_to):
    se_copy_gaussian(x.shape[0], x.shape[1], fptr(x), fptr(P), nb, fptr(x_to), fptr(P_to))

def copy_lanes(cnp.ndarray source, se_int nb, cnp.ndarray out):
    se_copy_lanes(source.shape[0], source.shape[1], source.shape[2], fptr(source), nb, fptr(out))

def symmetric_sum(cnp.ndarray base, cnp.ndarray X, cnp.ndarray Y, se_int nb, cnp.ndarray out):
    se_symmetric_sum(X.shape[0], X.shape[1], X.shape[2], fptr(base), fptr(X), fptr(Y), nb, fptr(out))

def residual(cnp.ndarray x, cnp.ndarray y, cnp.ndarray C, se_int nb, cnp.ndarray e):
    se_residual(C.shape[1], C.shape[0], C.shape[2], fptr(x), fptr(y), fptr(C), nb, fptr(e))

def observed_residual(cnp.ndarray x, cnp.ndarray y, cnp.ndarray C, cnp.ndarray obs, se_int nb, cnp.ndarray e):
    se_observed_residual(C.shape[1], C.shape[0], C.shape[2], fptr(x), fptr(y), fptr(C), fptr(obs), nb, fptr(e))

def whiten(cnp.ndarray e, cnp.ndarray chol, cnp.ndarray scale, se_int nb, cnp.ndarray z, cnp.ndarray nis):
    se_whiten(e.shape[0], e.shape[1], fptr(e), fptr(chol), fptr(scale), nb, fptr(z), fptr(nis))

def innovation(cnp.ndarray x, cnp.ndarray P, cnp.ndarray y, cnp.ndarray C, cnp.ndarray R, cnp.ndarray obs, cnp.ndarray n_obs, se_int nb, cnp.ndarray e, cnp.ndarray PCt, cnp.ndarray chol, cnp.ndarray scale, cnp.ndarray z, cnp.ndarray nis, cnp.ndarray loglik, cnp.ndarray work, cnp.ndarray bad, cnp.ndarray report=None):
    cdef double *rep = NULL
    if report is not None:
        rep = fptr(report)
    return se_innovation(x.shape[0], y.shape[0], x.shape[1], fptr(x), fptr(P), fptr(y), fptr(C), fptr(R), fptr(obs), fptr(n_obs), nb, fptr(e), fptr(PCt), fptr(chol), fptr(scale), fptr(z), fptr(nis), fptr(loglik), fptr(work), u8ptr(bad), rep)

def factor(cnp.ndarray chol, cnp.ndarray scale, se_int nb, cnp.ndarray det, cnp.ndarray pivot):
    cdef int positive = -1
    cdef int finite = se_factor(chol.shape[0], chol.shape[2], fptr(chol), fptr(scale), nb, fptr(det), fptr(pivot), &positive)
    return bool(finite), bool(positive)

def innovation_mean(cnp.ndarray x, cnp.ndarray y, cnp.ndarray C, cnp.ndarray obs, cnp.ndarray n_obs, cnp.ndarray chol, cnp.ndarray scale, cnp.ndarray log_det, se_int nb, cnp.ndarray e, cnp.ndarray z, cnp.ndarray nis, cnp.ndarray loglik):
    se_innovation_mean(x.shape[0], y.shape[0], x.shape[1], fptr(x), fptr(y), fptr(C), fptr(obs), fptr(n_obs), fptr(chol), fptr(scale), fptr(log_det), nb, fptr(e), fptr(z), fptr(nis), fptr(loglik))

def solve(cnp.ndarray chol, cnp.ndarray scale, cnp.ndarray v, se_int nb):
    se_solve(v.shape[0], v.shape[1], fptr(chol), fptr(scale), fptr(v), nb)

def solve_rows(cnp.ndarray chol, cnp.ndarray scale, cnp.ndarray V, se_int nb, cnp.ndarray inv):
    se_solve_rows(V.shape[1], V.shape[2], V.shape[0], fptr(chol), fptr(scale), fptr(V), nb, fptr(inv))

def back_substitute(cnp.ndarray chol, cnp.ndarray scale, cnp.ndarray v, se_int nb):
    se_back_substitute(v.shape[0], v.shape[1], fptr(chol), fptr(scale), fptr(v), nb)

def correct(cnp.ndarray x, cnp.ndarray P, cnp.ndarray C, cnp.ndarray R, cnp.ndarray use, se_int nb, cnp.ndarray PCt, cnp.ndarray chol, cnp.ndarray scale, cnp.ndarray z, cnp.ndarray K, cnp.ndarray T, cnp.ndarray AP, cnp.ndarray prior):
    se_correct(x.shape[0], z.shape[0], x.shape[1], fptr(x), fptr(P), fptr(C), fptr(R), u8ptr(use), nb, fptr(PCt), fptr(chol), fptr(scale), fptr(z), fptr(K), fptr(T), fptr(AP), fptr(prior))

def correct_mean(cnp.ndarray x, cnp.ndarray z, cnp.ndarray PCt, cnp.ndarray chol, cnp.ndarray scale, cnp.ndarray use, se_int nb):
    se_correct_mean(x.shape[0], z.shape[0], x.shape[1], fptr(x), fptr(z), fptr(PCt), fptr(chol), fptr(scale), u8ptr(use), nb)

def joseph_lost(cnp.ndarray P, cnp.ndarray prior, cnp.ndarray use, se_int nb, cnp.ndarray root, cnp.ndarray lost):
    return bool(se_joseph_lost(P.shape[0], P.shape[2], fptr(P), fptr(prior), u8ptr(use), nb, fptr(root), u8ptr(lost)))

def information_or_repair(cnp.ndarray P, cnp.ndarray prior, cnp.ndarray C, cnp.ndarray R, cnp.ndarray obs, cnp.ndarray n_obs, cnp.ndarray lost, se_int nb, cnp.ndarray report):
    se_information_or_repair(P.shape[0], C.shape[0], P.shape[2], fptr(P), fptr(prior), fptr(C), fptr(R), fptr(obs), fptr(n_obs), u8ptr(lost), nb, fptr(report))

def cholesky(cnp.ndarray A, cnp.ndarray out):
    return bool(se_cholesky(A.shape[0], fptr(A), fptr(out)))

def forward(cnp.ndarray Lo, cnp.ndarray Bm):
    se_forward(Lo.shape[0], Bm.shape[1], fptr(Lo), fptr(Bm))

def information_form(cnp.ndarray P, cnp.ndarray prior, cnp.ndarray C, cnp.ndarray R, cnp.ndarray obs, se_int b):
    return bool(se_information_form(P.shape[0], C.shape[0], P.shape[2], fptr(P), fptr(prior), fptr(C), fptr(R), fptr(obs), b))

def repair(cnp.ndarray P, se_int b, bint indefinite_only, cnp.ndarray report):
    return bool(se_repair(P.shape[0], P.shape[2], fptr(P), b, indefinite_only, fptr(report)))

def log_normalize(cnp.ndarray a, cnp.ndarray prob, cnp.ndarray total, se_int nb):
    se_log_normalize(a.shape[0], a.shape[1], fptr(a), fptr(prob), fptr(total), nb)

def mix(cnp.ndarray x, cnp.ndarray P, cnp.ndarray prob, cnp.ndarray log_prob, cnp.ndarray transition, cnp.ndarray log_transition, se_int nb, cnp.ndarray log_c, cnp.ndarray w, cnp.ndarray xm, cnp.ndarray Pm):
    se_mix(x.shape[1], x.shape[0], x.shape[2], fptr(x), fptr(P), fptr(prob), fptr(log_prob), fptr(transition), fptr(log_transition), nb, fptr(log_c), fptr(w), fptr(xm), fptr(Pm))

def predicted_mode_probabilities(cnp.ndarray prob, cnp.ndarray log_prob, cnp.ndarray transition, cnp.ndarray log_transition, se_int nb, cnp.ndarray log_c, cnp.ndarray w):
    se_predicted_mode_probabilities(prob.shape[0], prob.shape[1], fptr(prob), fptr(log_prob), fptr(transition), fptr(log_transition), nb, fptr(log_c), fptr(w))

def collapse(cnp.ndarray x, cnp.ndarray P, cnp.ndarray prob, cnp.ndarray log_prob, cnp.ndarray transition, cnp.ndarray log_transition, se_int nb, cnp.ndarray log_c, cnp.ndarray w, cnp.ndarray xm, cnp.ndarray Pm):
    se_collapse(x.shape[1], x.shape[0], x.shape[2], fptr(x), fptr(P), fptr(prob), fptr(log_prob), fptr(transition), fptr(log_transition), nb, fptr(log_c), fptr(w), fptr(xm), fptr(Pm))

def merge(cnp.ndarray w, cnp.ndarray x, cnp.ndarray P, se_int nb, cnp.ndarray xm, cnp.ndarray Pm):
    se_merge(x.shape[1], x.shape[0], x.shape[2], fptr(w), fptr(x), fptr(P), nb, fptr(xm), fptr(Pm))

def write_modes(cnp.ndarray x, cnp.ndarray P, se_int b, se_int i, se_int k, cnp.ndarray x_out, cnp.ndarray P_out):
    se_write_modes(x.shape[1], x.shape[0], x.shape[2], x_out.shape[1], fptr(x), fptr(P), b, i, k, fptr(x_out), fptr(P_out))

def log_weights(cnp.ndarray log_prob, cnp.ndarray log_transition, se_int j, se_int b, cnp.ndarray w):
    return se_log_weights(w.shape[0], w.shape[1], fptr(log_prob), fptr(log_transition), j, b, fptr(w))

def moments(cnp.ndarray w, cnp.ndarray x, cnp.ndarray P, se_int nb, cnp.ndarray xm, cnp.ndarray Pm):
    se_moments(x.shape[1], x.shape[0], x.shape[2], fptr(w), fptr(x), fptr(P), nb, fptr(xm), fptr(Pm))

def combine(cnp.ndarray x, cnp.ndarray P, cnp.ndarray prob, cnp.ndarray log_prob, se_int nb, cnp.ndarray xc, cnp.ndarray Pc, cnp.ndarray best):
    se_combine(x.shape[1], x.shape[0], x.shape[2], fptr(x), fptr(P), fptr(prob), fptr(log_prob), nb, fptr(xc), fptr(Pc), iptr(best))

def lane_index(cnp.ndarray index, se_int i0, se_int nb, se_int k, se_int j, cnp.ndarray out):
    se_lane_index(index.shape[2], index.shape[0], index.shape[1], iptr(index), i0, nb, k, j, iptr(out))
