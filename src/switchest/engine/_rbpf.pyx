# distutils: sources = src/switchest/engine/c/rbpf.c
"""Binding of the Rao-Blackwellized particle filter (engine/c/rbpf.c): the kernel
``particle_filter`` and the counter-based random stream (``uniform``, ``trial_keys``,
``resampling_positions``, ``ancestors``), whose streams are fixed bit for bit (engine/c/rbpf.c
documents the arithmetic)."""
cimport numpy as cnp
from libc.stdint cimport uint8_t, uint64_t
from ._common cimport fptr, iptr, u8ptr, kptr, se_int, start_binding
import numpy as np
start_binding()

cdef extern from "rbpf.h":
    double se_uniform(uint64_t key, se_int k, se_int j) nogil
    void se_trial_keys(se_int count, uint64_t root, uint64_t *keys) nogil
    void se_resampling_positions(uint64_t key, se_int k, se_int scheme, se_int nb,
                                 double *pos) nogil
    void se_ancestors(const double *w, const double *pos, se_int nb, se_int *out) nogil
    se_int se_particle_filter(se_int n, se_int m, se_int l, se_int L, se_int Np, se_int N,
                              se_int K, se_int S, se_int T, const double *y, const double *u,
                              const double *F, const double *G, const double *Qd,
                              const se_int *trans, const double *C, const double *R,
                              const double *transition, const double *log_transition,
                              const double *prob0, const double *log_prob0,
                              const uint64_t *keys, se_int k0, int predict_first,
                              int sample_timing, int optimal, se_int scheme, double threshold,
                              const double *x_init, const double *P_init,
                              const se_int *mode_init, const double *logw_init, double *x_out,
                              double *P_out, double *prob_out, se_int *mode_out,
                              double *loglik_out, uint8_t *flag_out, double *ess_out,
                              double *x_last, double *P_last, se_int *mode_last,
                              double *logw_last, double *report) nogil


cdef inline int shaped(cnp.ndarray a, str name, tuple shape) except -1:
    """Raise unless ``a`` has exactly ``shape`` (the kernel indexes without bounds checks)."""
    cdef int d
    if a.ndim != len(shape):
        raise ValueError(f"{name} must have shape {shape}, got {(<object>a).shape}")
    for d in range(a.ndim):
        if a.shape[d] != shape[d]:
            raise ValueError(f"{name} must have shape {shape}, got {(<object>a).shape}")
    return 0


def uniform(uint64_t key, se_int k, se_int j):
    """Uniform ``j`` of sample ``k`` of the trial with ``key``, in ``[0, 1)``: the top 53 bits
    of ``stream(stream(key, k), j)``, the sample's own SplitMix64 sequence."""
    return se_uniform(key, k, j)


def trial_keys(uint64_t root, se_int count):
    """The keys of trials ``0 .. count-1`` derived from a ``root`` key (uint64): element ``i`` of
    the SplitMix64 sequence started at ``root`` (Steele, Lea & Flood 2014, §3)."""
    cdef cnp.ndarray keys = np.empty(count, dtype=np.uint64)
    cdef uint64_t *pk = <uint64_t*>cnp.PyArray_DATA(keys)
    with nogil:
        se_trial_keys(count, root, pk)
    return keys


def resampling_positions(uint64_t key, se_int k, se_int scheme, se_int nb, cnp.ndarray pos):
    """The ``nb`` sorted positions in ``[0, 1]`` of a resampling at sample ``k``, from uniforms
    ``nb .. 2 nb - 1`` (Douc, Cappé & Moulines 2005, "Comparison of resampling schemes for
    particle filtering", §2): systematic ``(p + U) / nb`` with one ``U``; stratified
    ``(p + U_p) / nb``; multinomial the ``U_p`` sorted. Written into ``pos[:nb]``."""
    cdef double *pp = fptr(pos)
    if pos.ndim != 1 or nb < 0 or pos.shape[0] < nb:
        raise ValueError(f"pos must be a vector of at least nb = {nb} entries, got {(<object>pos).shape}")
    with nogil:
        se_resampling_positions(key, k, scheme, nb, pp)


def ancestors(cnp.ndarray w, cnp.ndarray pos, se_int nb, cnp.ndarray out):
    """``out[p]``: the particle whose cumulative-weight interval holds position ``pos[p]``
    (sorted, in ``[0, 1]``), the first ``j`` with ``w_0 + .. + w_j > pos[p] sum(w)``, at most the
    last positive weight: the inversion every resampling scheme shares (Douc, Cappé & Moulines
    2005, §2), merged in one pass over the sorted positions."""
    cdef double *pw = fptr(w)
    cdef double *pp = fptr(pos)
    cdef se_int *po = iptr(out)
    for name, a in (("w", w), ("pos", pos), ("out", out)):
        if a.ndim != 1 or nb < 0 or a.shape[0] < nb:
            raise ValueError(f"{name} must be a vector of at least nb = {nb} entries, "
                             f"got {(<object>a).shape}")
    with nogil:
        se_ancestors(pw, pp, nb, po)


