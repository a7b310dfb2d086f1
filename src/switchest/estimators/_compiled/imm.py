"""The compiled interacting multiple model filter (Blom & Bar-Shalom, 1988).

``imm_run`` filters every trial over every sample inside compiled code; ``imm_step`` processes
one sample of every trial (the streaming API). Both call the kernel of :mod:`.bank`, so they
run the one implementation of each equation (:mod:`.linalg`). Convention of switchest:
``transition[i, j]`` = P(mode j at k+1 | mode i at k), passed as its logarithm; mode
probabilities are kept as log-weights.

Mode ``j`` predicts into sample ``k`` with the transition ``trans[k, j]`` of the table
``F (M, n, n)``, ``G (M, n, l)``, ``Qd (M, n, n)`` (irregular sample times give different
entries per ``k``) and is updated with ``C[j]``, ``R[j]``. The input held over the interval
into sample ``k`` is ``u[:, k-1]``; sample 0 is update only.

Gating is decided mode by mode, a gated mode getting no weight at that sample (a truncated
likelihood); a sample no mode can use counts as missing (:func:`.bank.filter_bank`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..._checks import positive_int
from .arrays import check_gate, floats, indices
from .bank import LANES, filter_bank

__all__ = ["IMMOutput", "IMMStepOutput", "imm_run", "imm_step"]


class IMMOutput(NamedTuple):
    """What the IMM reports after each sample, for every trial.

    Attributes
    ----------
    x : ndarray, shape (N, K, n)
        Combined estimate, the mean of the mixture of the mode-matched posteriors.
    P : ndarray, shape (N, K, n, n)
        Covariance of that mixture.
    mode_prob : ndarray, shape (N, K, L)
    mode : ndarray of int64, shape (N, K)
        Most probable mode (the first on a tie).
    loglik : ndarray, shape (N, K)
        Log of the total likelihood ``sum_j c_j Lambda_j`` of the measurement given the past.
    flag : ndarray of uint8, shape (N, K)
        ``ACCEPTED`` (0), ``GATED`` (1: treated as missing) or ``PARTLY_GATED`` (2).
    status : int
        ``linalg.OK`` or the failure code that stopped the kernel (outputs then incomplete).
    repaired : int
        How many covariances (of a mode, trial and sample) were repaired to their rounding
        level (:func:`.linalg.repair`); :func:`~switchest.estimators._compiled.warn_for_repairs`
        warns about them.
    smallest_eigenvalue : float
        The smallest eigenvalue a repaired covariance had (``inf`` if none was).
    """

    x: np.ndarray
    P: np.ndarray
    mode_prob: np.ndarray
    mode: np.ndarray
    loglik: np.ndarray
    flag: np.ndarray
    status: int
    repaired: int = 0
    smallest_eigenvalue: float = math.inf


class IMMStepOutput(NamedTuple):
    """The IMM state after one sample of every trial, and what it reports.

    Attributes
    ----------
    x, P, log_prob : ndarray, shapes (N, L, n), (N, L, n, n), (N, L)
        Mode-matched posteriors and log mode probabilities: the state to continue from.
    combined_x, combined_P, mode_prob, mode : ndarray, shapes (N, n), (N, n, n), (N, L), (N,)
        The combined estimate and mode probabilities, as :class:`IMMOutput` reports them.
    loglik, flag : ndarray, shape (N,)
    status, repaired, smallest_eigenvalue
        As in :class:`IMMOutput`.
    """

    x: np.ndarray
    P: np.ndarray
    log_prob: np.ndarray
    combined_x: np.ndarray
    combined_P: np.ndarray
    mode_prob: np.ndarray
    mode: np.ndarray
    loglik: np.ndarray
    flag: np.ndarray
    status: int
    repaired: int = 0
    smallest_eigenvalue: float = math.inf


def imm_run(y, u, F, G, Qd, trans, C, R, log_transition, x0, P0, log_prob0, *,
            gate=math.inf, lanes: int = LANES) -> IMMOutput:
    """IMM filter of ``N`` trials over ``K`` samples (Bar-Shalom, Li & Kirubarajan §11.6.6).

    Parameters
    ----------
    y : array_like, shape (N, K, m)
        Measurements; a NaN component is missing.
    u : array_like, shape (N, K, l)
        Inputs; ``u[:, k-1]`` is held over the interval into sample ``k``.
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        Table of exact transitions.
    trans : array_like of int, shape (K, L)
        ``trans[k, j]``: the transition of mode ``j`` into sample ``k`` (row 0 unused).
    C, R : array_like, shapes (L, m, n), (L, m, m)
        Output matrix and measurement-noise covariance of each mode.
    log_transition : array_like, shape (L, L)
        ``log transition[i, j]``, ``-inf`` for an impossible switch.
    x0, P0 : array_like, shapes (n,), (n, n)
        Prior of every mode-matched filter at the first sample.
    log_prob0 : array_like, shape (L,)
        Log prior mode probabilities at the first sample.
    gate : float
        Largest normalized innovation squared a mode accepts (``inf``: no gate).
    lanes : int
        Trials per SIMD block (the results do not depend on it).
    """
    sizes: dict[str, int] = {}
    y = floats(y, "y", "NKm", sizes)
    u = floats(u, "u", "NKl", sizes)
    F = floats(F, "F", "Mnn", sizes)
    G = floats(G, "G", "Mnl", sizes)
    Qd = floats(Qd, "Qd", "Mnn", sizes)
    C = floats(C, "C", "Lmn", sizes)
    trans = indices(trans, "trans", "KL", sizes, "M")
    R = floats(R, "R", "Lmm", sizes)
    log_transition = floats(log_transition, "log_transition", "LL", sizes)
    x0 = floats(x0, "x0", "n", sizes)
    P0 = floats(P0, "P0", "nn", sizes)
    log_prob0 = floats(log_prob0, "log_prob0", "L", sizes)
    N, L = sizes["N"], sizes["L"]
    output, *_ = _bank(y, u, F, G, Qd, trans[None], C, R, log_transition,
                       np.tile(x0, (N, L, 1)), np.tile(P0, (N, L, 1, 1)),
                       np.tile(log_prob0, (N, 1)), False, check_gate(gate),
                       positive_int(lanes, "lanes"))
    return output


def imm_step(x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition, *,
             predict_first: bool, gate=math.inf) -> IMMStepOutput:
    """One sample of every trial: mix and predict (when ``predict_first``), then update.

    ``x (N, L, n)``, ``P (N, L, n, n)``, ``log_prob (N, L)`` are the mode-matched posteriors
    at the previous sample, ``y (N, m)``, ``u (N, l)``, ``trans (L,)`` the transition of each
    mode into this sample; the rest as in :func:`imm_run`, whose compiled kernel runs this
    one sample. Inputs are not modified.
    """
    sizes: dict[str, int] = {}
    x = floats(x, "x", "NLn", sizes)
    P = floats(P, "P", "NLnn", sizes)
    log_prob = floats(log_prob, "log_prob", "NL", sizes)
    y = floats(y, "y", "Nm", sizes)
    u = floats(u, "u", "Nl", sizes)
    F = floats(F, "F", "Mnn", sizes)
    G = floats(G, "G", "Mnl", sizes)
    Qd = floats(Qd, "Qd", "Mnn", sizes)
    trans = indices(trans, "trans", "L", sizes, "M")
    C = floats(C, "C", "Lmn", sizes)
    R = floats(R, "R", "Lmm", sizes)
    log_transition = floats(log_transition, "log_transition", "LL", sizes)
    out, x, P, log_prob = _bank(y[:, None], u[:, None], F, G, Qd, trans[None, None], C, R,
                                log_transition, x, P, log_prob, bool(predict_first),
                                check_gate(gate), LANES)
    return IMMStepOutput(x, P, log_prob, out.x[:, 0], out.P[:, 0], out.mode_prob[:, 0],
                         out.mode[:, 0], out.loglik[:, 0], out.flag[:, 0], out.status,
                         out.repaired, out.smallest_eigenvalue)


def _bank(y, u, F, G, Qd, trans, C, R, log_transition, x_init, P_init, log_prob_init,
          predict_first, gate, lanes):
    """The bank kernel with every mode ``j`` on its own ``C[j]``, ``R[j]``; returns the
    :class:`IMMOutput` and the mode-matched state after the last sample."""
    N, K, _ = y.shape
    L, n = x_init.shape[1], x_init.shape[2]
    x, P = np.empty((N, K, n)), np.empty((N, K, n, n))
    prob, mode = np.empty((N, K, L)), np.empty((N, K), dtype=np.int64)
    loglik, flag = np.empty((N, K)), np.empty((N, K), dtype=np.uint8)
    last = np.empty_like(x_init), np.empty_like(P_init), np.empty_like(log_prob_init)
    report = np.empty(2)
    status = filter_bank(y, u, F, G, Qd, trans, C, R, np.arange(L)[None, None],
                         np.exp(log_transition), log_transition, x_init, P_init, log_prob_init,
                         predict_first, gate, lanes, x, P, prob, mode, loglik, flag, *last,
                         report)
    return (IMMOutput(x, P, prob, mode, loglik, flag, int(status), int(report[0]),
                      float(report[1])), *last)
