"""Kalman filters along given transitions on the C engine: the whole loop over trials and samples.

``kalman_run`` filters every trial over every sample inside compiled code; ``kalman_step``
processes one sample of every trial (the streaming API). Both call the kernel of
``c/kalman.c`` (binding :mod:`._kalman`), which runs the equations of ``c/linalg.c`` (the one
implementation of each) once per group of trials that share their covariance.
``kalman_steady_run`` and ``kalman_steady_step`` apply fixed gains.

Transitions come as a table ``F (M, n, n)``, ``G (M, n, l)``, ``Qd (M, n, n)`` with an index
``trans (N, K)``: entry ``k`` is the transition predicting into sample ``k`` (entry 0 is not
used by ``kalman_run``: the first sample is update only). One index covers irregular sample
times, believed modes and exact switches inside an interval; the caller builds the table of
the distinct transitions. Output matrices come as ``C (L, m, n)``, ``R (L, m, m)`` with
``mode (N, K)``. The input held over the interval into sample ``k`` is ``u[:, k-1]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .._checks import positive_int
from ._arrays import check_gate, checked, replicated
from ._kalman import CHUNK, LANES, kalman_filter, steady_filter  # noqa: F401 (CHUNK: re-exported)
from ._parallel import Reported, run_values

__all__ = ["KalmanOutput", "KalmanRun", "kalman_run", "kalman_step", "kalman_steady_run",
           "kalman_steady_step"]


@dataclass
class KalmanOutput(Reported):
    """Posterior after each sample, for every trial.

    Attributes
    ----------
    x : ndarray, shape (N, K, n) (``(N, n)`` from a step)
    P : ndarray, shape (N, K, n, n) (``(N, n, n)`` from a step)
    loglik : ndarray, shape (N, K) (``(N,)`` from a step)
        Log-likelihood of each measurement given the past; 0 when nothing was observed or the
        sample was gated; NaN for fixed gains (that filter has no likelihood).
    flag : ndarray of uint8, shape (N, K) (``(N,)`` from a step)
        ``ACCEPTED`` (0) or ``GATED`` (1): an outlier or a gated measurement, treated as
        missing.
    status, repaired, smallest_eigenvalue
        The kernel's report (:class:`~switchest.engine.Reported`).
    """

    x: np.ndarray
    P: np.ndarray
    loglik: np.ndarray
    flag: np.ndarray


def kalman_run(y, u, F, G, Qd, trans, C, R, mode, x0, P0, *, gate=math.inf,
               lanes: int = LANES) -> KalmanOutput:
    """Kalman filter of ``N`` trials over ``K`` samples (Shankar et al. eqs (6)-(10)).

    Parameters
    ----------
    y : array_like, shape (N, K, m)
        Measurements; a NaN component is missing (update with the observed ones only).
    u : array_like, shape (N, K, l)
        Inputs; ``u[:, k-1]`` is held over the interval into sample ``k``.
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        Table of exact transitions ``x+ = F x + G u + w``, ``w ~ N(0, Qd)``.
    trans : array_like of int, shape (N, K)
        ``trans[:, k]`` indexes the transition into sample ``k``; ``trans[:, 0]`` is unused.
    C, R : array_like, shapes (L, m, n), (L, m, m)
        Output matrices and measurement-noise covariances.
    mode : array_like of int, shape (N, K)
        Which ``C``, ``R`` each sample uses.
    x0, P0 : array_like, shapes (n,), (n, n)
        Prior at the first sample.
    gate : float
        Largest normalized innovation squared ``e' S^-1 e`` accepted (``inf``: no gate);
        a measurement beyond it, or with a non-finite likelihood, is treated as missing.
    lanes : int
        Trials per block: the trials of a block that share their covariance run its equations
        once (``c/kalman.c``; the results do not depend on it).
    """
    sizes: dict[str, int] = {}
    y, u, F, G, Qd, trans, C, R, mode, x0, P0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn trans:NK<M C:Lmn R:Lmm mode:NK<L x0:n P0:nn",
        y, u, F, G, Qd, trans, C, R, mode, x0, P0)
    N = sizes["N"]
    return _one_mode(y, u, F, G, Qd, trans, C, R, mode, replicated(x0, (N,)),
                     replicated(P0, (N,)), False, check_gate(gate), positive_int(lanes, "lanes"))


class KalmanRun:
    """:func:`kalman_run` with its tables that do not change between calls checked and
    converted once: the output matrices ``C (L, m, n)``, noises ``R (L, m, m)``, the prior
    ``x0 (n,)``, ``P0 (n, n)``, ``gate`` and ``lanes``; :meth:`__call__` checks the rest and
    runs the same kernel on the same arrays. The arrays given are not modified; keep them
    unchanged while it is used."""

    def __init__(self, C, R, x0, P0, *, gate=math.inf, lanes: int = LANES):
        sizes: dict[str, int] = {}
        self.C, self.R, self.x0, self.P0 = checked(sizes, "C:Lmn R:Lmm x0:n P0:nn", C, R, x0, P0)
        self.sizes = sizes
        self.gate = check_gate(gate)
        self.lanes = positive_int(lanes, "lanes")

    def __call__(self, y, u, F, G, Qd, trans, mode) -> KalmanOutput:
        """:func:`kalman_run` of ``y (N, K, m)``, ``u (N, K, l)`` along the table ``F``, ``G``,
        ``Qd`` with ``trans (N, K)`` and ``mode (N, K)``."""
        sizes = dict(self.sizes)
        y, u, F, G, Qd, trans, mode = checked(
            sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn trans:NK<M mode:NK<L", y, u, F, G, Qd, trans,
            mode)
        N = sizes["N"]
        return _one_mode(y, u, F, G, Qd, trans, self.C, self.R, mode, replicated(self.x0, (N,)),
                         replicated(self.P0, (N,)), False, self.gate, self.lanes)


def kalman_step(x, P, y, u, F, G, Qd, C, R, *, predict_first: bool,
                gate=math.inf) -> KalmanOutput:
    """One sample of every trial: predict (when ``predict_first``) and update.

    ``x (N, n)``, ``P (N, n, n)`` the posterior at the previous sample, ``y (N, m)``,
    ``u (N, l)`` the input held over the interval, and per-trial ``F (N, n, n)``,
    ``G (N, n, l)``, ``Qd (N, n, n)``, ``C (N, m, n)``, ``R (N, m, m)``; the equations and
    ``gate`` as in :func:`kalman_run`, whose compiled kernel runs this one sample.
    """
    sizes: dict[str, int] = {}
    x, P, y, u, F, G, Qd, C, R = checked(
        sizes, "x:Nn P:Nnn y:Nm u:Nl F:Nnn G:Nnl Qd:Nnn C:Nmn R:Nmm", x, P, y, u, F, G, Qd, C, R)
    own = np.arange(sizes["N"])[:, None]  # trial i uses entry i of the per-trial "tables"
    out = _one_mode(y[:, None], u[:, None], F, G, Qd, own, C, R, own, x, P, bool(predict_first),
                    check_gate(gate), LANES)
    return replace(out, x=out.x[:, 0], P=out.P[:, 0], loglik=out.loglik[:, 0], flag=out.flag[:, 0])


def _one_mode(y, u, F, G, Qd, trans, C, R, mode, x_init, P_init, predict_first, gate, lanes):
    """The C kernel (``se_kalman_filter``) of every trial from ``x_init (N, n)``,
    ``P_init (N, n, n)``, into new output arrays."""
    N, K, _ = y.shape
    n = x_init.shape[1]
    x, P, loglik = np.empty((N, K, n)), np.empty((N, K, n, n)), np.empty((N, K))
    flag = np.empty((N, K), dtype=np.uint8)
    mine, shared = True, False  # per-trial arrays, sliced to each thread's trials; tables
    outcome = run_values(kalman_filter, (
        y, u, F, G, Qd, trans, C, R, mode, x_init, P_init, predict_first, gate, min(lanes, N), x,
        P, loglik, flag), (
        mine, mine, shared, shared, shared, mine, shared, shared, mine, mine, mine, shared, shared,
        shared, mine, mine, mine, mine), trials=N, samples=K, block=lanes)
    return KalmanOutput(x, P, loglik, flag, **outcome._asdict())


def kalman_steady_run(y, u, F, G, trans, C, mode, gain, P_prior, P_post, whiten, x0, *,
                      gate=math.inf, lanes: int = LANES) -> KalmanOutput:
    """Kalman filter with fixed gains (Zhang & Natarajan equation (6)), every trial and sample.

    ``x_k|k = x_k|k-1 + K_i (y_k - C_i x_k|k-1)`` with the gain ``gain[i] (n, m)`` of the
    mode ``i = mode[:, k]``; a sample with any component missing is not used at all. The
    reported covariance is read from the tables ``P_post[i]`` after an update and
    ``P_prior[i]`` otherwise, shape ``(L, n, n)``; ``loglik`` is NaN (the fixed-gain filter
    has no likelihood).

    ``whiten (L, m, m)`` holds ``W_i = L_i^-1`` for the steady innovation covariance
    ``S_i = C_i P_prior[i] C_i' + R_i = L_i L_i'``: the normalized innovation squared is
    ``e' S_i^-1 e = |W_i e|^2``. A measurement whose NIS exceeds ``gate`` or is not finite is
    not used (flag ``GATED``). Other arguments as in :func:`kalman_run`.
    """
    sizes: dict[str, int] = {}
    y, u, F, G, trans, C, mode, gain, P_prior, P_post, whiten, x0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl trans:NK<M C:Lmn mode:NK<L gain:Lnm P_prior:Lnn "
        "P_post:Lnn whiten:Lmm x0:n", y, u, F, G, trans, C, mode, gain, P_prior, P_post, whiten, x0)
    N, K, n = sizes["N"], sizes["K"], sizes["n"]
    x, P, loglik = np.empty((N, K, n)), np.empty((N, K, n, n)), np.empty((N, K))
    flag = np.empty((N, K), dtype=np.uint8)
    status = steady_filter(y, u, F, G, trans, C, mode, gain, P_prior, P_post, whiten,
                           np.repeat(x0[None], N, axis=0), False, check_gate(gate),
                           min(positive_int(lanes, "lanes"), N), x, P, loglik, flag)
    return KalmanOutput(x, P, loglik, flag, status=int(status))


def kalman_steady_step(x, y, u, F, G, C, gain, P_prior, P_post, whiten, *,
                       predict_first: bool, gate=math.inf) -> KalmanOutput:
    """One sample of every trial with fixed gains, as :func:`kalman_steady_run` (whose kernel
    runs it), with per-trial ``F``, ``G``, ``C``, ``gain (N, n, m)``, ``P_prior``,
    ``P_post (N, n, n)``, ``whiten (N, m, m)``."""
    sizes: dict[str, int] = {}
    x, y, u, F, G, C, gain, P_prior, P_post, whiten = checked(
        sizes, "x:Nn y:Nm u:Nl F:Nnn G:Nnl C:Nmn gain:Nnm P_prior:Nnn P_post:Nnn whiten:Nmm",
        x, y, u, F, G, C, gain, P_prior, P_post, whiten)
    N, n = sizes["N"], sizes["n"]
    own = np.arange(N)[:, None]
    x_out, P_out, loglik = np.empty((N, 1, n)), np.empty((N, 1, n, n)), np.empty((N, 1))
    flag = np.empty((N, 1), dtype=np.uint8)
    status = steady_filter(y[:, None], u[:, None], F, G, own, C, own, gain, P_prior, P_post,
                           whiten, x, bool(predict_first), check_gate(gate), min(LANES, N),
                           x_out, P_out, loglik, flag)
    return KalmanOutput(x_out[:, 0], P_out[:, 0], loglik[:, 0], flag[:, 0], status=int(status))