def particle_filter(cnp.ndarray y, cnp.ndarray u, cnp.ndarray F, cnp.ndarray G,
                    cnp.ndarray Qd, cnp.ndarray trans, cnp.ndarray C, cnp.ndarray R,
                    cnp.ndarray transition, cnp.ndarray log_transition, cnp.ndarray prob0,
                    cnp.ndarray log_prob0, cnp.ndarray keys, se_int k0, bint predict_first,
                    bint sample_timing, bint optimal, se_int scheme, double threshold,
                    cnp.ndarray x_init, cnp.ndarray P_init, cnp.ndarray mode_init,
                    cnp.ndarray logw_init, cnp.ndarray x_out, cnp.ndarray P_out,
                    cnp.ndarray prob_out, cnp.ndarray mode_out, cnp.ndarray loglik_out,
                    cnp.ndarray flag_out, cnp.ndarray ess_out, cnp.ndarray x_last,
                    cnp.ndarray P_last, cnp.ndarray mode_last, cnp.ndarray logw_last,
                    cnp.ndarray report):
    """Filter ``N`` trials over ``K`` samples with ``Np`` particles each (the kernel of
    :mod:`switchest.engine.rbpf`; arguments and outputs in the order and shapes of
    engine/c/rbpf.h, sizes read from the shapes, which are checked). Returns the status."""
    if y.ndim != 3 or u.ndim != 3 or x_init.ndim != 3 or C.ndim != 3 or F.ndim != 3:
        raise ValueError("y, u, x_init, C and F must have three axes")
    cdef se_int N = y.shape[0], K = y.shape[1], m = y.shape[2]
    cdef se_int S = x_init.shape[0], Np = x_init.shape[1], n = x_init.shape[2]
    cdef se_int L = C.shape[0], l = u.shape[2], M = F.shape[0], T = x_last.shape[0]
    if S != 1 and S != N:
        raise ValueError(f"x_init must have 1 or N = {N} rows, got {S}")
    if T != 0 and T != N:
        raise ValueError(f"x_last must have 0 or N = {N} rows, got {T}")
    for name, a, shape in (
            ("u", u, (N, K, l)), ("F", F, (M, n, n)), ("G", G, (M, n, l)), ("Qd", Qd, (M, n, n)),
            ("trans", trans, (K, L)), ("C", C, (L, m, n)), ("R", R, (L, m, m)),
            ("transition", transition, (L, L)), ("log_transition", log_transition, (L, L)),
            ("prob0", prob0, (L,)), ("log_prob0", log_prob0, (L,)), ("keys", keys, (N,)),
            ("P_init", P_init, (S, Np, n, n)), ("mode_init", mode_init, (S, Np)),
            ("logw_init", logw_init, (S, Np)), ("x_out", x_out, (N, K, n)),
            ("P_out", P_out, (N, K, n, n)), ("prob_out", prob_out, (N, K, L)),
            ("mode_out", mode_out, (N, K)), ("loglik_out", loglik_out, (N, K)),
            ("flag_out", flag_out, (N, K)), ("ess_out", ess_out, (N, K)),
            ("x_last", x_last, (T, Np, n)), ("P_last", P_last, (T, Np, n, n)),
            ("mode_last", mode_last, (T, Np)), ("logw_last", logw_last, (T, Np)),
            ("report", report, (2,))):
        shaped(a, name, shape)
    if K > 0 and L == 0:
        raise ValueError("particle_filter needs at least one mode")
    cdef se_int status
    with nogil:
        status = se_particle_filter(
            n, m, l, L, Np, N, K, S, T, fptr(y), fptr(u), fptr(F), fptr(G), fptr(Qd),
            iptr(trans), fptr(C), fptr(R), fptr(transition), fptr(log_transition),
            fptr(prob0), fptr(log_prob0), kptr(keys), k0, predict_first, sample_timing,
            optimal, scheme, threshold, fptr(x_init), fptr(P_init), iptr(mode_init),
            fptr(logw_init), fptr(x_out), fptr(P_out), fptr(prob_out), iptr(mode_out),
            fptr(loglik_out), u8ptr(flag_out), fptr(ess_out), fptr(x_last), fptr(P_last),
            iptr(mode_last), fptr(logw_last), fptr(report))
    return status
