"""Compiled Kalman filters along given transitions: the whole loop over trials and samples.

``kalman_run`` filters every trial over every sample inside compiled code; ``kalman_step``
processes one sample of every trial (the streaming API). Both call the kernel of
:mod:`.kalman_kernel`, which runs the equations of :mod:`.linalg` (the one implementation of
each) once per group of trials that share their covariance. ``kalman_steady_run`` and
``kalman_steady_step`` apply fixed gains.

Transitions come as a table ``F (M, n, n)``, ``G (M, n, l)``, ``Qd (M, n, n)`` with an index
``trans (N, K)``: entry ``k`` is the transition predicting into sample ``k`` (entry 0 is not
used by ``kalman_run``: the first sample is update only). One index covers irregular sample
times, believed modes and exact switches inside an interval; the caller builds the table of
the distinct transitions. Output matrices come as ``C (L, m, n)``, ``R (L, m, m)`` with
``mode (N, K)``. The input held over the interval into sample ``k`` is ``u[:, k-1]``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..._checks import positive_int
from .arrays import check_gate, checked
from .kalman_kernel import CHUNK, LANES, kalman_filter, lane_entries, predict_means, write_out
from .linalg import (
    ACCEPTED,
    GATED,
    OK,
    gather_matrices,
    gather_rows,
    gather_samples,
    jit,
    observe,
    residual,
)

__all__ = ["KalmanOutput", "kalman_run", "kalman_step", "kalman_steady_run", "kalman_steady_step"]


class KalmanOutput(NamedTuple):
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
    status : int
        ``OK`` or the failure code that stopped the kernel (outputs then incomplete);
        :func:`switchest.estimators._compiled.raise_for_status` turns it into an exception.
    repaired, smallest_eigenvalue
        How many covariances were repaired to their rounding level, and the smallest
        eigenvalue one had (``inf`` if none was): see :class:`.imm.IMMOutput`.
    """

    x: np.ndarray
    P: np.ndarray
    loglik: np.ndarray
    flag: np.ndarray
    status: int
    repaired: int = 0
    smallest_eigenvalue: float = math.inf


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
        once (:mod:`.kalman_kernel`; the results do not depend on it).
    """
    sizes: dict[str, int] = {}
    y, u, F, G, Qd, trans, C, R, mode, x0, P0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn trans:NK<M C:Lmn R:Lmm mode:NK<L x0:n P0:nn",
        y, u, F, G, Qd, trans, C, R, mode, x0, P0)
    N = sizes["N"]
    return _one_mode(y, u, F, G, Qd, trans, C, R, mode, np.repeat(x0[None], N, axis=0),
                     np.repeat(P0[None], N, axis=0), False, check_gate(gate),
                     positive_int(lanes, "lanes"))


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
    return KalmanOutput(out.x[:, 0], out.P[:, 0], out.loglik[:, 0], out.flag[:, 0], out.status,
                        out.repaired, out.smallest_eigenvalue)


def _one_mode(y, u, F, G, Qd, trans, C, R, mode, x_init, P_init, predict_first, gate, lanes):
    """:func:`.kalman_kernel.kalman_filter` of every trial from ``x_init (N, n)``,
    ``P_init (N, n, n)``, into new output arrays."""
    N, K, _ = y.shape
    n = x_init.shape[1]
    x, P, loglik = np.empty((N, K, n)), np.empty((N, K, n, n)), np.empty((N, K))
    flag, report = np.empty((N, K), dtype=np.uint8), np.empty(2)
    status = kalman_filter(y, u, F, G, Qd, trans, C, R, mode, x_init, P_init, predict_first, gate,
                           min(lanes, N), x, P, loglik, flag, report)
    return KalmanOutput(x, P, loglik, flag, int(status), int(report[0]), float(report[1]))


def kalman_steady_run(y, u, F, G, trans, C, mode, gain, P_prior, P_post, whiten, x0, *,
                      gate=math.inf, lanes: int = LANES) -> KalmanOutput:
    """Kalman filter with fixed gains (Zhang & Natarajan eq. (6)), every trial and sample.

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
    _steady_filter(y, u, F, G, trans, C, mode, gain, P_prior, P_post, whiten,
                   np.repeat(x0[None], N, axis=0), False, check_gate(gate),
                   min(positive_int(lanes, "lanes"), N), x, P, loglik, flag)
    return KalmanOutput(x, P, loglik, flag, OK)


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
    _steady_filter(y[:, None], u[:, None], F, G, own, C, own, gain, P_prior, P_post, whiten, x,
                   bool(predict_first), check_gate(gate), min(LANES, N), x_out, P_out, loglik,
                   flag)
    return KalmanOutput(x_out[:, 0], P_out[:, 0], loglik[:, 0], flag[:, 0], OK)


