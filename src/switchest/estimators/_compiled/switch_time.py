"""The compiled Kalman filter with estimated switching times (Shankar et al. §III-§IV).

``switch_time_run`` filters every trial over every sample inside compiled code, and so does one
call per sample (the streaming ``step``): the kernel :func:`switch_time_filter` holds the one
implementation of the filter, built on the equations of :mod:`.linalg` over blocks of trials
laid across SIMD lanes.

The mode at each sample is known. When it changes over an interval, from ``a`` to ``b``, the
switching instant ``tau`` is estimated from the likelihood of the new measurement,
``J_k(tau) = N(y; C x-(tau), C P-(tau) C' + R)`` (Shankar et al. §IV): the maximizer over the
grid ``tau_i = i T / g - T / (2 g)`` (eq. (23)), optionally refined by Brent's search over the
grid cell around it (:func:`_refine`), or the moment-matched merge of every grid hypothesis
(``marginal``). The filter then predicts with the transition of the estimate (eqs (4)-(5),
(6)-(7)) and updates (eqs (8)-(10), Joseph form).

``J_k`` needs ``C F``, ``C G u`` and ``C Qd C'`` of a hypothesis, not its ``F`` and ``Qd``: the
kernel pulls the output matrix back through the segments of the interval
(:func:`pull_back`, O(m n^2) per segment) and takes the innovation of ``y`` against the state
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
from typing import NamedTuple

import numpy as np

from .arrays import check_gate, checked, indices
from .bank import LANES
from .linalg import (
    ACCEPTED,
    GATED,
    NOT_FINITE,
    NOT_POSITIVE_DEFINITE,
    OK,
    _moments,
    borrow,
    correct,
    gather_matrices,
    gather_rows,
    gather_samples,
    information_or_repair,
    inline,
    innovation,
    jit,
    joseph_lost,
    log_normalize,
    observe,
    predict,
    repair,
    residual,
    symmetric_sum,
    write_lane,
)

__all__ = [
    "SwitchTimeOutput",
    "switch_time_run",
    "switch_time_filter",
    "pull_back",
    "coarse_outputs",
    "REFINE_TOLERANCE",
]

_GOLDEN_STEP = (3.0 - math.sqrt(5.0)) / 2.0  # 1 - 0.618...: Brent's golden-section step
_SQRT_EPS = math.sqrt(np.finfo(np.float64).eps)  # Brent's relative tolerance on the instant
_LOG_2PI = math.log(2.0 * math.pi)
REFINE_TOLERANCE = 1e-4  # Brent's tolerance on the refined instant (tol = 1e-4 T, _refine)


class SwitchTimeOutput(NamedTuple):
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
    status : int
        ``OK`` or the failure code that stopped the kernel (outputs then incomplete).
    repaired, smallest_eigenvalue
        Covariances repaired to their rounding level and the smallest eigenvalue one had
        (``inf`` if none was): see :class:`.imm.IMMOutput`.
    """

    x: np.ndarray
    P: np.ndarray
    loglik: np.ndarray
    offset: np.ndarray
    flag: np.ndarray
    status: int
    repaired: int = 0
    smallest_eigenvalue: float = math.inf


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
        (Brent's ``tol``, :func:`_refine`).
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
    flag, report = np.empty((N, K), dtype=np.uint8), np.empty(2)
    status = switch_time_filter(y, u, which, mode, prev, C, R, F, G, Qd, steps, grid_tau,
                                n_coarse, n_switch, x0, P0, bool(predict_first), bool(marginal),
                                bool(printed), check_gate(gate), iterations, tolerance,
                                outputs, LANES, x, P, loglik, offset, flag, report)
    return SwitchTimeOutput(x, P, loglik, offset, flag, int(status), int(report[0]),
                            float(report[1]))


def coarse_outputs(C, F, G, Qd, D: int, g: int, n_coarse: int):
    """The output map pulled back through each flow of the coarse section of the table:
    ``C_i F``, ``C_i G`` and ``C_i Qd C_i'`` of row ``(d L + i) N1 + c`` (mode ``i`` over
    ``c T / N1``, Shankar et al. eqs (4)-(5) with the exact process noise), with ``C_i`` the
    output matrix of that mode; the last flow of every refinement probe starts from them
    (:func:`_refine`). Shapes ``(D L N1, m, n)``, ``(D L N1, m, l)``, ``(D L N1, m, m)``; the
    last exactly symmetric."""
    C, F, G, Qd = (np.asarray(a, dtype=float) for a in (C, F, G, Qd))
    L, m = C.shape[0], C.shape[1]
    first = D * L * (1 + L * g)
    rows = slice(first, first + D * L * n_coarse)
    Ci = np.broadcast_to(C[None, :, None], (D, L, n_coarse, m, C.shape[2]))
    Ci = Ci.reshape(-1, m, C.shape[2])
    CF, CG = Ci @ F[rows], Ci @ G[rows]
    CQC = Ci @ Qd[rows] @ np.swapaxes(Ci, -1, -2)
    return CF, CG, 0.5 * (CQC + np.swapaxes(CQC, -1, -2))


# ---------------------------------------------------------------- lanes
@jit
def _take_rows(src, lane, ns, dst):
    """``dst[a, c] = src[a, lane[c]]``: the compacted lanes ``lane[:ns]`` of ``src (r, B)``."""
    for a in range(src.shape[0]):
        for c in range(ns):
            dst[a, c] = src[a, lane[c]]


@borrow
def _take_matrices(src, lane, ns, dst):
    """``dst[a, e, c] = src[a, e, lane[c]]``: the compacted lanes of ``src (r, s, B)``."""
    for a in range(src.shape[0]):
        _take_rows(src[a], lane, ns, dst[a])


@jit
def _put_rows(src, lane, ns, dst):
    """``dst[a, lane[c]] = src[a, c]``: compacted lanes back into their places."""
    for a in range(src.shape[0]):
        for c in range(ns):
            dst[a, lane[c]] = src[a, c]


@borrow
def _put_matrices(src, lane, ns, dst):
    """``dst[a, e, lane[c]] = src[a, e, c]``: compacted lanes of ``(r, s, B)`` arrays back."""
    for a in range(src.shape[0]):
        _put_rows(src[a], lane, ns, dst[a])


@borrow
def _gather_transition(F, G, Qd, index, nb, Fl, Gl, Ql):
    """Each lane's transition ``(F, G, Qd)[index[b]]`` of the table, into ``Fl``, ``Gl``,
    ``Ql``."""
    gather_matrices(F, index, nb, Fl)
    gather_matrices(G, index, nb, Gl)
    gather_matrices(Qd, index, nb, Ql)


# ---------------------------------------------------------------- the likelihood J_k(tau)
@inline
def pull_back(E, Go, Qo, F, G, Qd, rows, nb, EQ):
    """Pull the output map ``E (r, n, B)`` back through each lane's segment ``rows[b]`` of the
    table, ``x+ = Phi x + Gam u + w``, ``w ~ N(0, Qd)``, in place: ``Qo <- Qo + E Qd E'``,
    ``Go <- Go + E Gam``, ``E <- E Phi``.

    An interval of segments ``s = 1..S`` (in time order) has ``F = Phi_S ... Phi_1``,
    ``G = sum_s Phi_S ... Phi_{s+1} Gam_s`` and ``Qd = sum_s (Phi_S ... Phi_{s+1}) Qd_s
    (Phi_S ... Phi_{s+1})'`` (Shankar et al. eqs (4)-(5) with the exact process noise; the
    composition of :mod:`switchest.discretize`). Pulled back through ``s = S..1`` from
    ``E = C``, ``Go = 0``, ``Qo = 0``, the map ends as ``E = C F``, ``Go = C G``,
    ``Qo = C Qd C'`` at O(r n^2) per segment; from ``E = I`` it ends as ``F``, ``G``, ``Qd``.
    ``Qo`` comes back exactly symmetric (upper triangle computed, mirrored); ``EQ (r, n, B)``
    is scratch.
    """
    r, n, n_in = E.shape[0], E.shape[1], G.shape[2]
    for a in range(r):
        for c in range(n_in):
            for j in range(n):
                for b in range(nb):
                    Go[a, c, b] += E[a, j, b] * G[rows[b], j, c]
        _row_times_entries(E, Qd, rows, a, nb, EQ)
    symmetric_sum(Qo, EQ, E, nb, Qo)
    for a in range(r):  # E <- E Phi, a row at a time through EQ
        _row_times_entries(E, F, rows, a, nb, EQ)
        for j in range(n):
            for b in range(nb):
                E[a, j, b] = EQ[a, j, b]


@inline
def _row_times_entries(E, table, rows, a, nb, out):
    """``out[a] = E[a] table[rows[b]]`` in every lane ``b``: row ``a`` of ``E (r, n, B)`` times
    each lane's entry of ``table (M, n, n)``."""
    n = E.shape[1]
    for j in range(n):
        for b in range(nb):
            out[a, j, b] = 0.0
        for i in range(n):
            for b in range(nb):
                out[a, j, b] += E[a, i, b] * table[rows[b], i, j]


@inline
def _start(E, Go, Qo, C, nb):
    """``E = C``, ``Go = 0``, ``Qo = 0``: the output map before :func:`pull_back`."""
    for a in range(E.shape[0]):
        for j in range(E.shape[1]):
            for b in range(nb):
                E[a, j, b] = C[a, j, b]
        for c in range(Go.shape[1]):
            for b in range(nb):
                Go[a, c, b] = 0.0
        for c in range(Qo.shape[1]):
            for b in range(nb):
                Qo[a, c, b] = 0.0


@inline
def _likelihood(x, P, y, u, obs, n_obs, R, E, Go, Qo, printed, gate, nb, ye, Re, zero, e, PCt,
                chol, scale, z, nis, loglik, work, bad, J, report):
    """``J_k`` of one hypothesis per lane (Shankar et al. §IV), ``-inf`` where it is rejected.

    From the hypothesis' output map (``E = C F``, ``Go = C G``, ``Qo = C Qd C'``,
    :func:`pull_back`): ``y - C x-(tau) = (y - Go u) - E x`` and ``C P-(tau) C' + R =
    E P E' + (Qo + R)``, so ``J = log N(y - Go u; E x, E P E' + Qo + R)`` is the innovation of
    ``y - Go u`` against ``x``, ``P`` through ``E`` (:func:`.linalg.innovation`), rejected
    (``-inf``) where its normalized square exceeds ``gate`` or the likelihood is not finite.
    ``printed``: the paper's literal ``J = N(y; C x-(tau), R)`` (``P-`` replaced by 0 in the
    likelihood), rejected where its own normalized square is not finite or, with a finite
    gate, where the innovation's fails the gate. ``ye (m, B)``, ``Re (m, m, B)`` are scratch,
    ``zero (n, n, B)`` all zeros; the rest is the workspace of :func:`.linalg.innovation`, which
    repairs a failing ``P`` as the bank does.
    """
    m = y.shape[0]
    residual(u, y, Go, nb, ye)  # y - Go u
    for a in range(m):
        for c in range(m):
            for b in range(nb):
                Re[a, c, b] = R[a, c, b] + Qo[a, c, b]
    if not printed or gate < math.inf:
        status = innovation(x, P, ye, E, Re, obs, n_obs, nb, e, PCt, chol, scale, z, nis, loglik,
                            work, bad, report)
        if status != OK:
            return status
        for b in range(nb):
            J[b] = loglik[b] if math.isfinite(loglik[b]) and nis[b] <= gate else -math.inf
        if not printed:
            return OK
    status = innovation(x, zero, ye, E, R, obs, n_obs, nb, e, PCt, chol, scale, z, nis, loglik,
                        work, bad, report)
    if status != OK:
        return status
    for b in range(nb):
        gated = gate < math.inf and J[b] == -math.inf
        J[b] = loglik[b] if nis[b] < math.inf and not gated else -math.inf
    return OK


# ---------------------------------------------------------------- switching instant
@borrow
def _grid_maximum(sw, tables, opts, ns, d, lane, Fl, Gl, Ql, off, ws, lw, obsv, gs, report):
    """Grid maximum of Shankar et al. eq. (23) for the compacted switched lanes; writes the
    transition of the chosen instant into their lanes of ``Fl``, ``Gl``, ``Ql`` and the instant
    into ``off``, and leaves in ``gs`` the grid index ``best`` and its ``J_k``, ``best_ll``
    (``inf`` where uninformed). Returns the status.

    ``J_k`` (:func:`_likelihood`) is evaluated at every grid instant through its exact
    transition of the table; the first maximum wins. Where the measurement is missing or every
    instant rejects it, it says nothing of the instant: the middle one, ``g // 2``, is taken.
    """
    x, P, y, u, obs, n_obs, Cs, Rs, _, _, pair = sw
    F, G, Qd, grid_tau = tables[0], tables[1], tables[2], tables[4]
    printed, gate = opts[0], opts[1]
    e, PCt, chol, scale, z, nis, loglik, work, bad = ws
    ye, Re, zero = lw
    E, Go, Qo, EQ = obsv
    best, best_ll, J, rows = gs[0], gs[1], gs[2], gs[3]
    g = grid_tau.shape[1]
    first = tables[5]  # the first row of the grid section
    for r in range(g):
        for c in range(ns):
            rows[c] = first + pair[c] * g + r
        _start(E, Go, Qo, Cs, ns)
        pull_back(E, Go, Qo, F, G, Qd, rows, ns, EQ)
        status = _likelihood(x, P, y, u, obs, n_obs, Rs, E, Go, Qo, printed, gate, ns, ye, Re,
                             zero, e, PCt, chol, scale, z, nis, loglik, work, bad, J, report)
        if status != OK:
            return status
        for c in range(ns):
            if r == 0 or J[c] > best_ll[c]:
                best[c], best_ll[c] = r, J[c]
    for c in range(ns):
        if n_obs[c] == 0.0 or best_ll[c] == -math.inf:  # uninformed: the middle instant,
            best[c], best_ll[c] = g // 2, math.inf  # which no probe may replace
        off[lane[c]] = grid_tau[d, best[c]]
        rows[c] = first + pair[c] * g + best[c]
    for i in range(Fl.shape[0]):
        for j in range(Fl.shape[1]):
            for c in range(ns):
                Fl[i, j, lane[c]] = F[rows[c], i, j]
                Ql[i, j, lane[c]] = Qd[rows[c], i, j]
        for j in range(Gl.shape[1]):
            for c in range(ns):
                Gl[i, j, lane[c]] = G[rows[c], i, j]
    return OK


@inline
def _refine(sw, tables, opts, ns, d, lane, Fl, Gl, Ql, off, gs, pk, report):
    """Brent's search of ``J_k`` over the grid cell around the grid maximum (beyond Shankar et
    al.), for each compacted switched lane: ``[tau - T/(2g), tau + T/(2g)]`` clipped to
    ``[0, T]``, started from the grid instant ``tau`` and its ``J_k``. Returns the status.

    The search is Brent's method (Brent, *Algorithms for Minimization without Derivatives*,
    1973, ch. 5; ``fmin`` of Forsythe, Malcolm & Moler, 1977) on ``-J_k``: a parabola through
    the three best points where it falls inside the bracket and moves less than half the step
    before last, else a golden-section step into the larger part; no probe nearer than
    ``tol1 = sqrt(eps) |tau| + tol / 3`` to the best point, with ``tol = opts[3] T``. It
    stops when the best point lies within ``2 tol1 - w / 2`` of the middle of the bracket
    (width ``w``), i.e. the maximizer is bracketed to within about ``2 tol``, or after
    ``iterations`` probes. An uninformed lane (``J_k`` of its grid maximum ``inf``) is not
    searched.

    One step is added to Brent's, for a maximum at an edge of the cell (a switch near a
    sample, or a likelihood rising beyond the cell): golden-section steps close in on an edge
    by 0.618 per probe, about 17 probes from the middle to within ``1e-4 T``. So where a
    golden step is due and the best point and the two before it lie in order toward an edge
    that still bounds the bracket (``x < w < v`` toward the lower edge), more than ``2 tol1``
    from the best point, the edge is probed instead, once per edge; if it is the best point,
    the next probe is ``tol1`` inside it, which closes the bracket where it is worse. On the
    boost converter (1131 searches, Table I's switching) a search then takes 8.1 probes on
    average instead of 11.0 at g = 1, 6.8 instead of 9.9 at g = 3: about 4 instead of 17-19
    for the fifth of searches that end at an edge, as many as before (7-12) for the rest. The
    instants found agree with Brent's within the tolerance, but for one search in a thousand,
    where ``J_k`` has two maxima of nearly equal height in the cell and the two reached
    different ones.

    A probe at ``tau`` is quantized to ``k dt / (N1 N0)``, ``k = j N0 + q``, and its ``J_k``
    is exact there: the output map of ``b`` over ``(N1 - 1 - j) dt / N1`` (``C_b F``, ``C_b G``,
    ``C_b Qd C_b'`` of :func:`coarse_outputs`) is pulled back through the span ``j`` switching
    at ``q`` and ``a`` over ``j dt / N1`` (Shankar et al. eqs (4)-(5) composed as in
    :func:`pull_back`), then
    ``J = log N(y - Go u; E x, E P E' + Qo + R)`` (or the paper's literal ``N(y; C x-(tau),
    R)``) as in :func:`_likelihood`, a lane at a time: the equations of :func:`pull_back` and
    :func:`.linalg.innovation` (equilibrated Cholesky factor, eq. (8)) written out here, in
    one body, for one lane at a time: those functions loop over lanes innermost, and a probe
    has one lane. (Run on them instead, every switched lane probing in step, the refined
    filter took 1.9 times as long on the boost converter: about 9 lanes are too few to fill
    the SIMD registers, and each probe waits for the lane whose search runs longest. Nor did
    searches side by side pay, each in a slot that takes the next lane when its search ends,
    the slots' probes evaluated together so that their chains of divisions, roots and
    logarithms overlap: with the searches' state in arrays and the probe split into inlined
    parts, the refined filter took 1.5 times as long, with one slot as with four.) This
    function is inlined into the kernel: called with its forty arrays, each reference-counted
    (before :func:`switchest._jit.borrow`), it cost the refined filter a quarter of its time.
    A lane whose factorization fails has its ``P`` repaired (:func:`.linalg.repair`) and is
    factored once more.

    The grid instant is kept unless a probe beats it; a winning probe's transition is composed
    exactly (pulled back from ``I``) into the lane's ``Fl``, ``Gl``, ``Ql``, its instant
    written into ``off``.
    """
    x, P, y, u, obs, n_obs, _, Rs, row_a, row_b, pair = sw
    F, G, Qd, steps, grid_tau = tables[0], tables[1], tables[2], tables[3], tables[4]
    coarse, switch, n_coarse, n_switch = tables[6], tables[7], tables[8], tables[9]
    printed, gate, iterations, tolerance = opts
    best, best_ll, win = gs[0], gs[1], gs[4]
    CF, CG, CQC = tables[10], tables[11], tables[12]
    E, EQ, EF, Go, Qo, PCt, chol, scale, e, T1, T2, Gt = pk
    m, n, n_in = E.shape[0], E.shape[1], Go.shape[1]
    dt = steps[d]
    g = grid_tau.shape[1]
    N0 = n_switch - 1
    total = n_coarse * N0
    half = dt / (2 * g)
    tol = tolerance * dt
    first = 0 if not printed or gate < math.inf else 1  # 0: the innovation's J, 1: printed
    for c in range(ns):
        win[c] = -1
        if best_ll[c] == math.inf:  # uninformed: no probe may replace the middle instant
            continue
        top = best_ll[c]
        tau = grid_tau[d, best[c]]
        lo, hi = min(max(tau - half, 0.0), dt), min(max(tau + half, 0.0), dt)
        edge_lo, edge_hi = lo, hi  # the cell's edges (NaN once probed: an edge step)
        x_b = w = v = tau  # minimize f = -J: x_b the best point, w the second, v the last w
        fx = fw = fv = -top
        e_old = step = 0.0  # the step before last, the last step
        inward = 0.0  # after an edge that won: the direction into the cell
        for _ in range(iterations):
            xm = 0.5 * (lo + hi)
            tol1 = _SQRT_EPS * abs(x_b) + tol / 3.0
            tol2 = 2.0 * tol1
            if abs(x_b - xm) <= tol2 - 0.5 * (hi - lo):
                break
            edge = 0.0  # 1 / -1: this probe is the edge step toward lo / hi
            if inward != 0.0:  # tol1 inside the edge that won: if worse, the bracket closes
                at, inward = x_b + inward * tol1, 0.0
            else:
                golden = True
                if abs(e_old) > tol1:  # a parabola through x_b, w, v
                    r = (x_b - w) * (fx - fv)
                    q = (x_b - v) * (fx - fw)
                    p = (x_b - v) * q - (x_b - w) * r
                    q = 2.0 * (q - r)
                    if q > 0.0:
                        p = -p
                    q = abs(q)
                    r = e_old
                    e_old = step
                    if abs(p) < abs(0.5 * q * r) and p > q * (lo - x_b) and p < q * (hi - x_b):
                        golden = False
                        step = p / q
                        if (x_b + step) - lo < tol2 or hi - (x_b + step) < tol2:
                            step = tol1 if xm - x_b >= 0.0 else -tol1
                if golden and lo == edge_lo and x_b < w < v and x_b - lo > tol2:
                    at, edge, edge_lo = lo, 1.0, math.nan  # heading for lo: probe it
                elif golden and hi == edge_hi and x_b > w > v and hi - x_b > tol2:
                    at, edge, edge_hi = hi, -1.0, math.nan  # heading for hi: probe it
                else:
                    if golden:  # into the larger part of the bracket
                        e_old = lo - x_b if x_b >= xm else hi - x_b
                        step = _GOLDEN_STEP * e_old
                    if abs(step) >= tol1:
                        at = x_b + step
                    else:
                        at = x_b + (tol1 if step >= 0.0 else -tol1)
            # ---- the probe: J_k at the table instant k (Shankar et al. §IV)
            k = min(max(int(math.floor(at / dt * total + 0.5)), 0), total)
            j = k // N0
            s = k - j * N0
            if j == n_coarse:  # at the end of the interval: the last span, switching at its end
                j, s = n_coarse - 1, N0
            ra = coarse + row_a[c] * n_coarse + j
            rb = row_b[c] * n_coarse + n_coarse - 1 - j
            for a in range(m):  # C b over (N1 - 1 - j) dt / N1: E, Go, Qo from the table
                for i in range(n):
                    E[a, i] = CF[rb, a, i]
                for i in range(n_in):
                    Go[a, i] = CG[rb, a, i]
                for i in range(m):
                    Qo[a, i] = CQC[rb, a, i]
            for flow in range(2):  # pulled back through the span, then a (see pull_back)
                row = switch + pair[c] * n_switch + s if flow == 0 else ra
                for a in range(m):  # Go <- Go + E Gam; EQ = E Qd, EF = E Phi
                    for i in range(n_in):
                        acc = Go[a, i]
                        for h in range(n):
                            acc += E[a, h] * G[row, h, i]
                        Go[a, i] = acc
                    for i in range(n):
                        acc, acc_f = 0.0, 0.0
                        for h in range(n):
                            acc += E[a, h] * Qd[row, h, i]
                            acc_f += E[a, h] * F[row, h, i]
                        EQ[a, i] = acc
                        EF[a, i] = acc_f
                for a in range(m):  # Qo <- Qo + E Qd E', symmetric
                    for i in range(a, m):
                        acc = Qo[a, i]
                        for h in range(n):
                            acc += EQ[a, h] * E[i, h]
                        Qo[a, i] = acc
                        Qo[i, a] = acc
                E, EF = EF, E  # E <- E Phi
            J = -math.inf
            kind, repaired = first, False
            while kind < 2:  # the innovation of y - Go u through E (kind 0: with P; 1: without)
                for a in range(m):  # e = y - Go u - E x, P E' over the observed components
                    acc = y[a, c]
                    for i in range(n_in):
                        acc -= Go[a, i] * u[i, c]
                    for h in range(n):
                        acc -= E[a, h] * x[h, c]
                    e[a] = acc if obs[a, c] > 0.0 else 0.0
                    for i in range(n):
                        acc = 0.0
                        if kind == 0:
                            for h in range(n):
                                acc += P[i, h, c] * E[a, h]
                        PCt[i, a] = acc * obs[a, c]
                finite, positive = True, True
                log_det, det = 0.0, 1.0
                for a in range(m):  # S = E P E' + Qo + R (kind 1: R), lower triangle; D
                    for i in range(a + 1):
                        acc = (Rs[a, i, c] + Qo[a, i] if kind == 0 else Rs[a, i, c]) * obs[i, c]
                        for h in range(n):
                            acc += E[a, h] * PCt[h, i]
                        unit = 1.0 if a == i else 0.0
                        chol[a, i] = acc * obs[a, c] + unit * (1.0 - obs[a, c])
                    diag = chol[a, a]
                    finite &= math.isfinite(diag)
                    positive &= diag > 0.0
                    scale[a] = 1.0 / math.sqrt(diag)
                    log_det += math.log(diag)
                if not finite:
                    return NOT_FINITE
                for h in range(m):  # D^-1/2 S D^-1/2 = L L', column by column
                    pivot = chol[h, h] * scale[h] * scale[h]
                    for i in range(h):
                        pivot -= chol[h, i] * chol[h, i]
                    positive &= pivot > 0.0
                    chol[h, h] = math.sqrt(pivot)
                    det *= pivot
                    for a in range(h + 1, m):
                        acc = chol[a, h] * scale[a] * scale[h]
                        for i in range(h):
                            acc -= chol[a, i] * chol[h, i]
                        chol[a, h] = acc / chol[h, h]
                if not positive:
                    if kind == 0 and not repaired and repair(P, c, False, report):
                        repaired = True
                        continue
                    return NOT_POSITIVE_DEFINITE
                nis = 0.0
                for a in range(m):  # z = L^-1 D^-1/2 e (into e), nis = |z|^2
                    acc = scale[a] * e[a]
                    for i in range(a):
                        acc -= chol[a, i] * e[i]
                    acc /= chol[a, a]
                    e[a] = acc
                    nis += acc * acc
                loglik = -0.5 * (nis + log_det + math.log(det) + n_obs[c] * _LOG_2PI)
                if kind == 0:  # rejected beyond the gate or where not finite
                    J = loglik if math.isfinite(loglik) and nis <= gate else -math.inf
                    if not printed:
                        break
                else:  # printed: rejected where its own nis is not finite, or gated
                    gated = gate < math.inf and J == -math.inf
                    J = loglik if nis < math.inf and not gated else -math.inf
                kind += 1
            # ---- Brent's bookkeeping
            if J > top:
                top, win[c] = J, k
            fu = -J
            if fu <= fx:
                inward = edge
                if at >= x_b:
                    lo = x_b
                else:
                    hi = x_b
                v, fv, w, fw, x_b, fx = w, fw, x_b, fx, at, fu
            else:
                if at < x_b:
                    lo = at
                else:
                    hi = at
                if fu <= fw or w == x_b:
                    v, fv, w, fw = w, fw, at, fu
                elif fu <= fv or v == x_b or v == w:
                    v, fv = at, fu
        if win[c] < 0:
            continue
        # ---- a probe won: its instant, and its transition composed in time order
        b = lane[c]
        off[b] = win[c] * (dt / total)
        j, s = win[c] // N0, win[c] % N0
        if j == n_coarse:
            j, s = n_coarse - 1, N0
        for flow in range(3):  # a over j dt / N1, the span, b over the rest
            if flow == 0:
                row = coarse + row_a[c] * n_coarse + j
            elif flow == 1:
                row = switch + pair[c] * n_switch + s
            else:
                row = coarse + row_b[c] * n_coarse + n_coarse - 1 - j
            if flow == 0:
                for h in range(n):
                    for i in range(n):
                        Fl[h, i, b] = F[row, h, i]
                        Ql[h, i, b] = Qd[row, h, i]
                    for i in range(n_in):
                        Gl[h, i, b] = G[row, h, i]
                continue
            for h in range(n):  # T1 = Phi F, T2 = Phi Qd, Gt = Phi G + Gam
                for i in range(n):
                    acc, acc_q = 0.0, 0.0
                    for k2 in range(n):
                        acc += F[row, h, k2] * Fl[k2, i, b]
                        acc_q += F[row, h, k2] * Ql[k2, i, b]
                    T1[h, i] = acc
                    T2[h, i] = acc_q
                for i in range(n_in):
                    acc = G[row, h, i]
                    for k2 in range(n):
                        acc += F[row, h, k2] * Gl[k2, i, b]
                    Gt[h, i] = acc
            for h in range(n):  # F <- Phi F, G <- Phi G + Gam, Qd <- Phi Qd Phi' + Qd_s
                for i in range(n):
                    Fl[h, i, b] = T1[h, i]
                for i in range(n_in):
                    Gl[h, i, b] = Gt[h, i]
                for i in range(h, n):
                    acc = Qd[row, h, i]
                    for k2 in range(n):
                        acc += T2[h, k2] * F[row, i, k2]
                    Ql[h, i, b] = acc
            for h in range(n):
                for i in range(h):
                    Ql[h, i, b] = Ql[i, h, b]
    return OK


# ---------------------------------------------------------------- measurement update
@borrow
def _update(x, P, y, C, R, obs, n_obs, gate, nb, ws, cs, use, report):
    """Measurement update of every lane, as the bank does for one mode
    (:func:`.bank.filter_bank`): innovation (:func:`.linalg.innovation`, repairing), the gate
    (``use``: the normalized innovation squared within ``gate`` and a finite likelihood), the
    Joseph-form correction of the lanes that use it (Shankar et al. eqs (8)-(10)), and the
    information form where Joseph's loses its digits, a repair where neither resolves ``P``
    (:func:`.linalg.information_or_repair`). ``ws`` is the workspace of
    :func:`.linalg.innovation`, ``cs`` ``(gain, T, AP, prior, root, lost)``. Returns the
    status."""
    nis, loglik = ws[5], ws[6]
    gain, T, AP, prior, root, lost = cs
    status = innovation(x, P, y, C, R, obs, n_obs, nb, *ws, report)
    if status != OK:
        return status
    for b in range(nb):
        use[b] = math.isfinite(loglik[b]) and nis[b] <= gate
    correct(x, P, C, R, use, nb, *ws[1:5], gain, T, AP, prior)
    if joseph_lost(P, prior, use, nb, root, lost):  # rare: lane by lane
        information_or_repair(P, prior, C, R, obs, n_obs, lost, nb, report)
    return OK


@borrow
def _merge(sw, tables, gate, ns, d, lane, x, P, lik, flg, off, ws, cs, hyp, flow, xs, report):
    """The switching instant marginalized over the grid (beyond Shankar et al.), for the
    compacted switched lanes: every grid instant ``tau_i`` is predicted (eqs (6)-(7)) and
    updated (:func:`_update`), the hypotheses get the posterior weights
    ``w_i = p(y | tau_i) / sum_k p(y | tau_k)`` of a uniform prior (log-sum-exp) and are merged
    by moment matching (:func:`.linalg._moments`); the likelihood is the grid mean
    ``(1/g) sum_i p(y | tau_i)`` and the instant the posterior mean ``sum_i w_i tau_i``. Where
    every instant rejects the measurement, the predictions are weighed equally and the sample
    is flagged ``GATED``. Writes the lanes' ``x``, ``P``, ``lik``, ``flg``, ``off``; returns the
    status."""
    xc, Pc, y, u, obs, n_obs, Cs, Rs, _, _, pair = sw
    F, G, Qd, grid_tau, first = tables[0], tables[1], tables[2], tables[4], tables[5]
    xh, Ph, llh, wh, total, xm, Pm, use, index = hyp
    Phi, Gam, Q = flow
    AP = cs[2]
    loglik = ws[6]
    g = grid_tau.shape[1]
    for r in range(g):
        for c in range(ns):
            index[c] = first + pair[c] * g + r
        _gather_transition(F, G, Qd, index, ns, Phi, Gam, Q)
        for i in range(xc.shape[0]):
            for c in range(ns):
                xh[r, i, c] = xc[i, c]
            for j in range(xc.shape[0]):
                for c in range(ns):
                    Ph[r, i, j, c] = Pc[i, j, c]
        predict(xh[r], Ph[r], Phi, Gam, u, Q, ns, AP, xs)
        status = _update(xh[r], Ph[r], y, Cs, Rs, obs, n_obs, gate, ns, ws, cs, use, report)
        if status != OK:
            return status
        for c in range(ns):
            llh[r, c] = loglik[c] if use[c] else -math.inf
    for c in range(ns):
        rejected = True
        for r in range(g):
            rejected &= llh[r, c] == -math.inf
        if rejected:  # weigh the predictions equally
            for r in range(g):
                llh[r, c] = 0.0
        flg[lane[c]] = GATED if rejected else ACCEPTED
    log_normalize(llh, wh, total, ns)  # w_i = p(y | tau_i) / sum_k p(y | tau_k)
    _moments(wh, xh, Ph, ns, xm, Pm)
    _put_rows(xm, lane, ns, x)
    _put_matrices(Pm, lane, ns, P)
    log_g = math.log(g)
    for c in range(ns):
        tau = 0.0
        for r in range(g):
            tau += wh[r, c] * grid_tau[d, r]
        off[lane[c]] = tau
        lik[lane[c]] = total[c] - log_g if flg[lane[c]] == ACCEPTED else 0.0
    return OK


# ---------------------------------------------------------------- the kernel
@jit
def switch_time_filter(y, u, which, mode, prev, C, R, F, G, Qd, steps, grid_tau, n_coarse,
                       n_switch, x_init, P_init, predict_first, marginal, printed, gate,
                       iterations, tolerance, outputs, lanes, x_out, P_out, loglik_out,
                       offset_out, flag_out, report):
    """Filter ``N`` trials over ``K`` samples, estimating the switching instant of every
    interval whose mode changes (Shankar et al. §IV).

    Parameters
    ----------
    y, u, which, mode, prev, C, R, F, G, Qd, steps, grid_tau
        As in :func:`switch_time_run` (the table's layout in the module docstring).
    n_coarse, n_switch : int
        ``N1`` and ``N0 + 1``: the refinement sections' lengths per mode and per mode pair (0
        without).
    x_init, P_init : (N, n), (N, n, n) float64
        Each trial's state before the first sample.
    predict_first : bool
        Whether the first sample is predicted into (a streaming step) or only updated.
    marginal, printed : bool
    gate : float
    iterations : int
        The most probes of the refinement's search per switched lane (0: no refinement).
    lanes : int
        Trials per block.
    x_out, P_out, loglik_out, offset_out, flag_out
        Written: the posterior ``(N, K, n)``, ``(N, K, n, n)``, the log-likelihood, the
        estimated switching offset (NaN without a switch) and the flag ``(N, K)``.
    report : (2,) float64
        Written: repairs and the smallest eigenvalue before one (:func:`.linalg.repair`).

    Returns
    -------
    status : int
        ``OK``, or the failure code of the innovation covariance (of a grid instant, a
        refinement probe or the update) that stopped the kernel (outputs then incomplete).

    Notes
    -----
    At each sample the kernel compacts the lanes whose mode changed, estimates their switching
    instant (:func:`_grid_maximum`, :func:`_refine`; every lane's transition is otherwise the
    no-switch one of the mode before the interval), predicts every lane (eqs (6)-(7)) and
    updates it (:func:`_update`); with ``marginal`` the switched lanes' posteriors are then
    replaced by the merge of their grid hypotheses (:func:`_merge`). The predicted state of a
    lane whose measurement is rejected is its posterior, as for a missing measurement.
    """
    N, K, m = y.shape
    n, n_in, L = x_init.shape[1], u.shape[2], C.shape[0]
    D, g = grid_tau.shape
    B = lanes
    coarse = D * L * (1 + L * g)
    tables = (F, G, Qd, steps, grid_tau, D * L, coarse, coarse + D * L * n_coarse, n_coarse,
              n_switch, outputs[0], outputs[1], outputs[2])  # with the first rows of the grid,
    # coarse and switch sections, and the output map pulled back through the coarse section
    opts = (printed, gate, iterations, tolerance)
    x, P = np.empty((n, B)), np.empty((n, n, B))
    yl, ul, obs, n_obs = np.empty((m, B)), np.empty((n_in, B)), np.empty((m, B)), np.empty(B)
    Fl, Gl, Ql = np.empty((n, n, B)), np.empty((n, n_in, B)), np.empty((n, n, B))
    Cl, Rl = np.empty((m, n, B)), np.empty((m, m, B))
    index, use = np.empty(B, dtype=np.int64), np.empty(B, dtype=np.bool_)
    lik, off, flg = np.empty(B), np.empty(B), np.empty(B, dtype=np.uint8)
    ws = (np.empty((m, B)), np.empty((n, m, B)), np.empty((m, m, B)), np.empty((m, B)),
          np.empty((m, B)), np.empty(B), np.empty(B), np.empty((3, B)),
          np.zeros(B, dtype=np.bool_))
    cs = (np.empty((n, m, B)), np.empty((n, m, B)), np.empty((n, n, B)), np.empty((n, n, B)),
          np.empty((n, B)), np.empty(B, dtype=np.bool_))
    xs = np.empty((n, B))
    lane, mode_c = np.empty(B, dtype=np.int64), np.empty(B, dtype=np.int64)
    sw = (np.empty((n, B)), np.empty((n, n, B)), np.empty((m, B)), np.empty((n_in, B)),
          np.empty((m, B)), np.empty(B), np.empty((m, n, B)), np.empty((m, m, B)),
          np.empty(B, dtype=np.int64), np.empty(B, dtype=np.int64), np.empty(B, dtype=np.int64))
    lw = (np.empty((m, B)), np.empty((m, m, B)), np.zeros((n, n, B)))
    obsv = (np.empty((m, n, B)), np.empty((m, n_in, B)), np.empty((m, m, B)), np.empty((m, n, B)))
    flow = (np.empty((n, n, B)), np.empty((n, n_in, B)), np.empty((n, n, B)))
    gs = (np.empty(B, dtype=np.int64), np.empty(B), np.empty(B), np.empty(B, dtype=np.int64),
          np.empty(B, dtype=np.int64))
    pk = (np.empty((m, n)), np.empty((m, n)), np.empty((m, n)), np.empty((m, n_in)),
          np.empty((m, m)), np.empty((n, m)), np.empty((m, m)), np.empty(m), np.empty(m),
          np.empty((n, n)), np.empty((n, n)), np.empty((n, n_in)))
    G_h = g if marginal else 0
    hyp = (np.empty((G_h, n, B)), np.empty((G_h, n, n, B)), np.empty((G_h, B)),
           np.empty((G_h, B)), np.empty(B), np.empty((n, B)), np.empty((n, n, B)),
           np.empty(B, dtype=np.bool_), np.empty(B, dtype=np.int64))
    report[0], report[1] = 0.0, math.inf
    for i0 in range(0, N, B):
        nb = min(B, N - i0)
        gather_rows(x_init, i0, nb, x)
        for r in range(n):
            for c in range(n):
                for b in range(nb):
                    P[r, c, b] = P_init[i0 + b, r, c]
        for k in range(K):
            gather_samples(y, i0, nb, k, yl)
            observe(yl, nb, obs, n_obs)
            ns, d = 0, 0
            for b in range(nb):
                off[b] = math.nan
            if k > 0 or predict_first:
                d = which[k]
                gather_samples(u, i0, nb, k, ul)
                for b in range(nb):
                    before, after = prev[i0 + b, k], mode[i0 + b, k]
                    index[b] = d * L + before  # no switch: the mode before the interval
                    if before != after:
                        lane[ns], mode_c[ns] = b, after
                        sw[8][ns], sw[9][ns] = d * L + before, d * L + after
                        sw[10][ns] = (d * L + before) * L + after
                        ns += 1
                _gather_transition(F, G, Qd, index, nb, Fl, Gl, Ql)
                if ns:
                    _take_rows(x, lane, ns, sw[0])
                    _take_matrices(P, lane, ns, sw[1])
                    _take_rows(yl, lane, ns, sw[2])
                    _take_rows(ul, lane, ns, sw[3])
                    _take_rows(obs, lane, ns, sw[4])
                    for c in range(ns):
                        sw[5][c] = n_obs[lane[c]]
                    gather_matrices(C, mode_c, ns, sw[6])
                    gather_matrices(R, mode_c, ns, sw[7])
                if ns and not marginal:
                    status = _grid_maximum(sw, tables, opts, ns, d, lane, Fl, Gl, Ql, off, ws,
                                           lw, obsv, gs, report)
                    if status == OK and iterations:
                        status = _refine(sw, tables, opts, ns, d, lane, Fl, Gl, Ql, off, gs,
                                         pk, report)
                    if status != OK:
                        return status
                predict(x, P, Fl, Gl, ul, Ql, nb, cs[2], xs)
            for b in range(nb):
                index[b] = mode[i0 + b, k]
            gather_matrices(C, index, nb, Cl)
            gather_matrices(R, index, nb, Rl)
            status = _update(x, P, yl, Cl, Rl, obs, n_obs, gate, nb, ws, cs, use, report)
            if status != OK:
                return status
            for b in range(nb):
                lik[b] = ws[6][b] if use[b] else 0.0
                flg[b] = ACCEPTED if use[b] else GATED
            if ns and marginal:
                status = _merge(sw, tables, gate, ns, d, lane, x, P, lik, flg, off, ws, cs,
                                hyp, flow, xs, report)
                if status != OK:
                    return status
            for b in range(nb):
                i = i0 + b
                loglik_out[i, k] = lik[b]
                offset_out[i, k] = off[b]
                flag_out[i, k] = flg[b]
                write_lane(x, P, b, i, k, x_out, P_out)
    return OK
