"""The Kalman filter with estimated switching times on the C engine (Shankar et al. §III-§IV).

``switch_time_run`` filters every trial over every sample inside compiled code, and so does one
call per sample (the streaming ``step``): the kernel of ``c/switch_time.c`` (binding
:mod:`._switch_time`, ``switch_time_filter``) holds the one implementation of the filter, built
on the equations of ``c/linalg.c`` over blocks of trials laid across SIMD lanes.

The mode at each sample is known. When it changes over an interval, from ``a`` to ``b``, the
switching instant ``tau`` is estimated from the likelihood of the new measurement,
``J_k(tau) = N(y; C x-(tau), C P-(tau) C' + R)`` (Shankar et al. §IV): the maximizer over the
grid ``tau_i = i T / g - T / (2 g)`` (eq. (23)), optionally refined by Brent's search over the
grid cell around it (``refine`` of ``c/switch_time.c``), or the moment-matched merge of every
grid hypothesis (``marginal``). The filter then predicts with the transition of the estimate
(eqs (4)-(5), (6)-(7)) and updates (eqs (8)-(10), Joseph form).

``J_k`` needs ``C F``, ``C G u`` and ``C Qd C'`` of a hypothesis, not its ``F`` and ``Qd``: the
kernel pulls the output matrix back through the segments of the interval (``pull_back`` of
``c/switch_time.c``, O(m n^2) per segment) and takes the innovation of ``y`` against the state
of the previous sample, ``x``, ``P``, through ``C F`` with the noise ``C Qd C' + R`` — the
same Gaussian as the innovation of the prediction. Only the chosen hypothesis is predicted.

Tables: one transition table ``F (M, n, n)``, ``G (M, n, l)``, ``Qd (M, n, n)`` holds, for each
of the ``D`` distinct sampling steps ``d`` (``D`` entries of ``steps``) and modes ``i``, ``j``,
in four sections:

* ``d L + i``: mode ``i`` over the step, no switch (:func:`switchest.discretize.mode_steps`);
* ``D L + ((d L + i) L + j) g + r``: switch from ``i`` to ``j`` at grid instant ``r``
  (:func:`switchest.discretize.pairwise_grid`);
* ``D L (1 + L g) + (d L + i) N1 + c``: mode ``i`` over ``c T / N1`` (refinement only);
* ``D L (1 + L g + N1) + ((d L + i) L + j) (N0 + 1) + q``: a span ``T / N1`` switching from
  ``i`` to ``j`` at ``q T / (N1 N0)`` (refinement only).

The last two are the :class:`switchest.discretize.OffsetTable` of the step (``N1 = N0 =
2^9``). A refinement probe at ``tau`` is quantized to ``(c N0 + q) T / (N1 N0)`` (3.8e-6 T,
under 1/25 of the search's tolerance :data:`REFINE_TOLERANCE` ``T``) and composed from three
flows of the table, ``i`` over ``c T / N1``, the span ``c`` switching at ``q``, ``j`` over
``(N1 - 1 - c) T / N1``: no matrix exponential per probe. The last flow's ``C_j F``, ``C_j G``,
``C_j Qd C_j'`` are computed once per table (:func:`coarse_outputs`), so that a probe pulls the
output map back through two flows only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import ACCEPTED, GATED, NOT_FINITE, NOT_POSITIVE_DEFINITE, OK  # noqa: F401
from ._arrays import check_gate, checked, indices
from ._parallel import Reported, run_split
from ._switch_time import switch_time_filter

__all__ = [
    "SwitchTimeOutput",
    "switch_time_run",
    "switch_time_filter",
    "coarse_outputs",
    "REFINE_TOLERANCE",
    "LANES",
]

LANES = 16  # trials per block: four AVX2 registers of float64 per row
REFINE_TOLERANCE = 1e-4  # Brent's tolerance on the refined instant (tol = 1e-4 T, refine)


@dataclass
class SwitchTimeOutput(Reported):
    """What the filter reports after each sample, for every trial.

    Attributes
    ----------
    x : ndarray, shape (N, K, n)
    P : ndarray, shape (N, K, n, n)
    loglik : ndarray, shape (N, K)
        Log-likelihood of each measurement given the past (0 when nothing was observed or the
        measurement was rejected); with ``marginal``, over an interval with a switch, the log
        of the grid mean ``(1/g) sum_i p(y | tau_i)``.
    offset : ndarray, shape (N, K)
        Estimated switching instant from the start of the interval into each sample (NaN
        without a switch): a grid instant, a refined (quantized) instant, or with ``marginal``
        the posterior mean.
    flag : ndarray of uint8, shape (N, K)
        ``ACCEPTED`` (0) or ``GATED`` (1): the measurement was rejected, treated as missing.
    status, repaired, smallest_eigenvalue
        The kernel's report (:class:`~switchest.engine.Reported`).
    """

    x: np.ndarray
    P: np.ndarray
    loglik: np.ndarray
    offset: np.ndarray
    flag: np.ndarray


def switch_time_run(y, u, which, mode, prev, C, R, F, G, Qd, steps, grid_tau, x0, P0, *,
                    levels=(0, 0), predict_first: bool, marginal: bool, printed: bool,
                    gate=math.inf, iterations: int = 0, tolerance: float = REFINE_TOLERANCE,
                    outputs=None) -> SwitchTimeOutput:
    """Switch-time Kalman filter of ``N`` trials over ``K`` samples (Shankar et al. §IV).

    Parameters
    ----------
    y : array_like, shape (N, K, m)
        Measurements; a NaN component is missing.
    u : array_like, shape (N, K, l)
        ``u[:, k]``: the input held over the interval into sample ``k``.
    which : array_like of int, shape (K,)
        The sampling step (an entry of ``steps``) of the interval into each sample; read only
        where the kernel predicts (``k > 0``, or ``k = 0`` with ``predict_first``).
    mode, prev : array_like of int, shape (N, K)
        The mode at each sample and over the interval before the switch into it (``prev ==
        mode``: no switch).
    C, R : array_like, shapes (L, m, n), (L, m, m)
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        The transition table, in the four sections of the module docstring.
    steps : array_like, shape (D,)
        The distinct sampling steps.
    grid_tau : array_like, shape (D, g)
        The grid instants of each step (eq. (23)).
    x0, P0 : array_like, shapes (N, n), (N, n, n)
        Each trial's state before the first sample.
    levels : (int, int)
        ``(N1, N0 + 1)``: the lengths of the refinement sections per mode and per mode pair
        (``(0, 0)`` without).
    predict_first : bool
        Whether the first sample is predicted into (a streaming step) or only updated.
    marginal : bool
        Merge the grid hypotheses (moment matching, uniform prior) instead of keeping their
        maximizer.
    printed : bool
        Maximize the paper's literal ``J_k(tau) = N(y; C x-(tau), R)`` (gated by the innovation
        gate) instead of the innovation likelihood.
    gate : float
        Largest normalized innovation squared accepted (``inf``: no gate).
    iterations : int
        Most probes of the refinement's search (0: no refinement; needs the last sections).
    tolerance : float
        The refinement's tolerance on the switching instant, in units of the sampling step
        (Brent's ``tol``, ``refine`` of ``c/switch_time.c``).
    outputs : tuple of array_like, optional
        ``(C F, C G, C Qd C')`` of the coarse section with each row's own mode's ``C``, shapes
        ``(D L N1, m, n)``, ``(D L N1, m, l)``, ``(D L N1, m, m)`` (:func:`coarse_outputs`;
        computed here when not given).
    """
    sizes: dict[str, int] = {}
    y, u, C, R, mode, prev, F, G, Qd, steps, grid_tau, x0, P0 = checked(
        sizes, "y:NKm u:NKl C:Lmn R:Lmm mode:NK<L prev:NK<L F:Mnn G:Mnl Qd:Mnn steps:D "
        "grid_tau:Dg x0:Nn P0:Nnn", y, u, C, R, mode, prev, F, G, Qd, steps, grid_tau, x0, P0)
    if sizes["D"]:
        which = indices(which, "which", "K", sizes, "D")
    else:  # no interval: nothing is predicted, the table is not read
        which = np.zeros(sizes["K"], dtype=np.int64)
    n_coarse, n_switch = (int(v) for v in levels)
    iterations = int(iterations)
    D, L, g = sizes["D"], sizes["L"], sizes["g"]
    expected = D * L * (1 + L * g + n_coarse + L * n_switch)
    if sizes["M"] != expected:
        raise ValueError(f"F must hold D L (1 + L g + N1 + L (N0 + 1)) = {expected} transitions "
                         f"(D = {D}, L = {L}, g = {g}, levels = {levels}), got {sizes['M']}")
    if iterations < 0 or (iterations and (n_coarse < 1 or n_switch < 2)):
        raise ValueError(f"iterations = {iterations} needs refinement levels, got {levels}")
    tolerance = float(tolerance)
    if not (math.isfinite(tolerance) and tolerance >= 0.0):
        raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance}")
    if outputs is None:
        outputs = coarse_outputs(C, F, G, Qd, D, g, n_coarse)
    sizes["H"] = D * L * n_coarse
    outputs = tuple(checked(sizes, "outputs[0]:Hmn outputs[1]:Hml outputs[2]:Hmm", *outputs))
    predicting = slice(0 if predict_first else 1, None)
    if not D and which[predicting].size:
        raise ValueError("steps must hold the sampling step of every predicted sample, got none")
    N, K, n = sizes["N"], sizes["K"], sizes["n"]
    x, P = np.empty((N, K, n)), np.empty((N, K, n, n))
    loglik, offset = np.empty((N, K)), np.empty((N, K))
    flag = np.empty((N, K), dtype=np.uint8)
    mine, shared = True, False  # per-trial arrays, sliced to each thread's trials; tables
    outcome = run_split(switch_time_filter, [
        (y, mine), (u, mine), (which, shared), (mode, mine), (prev, mine), (C, shared),
        (R, shared), (F, shared), (G, shared), (Qd, shared), (steps, shared),
        (grid_tau, shared), (n_coarse, shared), (n_switch, shared), (x0, mine), (P0, mine),
        (bool(predict_first), shared), (bool(marginal), shared), (bool(printed), shared),
        (check_gate(gate), shared), (iterations, shared), (tolerance, shared),
        (outputs, shared), (LANES, shared), (x, mine), (P, mine), (loglik, mine),
        (offset, mine), (flag, mine)], trials=N, samples=K, block=LANES)
    return SwitchTimeOutput(x, P, loglik, offset, flag, **outcome._asdict())


def coarse_outputs(C, F, G, Qd, D: int, g: int, n_coarse: int):
    """The output map pulled back through each flow of the coarse section of the table:
    ``C_i F``, ``C_i G`` and ``C_i Qd C_i'`` of row ``(d L + i) N1 + c`` (mode ``i`` over
    ``c T / N1``, Shankar et al. eqs (4)-(5) with the exact process noise), with ``C_i`` the
    output matrix of that mode; the last flow of every refinement probe starts from them
    (``refine`` of ``c/switch_time.c``). Shapes ``(D L N1, m, n)``, ``(D L N1, m, l)``,
    ``(D L N1, m, m)``; the last exactly symmetric."""
    C, F, G, Qd = (np.asarray(a, dtype=float) for a in (C, F, G, Qd))
    L, m = C.shape[0], C.shape[1]
    first = D * L * (1 + L * g)
    rows = slice(first, first + D * L * n_coarse)
    Ci = np.broadcast_to(C[None, :, None], (D, L, n_coarse, m, C.shape[2]))
    Ci = Ci.reshape(-1, m, C.shape[2])
    CF, CG = Ci @ F[rows], Ci @ G[rows]
    CQC = Ci @ Qd[rows] @ np.swapaxes(Ci, -1, -2)
    return CF, CG, 0.5 * (CQC + np.swapaxes(CQC, -1, -2))