@jit
def _steady_filter(y, u, F, G, trans, C, mode, gain, P_prior, P_post, whiten, x_init,
                   predict_first, gate, lanes, x_out, P_out, loglik_out, flag_out):
    """Fixed-gain filter of every trial from ``x_init[i]``, in blocks of ``lanes`` trials:
    ``x <- F x + G u`` (:func:`.kalman_kernel.predict_means`), then ``x <- x + K (y - C x)`` in the
    lanes where every component of ``y`` is observed and its normalized innovation squared
    ``|W e|^2`` passes ``gate`` (Zhang & Natarajan eq. (6)); ``P`` is copied from the tables,
    ``loglik`` is NaN. A lane's matrices are gathered when its entry changes; the outputs are
    buffered and written trial by trial (:func:`.kalman_kernel.write_out`)."""
    N, K, m = y.shape
    n, n_in, B, L = x_init.shape[1], u.shape[2], lanes, P_prior.shape[0]
    x, xs, yl, ul = np.empty((n, B)), np.empty((n, B)), np.empty((m, B)), np.empty((n_in, B))
    Fl, Gl, held = np.empty((n, n, B)), np.empty((n, n_in, B)), np.empty((2, B), dtype=np.int64)
    Cl, Kl, Wl, e = np.empty((m, n, B)), np.empty((n, m, B)), np.empty((m, m, B)), np.empty((m, B))
    obs, n_obs, v = np.empty((m, B)), np.empty(B), np.empty(B)
    nis, use = np.empty(B), np.empty(B, dtype=np.bool_)
    # the buffers of write_out; its covariances are the tables (prior, then posterior)
    x_buf, entry_buf = np.empty((B, CHUNK, n)), np.empty((B, CHUNK), dtype=np.int64)
    P_buf, loglik_buf = np.empty((2 * L, CHUNK, n * n)), np.full((B, CHUNK), np.nan)
    flag_buf = np.empty((B, CHUNK), dtype=np.uint8)
    for i in range(L):
        for t in range(CHUNK):
            for r in range(n):
                for c in range(n):
                    P_buf[i, t, r * n + c] = P_prior[i, r, c]
                    P_buf[L + i, t, r * n + c] = P_post[i, r, c]
    P_rows = P_out.reshape((N, K, n * n))
    for i0 in range(0, N, B):
        nb = min(B, N - i0)
        gather_rows(x_init, i0, nb, x)
        held.fill(-1)  # no entry held: each lane gathers its matrices at its first sample
        for k in range(K):
            if k > 0 or predict_first:
                predict_means(trans, F, G, u, i0, nb, k, held[0], Fl, Gl, ul, x, xs)
            if lane_entries(mode, i0, nb, k, held[1]):
                gather_matrices(C, held[1], nb, Cl)
                gather_matrices(gain, held[1], nb, Kl)
                gather_matrices(whiten, held[1], nb, Wl)
            gather_samples(y, i0, nb, k, yl)
            observe(yl, nb, obs, n_obs)
            residual(x, yl, Cl, nb, e)
            _whitened_norm(e, Wl, nb, v, nis)
            t = k % CHUNK
            for b in range(nb):
                seen = n_obs[b] == m
                use[b] = seen and math.isfinite(nis[b]) and nis[b] <= gate
                flag_buf[b, t] = GATED if seen and not use[b] else ACCEPTED
                entry_buf[b, t] = held[1, b] + (L if use[b] else 0)
            _steady_correct(x, e, Kl, use, nb)
            for b in range(nb):
                for r in range(n):
                    x_buf[b, t, r] = x[r, b]
            if t == CHUNK - 1 or k == K - 1:
                write_out(x_buf, P_buf, entry_buf, loglik_buf, flag_buf, i0, nb, k - t, t + 1,
                          x_out, P_rows, loglik_out, flag_out)


@jit
def _whitened_norm(e, W, nb, v, nis):
    """``nis[b] = |W e|^2`` (= ``e' S^-1 e`` for ``S^-1 = W' W``) in every lane; NaN where a
    component of ``e`` is missing. ``v (B,)`` is scratch."""
    m = e.shape[0]
    for b in range(nb):
        nis[b] = 0.0
    for a in range(m):
        for b in range(nb):
            v[b] = 0.0
        for c in range(a + 1):  # W is lower triangular
            for b in range(nb):
                v[b] += W[a, c, b] * e[c, b]
        for b in range(nb):
            nis[b] += v[b] * v[b]


@jit
def _steady_correct(x, e, gain, use, nb):
    """``x <- x + K e`` in the lanes that use their measurement (Zhang & Natarajan eq. (6));
    the other lanes keep ``x`` as predicted."""
    n, m = gain.shape[0], gain.shape[1]
    for i in range(n):
        for a in range(m):
            for b in range(nb):
                x[i, b] += gain[i, a, b] * e[a, b] if use[b] else 0.0
