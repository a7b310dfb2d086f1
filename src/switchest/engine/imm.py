"""The compiled interacting multiple model filter (Blom & Bar-Shalom, 1988).

``imm_run`` filters every trial over every sample inside compiled code; ``imm_step`` processes
one sample of every trial (the streaming API). Both call the C kernel ``se_filter_bank`` of
``engine/c/bank.c`` (through :mod:`._imm`), so they run the one implementation of each equation
(``engine/c/linalg.c``). Convention of switchest:
``transition[i, j]`` = P(mode j at k+1 | mode i at k), passed as its logarithm; mode
probabilities are kept as log-weights.

Mode ``j``'s transition into sample ``k`` is ``trans[k, j]`` of the table ``F (M, n, n)``,
``G (M, n, l)``, ``Qd (M, n, n)`` (irregular sample times give different entries per ``k``);
mode ``j`` is updated with ``C[j]``, ``R[j]``. The input held over the interval into sample
``k`` is ``u[:, k-1]``; sample 0 is update only. ``timing`` (docs/conventions.rst) says which
mode's transition a mode-matched Gaussian takes into ``k``: in the ``"sample"`` timing (the
mode of sample ``k - 1`` governs the interval into ``k``) each posterior ``i`` of
sample ``k - 1`` is predicted through ``trans[k, i]`` and the predictions are then mixed; in
the ``"interval"`` timing (the default; Bar-Shalom, Li & Kirubarajan §11.6.6) the posteriors
are mixed and mode ``j``'s mixture is predicted through ``trans[k, j]``.

Gating is decided mode by mode, a gated mode getting no weight at that sample (a truncated
likelihood); a sample no mode can use counts as missing (``se_filter_bank``,
``engine/c/bank.c``).

``interaction="collapse"`` replaces the IMM's mixing by GPB1's collapse of the mode-matched
posteriors into one Gaussian (Bar-Shalom, Li & Kirubarajan §11.6.4); ``modes_out=True`` also
returns the mode-matched posteriors after each sample's update (the input of a smoother).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .._checks import check_timing, positive_int
from ._arrays import check_gate, checked
from ._imm import filter_bank
from ._parallel import run_split

__all__ = ["LANES", "MIX", "COLLAPSE", "IMMOutput", "imm_run", "imm_run_per_trial", "imm_step",
           "is_sample_timing"]

LANES = 16  # trials per block: four AVX2 registers of float64 per row of lanes

# the interaction of filter_bank's mode-matched filters at each sample after the first
MIX = 0  # the IMM's: mode j restarts from the mixture with weights mu_{i|j}
COLLAPSE = 1  # GPB1's: every mode restarts from the one Gaussian of all modes' mixture

_INTERACTIONS = {"mix": MIX, "collapse": COLLAPSE}


class IMMOutput(NamedTuple):
    """What the IMM reports after each sample, for every trial (:func:`imm_run`; from
    :func:`imm_step`, the one sample as ``K = 1``).

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
        ``OK`` (0) or the failure code that stopped the kernel (outputs then incomplete).
    repaired : int
        How many covariances (of a mode, trial and sample) were repaired to their rounding
        level (``se_repair``, ``engine/c/linalg.c``);
        :func:`~switchest.engine.warn_for_repairs` warns about them.
    smallest_eigenvalue : float
        The smallest eigenvalue a repaired covariance had (``inf`` if none was).
    x_modes : ndarray, shape (N, K, L, n), or None
        The mode-matched posterior means after each sample's update, where asked for
        (``modes_out=True``).
    P_modes : ndarray, shape (N, K, L, n, n), or None
        Their covariances.
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
    x_modes: np.ndarray | None = None
    P_modes: np.ndarray | None = None


