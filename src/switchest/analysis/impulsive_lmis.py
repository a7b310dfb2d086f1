"""Impulsive observers under aperiodic sampling: LMI synthesis and closed-loop analysis.

Etienne, Motchon, Duviella & Guelton (seed 004), Theorems 8 and 10. Both rest on a
clock-dependent quadratic Lyapunov function :math:`V = e^\\top P^{\\sigma}(\\theta) e` with
:math:`\\theta = t - t_k` the time since the last sample and (eqs (10), (29))

.. math::

    P^i(\\theta) = P_0^i + \\theta P_1^i, \\qquad \\theta \\in [0, \\tau_{\\max}]

:math:`P_1` is the slope, not an end value. Every condition is affine in :math:`\\theta`, so
it is imposed at the two ends of its interval and holds on all of it.

Theorem 8 (synchronous mode knowledge), as derived from its proof:

* (5)  :math:`P^i(\\theta) \\succ 0`, :math:`\\theta \\in \\{0, \\tau_{\\max}\\}`;
* (6)  :math:`\\operatorname{He}(P^i(\\theta) A_i) + P_1^i + \\alpha P^i(\\theta) \\prec 0`,
  :math:`\\theta \\in \\{0, \\tau_{\\max}\\}` (flow: :math:`dV/dt \\le -\\alpha V`);
* (7)  :math:`\\begin{bmatrix} \\mu_c P^i(\\theta) & (P_0^i - L_i C_i)^\\top \\\\
  P_0^i - L_i C_i & P_0^i \\end{bmatrix} \\succ 0`,
  :math:`\\theta \\in \\{\\tau_{\\min}, \\tau_{\\max}\\}` (jump: by Schur,
  :math:`(I - G_i C_i)^\\top P_0^i (I - G_i C_i) \\prec \\mu_c P^i(\\theta)` with
  :math:`G_i = (P_0^i)^{-1} L_i`);
* (8)  :math:`P^i(\\theta) \\prec \\mu_s P^j(\\theta)`, :math:`i \\ne j`,
  :math:`\\theta \\in \\{0, \\tau_{\\max}\\}` (switches);
* (9)  :math:`\\beta > 0` with the rate (11) of
  :func:`~switchest.analysis.impulsive_rates.impulsive_observer_decay_rate`;

then :math:`\\lVert e(t) \\rVert \\le M \\exp(-\\beta t) \\lVert e(0^+) \\rVert`.

Discrepancies with the printed Theorem 8, each checked against the proof (those of the
rate (9)/(11) are in :mod:`switchest.analysis.impulsive_rates`):

* (7) is printed
  :math:`\\begin{bmatrix} \\mu_c P(\\theta) & P_0 - L C_j \\\\ \\star & P_0 \\end{bmatrix}`: its
  Schur complement is :math:`\\mu_c P - (P_0 - L C) P_0^{-1} (P_0 - L C)^\\top`, not the bound
  :math:`(P_0 - L C)^\\top P_0^{-1} (P_0 - L C) \\prec \\mu_c P` the proof needs; the
  off-diagonal block must be transposed. :math:`C_j` must be :math:`C_i` (no :math:`j` is
  quantified; a sample never coincides with a switch), and the range
  ":math:`]\\tau_{\\min}, \\tau_{\\max}\\}`" means the ends
  :math:`\\{\\tau_{\\min}, \\tau_{\\max}\\}`.
* (6) is printed with :math:`\\alpha / \\mu_c`; the proof uses :math:`\\Gamma \\prec -\\alpha P`.
  With :math:`\\alpha > 0` and :math:`\\mu_c < 1` the printed form is only more conservative,
  with :math:`\\alpha < 0` it does not imply the proof's step. Implemented with :math:`\\alpha`.
* (8) is printed for all :math:`i, j`; for :math:`i = j` and :math:`\\mu_s = 1` it reads
  :math:`P \\prec P` (infeasible), and the proof only uses :math:`i \\ne j`.

Theorem 10 (mode estimate delayed by at most :math:`\\delta`, observer-based control
:math:`u = K_{\\hat\\sigma} \\hat x`): the same structure on the extended state
:math:`z = [x; e]` (eqs (21)-(23), :func:`closed_loop_matrices`),
with :math:`Q^i` indexed by the estimated mode :math:`i` and the true mode :math:`j`:

* (24) :math:`Q^i(\\theta) \\succ 0`;
* (25) :math:`\\operatorname{He}(Q^i(\\theta) \\mathrm{Acl}[j, i]) + Q_1^i
  + \\alpha_{ij} Q^i(\\theta) \\prec 0`, :math:`\\alpha_{ii} = \\alpha`,
  :math:`\\alpha_{ij} = -\\bar\\alpha` (:math:`i \\ne j`);
* (26) :math:`\\begin{bmatrix} \\mu_{ij} Q^i(\\theta) & J[j, i]^\\top Q_0^i \\\\
  Q_0^i J[j, i] & Q_0^i \\end{bmatrix} \\succ 0`,
  :math:`\\theta \\in \\{\\tau_{\\min}, \\tau_{\\max}\\}`, :math:`\\mu_{ii} = \\mu_c`,
  :math:`\\mu_{ij} = \\bar\\mu_c`;
* (27) :math:`Q^i(\\theta) \\prec \\mu_s Q^j(\\theta)`, :math:`i \\ne j`;
* (28) :math:`\\beta > 0` with the rate of
  :func:`~switchest.analysis.impulsive_rates.impulsive_closed_loop_decay_rate`.

Discrepancies with the printed Theorem 10: (26) is transposed like (7); (22b) has the wrong
sign (see ``closed_loop_matrices``); the rate (28)/(31) miscounts the samples
(:mod:`switchest.analysis.impulsive_rates`; the printed value is kept in the result as
``printed_beta``). With the §4 scalars and the block of (26) as printed the LMIs (24)-(27)
are feasible (for the observer gains of Theorem 8), but the :math:`Q` they return violates
:math:`J^\\top Q_0 J \\prec \\mu Q(\\tau)`; the corrected LMIs are infeasible
(tests/analysis/test_impulsive_lmis.py).

The certificates these functions return are defined in
:mod:`switchest.analysis.impulsive_certificates` and the rates in
:mod:`switchest.analysis.impulsive_rates`; both are importable from here too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .._checks import float_array, gain_stack, positive_scalar
from .._linalg import symmetrize
from ..system import SwitchedLinearSystem
from ._lmi import cp, max_eigenvalue, min_eigenvalue, solve_sdp, symmetric_block
from .impulsive_certificates import (
    ClosedLoopCertificate,
    ImpulsiveObserverCertificate,
    ImpulsiveObserverSearch,
)
from .impulsive_rates import (
    _printed_theorem10_rate,
    _scalars8,
    impulsive_closed_loop_decay_rate,
    impulsive_observer_decay_rate,
    largest_tolerable_delay,
)
from .scalar_search import largest_feasible

__all__ = [
    "ClosedLoopCertificate",
    "ClosedLoopLMIs",
    "ImpulsiveObserverCertificate",
    "ImpulsiveObserverSearch",
    "closed_loop_matrices",
    "impulsive_closed_loop_analysis",
    "impulsive_observer_search",
    "impulsive_observer_synthesis",
    "impulsive_observer_decay_rate",
    "impulsive_closed_loop_decay_rate",
    "largest_tolerable_delay",
]

_DEFAULT_MU_S = (2.0, 5.0, 10.0, 16.0, 25.0, 40.0)
_DEFAULT_MU_C = (0.3, 0.5, 0.7, 0.85, 0.95, 1.0)


# ---------------------------------------------------------------------- closed loop
def closed_loop_matrices(system: SwitchedLinearSystem, K, G) -> tuple[np.ndarray, np.ndarray]:
    """Flow and jump matrices of the observer-based closed loop (Etienne et al. eqs (21)-(23)).

    With :math:`u = K_{\\hat\\sigma} \\hat x` and :math:`z = [x; e]`, :math:`e = x - \\hat x`, the
    plant (1) and the observer (2) give :math:`dz/dt = \\mathrm{Acl}[\\sigma, \\hat\\sigma] z`
    between samples and :math:`z(t_k^+) = J[\\sigma, \\hat\\sigma] z(t_k)` at the samples, with
    (eq. (22a))

    .. math::

        \\mathrm{Acl}[j, i] = \\begin{bmatrix} A_j + B_j K_i & -B_j K_i \\\\
            A_{ji} + B_{ji} K_i & A_i - B_{ji} K_i \\end{bmatrix}, \\qquad
        J[j, i] = \\begin{bmatrix} I & 0 \\\\ -G_i C_{ji} & I - G_i C_i \\end{bmatrix}

    :math:`A_{ji} = A_j - A_i`, :math:`B_{ji} = B_j - B_i`, :math:`C_{ji} = C_j - C_i`
    (eq. (23)), :math:`j` the true and :math:`i` the estimated mode (the paper's
    :math:`A_{\\sigma \\hat\\sigma}`).

    Discrepancy: the printed eq. (22b) has :math:`+G C_{ji}` in the lower-left block.
    From (1)-(2),
    :math:`e^+ = x - \\hat x - G_i (C_j x - C_i \\hat x) = -G_i C_{ji} x + (I - G_i C_i) e`:
    the sign is minus. It matters only when the output matrices differ between
    modes (in §4, :math:`C_1 = C_2` and the block vanishes).

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous time, with ``L`` modes, ``n`` states, ``l`` inputs, ``m`` outputs.
    K : array_like, shape (L, l, n)
        State-feedback gains, applied as :math:`u = K_i \\hat x` (no minus sign).
    G : array_like, shape (L, n, m)
        Observer gains.

    Returns
    -------
    Acl, J : ndarray, shape (L, L, 2n, 2n)
        Indexed ``[true mode, estimated mode]``.
    """
    system = _check_system(system)
    L, n, m, n_in = system.n_modes, system.n_states, system.n_outputs, system.n_inputs
    K = gain_stack(K, "K", (L, n_in, n), "(L, l, n)")
    G = gain_stack(G, "G", (L, n, m), "(L, n, m)")
    A, B, C = system.A, system.B, system.C
    Aj, Ai = A[:, None], A[None, :]  # [j, i]: true mode j, estimated mode i
    Bj, Bi = B[:, None], B[None, :]
    BK = Bj @ K[None, :]  # B_j K_i
    dBK = (Bj - Bi) @ K[None, :]  # B_ji K_i
    Acl = np.block([[Aj + BK, -BK], [Aj - Ai + dBK, Ai - dBK]])
    GdC = G[None, :] @ (C[:, None] - C[None, :])  # G_i C_ji
    eye = np.broadcast_to(np.eye(n), GdC.shape)
    J = np.block([[eye, np.zeros_like(GdC)], [-GdC, eye - np.broadcast_to(G @ C, GdC.shape)]])
    return Acl, J


# ---------------------------------------------------------------------- Theorem 8
def impulsive_observer_synthesis(
    system: SwitchedLinearSystem,
    tau_min: float,
    tau_max: float,
    dwell: float,
    alpha: float,
    mu_s: float,
    mu_c: float,
    *,
    margin: float = 1e-3,
) -> ImpulsiveObserverCertificate:
    """Impulsive observer gains for synchronous mode knowledge (Etienne et al. Theorem 8).

    Solves the LMIs (5)-(8) in :math:`P_0^i, P_1^i, L_i` for fixed :math:`(\\alpha, \\mu_s, \\mu_c)`
    in their corrected forms (module docstring): strict inequalities posed with the
    explicit ``margin`` after the normalization :math:`P^i(\\theta) \\succeq I` (the LMIs are
    homogeneous), as a feasibility problem. The solution is re-checked with numpy eigenvalues
    (slack at least :math:`\\mathrm{margin} / 2`) before ``holds=True``.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous time, L modes.
    tau_min, tau_max : float
        Sampling intervals lie in :math:`[\\tau_{\\min}, \\tau_{\\max}]` (Assumption 2).
    dwell : float
        Average dwell time :math:`s` (Assumption 1).
    alpha : float
        Flow decay rate :math:`\\alpha` (underlined alpha; any real).
    mu_s : float
        Switching growth bound, :math:`\\ge 1`.
    mu_c : float
        Jump bound (underlined mu_c), positive (the paper takes :math:`(0, 1]`).
    margin : float, optional
        Slack posed on the strict LMIs (keyword-only).

    Returns
    -------
    ImpulsiveObserverCertificate
        With :math:`G_i = (P_0^i)^{-1} L_i` and the rate :math:`\\beta` of (11).
    """
    system = _check_system(system)
    _scalars8(alpha, mu_s, mu_c, tau_min, tau_max, dwell)
    problem = _Theorem8(system, tau_min, tau_max, dwell, positive_scalar(margin, "margin"))
    return problem.solve(alpha, mu_s, mu_c)


def impulsive_observer_search(
    system: SwitchedLinearSystem,
    tau_min: float,
    tau_max: float,
    dwell: float,
    *,
    mu_s: Sequence[float] | None = None,
    mu_c: Sequence[float] | None = None,
    alpha_tol: float = 1e-3,
    margin: float = 1e-3,
) -> ImpulsiveObserverSearch:
    """Search the scalars of Theorem 8 for the largest guaranteed rate :math:`\\beta`.

    The paper fixes :math:`(\\alpha, \\mu_s, \\mu_c)` by hand (Remark 12). For fixed
    :math:`(\\mu_s, \\mu_c)` the LMIs stay feasible when :math:`\\alpha` decreases (it multiplies
    :math:`P \\succ 0` in (6)), so the largest feasible :math:`\\alpha` is found by bisection,
    starting where :math:`\\beta = 0` (below it no positive rate is possible) and
    doubling the step upward until infeasible; :math:`\\beta` of (11) is then evaluated
    over the :math:`(\\mu_s, \\mu_c)` grid, and the best certificate returned. One
    parametrized SDP is compiled once and re-solved.

    Parameters
    ----------
    system, tau_min, tau_max, dwell
        As in :func:`impulsive_observer_synthesis`.
    mu_s : sequence of float, optional
        Grid of :math:`\\mu_s \\ge 1` (default ``(2, 5, 10, 16, 25, 40)``; ``(1,)`` for one mode).
    mu_c : sequence of float, optional
        Grid of :math:`\\mu_c > 0` (default ``(0.3, 0.5, 0.7, 0.85, 0.95, 1)``).
    alpha_tol : float, optional
        Bisection tolerance on :math:`\\alpha`.
    margin : float, optional
        As in :func:`impulsive_observer_synthesis`.

    Returns
    -------
    ImpulsiveObserverSearch
    """
    system = _check_system(system)
    alpha_tol = positive_scalar(alpha_tol, "alpha_tol")
    default_mu_s = (1.0,) if system.n_modes == 1 else _DEFAULT_MU_S
    grid_s = _grid(default_mu_s if mu_s is None else mu_s, "mu_s")
    grid_c = _grid(_DEFAULT_MU_C if mu_c is None else mu_c, "mu_c")
    _scalars8(0.0, 1.0, 1.0, tau_min, tau_max, dwell)
    problem = _Theorem8(system, tau_min, tau_max, dwell, positive_scalar(margin, "margin"))
    alphas = np.full((grid_s.size, grid_c.size), np.nan)
    betas = np.full_like(alphas, np.nan)
    best = None
    for r, ms in enumerate(grid_s):
        for c, mc in enumerate(grid_c):
            rate0 = impulsive_observer_decay_rate(0.0, ms, mc, tau_min, tau_max, dwell)
            lo = -2 * rate0 + alpha_tol  # beta > 0 from here on
            found = largest_feasible(  # bracket by doubling steps, then bisect
                lambda alpha, ms=ms, mc=mc: problem.solve(alpha, ms, mc),
                lambda cert: cert.lmi_feasible, lo, tol=alpha_tol, step=1.0, doublings=12)
            if found is None:
                continue
            alphas[r, c], cert = found
            betas[r, c] = cert.beta
            if cert.holds and (best is None or cert.beta > best.beta):
                best = cert
    if best is None:
        unknown = dict.fromkeys(("beta", "alpha", "mu_s", "mu_c"), math.nan)
        best = _failed8("searched", "no scalars on the grid gave feasible LMIs with beta > 0",
                        {**unknown, "tau_min": float(tau_min), "tau_max": float(tau_max),
                         "dwell": float(dwell)})
    return ImpulsiveObserverSearch(
        best=best, mu_s=grid_s, mu_c=grid_c, alpha=alphas, beta=betas, n_solves=problem.n_solves
    )


class _Theorem8:
    """The LMIs (5)-(8) in :math:`P_0, P_1, L` with the scalars as cvxpy parameters (compiled
    once)."""

    def __init__(self, system, tau_min, tau_max, dwell, margin):
        self.system, self.dwell, self.margin = system, float(dwell), margin
        Lm, n, m = system.n_modes, system.n_states, system.n_outputs
        self.lmi = _ClockLMI(Lm, n, tau_min, tau_max, margin)
        self.alpha, self.mu_c = cp.Parameter(), cp.Parameter(pos=True)
        self.L = [cp.Variable((n, m)) for _ in range(Lm)]
        for i in range(Lm):
            self.lmi.add_flow(i, system.A[i], self.alpha)
            self.lmi.add_jump(i, self.lmi.P0[i] - self.L[i] @ system.C[i],  # P0 (I - G C)
                              self.mu_c)

    @property
    def n_solves(self) -> int:
        return self.lmi.n_solves

    def solve(self, alpha, mu_s, mu_c) -> ImpulsiveObserverCertificate:
        alpha, mu_s, mu_c, tau_min, tau_max, dwell = _scalars8(
            alpha, mu_s, mu_c, self.lmi.tau_min, self.lmi.tau_max, self.dwell
        )
        beta = impulsive_observer_decay_rate(alpha, mu_s, mu_c, tau_min, tau_max, dwell)
        common = {"beta": beta, "alpha": alpha, "mu_s": mu_s, "mu_c": mu_c, "tau_min": tau_min,
                  "tau_max": tau_max, "dwell": dwell}
        self.alpha.value, self.mu_c.value = alpha, mu_c
        status, P0, P1, slack = self.lmi.solve(mu_s)
        if P0 is None:
            return _failed8(status, _unsolved("(5)-(8)", status, slack, self.margin), common)
        L = np.stack([v.value for v in self.L])
        G = np.linalg.solve(P0, L)  # G_i = (P0^i)^-1 L_i
        if beta <= 0:
            note = (
                f"LMIs (5)-(8) hold but the rate condition (9) fails: beta = {beta:.4g} <= 0; "
                "no convergence is certified"
            )
            return ImpulsiveObserverCertificate(
                False, True, P0, P1, L, G, **common, margin=slack, solver_status=status, note=note
            )
        note = f"the observation error decays at least as exp(-{beta:.4g} t) (Theorem 8, verified)"
        return ImpulsiveObserverCertificate(
            True, True, P0, P1, L, G, **common, margin=slack, solver_status=status, note=note
        )


# ---------------------------------------------------------------------- Theorem 10
def impulsive_closed_loop_analysis(
    system: SwitchedLinearSystem,
    K,
    G,
    tau_min: float,
    tau_max: float,
    dwell: float,
    delta: float,
    alpha: float,
    alpha_bar: float,
    mu_s: float,
    mu_c: float,
    mu_c_bar: float,
    *,
    margin: float = 1e-3,
) -> ClosedLoopCertificate:
    """Observer-based control with a delayed mode estimate (Etienne et al. Theorem 10).

    For given controller gains ``K`` (:math:`u = K_{\\hat\\sigma} \\hat x`) and observer gains
    ``G``, solves the LMIs (24)-(27) in :math:`Q_0^i, Q_1^i` on the extended system
    (21)-(23) (jump sign and (26) corrected, module docstring) and evaluates the
    corrected rate condition (28) (:func:`impulsive_closed_loop_decay_rate`). Posed and verified as
    in :func:`impulsive_observer_synthesis`. For many scalars with one ``K`` and
    ``G`` (a sweep, a bisection), :class:`ClosedLoopLMIs` compiles the LMIs once.

    Parameters
    ----------
    system : SwitchedLinearSystem
    K : array_like, shape (L, l, n)
    G : array_like, shape (L, n, m)
    tau_min, tau_max, dwell : float
        As in Theorem 8.
    delta : float
        Largest delay of the mode estimate (Assumption 5), :math:`\\ge 0`.
    alpha, alpha_bar : float
        Flow rates with the right (:math:`dV/dt \\le -\\alpha V`) and the wrong
        (:math:`dV/dt \\le \\bar\\alpha V`) mode estimate.
    mu_s : float
        :math:`\\ge 1`.
    mu_c, mu_c_bar : float
        Jump bounds with the right and the wrong mode estimate, positive.
    margin : float, optional

    Returns
    -------
    ClosedLoopCertificate
    """
    lmis = ClosedLoopLMIs(system, K, G, tau_min, tau_max, dwell, margin=margin)
    return lmis.analyze(delta, alpha, alpha_bar, mu_s, mu_c, mu_c_bar)


class ClosedLoopLMIs:
    """The LMIs (24)-(27) of Theorem 10 for one plant, controller and observer, compiled once.

    The scalars :math:`\\alpha, \\bar\\alpha, \\mu_s, \\mu_c, \\bar\\mu_c` enter the LMIs as cvxpy
    parameters (the problem is DPP), so every :meth:`analyze` re-solves one compiled
    problem: a search over the scalars costs a solve per point, not a model build and
    compilation (:math:`\\delta` enters only the rate (28), not the LMIs).

    Parameters
    ----------
    system, K, G, tau_min, tau_max, dwell
        As in :func:`impulsive_closed_loop_analysis`.
    margin : float, optional
        As in :func:`impulsive_closed_loop_analysis` (keyword-only).

    Attributes
    ----------
    n_solves : int
        SDPs solved so far.
    """

    def __init__(self, system, K, G, tau_min, tau_max, dwell, *, margin: float = 1e-3):
        system = _check_system(system)
        Acl, J = closed_loop_matrices(system, K, G)
        _, _, _, self.tau_min, self.tau_max, self.dwell = _scalars8(
            0.0, 1.0, 1.0, tau_min, tau_max, dwell
        )
        self.margin = positive_scalar(margin, "margin")
        self._alpha, self._alpha_bar = cp.Parameter(), cp.Parameter()
        self._mu_c, self._mu_c_bar = cp.Parameter(pos=True), cp.Parameter(pos=True)
        Lm = system.n_modes
        self._lmi = _ClockLMI(Lm, 2 * system.n_states, self.tau_min, self.tau_max, self.margin)
        # i: estimated mode (indexes Q), j: true mode;
        # (30): (alpha, mu_c) if i == j else (-alpha_bar, mu_c_bar)
        for i in range(Lm):
            for j in range(Lm):
                self._lmi.add_flow(i, Acl[j, i], self._alpha if i == j else -self._alpha_bar)
                self._lmi.add_jump(
                    i, self._lmi.P0[i] @ J[j, i], self._mu_c if i == j else self._mu_c_bar
                )

    @property
    def n_solves(self) -> int:
        return self._lmi.n_solves

    def analyze(self, delta: float, alpha: float, alpha_bar: float, mu_s: float, mu_c: float,
                mu_c_bar: float) -> ClosedLoopCertificate:
        """Theorem 10 at these scalars (arguments as in :func:`impulsive_closed_loop_analysis`).

        Returns
        -------
        ClosedLoopCertificate
        """
        tau_min, tau_max, dwell = self.tau_min, self.tau_max, self.dwell
        beta = impulsive_closed_loop_decay_rate(
            alpha, alpha_bar, mu_s, mu_c, mu_c_bar, tau_min, tau_max, dwell, delta
        )
        alpha, mu_s, mu_c = float(alpha), float(mu_s), float(mu_c)
        alpha_bar, mu_c_bar, delta = float(alpha_bar), float(mu_c_bar), float(delta)
        printed = _printed_theorem10_rate(
            alpha, alpha_bar, mu_s, mu_c, mu_c_bar, tau_min, tau_max, dwell, delta
        )
        scalars = {"alpha": alpha, "alpha_bar": alpha_bar, "mu_s": mu_s, "mu_c": mu_c,
                   "mu_c_bar": mu_c_bar, "delta": delta, "tau_min": tau_min, "tau_max": tau_max,
                   "dwell": dwell}
        self._alpha.value, self._alpha_bar.value = alpha, alpha_bar
        self._mu_c.value, self._mu_c_bar.value = mu_c, mu_c_bar
        status, Q0, Q1, slack = self._lmi.solve(mu_s)
        common = {"beta": beta, "printed_beta": printed, "scalars": scalars,
                  "solver_status": status}
        if Q0 is None:
            unsolved = _unsolved("(24)-(27)", status, slack, self.margin)
            note = f"{unsolved}; stability is not certified"
            return ClosedLoopCertificate(False, False, None, None, margin=math.nan, **common,
                                         note=note)
        if beta <= 0:
            note = (
                f"LMIs (24)-(27) hold but the rate condition (28) fails: beta = {beta:.4g} <= 0 "
                f"(printed (31): {printed:.4g}); stability is not certified"
            )
            return ClosedLoopCertificate(False, True, Q0, Q1, margin=slack, **common, note=note)
        note = f"z = [x; e] decays at least as exp(-{beta:.4g} t) (Theorem 10, verified)"
        return ClosedLoopCertificate(True, True, Q0, Q1, margin=slack, **common, note=note)


# ---------------------------------------------------------------------- shared LMI pieces
class _ClockLMI:
    """LMIs on :math:`P^i(\\theta) = P_0^i + \\theta P_1^i` shared by Theorems 8 and 10.

    * :math:`P^i(\\theta) \\succeq I` at :math:`\\theta \\in \\{0, \\tau_{\\max}\\}` ((5)/(24),
      normalized: homogeneous LMIs);
    * :math:`P^i(\\theta) \\preceq \\mu_s P^j(\\theta) - \\mathrm{margin} \\, I`, :math:`i \\ne j`
      ((8)/(27));
    * :meth:`add_flow`: :math:`\\operatorname{He}(P^i(\\theta) A) + P_1^i + \\mathrm{rate} \\,
      P^i(\\theta) \\preceq -\\mathrm{margin} \\, I` ((6)/(25));
    * :meth:`add_jump`: :math:`\\begin{bmatrix} \\mu P^i(\\theta) & \\Omega^\\top \\\\
      \\Omega & P_0^i \\end{bmatrix} \\succeq \\mathrm{margin} \\, I` at
      :math:`\\theta \\in \\{\\tau_{\\min}, \\tau_{\\max}\\}`, :math:`\\Omega = P_0^i M` for the
      jump :math:`e^+ = M e` ((7)/(26), corrected).

    ``rate``, ``mu`` and ``mu_s`` may be cvxpy parameters, so one compiled problem is re-solved.
    """

    def __init__(self, n_modes, size, tau_min, tau_max, margin):
        self.tau_min, self.tau_max, self.margin = float(tau_min), float(tau_max), margin
        self.P0 = [cp.Variable((size, size), symmetric=True) for _ in range(n_modes)]
        self.P1 = [cp.Variable((size, size), symmetric=True) for _ in range(n_modes)]
        self.mu_s = cp.Parameter(pos=True)
        self.flows, self.jumps, self.constraints = [], [], []
        self.n_solves = 0
        self._problem = None
        eye = np.eye(size)
        for theta in (0.0, self.tau_max):
            P = [self._at(i, theta) for i in range(n_modes)]
            self.constraints += [symmetric_block([[Pi - eye]]) >> 0 for Pi in P]
            self.constraints += [
                symmetric_block([[self.mu_s * P[j] - P[i] - margin * eye]]) >> 0
                for i in range(n_modes)
                for j in range(n_modes)
                if i != j
            ]

    def _at(self, i, theta):
        return self.P0[i] + theta * self.P1[i]

    def add_flow(self, i, A, rate) -> None:
        eye = np.eye(A.shape[0])
        for theta in (0.0, self.tau_max):
            P = self._at(i, theta)
            self.constraints.append(
                symmetric_block([[P @ A + A.T @ P + self.P1[i] + rate * P + self.margin * eye]])
                << 0
            )
        self.flows.append((i, A, rate))

    def add_jump(self, i, omega, mu) -> None:
        eye = np.eye(2 * omega.shape[0])
        for theta in (self.tau_min, self.tau_max):
            block = symmetric_block([[mu * self._at(i, theta), omega.T], [None, self.P0[i]]])
            self.constraints.append(block - self.margin * eye >> 0)
        self.jumps.append((i, omega, mu))

    def solve(self, mu_s):
        """Solve for the current parameter values: ``(status, P0, P1, slack)``.

        ``P0, P1`` are None unless the solution passed the numpy re-check (slack at
        least :math:`\\mathrm{margin} / 2`). The solver status is never the verdict: an
        ``optimal_inaccurate`` answer is accepted only through that re-check, and
        CVXOPT is tried when CLARABEL gives no verified solution without deciding.
        """
        if self._problem is None:
            self._problem = cp.Problem(cp.Minimize(0), self.constraints)
        self.mu_s.value = mu_s
        self.n_solves += 1
        status, slack = "solver_error", math.nan
        for solver in ("CLARABEL", "CVXOPT"):
            outcome = solve_sdp(self._problem, solvers=(solver,))
            status = outcome.status
            if status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) and self.P0[0].value is not None:
                P0 = symmetrize(np.stack([v.value for v in self.P0]))
                P1 = symmetrize(np.stack([v.value for v in self.P1]))
                slack = self._slack(P0, P1, mu_s)
                if slack >= 0.5 * self.margin:
                    return status, P0, P1, slack
            if outcome.decided:
                break
        return status, None, None, slack

    def _slack(self, P0, P1, mu_s) -> float:
        """Smallest slack of the strict LMIs recomputed with numpy from the solver's matrices
        (:math:`P(\\theta) \\succeq I` checked as :math:`P(\\theta) \\succ 0`)."""
        slacks = []
        for theta in (0.0, self.tau_max):
            P = P0 + theta * P1
            slacks.append(min_eigenvalue(P))
            slacks += [
                min_eigenvalue(mu_s * P[j] - P[i])
                for i in range(len(P))
                for j in range(len(P))
                if i != j
            ]
            for i, A, rate in self.flows:
                r = _value(rate)
                slacks.append(-max_eigenvalue(P[i] @ A + A.T @ P[i] + P1[i] + r * P[i]))
        for theta in (self.tau_min, self.tau_max):
            for i, omega, mu in self.jumps:
                W = np.asarray(omega.value)
                block = np.block([[_value(mu) * (P0[i] + theta * P1[i]), W.T], [W, P0[i]]])
                slacks.append(min_eigenvalue(block))
        return float(np.min(np.hstack([np.ravel(s) for s in slacks])))


# ---------------------------------------------------------------------- helpers
def _unsolved(which: str, status: str, slack: float, margin: float) -> str:
    if math.isnan(slack):
        return f"the LMIs {which} have no solution (solver status {status!r})"
    return (
        f"the solver's solution of the LMIs {which} failed the numpy re-check (slack {slack:.3g} "
        f"< {0.5 * margin:.3g}, solver status {status!r})"
    )


def _failed8(status: str, note: str, common: dict) -> ImpulsiveObserverCertificate:
    """The certificate of LMIs (5)-(8) left unsolved: no matrices, no gains."""
    return ImpulsiveObserverCertificate(False, False, None, None, None, None, **common,
                                        margin=math.nan, solver_status=status, note=note)


def _grid(values, name: str) -> np.ndarray:
    arr = float_array(values, name, ndim=1)
    if arr.size == 0 or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name} must be a non-empty grid of positive numbers, got {arr.tolist()}")
    if name == "mu_s" and np.any(arr < 1):
        raise ValueError(f"mu_s must be >= 1, got {arr.min():g}")
    return arr


def _value(x) -> float:
    return float(x.value) if isinstance(x, cp.Expression) else float(x)


def _check_system(system) -> SwitchedLinearSystem:
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    if not system.is_continuous:
        raise ValueError(f"system must be continuous-time, got domain {system.domain!r}")
    return system
