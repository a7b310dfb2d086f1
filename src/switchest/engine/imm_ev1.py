"""The IMM extended-Viterbi filter with gridded switching times, on the C engine.

Shankar, Yang & Hespanha, Algorithm 1, on the IMM-EV1 of Ho & Chen (2006): one Kalman filter
per destination mode ``i``. At each sample every predecessor ``j`` and, when ``j != i``, every
switching instant ``tau_k`` of the grid of eq. (23) is a hypothesis, predicted with the exact
transition of that switch (eqs (4)-(5)), ``epsilon I`` added to its predicted covariance
(§IV), and scored by its likelihood ``J`` of the measurement. ``imm_ev1_run`` filters every
trial over every sample; ``imm_ev1_step`` processes one sample (the streaming API). Both call
:func:`viterbi_bank`, the binding of the C kernel ``se_viterbi_bank`` (``engine/c/imm_ev1.c``),
which uses the Kalman equations of ``engine/c/linalg.c``; trials are laid across SIMD lanes in
blocks, and so are the hypotheses: a lane holds one hypothesis of one trial, so that each
equation runs once per sample over all of them.

Each sample takes two passes (``se_viterbi_bank``, Notes): the likelihoods of all ``L^2 g``
hypotheses, without forming their predictions; then, once each destination has chosen its
predecessor and instant, the prediction and update of the chosen hypotheses only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import positive_int, positive_scalar
from ._arrays import check_gate, checked, indices
from ._imm_ev1 import viterbi_bank
from ._parallel import MixtureOutput, run_split

__all__ = ["IMMEV1Output", "imm_ev1_run", "imm_ev1_step", "viterbi_bank"]

LANES = 16  # trials per block: four AVX2 registers of float64 per row of lanes


@dataclass
class IMMEV1Output(MixtureOutput):
    """IMM-EV1's estimates (:func:`imm_ev1_run`, and :func:`imm_ev1_step` as ``K = 1``): ``x``,
    ``P`` of the destination of largest weight (the MAP path) or, with ``combined``, of the
    mixture of the destinations, the normalized path weights of the destinations as
    ``mode_prob`` and the MAP destination as ``mode`` (:class:`MixtureOutput`), and

    Attributes
    ----------
    switch_offset : ndarray, shape (N, K)
        Its switching instant as an offset into the interval, NaN where it did not switch.
    outlier : ndarray of bool, shape (N, K)
        True where every hypothesis rejected the measurement (treated as missing).
    status, repaired, smallest_eigenvalue
        The kernel's report (:class:`~switchest.engine.Reported`).
    """

    switch_offset: np.ndarray
    outlier: np.ndarray


def imm_ev1_run(y, u, F, G, Qd, table, tau, C, R, log_transition, x0, P0, log_weight0, *,
                epsilon, gate=math.inf, printed=False, marginal=False, by_path=True,
                combined=False, lanes: int = LANES) -> IMMEV1Output:
    """IMM-EV1 filter of ``N`` trials over ``K`` samples (Shankar et al., Algorithm 1).

    Parameters
    ----------
    y, u : array_like, shapes (N, K, m), (N, K, l)
        Measurements and inputs, as in :func:`.imm.imm_run`.
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        Transitions of the hypotheses, ``M = D L L g`` (entry ``((d L + j) L + i) g + k``:
        from ``j`` to ``i`` at ``tau[d, k]``), e.g. :func:`switchest.discretize.pairwise_grid`
        of each of ``D`` interval lengths, reshaped and concatenated.
    table : array_like of int, shape (K,)
        The interval length ``d`` into each sample (entry 0 unused).
    tau : array_like, shape (D, g)
        The switching-time grid of each interval length (eq. (23)).
    C, R : array_like, shapes (L, m, n), (L, m, m)
    log_transition : array_like, shape (L, L)
        ``log pi_ji`` added to the path weights; zeros for none.
    x0, P0 : array_like, shapes (n,), (n, n)
        Prior of every destination's filter at the first sample.
    log_weight0 : array_like, shape (L,)
        Normalized log prior weights.
    epsilon : float
        ``epsilon I`` added to every predicted covariance (§IV).
    gate : float
        Largest normalized innovation squared a hypothesis accepts (``inf``: no gate).
    printed, marginal, by_path, combined : bool
        The filter's ``likelihood="printed"``, ``switch_time="marginal"``,
        ``predecessor="path"`` and ``estimate="mixture"`` (``x``, ``P`` the moments of the
        mixture of the destinations' posteriors instead of the MAP destination's).
    lanes : int
        Trials per SIMD block (the results do not depend on it).
    """
    sizes: dict[str, int] = {}
    y, u, x0, P0, log_weight0 = checked(sizes, "y:NKm u:NKl x0:n P0:nn log_weight0:L",
                                        y, u, x0, P0, log_weight0)
    N, L = sizes["N"], sizes["L"]
    state = (np.tile(x0, (N, L, 1)), np.tile(P0, (N, L, 1, 1)), np.tile(log_weight0, (N, 1)),
             np.tile(np.arange(L), (N, 1)), np.full((N, L), np.nan))
    tables = _tables(F, G, Qd, tau, C, R, log_transition, epsilon, sizes)
    table = indices(table, "table", "K", sizes, "D")
    out, _ = _viterbi(y, u, tables, table, state, False, check_gate(gate), printed, marginal,
                      by_path, combined, positive_int(lanes, "lanes"))
    return out


def imm_ev1_step(x, P, log_weight, predecessor, switch_offset, y, u, F, G, Qd, tau, C, R,
                 log_transition, *, predict_first: bool, epsilon, gate=math.inf, printed=False,
                 marginal=False, by_path=True,
                 combined=False) -> tuple[IMMEV1Output, tuple[np.ndarray, ...]]:
    """One sample of every trial: the hypotheses of one interval and the update (when
    ``predict_first``), else the update of every destination's filter alone.

    ``x (N, L, n)``, ``P (N, L, n, n)``, ``log_weight (N, L)``, ``predecessor (N, L)``,
    ``switch_offset (N, L)`` are the state at the previous sample, ``y (N, m)``, ``u (N, l)``
    this sample's measurement and the input held over the interval, ``F``, ``G``, ``Qd``
    ``(L L g, ...)`` and ``tau (g,)`` the hypotheses of this interval (read only when
    ``predict_first``); the rest as in :func:`imm_ev1_run`, whose compiled kernel runs this
    one sample. Inputs are not modified.

    Returns
    -------
    output : IMMEV1Output
        What the IMM-EV1 reports for this sample, each array with a sample axis of length 1.
    state : tuple of ndarray
        ``x``, ``P``, ``log_weight``, ``predecessor``, ``switch_offset`` after this sample,
        shaped as given: the state to continue from.
    """
    sizes: dict[str, int] = {}
    x, P, log_weight, predecessor, switch_offset, y, u, tau = checked(
        sizes, "x:NLn P:NLnn log_weight:NL predecessor:NL<L switch_offset:NL y:Nm u:Nl tau:g",
        x, P, log_weight, predecessor, switch_offset, y, u, tau)
    tables = _tables(F, G, Qd, tau[None], C, R, log_transition, epsilon, sizes)
    state = (x.copy(), P.copy(), log_weight.copy(), predecessor.copy(), switch_offset.copy())
    return _viterbi(y[:, None], u[:, None], tables, np.zeros(1, dtype=np.int64), state,
                    bool(predict_first), check_gate(gate), printed, marginal, by_path, combined,
                    LANES)


def _tables(F, G, Qd, tau, C, R, log_transition, epsilon, sizes):
    """The validated hypothesis tables and what the likelihood pass reads of them:
    ``H = C_i F``, ``Gy = C_i G`` and ``S0 = C_i (Qd + epsilon I) C_i' + R_i`` per entry
    (the likelihood pass of ``engine/c/imm_ev1.c``), with ``i`` the destination of each entry."""
    F, G, Qd, tau, C, R, log_transition = checked(
        sizes, "F:Mnn G:Mnl Qd:Mnn tau:Dg C:Lmn R:Lmm log_transition:LL",
        F, G, Qd, tau, C, R, log_transition)
    epsilon = positive_scalar(epsilon, "epsilon", allow_zero=True)
    D, L, g, n = sizes["D"], sizes["L"], sizes["g"], sizes["n"]
    if sizes["M"] != D * L * L * g:
        raise ValueError(f"F, G, Qd must hold D L L g = {D} x {L} x {L} x {g} = {D * L * L * g} "
                         f"transitions (interval lengths x modes x modes x grid), "
                         f"got {sizes['M']}")
    dest = np.broadcast_to(np.arange(L)[None, None, :, None], (D, L, L, g)).ravel()
    Ci, Ri = C[dest], R[dest]
    Ct = np.swapaxes(Ci, -1, -2)
    S0 = Ci @ (Qd + epsilon * np.eye(n)) @ Ct + Ri
    S0 = 0.5 * (S0 + np.swapaxes(S0, -1, -2))
    return (F, G, Qd, np.ascontiguousarray(Ci @ F), np.ascontiguousarray(Ci @ G),
            np.ascontiguousarray(S0), tau, C, R, log_transition, epsilon)


def _viterbi(y, u, tables, table, state, predict_first, gate, printed, marginal, by_path,
             combined, lanes):
    """:func:`viterbi_bank` from ``state`` (``x, P, log_weight, predecessor, offset`` per
    trial and destination); returns the :class:`IMMEV1Output` and the state after the last
    sample."""
    N, K, _ = y.shape
    L, n = state[0].shape[1], state[0].shape[2]
    x, P = np.empty((N, K, n)), np.empty((N, K, n, n))
    prob, mode = np.empty((N, K, L)), np.empty((N, K), dtype=np.int64)
    offset, outlier = np.empty((N, K)), np.empty((N, K), dtype=np.uint8)
    last = tuple(np.empty_like(a) for a in state)
    mine, shared = True, False  # per-trial arrays, sliced to each thread's trials; tables
    outcome = run_split(viterbi_bank, [
        (y, mine), (u, mine), (table, shared), *((a, shared) for a in tables),
        *((a, mine) for a in state), (predict_first, shared), (gate, shared),
        (bool(printed), shared), (bool(marginal), shared), (bool(by_path), shared),
        (bool(combined), shared), (lanes, shared), (x, mine), (P, mine), (prob, mine),
        (mode, mine), (offset, mine), (outlier, mine), *((a, mine) for a in last)],
        trials=N, samples=K, block=lanes)
    return IMMEV1Output(x, P, prob, mode, offset, outlier.view(np.bool_),
                        **outcome._asdict()), last