def imm_run(y, u, F, G, Qd, trans, C, R, log_transition, x0, P0, log_prob0, *,
            gate=math.inf, lanes: int = LANES, interaction: str = "mix",
            timing: str = "interval", modes_out: bool = False) -> IMMOutput:
    """IMM filter of ``N`` trials over ``K`` samples (Bar-Shalom, Li & Kirubarajan §11.6.6),
    or GPB1 (``interaction="collapse"``, §11.6.4).

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
    interaction : {"mix", "collapse"}
        Into each sample, mode ``j`` restarts from the IMM's mixture with weights
        ``mu_{i|j} = pi_ij mu_i / c_j`` (``"mix"``) or, for GPB1, from the one Gaussian with
        the moments of all modes' mixture, ``mu_{i|j} = mu_i`` (``"collapse"``); the predicted
        mode probabilities ``c_j = sum_i pi_ij mu_i`` are the same.
    timing : {"sample", "interval"}
        Where the interaction falls (``se_filter_bank``, ``engine/c/bank.c``): after each
        mode-matched posterior is predicted through its own transition (``"sample"``), or
        before mode ``j``'s mixture is predicted through mode ``j``'s (``"interval"``,
        Bar-Shalom's, the default).
    modes_out : bool
        Whether to return the mode-matched posteriors after each sample's update
        (``IMMOutput.x_modes``, ``P_modes``; None otherwise).
    """
    sizes: dict[str, int] = {}
    y, u, F, G, Qd, C, trans, R, log_transition, x0, P0, log_prob0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn C:Lmn trans:KL<M R:Lmm log_transition:LL x0:n "
        "P0:nn log_prob0:L", y, u, F, G, Qd, C, trans, R, log_transition, x0, P0, log_prob0)
    N, L = sizes["N"], sizes["L"]
    output, _ = _bank(y, u, F, G, Qd, trans[None], C, R, np.arange(L)[None, None],
                      log_transition[None], np.tile(x0, (N, L, 1)), np.tile(P0, (N, L, 1, 1)),
                      np.tile(log_prob0, (N, 1)), _interaction(interaction),
                      is_sample_timing(timing), False, check_gate(gate),
                      positive_int(lanes, "lanes"), bool(modes_out))
    return output


def imm_run_per_trial(y, u, F, G, Qd, trans, C, R, out_index, log_transition, x0, P0, log_prob0,
                      *, gate=math.inf, timing: str = "interval") -> IMMOutput:
    """The IMM of :func:`imm_run` with a model of its own for each trial: its transitions,
    output matrices, noises and mode transition matrix (e.g. one record filtered under many
    candidate parameters at once, the trials then filling the SIMD lanes).

    Parameters
    ----------
    trans : array_like of int, shape (N, K, L)
        ``trans[i, k, j]``: the entry of the table ``F``, ``G``, ``Qd`` that mode ``j`` of
        trial ``i`` moves through into sample ``k`` (``[:, 0]`` unused).
    C, R : array_like, shapes (M', m, n), (M', m, m)
        Table of output matrices and measurement-noise covariances.
    out_index : array_like of int, shape (N, L)
        ``out_index[i, j]``: the entry of ``C``, ``R`` that mode ``j`` of trial ``i`` measures
        through.
    log_transition : array_like, shape (N, L, L)
        Each trial's ``log transition[i, j]``.

    The other arguments as in :func:`imm_run` (interaction ``"mix"``).
    """
    sizes: dict[str, int] = {}
    y, u, F, G, Qd, C, R, trans, out_index, log_transition, x0, P0, log_prob0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn C:Smn R:Smm trans:NKL<M out_index:NL<S "
        "log_transition:NLL x0:n P0:nn log_prob0:L", y, u, F, G, Qd, C, R, trans, out_index,
        log_transition, x0, P0, log_prob0)
    N, L = sizes["N"], sizes["L"]
    output, _ = _bank(y, u, F, G, Qd, trans, C, R, out_index[:, None], log_transition,
                      np.tile(x0, (N, L, 1)), np.tile(P0, (N, L, 1, 1)),
                      np.tile(log_prob0, (N, 1)), MIX, is_sample_timing(timing), False,
                      check_gate(gate), LANES, False)
    return output


