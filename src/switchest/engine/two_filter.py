"""The engine's backward pass of the two-filter smoother of a bank of mode-matched filters.

Backward information messages per mode, ``beta_i(k)(x) = p(y_{k+1..K-1} | x_k = x, r_k = i)``
kept as ``exp(c - x' Omega x / 2 + omega' x)``, built from the later measurements (step 1),
taken back through each mode's dynamics (step 2) and collapsed over the next mode by
log-linear pooling weighed by the evidence (step 3), then combined with the forward filter's
mode-matched posteriors by Bayes' rule (Helmick, Blair & Hoffman 1995, IEEE Trans. Inf. Theory
41(6), "Fixed-interval smoothing for Markovian switching systems"; Mayne 1966, Fraser & Potter
1969 for one mode). Every equation, numbered, is in the module docstring of
:mod:`switchest.estimators.two_filter`, the function that calls this one; each step's C
function (``measure_``, ``dynamics_``, ``pool_``, ``evidence_`` of ``engine/c/two_filter.c``)
repeats it beside its code.

The systems ``I + P Omega`` and ``I + Omega Qd`` (eigenvalues ``>= 1``, not symmetric) are
solved by an LU factorization with partial pivoting per lane (``se_lu``, ``se_lu_solve`` of
``engine/c/linalg.c``), the measurement's ``R`` over the observed components by the filters'
equilibrated Cholesky factorization (``se_innovation``). Trials are processed in blocks of
``lanes`` laid across SIMD lanes (``engine/c/linalg.h``); the results do not depend on the
block size nor on the thread count. The kernel (``se_two_filter_backward``) returns
``NOT_FINITE`` at the first smoothed posterior or mode probability that is not finite (its
outputs are then incomplete); this module checks the arrays, allocates the outputs and calls
the kernel through its binding (``engine/_backward.pyx``), over threads
(:func:`._parallel.run_split`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .._checks import check_timing, positive_int
from . import OK
from ._arrays import checked
from ._backward import two_filter_backward
from ._parallel import Reported, run_split

__all__ = ["LANES", "TwoFilterOutput", "two_filter_run"]

LANES = 64  # trials per block: the pass runs many short loops over the lanes per mode pair (LU
# steps, row exchanges), each with a fixed cost; on the vehicle (n = 4, L = 3) 16 lanes took 1.3
# times the time of 64, 32 lanes 1.03 times


@dataclass
class TwoFilterOutput(Reported):
    """The smoothed mode-matched posteriors of every trial and sample (:func:`two_filter_run`).

    Attributes
    ----------
    x_modes, P_modes : ndarray or None, shapes (N, K, L, n), (N, K, L, n, n)
        Smoothed mode-matched posteriors ``x_i(k|K)``, ``P_i(k|K)`` (None when not asked
        for).
    mode_prob : ndarray, shape (N, K, L)
        Smoothed mode probabilities ``mu_i(k|K)``.
    x, P : ndarray, shapes (N, K, n), (N, K, n, n)
        The moments of the smoothed mixture over the modes.
    mode : ndarray of int64, shape (N, K)
        The most probable smoothed mode (the first on a tie).
    status, repaired, smallest_eigenvalue
        The kernel's report (:class:`~switchest.engine.Reported`; nothing is repaired here).
    """

    x_modes: np.ndarray | None
    P_modes: np.ndarray | None
    mode_prob: np.ndarray
    x: np.ndarray
    P: np.ndarray
    mode: np.ndarray


def two_filter_run(x_modes, P_modes, mode_prob, y, u, F, G, Qd, trans, transition, C, R, *,
                   outlier=None, timing: str = "interval", lanes: int = LANES,
                   modes_out: bool = True) -> TwoFilterOutput:
    """The two-filter smoother's backward pass over ``N`` trials of ``K`` samples.

    Parameters
    ----------
    x_modes, P_modes : array_like, shapes (N, K, L, n), (N, K, L, n, n)
        The forward filter's mode-matched posteriors after each sample's update.
    mode_prob : array_like, shape (N, K, L)
        Its mode probabilities after each sample's update.
    y : array_like, shape (N, K, m)
        The measurements (NaN: a missing component).
    u : array_like, shape (N, K, l)
        Inputs, ``u[:, k]`` held over the interval into sample ``k + 1``.
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        Table of exact transitions.
    trans : array_like of int, shape (N or 1, K, L)
        ``trans[., k, j]``: the entry of mode ``j``'s transition into sample ``k`` (row 0
        unused; a first axis of length 1 is shared by every trial).
    transition : array_like, shape (L, L)
        ``transition[i, j]`` = P(mode j at k+1 | mode i at k).
    C, R : array_like, shapes (L, m, n), (L, m, m)
        Each mode's output matrix and measurement noise covariance.
    outlier : array_like of bool, shape (N, K), optional
        Samples the forward filter rejected (treated as missing).
    timing : {"sample", "interval"}
        Which mode governs the interval ``k -> k+1``: that of sample ``k`` or of ``k+1``.
    lanes : int
        Trials per SIMD block (the results do not depend on it).
    modes_out : bool
        Whether to report the smoothed mode-matched posteriors (``x_modes``, ``P_modes``;
        None otherwise, and their writing is saved).

    Returns
    -------
    TwoFilterOutput
        The smoothed posteriors and mode probabilities, and the kernel's status (``OK``, or
        ``NOT_FINITE`` where a result is not finite, ``NOT_POSITIVE_DEFINITE`` where an
        ``R`` is not).
    """
    timing = check_timing(timing)
    sizes: dict[str, int] = {}
    x_modes, P_modes, mode_prob, y, u, F, G, Qd, transition, C, R = checked(
        sizes, "x_modes:NKLn P_modes:NKLnn mode_prob:NKL y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn "
        "transition:LL C:Lmn R:Lmm", x_modes, P_modes, mode_prob, y, u, F, G, Qd, transition,
        C, R)
    (trans,) = checked(sizes, "trans:TKL<M", trans)
    N, K, L, n = x_modes.shape
    if sizes["T"] not in (1, N):
        raise ValueError(f"trans must have shape (N or 1, K, L) = ({N} or 1, {K}, {L}), "
                         f"got {trans.shape}")
    if outlier is None:
        flags = np.zeros((N, K), dtype=np.uint8)
    else:
        flags = np.asarray(outlier, dtype=bool)
        if flags.shape != (N, K):
            raise ValueError(f"outlier must have shape (N, K) = ({N}, {K}), got {flags.shape}")
        flags = np.ascontiguousarray(flags.view(np.uint8))
    with np.errstate(divide="ignore"):
        log_prob, log_transition = np.log(mode_prob), np.log(transition)
    lanes = positive_int(lanes, "lanes")
    size = (N, K, L) if modes_out else (0, K, L)  # zero trials: the kernel writes none
    out = TwoFilterOutput(np.empty((*size, n)), np.empty((*size, n, n)), np.empty((N, K, L)),
                          np.empty((N, K, n)), np.empty((N, K, n, n)),
                          np.empty((N, K), dtype=np.int64), status=OK)
    mine, shared = True, False  # per-trial arrays, sliced to each thread's trials; the rest
    # (trans of first axis 1 serves every trial; without modes_out the zero-trial x_modes)
    outcome = run_split(_backward, [
        (x_modes, mine), (P_modes, mine), (log_prob, mine), (y, mine), (u, mine),
        (flags, mine), (F, shared), (G, shared), (Qd, shared), (trans, len(trans) > 1),
        (log_transition, shared), (C, shared), (R, shared), (lanes, shared),
        (timing == "sample", shared), (out.x_modes, modes_out), (out.P_modes, modes_out),
        (out.mode_prob, mine), (out.x, mine), (out.P, mine), (out.mode, mine)],
        trials=N, samples=K, block=lanes)
    out = replace(out, **outcome._asdict())
    return out if modes_out else replace(out, x_modes=None, P_modes=None)


def _backward(x_f, P_f, log_prob_f, y, u, outlier, F, G, Qd, trans, log_transition, C, R,
              lanes, sample_timing, x_s, P_s, prob_s, x_c, P_c, mode_c, report):
    """:func:`._backward.two_filter_backward` with its report last, as
    :func:`._parallel.run_split` calls a kernel."""
    return two_filter_backward(x_f, P_f, log_prob_f, y, u, outlier, F, G, Qd, trans,
                               log_transition, C, R, lanes, sample_timing, x_s, P_s, prob_s,
                               x_c, P_c, mode_c, report)
