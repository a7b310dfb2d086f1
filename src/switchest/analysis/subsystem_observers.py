"""Mean-square design of subsystem observers for randomly switched systems (Wang et al., seed 003).

The observers, their sub-states and their sampled error system
:math:`e_{k+1} = \\Lambda(\\alpha_k) e_k + \\Gamma(\\alpha_k) d_k` (Theorem 1, eq. (15)) are
built in :mod:`switchest.analysis.subsystem_error_dynamics`, whose names are exported here too.
This module answers the paper's design questions with the mathematically right quantities:

* the critical interval (Theorem 3, eq. (20); Example 2's per-component
  thresholds; the exact fast-observer threshold) (:func:`critical_interval`);
* gains: per-mode pole placement, the whole family of placing gains, the
  Kalman-Bucy gains of Example 1, Example 2's admissible gain bounds, and the
  gain that minimizes the steady-state MS error (§5.2) (:func:`place_gains`,
  :func:`pole_placement_gain`, :func:`kalman_bucy_gains`,
  :func:`decoupled_gain_bounds`, :func:`optimal_gains`).

Gains are given in state coordinates, as in :func:`substate_gains`.

Paper discrepancies (each tested in ``tests/analysis/test_subsystem_observers.py``; those of
Theorem 2 and eq. (21) are in :mod:`switchest.analysis.subsystem_error_dynamics`):

* Theorem 3's step (20),
  :math:`\\mathbb{E} \\lVert \\Lambda^2 F e^{A_k T} \\Phi \\rVert^2 \\le q_{\\max} h(T)`, has no
  justification (the projection :math:`\\Lambda^2` only removes block i); the bound it
  defines (:attr:`CriticalInterval.printed_t_max`) is kept because §6's
  :math:`T_{\\max} = 0.7365` is that bound. The existence claim itself is right for the
  exact MS test: in the limit of infinitely fast sub-observers the open-loop
  second-moment operator has spectral radius below 1 at :math:`T = 0` (an error
  surviving every mode's projection lies in :math:`\\ker F = \\{0\\}`), hence on
  :math:`[0, \\mathrm{fast\\_observer})` (:attr:`CriticalInterval.fast_observer`).
* The paper mixes :math:`e^{(a-L)T}` (Example 2's gain bounds, Example 4's gammas)
  and :math:`e^{2(a-L)T}` (Examples 1-2's gammas); second moments need the latter.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import LinAlgError, solve_continuous_are
from scipy.optimize import brentq, minimize

from .._checks import float_array, positive_scalar
from ..discretize import interval, mode_steps
from ..system import SwitchedLinearSystem
from ._lmi import rounding_allowance
from .stability import ms_stable_iid, spectral_radius
from .subsystem_error_dynamics import (
    ErrorDynamics,
    MSConvergence,
    SteadyState,
    SubsystemStructure,
    _open_loop,
    _probabilities,
    _structure,
    error_dynamics,
    ms_convergence,
    second_moments,
    steady_state,
    substate_gains,
    subsystem_structure,
)

__all__ = [
    "CriticalInterval",
    "ErrorDynamics",
    "GainBounds",
    "MSConvergence",
    "OptimalGains",
    "SteadyState",
    "SubsystemStructure",
    "critical_interval",
    "critical_interval_nbytes",
    "decoupled_gain_bounds",
    "error_dynamics",
    "kalman_bucy_gains",
    "ms_convergence",
    "optimal_gains",
    "place_gains",
    "pole_placement_gain",
    "second_moments",
    "steady_state",
    "substate_gains",
    "subsystem_structure",
]

_GRID_POINTS = 96  # log-spaced T grid on which the first threshold crossing is located


# ---------------------------------------------------------------------- results
@dataclass(frozen=True)
class CriticalInterval:
    """Critical switching intervals (:func:`critical_interval`); ``inf`` if none in range.

    Attributes
    ----------
    printed_t_max : float
        Smallest :math:`T` with :math:`q_{\\max} h(T) = 1`,
        :math:`h(T) = \\max_i \\lVert F e^{A_i T} \\Phi \\rVert^2`, :math:`q_{\\max}` the largest
        probability that a block runs open loop (Wang et al. eq. (20); their
        :math:`\\max_i (1 - p_i)` when every mode has its own block).
        The §6 :math:`T_{\\max}`; not a proven bound (module docstring).
    fast_observer : float
        Smallest :math:`T` with :math:`\\rho(\\sum_i p_i O_i \\otimes O_i) = 1`,
        :math:`O_i = \\Lambda(i)` with its closed-loop block set to zero: below it, fast enough
        sub-observers are MS convergent.
    per_block : ndarray, shape (B,)
        Per block g, the smallest :math:`T` with
        :math:`\\rho(\\sum_{b(i) \\ne g} p_i D_i \\otimes D_i) = 1`,
        :math:`D_i = F_g e^{A_i T} \\Phi_g`: the threshold of block g on its own (Example 2's
        :math:`T_{\\max}^1, T_{\\max}^2`). Above it no gain makes block g MS convergent when the
        blocks decouple.
    q_max : float
        The :math:`q_{\\max}` of ``printed_t_max``.
    """

    printed_t_max: float
    fast_observer: float
    per_block: np.ndarray
    q_max: float


@dataclass(frozen=True)
class GainBounds:
    """Admissible scalar gains of a decoupled design (:func:`decoupled_gain_bounds`).

    Attributes
    ----------
    mode : ndarray of int, shape (B,)
        The mode closing the loop on each (one-dimensional) block.
    open_loop : ndarray, shape (B,)
        :math:`o_g = \\sum_{i \\ne \\mathrm{mode}} p_i (F_g e^{A_i T} \\Phi_g)^2`, the block's
        open-loop second-moment factor.
    max_rate : ndarray, shape (B,)
        Closed-loop rates :math:`a_c` with :math:`p e^{2 a_c T} + o_g < 1` are those below it
        (``-inf`` when :math:`o_g \\ge 1`).
    min_loop_gain : ndarray, shape (B,)
        :math:`L C_2 > A_{22} - \\mathrm{max\\_rate}`: the loop gain bound (Example 2's
        :math:`L_1 > \\dots, L_2 > \\dots` for unit output gains).
    feasible : ndarray of bool, shape (B,)
        Per block: :math:`o_g < 1` beyond its rounding (some gain closes that block's loop).
    """

    mode: np.ndarray
    open_loop: np.ndarray
    max_rate: np.ndarray
    min_loop_gain: np.ndarray
    feasible: np.ndarray

    @property
    def holds(self) -> bool:
        """Every block is ``feasible``: admissible gains exist for every block."""
        return bool(np.all(self.feasible))


@dataclass(frozen=True)
class OptimalGains:
    """Outcome of :func:`optimal_gains`.

    Attributes
    ----------
    gains : ndarray, shape (L, n, m)
        Gains (state coordinates) minimizing the steady-state MS error.
    mu : float
        Their :math:`\\operatorname{tr} V` (or :math:`\\operatorname{tr} V_x`, per the
        objective).
    radius : float
        MS spectral radius at the optimum (:math:`< 1`).
    holds : bool
        The optimizer's verdict: it converged to a (local) minimum. A numerical verdict,
        not a proof; ``radius`` is below ``max_radius`` whatever it says.
    """

    gains: np.ndarray
    mu: float
    radius: float
    holds: bool


# ---------------------------------------------------------------------- critical interval
def critical_interval(
    system: SwitchedLinearSystem, p, *, structure: SubsystemStructure | None = None
) -> CriticalInterval:
    """Critical switching intervals of Wang et al. Theorem 3 and Example 2.

    Each threshold is the first crossing of 1, located on a log-spaced grid of
    :math:`T` up to :math:`40 / \\max_i \\lVert A_i \\rVert` and refined by Brent's method;
    ``inf`` when there is no crossing in that range. See :class:`CriticalInterval`.
    """
    structure = _structure(system, structure)
    p = _probabilities(p, system.n_modes)
    scale = max(1.0, float(np.max(np.linalg.norm(system.A, ord=2, axis=(1, 2)))))
    grid = np.geomspace(1e-6, 40.0, _GRID_POINTS) / scale
    open_prob = np.array([1.0 - p[structure.block == b].sum() for b in range(structure.n_blocks)])
    q_max = float(open_prob.max())

    def exps(Ts):
        Ts = np.asarray(Ts, dtype=float)
        return interval(system, Ts[:, None], np.arange(system.n_modes)[:, None]).F  # (G, L, n, n)

    def theorem3(Ts):
        h = np.linalg.norm(structure.F @ exps(Ts) @ structure.Phi, ord=2, axis=(-2, -1)) ** 2
        return q_max * h.max(axis=1)  # eq. (20): q_max h(T)

    def fast(Ts):
        return _radius(p, _open_loop(structure, exps(Ts)))

    def block_fn(g):
        r = structure.rows(g)
        weight = np.where(structure.block == g, 0.0, p)

        def fn(Ts):
            D = structure.F_blocks[g] @ exps(Ts) @ structure.Phi[:, r]
            return _radius(weight, D)

        return fn

    per_block = np.array([_first_crossing(block_fn(g), grid) for g in range(structure.n_blocks)])
    return CriticalInterval(
        printed_t_max=_first_crossing(theorem3, grid),
        fast_observer=_first_crossing(fast, grid),
        per_block=per_block,
        q_max=q_max,
    )


def critical_interval_nbytes(system: SwitchedLinearSystem) -> float:
    """Memory of the :math:`n^2 \\times n^2` second-moment matrices :func:`critical_interval`
    stacks over its grid of :math:`T`: :math:`8 G n^4` bytes (:math:`G = 96` grid points, at most
    :math:`n` sub-states)."""
    return 8.0 * _GRID_POINTS * float(system.n_states) ** 4


# ---------------------------------------------------------------------- gains
def place_gains(
    structure: SubsystemStructure, poles: Sequence, *, method: str = "YT"
) -> np.ndarray:
    """Per-mode pole placement of the sub-observers (Wang et al. §4.2, §6).

    Mode i's gain places the eigenvalues of :math:`A_c^i = A_{22}^i - L_i C_2^i` at
    ``poles[i]`` with :func:`scipy.signal.place_poles` on the dual pair. Output
    channels that carry no information in mode i (zero rows of :math:`C_2^i`, e.g. a
    lost packet) are removed first: the gain is designed on an orthonormal basis
    of the row space of :math:`C_2^i` and is zero on the rest. With one remaining
    output the gain is unique (Ackermann); with several it is not, and
    ``method`` chooses one (MATLAB's ``place`` chooses another; see
    :func:`pole_placement_gain`).

    Parameters
    ----------
    structure : SubsystemStructure
    poles : sequence of length L
        ``poles[i]``: the :math:`n_i` desired eigenvalues of mode i's sub-observer
        (``None`` or empty for a mode that observes nothing).
    method : {"YT", "KNV0"}
        Passed to :func:`scipy.signal.place_poles`.

    Returns
    -------
    ndarray, shape (L, n, m)
        Gains in state coordinates (:math:`F_b^\\top L_i`).
    """
    from scipy.signal import place_poles  # scipy.signal: most of a second to import
    L, n = structure.block.size, structure.F.shape[1]
    m = structure.C2[0].shape[0]
    if isinstance(poles, (str, bytes)) or not isinstance(poles, Sequence) or len(poles) != L:
        raise ValueError(
            f"poles must be a sequence of length L = {L} (one entry per mode), got {poles!r}"
        )
    gains = np.zeros((L, n, m))
    for i in range(L):
        size = structure.A22[i].shape[0]
        want = np.zeros(0) if poles[i] is None else np.asarray(poles[i], dtype=complex).ravel()
        if want.size != size:
            raise ValueError(
                f"poles[{i}] must hold n_{i} = {size} poles (mode {i}'s observable sub-state), got "
                f"{want.size}"
            )
        if size == 0:
            continue
        U, s, Vh = np.linalg.svd(structure.C2[i], full_matrices=False)
        keep = s > 1e-12 * max(1.0, s[0])
        reduced = s[keep, None] * Vh[keep]  # orthonormal-basis outputs: C2 = U_r reduced
        want = want.real if np.all(want.imag == 0) else want
        K = place_poles(structure.A22[i].T, reduced.T, want, method=method).gain_matrix
        Lsub = K.T @ U[:, keep].T  # L_i C2 = K' U_r' U_r reduced = K' reduced
        gains[i] = structure.F_blocks[structure.block[i]].T @ Lsub
    return gains


def pole_placement_gain(A, C, poles, directions) -> np.ndarray:
    """Every observer gain that places distinct real poles, by its free parameters.

    For :math:`A - L C` with eigenvalues :math:`\\lambda_j` and left eigenvectors :math:`w_j`,
    :math:`w_j^\\top (A - \\lambda_j I) = g_j^\\top C` with :math:`g_j = L^\\top w_j`; choosing the
    output directions :math:`g_j` fixes :math:`w_j^\\top = g_j^\\top C (A - \\lambda_j I)^{-1}` and
    :math:`L = (W^\\top)^{-1} G^\\top`. With one output every :math:`g_j` is a scalar and the gain
    is unique; with :math:`m` outputs each pole leaves :math:`m - 1` free parameters — which is
    why Wang et al.'s ``place`` gain for the two-output 5-bus mode cannot be
    reproduced by another implementation, only by its directions.

    Parameters
    ----------
    A : array_like, shape (n, n)
    C : array_like, shape (m, n)
    poles : array_like, shape (n,)
        Distinct real poles, none an eigenvalue of :math:`A`.
    directions : array_like, shape (n, m)
        :math:`g_j` per pole (any nonzero scale).

    Returns
    -------
    ndarray, shape (n, m)
    """
    A = float_array(A, "A", ndim=2)
    C = float_array(C, "C", ndim=2)
    n, m = A.shape[0], C.shape[0]
    poles = float_array(poles, "poles", ndim=1)
    G = float_array(directions, "directions", ndim=2)
    if A.shape != (n, n) or C.shape[1] != n or poles.shape != (n,) or G.shape != (n, m):
        raise ValueError(
            f"A (n, n), C (m, n), poles (n,), directions (n, m) must agree, got {A.shape}, "
            f"{C.shape}, {poles.shape}, {G.shape}"
        )
    if np.unique(poles).size != n:
        raise ValueError(f"poles must be distinct, got {poles.tolist()}")
    try:
        W = np.stack(
            [np.linalg.solve((A - lam * np.eye(n)).T, C.T @ g) for lam, g in zip(poles, G)], axis=1
        )  # w_j = (A - lambda_j I)^{-T} C' g_j
        return np.linalg.solve(W.T, G)  # L' W = G
    except np.linalg.LinAlgError as exc:
        raise ValueError(
            "poles must not be eigenvalues of A and directions must give independent eigenvectors"
        ) from exc


def kalman_bucy_gains(
    system: SwitchedLinearSystem, *, structure: SubsystemStructure | None = None
) -> np.ndarray:
    """Steady-state Kalman-Bucy gains of each mode's observable sub-state (Wang et al. §4.1).

    :math:`L_i = P C_2^\\top R^{-1}` with
    :math:`A_{22} P + P A_{22}^\\top - P C_2^\\top R^{-1} C_2 P = 0` (no state noise), the design
    Example 1 shows can diverge under random switching (:math:`L_i = 2 a_i` for the scalar
    pair).
    """
    structure = _structure(system, structure)
    L, n, m = system.n_modes, system.n_states, system.n_outputs
    gains = np.zeros((L, n, m))
    for i in range(L):
        b = structure.block[i]
        if b < 0:
            continue
        R = system.R[i]
        if np.linalg.eigvalsh(R)[0] <= 0:
            raise ValueError(f"system.R[{i}] must be positive definite for a Kalman-Bucy gain")
        A22, C2 = structure.A22[i], structure.C2[i]
        try:
            P = solve_continuous_are(A22.T, C2.T, np.zeros_like(A22), R)
        except (LinAlgError, ValueError) as exc:
            raise ValueError(
                f"no stabilizing Riccati solution for mode {i}'s sub-state: {exc}"
            ) from exc
        gains[i] = structure.F_blocks[b].T @ (P @ C2.T @ np.linalg.inv(R))
    return gains


def decoupled_gain_bounds(
    system: SwitchedLinearSystem, p, T: float, *, structure: SubsystemStructure | None = None
) -> GainBounds:
    """Admissible gains when the error decouples into scalar components (Wang et al. Example 2).

    Requires every block to be one-dimensional, closed by exactly one mode, and
    every :math:`\\Lambda(i)` diagonal. Block g then obeys
    :math:`\\mathbb{E} e_{k+1}^2 = (p_i e^{2 a_c T} + o_g) \\mathbb{E} e_k^2 + \\dots`, which is
    below 1 iff :math:`a_c < \\ln((1 - o_g) / p_i) / (2T)`. The paper prints
    :math:`L_1 > 25.7775`, :math:`L_2 > 6.3407`, which is this bound with :math:`e^{(a - L)T}`
    in place of :math:`e^{2(a - L)T}`.
    """
    structure = _structure(system, structure)
    p = _probabilities(p, system.n_modes)
    T = positive_scalar(T, "T")
    B = structure.n_blocks
    closers = [np.flatnonzero(structure.block == g) for g in range(B)]
    expAT = mode_steps(system, T).F
    O = _open_loop(structure, expAT)
    off = O - O * np.eye(structure.n_substates)
    if (
        any(c.size != 1 for c in closers)
        or np.any(np.diff(structure.offsets) != 1)
        or np.any(np.abs(off) > 1e-12 * max(1.0, np.abs(O).max()))
    ):
        raise ValueError(
            "decoupled_gain_bounds needs one-dimensional blocks, each closed by one mode, "
            "and diagonal Lambda(i) (the decoupled scalar components of Wang et al. Examples 1-4)"
        )
    mode = np.array([c[0] for c in closers])
    open_loop = np.einsum("i,igg->g", p, O**2)  # rows of the closing mode are zero in O
    feasible = open_loop + rounding_allowance(open_loop, system.n_modes) < 1.0  # L terms
    with np.errstate(divide="ignore", invalid="ignore"):
        max_rate = np.where(feasible, np.log((1.0 - open_loop) / p[mode]) / (2.0 * T), -np.inf)
    a22 = np.array([structure.A22[i][0, 0] for i in mode])
    return GainBounds(
        mode=mode,
        open_loop=open_loop,
        max_rate=max_rate,
        min_loop_gain=a22 - max_rate,
        feasible=feasible,
    )


def optimal_gains(
    system: SwitchedLinearSystem,
    p,
    T: float,
    initial_gains,
    *,
    structure: SubsystemStructure | None = None,
    objective: str = "z",
    max_radius: float = 1.0,
) -> OptimalGains:
    """Gains minimizing the steady-state MS error under the MS constraint (Wang et al. §5.2).

    Minimizes :math:`\\operatorname{tr} V` (``objective="z"``, the paper's :math:`\\mu_\\infty`) or
    :math:`\\operatorname{tr} \\Phi V \\Phi^\\top` (``"x"``) of :func:`steady_state` over the free
    entries of every sub-observer gain (those acting on informative outputs), subject to
    :math:`\\rho(\\mathbb{E}[\\Lambda \\otimes \\Lambda]) < \\mathrm{max\\_radius}`, by Nelder-Mead
    from ``initial_gains`` (which must satisfy the constraint). For a fixed :math:`T` this
    is §5.2's inner problem; the trade-off in :math:`T` is the curve of its optimum
    over :math:`T`.

    ``max_radius = 1`` is the paper's constraint. The steady-state error does not
    see how fast the second moment converges, and where a weakly contracting
    direction is not driven by noise the optimum sits on the stability boundary
    (on the IEEE 5-bus case: spectral radius 0.9999998, an observer that barely
    converges); ``max_radius < 1`` asks for a guaranteed convergence rate
    (the second moment contracts at least by ``max_radius`` per interval).
    """
    structure = _structure(system, structure)
    p = _probabilities(p, system.n_modes)
    T = positive_scalar(T, "T")
    if objective not in ("z", "x"):
        raise ValueError(f"objective must be 'z' or 'x', got {objective!r}")
    max_radius = positive_scalar(max_radius, "max_radius")
    if max_radius > 1:
        raise ValueError(
            f"max_radius must be at most 1 (mean-square stability), got {max_radius:g}")
    start = substate_gains(structure, initial_gains, "initial_gains")
    # free parameters: L_i U_r (columns on the informative output directions of C2^i)
    bases = []
    for i in range(system.n_modes):
        U, s, _ = np.linalg.svd(structure.C2[i], full_matrices=False)
        bases.append(U[:, s > 1e-12 * max(1.0, s[0] if s.size else 1.0)])
    theta0 = np.concatenate([(start[i] @ bases[i]).ravel() for i in range(system.n_modes)])

    def gains_of(theta):
        out, at = np.zeros((system.n_modes, system.n_states, system.n_outputs)), 0
        for i, U in enumerate(bases):
            size = start[i].shape[0] * U.shape[1]
            if start[i].shape[0]:
                Lsub = theta[at : at + size].reshape(start[i].shape[0], U.shape[1]) @ U.T
                out[i] = structure.F_blocks[structure.block[i]].T @ Lsub
            at += size
        return out

    def cost(theta):
        dyn = error_dynamics(system, gains_of(theta), T, structure=structure)
        if ms_stable_iid(dyn.Lam, p).radius >= max_radius:
            return np.inf
        ss = steady_state(dyn, p)
        return ss.mu if objective == "z" else ss.mu_x

    if not np.isfinite(cost(theta0)):
        raise ValueError("initial_gains must give a mean-square stable error system with spectral "
                         f"radius below max_radius = {max_radius:g}")
    res = minimize(
        cost,
        theta0,
        method="Nelder-Mead",
        options={"xatol": 1e-8, "fatol": 1e-12, "maxiter": 20000},
    )
    best = gains_of(res.x)
    dyn = error_dynamics(system, best, T, structure=structure)
    return OptimalGains(
        gains=best,
        mu=float(res.fun),
        radius=ms_stable_iid(dyn.Lam, p).radius,
        holds=bool(res.success),
    )


# ---------------------------------------------------------------------- helpers
def _radius(weights: np.ndarray, D: np.ndarray) -> np.ndarray:
    """:math:`\\rho(\\sum_i w_i D_i \\otimes D_i)` for :math:`D` ``(G, L, k, k)``, per grid
    point."""
    k = D.shape[-1]
    K = np.einsum("i,giab,gicd->gacbd", weights, D, D).reshape(D.shape[0], k * k, k * k)
    return spectral_radius(K)


def _first_crossing(fn, grid: np.ndarray) -> float:
    """Smallest :math:`T` in the grid's range with :math:`\\mathrm{fn}(T) = 1` (``fn`` below 1
    before it)."""
    with np.errstate(over="ignore", invalid="ignore"):
        values = fn(grid)
    above = ~(values < 1.0)
    if not above.any():
        return float("inf")
    j = int(np.argmax(above))
    if j == 0:
        return 0.0
    return float(
        brentq(
            lambda T: float(fn(np.array([T]))[0]) - 1.0,
            grid[j - 1],
            grid[j],
            xtol=1e-13,
            rtol=1e-13,
        )
    )
