"""The Rao-Blackwellized particle filter for jump-Markov linear systems (engine: the kernel in
``c/rbpf.c`` behind :mod:`._rbpf`).

Each particle carries a mode and the Kalman filter ``(x, P)`` conditional on its mode history
(Doucet, de Freitas, Murphy & Russell 2000, §3; Doucet, Gordon & Krishnamurthy 2001, §III).
The particles of one trial are laid across the SIMD lanes of ``c/linalg.c`` (``x (n, Np)``,
``P (n, n, Np)``), so that the Kalman equations run there, once for all particles; the kernel
loops over trials and samples. ``rbpf_run`` filters whole records, ``rbpf_step`` one sample of
every trial (the streaming API); both call the kernel :func:`particle_filter`.

Randomness is counter-based (Salmon, Moraes, Dror & Shaw 2011, "Parallel random numbers: as
easy as 1, 2, 3"): uniform ``j`` of sample ``k`` of a trial is a pure function of the trial's
64-bit ``key``, ``k`` and ``j`` (:func:`uniform`), so a trial's result depends on its key alone
(not on the batch it ran in), and a streaming step needs nothing but the key and the sample
index to continue. At sample ``k``, uniforms ``0 .. Np-1`` draw the particles' modes and
``Np .. 2 Np - 1`` the resampling positions.

Convention of switchest: ``transition[i, j]`` = P(mode j at k+1 | mode i at k). ``trans[k, r]``
is mode ``r``'s transition over the interval into sample ``k`` in the table ``F, G, Qd``; mode
``r`` at sample ``k`` is updated with ``C[r]``, ``R[r]``; the input held over the interval into
sample ``k`` is ``u[:, k-1]``. Which mode's transition a particle takes into sample ``k`` is the
timing (:doc:`/conventions`): with ``sample_timing`` its mode at ``k-1`` (the mode of a sample
governs the interval after it, ``x_k = F(r_{k-1}) x_{k-1} + G(r_{k-1}) u_{k-1} + w``: the
particle is predicted, then its mode at ``k`` drawn), else its mode at ``k`` (Bar-Shalom's
timing, ``x_k = F(r_k) x_{k-1} + G(r_k) u_{k-1} + w``: the mode drawn, then the particle
predicted with it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import positive_int
from ._arrays import checked
from ._parallel import MixtureOutput, run_split
from ._rbpf import ancestors, particle_filter, resampling_positions, trial_keys, uniform

__all__ = [
    "RESAMPLING",
    "RBPFOutput",
    "ancestors",
    "particle_filter",
    "rbpf_run",
    "rbpf_step",
    "resampling_positions",
    "trial_keys",
    "uniform",
]

RESAMPLING = {"systematic": 0, "stratified": 1, "multinomial": 2}
"""The resampling schemes by name, and the code the kernel takes for each."""


@dataclass
class RBPFOutput(MixtureOutput):
    """The RBPF's estimates (:func:`rbpf_run`, and :func:`rbpf_step` as ``K = 1``): ``x``, ``P``
    of the mixture of the particles' filters, the sum of the particles' weights in each mode as
    ``mode_prob`` and the most probable mode (:class:`MixtureOutput`), and

    Attributes
    ----------
    loglik : ndarray, shape (N, K)
        Log of the particle estimate of ``p(y_k | y_{0:k-1})``.
    flag : ndarray of uint8, shape (N, K)
        ``ACCEPTED`` (0) or ``GATED`` (1: no particle's likelihood was finite, the sample was
        treated as missing).
    ess : ndarray, shape (N, K)
        Effective sample size ``1 / sum_p w_p^2`` before resampling.
    status, repaired, smallest_eigenvalue
        The kernel's report (:class:`~switchest.engine.Reported`).
    """

    loglik: np.ndarray
    flag: np.ndarray
    ess: np.ndarray


def rbpf_run(y, u, F, G, Qd, trans, C, R, transition, x0, P0, prob0, keys, *, particles: int,
             sample_timing: bool, optimal: bool, scheme: int, threshold: float) -> RBPFOutput:
    """RBPF of ``N`` trials over ``K`` samples (:func:`particle_filter`), every particle
    starting from the prior ``(x0, P0)`` at sample 0 with its mode drawn from ``prob0``.

    Parameters
    ----------
    y, u : array_like, shapes (N, K, m), (N, K, l)
        Measurements (NaN: missing) and inputs (``u[:, k-1]`` held into sample ``k``).
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        Table of exact transitions.
    trans : array_like of int, shape (K, L)
        ``trans[k, r]``: the transition of mode ``r`` into sample ``k`` (row 0 unused).
    C, R : array_like, shapes (L, m, n), (L, m, m)
    transition : array_like, shape (L, L)
        ``transition[i, j]`` = P(mode j at k+1 | mode i at k).
    x0, P0, prob0 : array_like, shapes (n,), (n, n), (L,)
        Prior of every particle's filter and mode probabilities at sample 0.
    keys : array_like of uint64, shape (N,)
        Each trial's random key.
    particles, sample_timing, optimal, scheme, threshold
        As ``se_particle_filter`` in ``c/rbpf.c`` documents them.
    """
    sizes: dict[str, int] = {}
    y, u, F, G, Qd, trans, C, R, transition, x0, P0, prob0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn trans:KL<M C:Lmn R:Lmm transition:LL x0:n "
        "P0:nn prob0:L", y, u, F, G, Qd, trans, C, R, transition, x0, P0, prob0)
    Np = positive_int(particles, "particles")
    N, n = sizes["N"], sizes["n"]
    state = (np.tile(x0, (1, Np, 1)), np.tile(P0, (1, Np, 1, 1)),
             np.zeros((1, Np), dtype=np.int64), np.full((1, Np), -math.log(Np)))
    last = (np.empty((0, Np, n)), np.empty((0, Np, n, n)), np.empty((0, Np), dtype=np.int64),
            np.empty((0, Np)))
    return _kernel(y, u, F, G, Qd, trans, C, R, transition, prob0, _keys(keys, N), 0, False,
                   sample_timing, optimal, scheme, threshold, state, last)[0]


def rbpf_step(x, P, mode, log_weight, y, u, F, G, Qd, trans, C, R, transition, prob0, keys, k,
              *, predict_first: bool, sample_timing: bool, optimal: bool, scheme: int,
              threshold: float) -> tuple[RBPFOutput, tuple[np.ndarray, ...]]:
    """One sample ``k`` of every trial: predict (when ``predict_first``; before or after the
    draw of the modes, by ``sample_timing``), sample the modes and update each particle's
    filter, reweight, resample if due.

    ``x (N, Np, n)``, ``P (N, Np, n, n)``, ``mode (N, Np)``, ``log_weight (N, Np)`` are the
    particles after the previous sample, ``y (N, m)``, ``u (N, l)``, ``trans (L,)`` the
    transition of each mode into this sample, ``k`` its index in the record (the uniforms of
    :func:`uniform`); the rest as in :func:`rbpf_run`. Inputs are not modified.

    Returns
    -------
    output : RBPFOutput
        What the RBPF reports for this sample, each array with a sample axis of length 1.
    state : tuple of ndarray
        ``x``, ``P``, ``mode``, ``log_weight`` after this sample: the particles to continue
        from.
    """
    sizes: dict[str, int] = {}
    x, P, log_weight, y, u, F, G, Qd, trans, C, R, transition, prob0 = checked(
        sizes, "x:NPn P:NPnn log_weight:NP y:Nm u:Nl F:Mnn G:Mnl Qd:Mnn trans:L<M C:Lmn R:Lmm "
        "transition:LL prob0:L", x, P, log_weight, y, u, F, G, Qd, trans, C, R, transition,
        prob0)
    mode = checked(sizes, "mode:NP<L", mode)[0]
    N, Np, n = sizes["N"], sizes["P"], sizes["n"]
    last = (np.empty((N, Np, n)), np.empty((N, Np, n, n)), np.empty((N, Np), dtype=np.int64),
            np.empty((N, Np)))
    return _kernel(y[:, None], u[:, None], F, G, Qd, trans[None], C, R, transition, prob0,
                   _keys(keys, N), int(k), bool(predict_first), sample_timing, optimal, scheme,
                   threshold, (x, P, mode, log_weight), last)


def _keys(keys, N: int) -> np.ndarray:
    """``keys`` as a C-contiguous uint64 array of shape ``(N,)``."""
    keys = np.ascontiguousarray(keys, dtype=np.uint64)
    if keys.shape != (N,):
        raise ValueError(f"keys must have shape (N,) = ({N},), got {keys.shape}")
    return keys


def _kernel(y, u, F, G, Qd, trans, C, R, transition, prob0, keys, k0, predict_first,
            sample_timing, optimal, scheme, threshold, state,
            last) -> tuple[RBPFOutput, tuple[np.ndarray, ...]]:
    """:func:`particle_filter` with its outputs allocated; returns them and ``last``."""
    N, K, _ = y.shape
    n, L = state[0].shape[2], C.shape[0]
    x, P = np.empty((N, K, n)), np.empty((N, K, n, n))
    prob, mode = np.empty((N, K, L)), np.empty((N, K), dtype=np.int64)
    loglik, flag, ess = np.empty((N, K)), np.empty((N, K), dtype=np.uint8), np.empty((N, K))
    with np.errstate(divide="ignore"):  # log 0 = -inf: an impossible switch or first mode
        log_transition, log_prob0 = np.log(transition), np.log(prob0)
    mine, shared = True, False  # per-trial arrays, sliced to each thread's trials; the rest
    outcome = run_split(particle_filter, [
        (y, mine), (u, mine), (F, shared), (G, shared), (Qd, shared), (trans, shared),
        (C, shared), (R, shared), (transition, shared), (log_transition, shared),
        (prob0, shared), (log_prob0, shared), (keys, mine), (k0, shared),
        (predict_first, shared), (bool(sample_timing), shared), (bool(optimal), shared),
        (int(scheme), shared), (float(threshold), shared), *((a, len(a) > 1) for a in state),
        (x, mine), (P, mine), (prob, mine), (mode, mine), (loglik, mine), (flag, mine),
        (ess, mine), *((a, mine) for a in last)], trials=N, samples=K * state[0].shape[1],
        block=1)
    return RBPFOutput(x, P, prob, mode, loglik, flag, ess, **outcome._asdict()), last