def imm_step(x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition, *,
             predict_first: bool, gate=math.inf, interaction: str = "mix",
             timing: str = "interval") -> tuple[IMMOutput, tuple[np.ndarray, ...]]:
    """One sample of every trial: mix (or collapse) and predict, in the order of ``timing``
    (when ``predict_first``), then update.

    ``x (N, L, n)``, ``P (N, L, n, n)``, ``log_prob (N, L)`` are the mode-matched posteriors
    at the previous sample, ``y (N, m)``, ``u (N, l)``, ``trans (L,)`` the transition of each
    mode into this sample; the rest as in :func:`imm_run`, whose compiled kernel runs this
    one sample, with the same ``interaction`` and ``timing``. Inputs are not modified.

    Returns
    -------
    output : IMMOutput
        What the IMM reports for this sample, each array with a sample axis of length 1.
    state : tuple of ndarray
        ``x``, ``P``, ``log_prob`` after this sample, shaped as given: the state to continue
        from.
    """
    sizes: dict[str, int] = {}
    x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition = checked(
        sizes, "x:NLn P:NLnn log_prob:NL y:Nm u:Nl F:Mnn G:Mnl Qd:Mnn trans:L<M C:Lmn R:Lmm "
        "log_transition:LL", x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition)
    return _bank(y[:, None], u[:, None], F, G, Qd, trans[None, None], C, R,
                 np.arange(sizes["L"])[None, None], log_transition[None], x, P, log_prob,
                 _interaction(interaction), is_sample_timing(timing), bool(predict_first),
                 check_gate(gate), LANES, False)


def _interaction(name) -> int:
    """The bank's code for the interaction called ``name``."""
    if not isinstance(name, str) or name not in _INTERACTIONS:
        raise ValueError(f"interaction must be one of {tuple(_INTERACTIONS)}, got {name!r}")
    return _INTERACTIONS[name]


def is_sample_timing(timing) -> bool:
    """Whether ``timing`` (checked: "sample" or "interval") is the ``"sample"`` timing: the
    kernels take it as a bool."""
    return check_timing(timing) == "sample"


def _bank(y, u, F, G, Qd, trans, C, R, out_index, log_transition, x_init, P_init,
          log_prob_init, interaction, sample_timing, predict_first, gate, lanes, modes_out):
    """The bank kernel (``se_filter_bank``, ``engine/c/bank.c``: ``trans``, ``out_index``,
    ``log_transition`` shared by the trials where their first axis has length 1); returns the
    :class:`IMMOutput` (with the mode-matched posteriors of every sample if ``modes_out``)
    and the mode-matched state ``(x, P, log_prob)`` after the last sample."""
    N, K, _ = y.shape
    L, n = x_init.shape[1], x_init.shape[2]
    x, P = np.empty((N, K, n)), np.empty((N, K, n, n))
    prob, mode = np.empty((N, K, L)), np.empty((N, K), dtype=np.int64)
    loglik, flag = np.empty((N, K)), np.empty((N, K), dtype=np.uint8)
    size = (N, K, L) if modes_out else (0, 0, 0)  # zero-size: not written
    x_modes, P_modes = np.empty((*size, n)), np.empty((*size, n, n))
    last = np.empty_like(x_init), np.empty_like(P_init), np.empty_like(log_prob_init)
    mine, shared = True, False  # per-trial arrays, sliced to each thread's trials; the rest
    # (an array whose first axis of length 1 serves every trial is shared)
    outcome = run_split(filter_bank, [
        (y, mine), (u, mine), (F, shared), (G, shared), (Qd, shared), (trans, len(trans) > 1),
        (C, shared), (R, shared), (out_index, len(out_index) > 1),
        (np.exp(log_transition), len(log_transition) > 1),
        (log_transition, len(log_transition) > 1), (x_init, mine), (P_init, mine),
        (log_prob_init, mine),
        (interaction, shared), (sample_timing, shared), (predict_first, shared),
        (gate, shared), (lanes, shared), (x, mine), (P, mine), (prob, mine), (mode, mine),
        (loglik, mine), (flag, mine), (x_modes, modes_out), (P_modes, modes_out),
        *((a, mine) for a in last)], trials=N, samples=K, block=lanes)
    modes = (x_modes, P_modes) if modes_out else (None, None)
    return IMMOutput(x, P, prob, mode, loglik, flag, *outcome, *modes), last
