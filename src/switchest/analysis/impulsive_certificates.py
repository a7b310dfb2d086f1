"""What the LMIs of the impulsive observer prove: the certificates of Theorems 8 and 10.

Etienne, Motchon, Duviella & Guelton (seed 004). A certificate holds the clock-dependent
Lyapunov matrices :math:`P^i(\\theta) = P_0^i + \\theta P_1^i` (eq. (10); :math:`Q` on the closed
loop's extended state, eq. (29)) found by :mod:`switchest.analysis.impulsive_lmis`, the scalars
they were found for, the decay rate :math:`\\beta` of :mod:`switchest.analysis.impulsive_rates`,
and the verdict ``holds``; its ``overshoot`` is the constant :math:`M` of
:math:`\\lVert e(t) \\rVert \\le M \\exp(-\\beta t) \\lVert e(0^+) \\rVert`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import float_array, positive_scalar
from ._lmi import max_eigenvalue, min_eigenvalue
from .impulsive_rates import _switch_cost

__all__ = ["ClosedLoopCertificate", "ImpulsiveObserverCertificate", "ImpulsiveObserverSearch"]


class _ClockCertificate:
    """What the certificates of Theorems 8 and 10 share: the evaluation and overshoot of their
    Lyapunov matrices, affine in the clock :math:`\\theta`."""

    def _clock(self, M0: np.ndarray | None, M1: np.ndarray, theta, name: str) -> np.ndarray:
        """:func:`_clock_affine`, or the error that the LMIs gave no matrix ``name``."""
        if M0 is None:
            raise ValueError(f"the certificate holds no {name}: the LMIs were not feasible")
        return _clock_affine(M0, M1, theta)

    def _overshoot(self, N0: float, M0: np.ndarray, M1: np.ndarray, tau_max: float,
                   switch_cost: float, mu_c: float) -> float:
        """:math:`M = \\sqrt{\\exp(N_0 c) \\, \\theta_{\\max} / (\\mu_c' \\theta_{\\min})}` (proof
        of Theorem 8, eqs (19)-(20)), :math:`c` the growth of :math:`\\ln V` charged to a switch.

        :math:`\\theta_{\\max}` is the largest eigenvalue of the :math:`M_0^i`,
        :math:`\\theta_{\\min}` the smallest of the :math:`M^i(\\theta)` over
        :math:`[0, \\tau_{\\max}]` (attained at an end: the smallest eigenvalue is concave),
        :math:`\\mu_c' = \\mu_c` when :math:`\\mu_c \\le 1` and 1 otherwise, ``N0`` the chatter
        bound of Assumption 1.
        """
        if not self.holds:
            raise ValueError("no overshoot bound: the certificate is not feasible")
        N0 = positive_scalar(N0, "N0", allow_zero=True)
        ends = _clock_affine(M0, M1, np.array([0.0, tau_max]))
        top = float(np.max(max_eigenvalue(M0)))
        low = float(np.min(min_eigenvalue(ends)))
        return math.sqrt(math.exp(N0 * switch_cost) * top / (min(mu_c, 1.0) * low))


def _clock_affine(M0: np.ndarray, M1: np.ndarray, theta) -> np.ndarray:
    """:math:`M_0^i + \\theta M_1^i` for ``theta (...)``: shape ``(..., L, k, k)`` (eq. (10))."""
    theta = float_array(theta, "theta")
    return M0 + theta[..., None, None, None] * M1


@dataclass(frozen=True)
class ImpulsiveObserverCertificate(_ClockCertificate):
    """Outcome of :func:`~switchest.analysis.impulsive_observer_synthesis` (Etienne et al.
    Theorem 8).

    Attributes
    ----------
    holds : bool
        Theorem 8's conclusion is proven: the LMIs (5)-(8) were solved, their solution
        passed the numpy re-check, and the rate condition (9) holds (:math:`\\beta > 0`).
    lmi_feasible : bool
        The LMIs alone (verified); ``holds`` also needs :math:`\\beta > 0`.
    P0, P1 : ndarray, shape (L, n, n), or None
        :math:`P^i(\\theta) = \\mathrm{P0}[i] + \\theta \\, \\mathrm{P1}[i]` (eq. (10)); ``P1`` is
        the slope. Normalized so that :math:`P^i(\\theta) \\succeq I` at
        :math:`\\theta \\in \\{0, \\tau_{\\max}\\}`.
    L : ndarray, shape (L, n, m), or None
        The LMI variables :math:`L_i = P_0^i G_i`.
    G : ndarray, shape (L, n, m), or None
        Observer gains :math:`G_i = (P_0^i)^{-1} L_i`.
    beta : float
        Decay rate of :math:`\\lVert e \\rVert` that the scalars give (eq. (11), corrected for
        :math:`\\mu_c > 1`); guaranteed only when ``holds``.
    alpha, mu_s, mu_c : float
        The fixed scalars.
    tau_min, tau_max, dwell : float
        Sampling range (Assumption 2) and average dwell time (Assumption 1).
    margin : float
        Smallest verified slack of the strict LMIs (NaN when not solved).
    solver_status : str
    note : str
    """

    holds: bool
    lmi_feasible: bool
    P0: np.ndarray | None
    P1: np.ndarray | None
    L: np.ndarray | None
    G: np.ndarray | None
    beta: float
    alpha: float
    mu_s: float
    mu_c: float
    tau_min: float
    tau_max: float
    dwell: float
    margin: float
    solver_status: str
    note: str

    def overshoot(self, N0: float = 1.0) -> float:
        """:math:`M` in :math:`\\lVert e(t) \\rVert
        \\le M \\exp(-\\beta t) \\lVert e(0^+) \\rVert` (proof of Theorem 8, eqs (19)-(20)).

        :math:`M^2 = \\mu_s^{N_0} \\theta_{\\max} / (\\mu_c' \\theta_{\\min})`
        (``_ClockCertificate._overshoot`` with :math:`c = \\ln(\\mu_s)`). :math:`e(0^+)` is the
        error just after the correction at :math:`t_0` (the clock starts there), and ``N0`` the
        chatter bound of Assumption 1.
        """
        return self._overshoot(N0, self.P0, self.P1, self.tau_max, math.log(self.mu_s),
                               self.mu_c)

    def P(self, theta) -> np.ndarray:
        """:math:`P^i(\\theta) = P_0^i + \\theta P_1^i` for ``theta (...)``, shape
        ``(..., L, n, n)``."""
        return self._clock(self.P0, self.P1, theta, "P")


@dataclass(frozen=True)
class ImpulsiveObserverSearch:
    """Outcome of :func:`~switchest.analysis.impulsive_observer_search`.

    Attributes
    ----------
    best : ImpulsiveObserverCertificate
        The certificate with the largest :math:`\\beta` found (``holds=False`` if none).
    mu_s, mu_c : ndarray, shapes (a,), (b,)
        The grids searched.
    alpha : ndarray, shape (a, b)
        Largest :math:`\\alpha` (to ``alpha_tol``) with feasible LMIs for each
        :math:`(\\mu_s, \\mu_c)`, searched above the value where :math:`\\beta = 0`; NaN where
        the LMIs are infeasible there (no positive rate).
    beta : ndarray, shape (a, b)
        Rate (11) at ``alpha``; NaN where ``alpha`` is.
    n_solves : int
        Number of SDPs solved.
    """

    best: ImpulsiveObserverCertificate
    mu_s: np.ndarray
    mu_c: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    n_solves: int

    @property
    def holds(self) -> bool:
        """The best certificate proves Theorem 8's conclusion (``best.holds``)."""
        return self.best.holds


@dataclass(frozen=True)
class ClosedLoopCertificate(_ClockCertificate):
    """Outcome of :func:`~switchest.analysis.impulsive_closed_loop_analysis` (Etienne et al.
    Theorem 10).

    Attributes
    ----------
    holds : bool
        Theorem 10's conclusion (corrected) is proven: LMIs (24)-(27) solved and verified
        with numpy, and :math:`\\beta > 0`.
    lmi_feasible : bool
        The LMIs alone.
    Q0, Q1 : ndarray, shape (L, 2n, 2n), or None
        :math:`Q^i(\\theta) = \\mathrm{Q0}[i] + \\theta \\, \\mathrm{Q1}[i]` (eq. (29)), normalized
        :math:`\\succeq I` at the ends.
    beta : float
        Rate of :func:`~switchest.analysis.impulsive_closed_loop_decay_rate` (the corrected
        (31)); reported whatever the LMIs, so ``holds`` is the verdict.
    printed_beta : float
        Eq. (31) as printed (``-printed_beta`` is the left side of (28)), for comparison.
    scalars : dict
        ``alpha, alpha_bar, mu_s, mu_c, mu_c_bar, delta, tau_min, tau_max, dwell``.
    margin, solver_status, note
        As in :class:`ImpulsiveObserverCertificate`.
    """

    holds: bool
    lmi_feasible: bool
    Q0: np.ndarray | None
    Q1: np.ndarray | None
    beta: float
    printed_beta: float
    scalars: dict
    margin: float
    solver_status: str
    note: str

    def overshoot(self, N0: float = 1.0) -> float:
        """:math:`M` in :math:`\\lVert z(t) \\rVert
        \\le M \\exp(-\\beta t) \\lVert z(0^+) \\rVert` (proof of Theorem 10, corrected).

        :math:`M^2 = \\exp(N_0 c) \\, \\theta_{\\max} / (\\mu_c' \\theta_{\\min})` with
        :math:`c = \\ln(\\mu_s) + \\delta (\\alpha + \\bar\\alpha)^+ + q \\ln(\\bar\\mu_c/\\mu_c)^+`
        the per-switch cost of :func:`~switchest.analysis.impulsive_closed_loop_decay_rate`,
        :math:`\\theta_{\\max}`, :math:`\\theta_{\\min}` and :math:`\\mu_c'` as in
        :meth:`ImpulsiveObserverCertificate.overshoot`, :math:`z(0^+)` the state just after the
        jump at :math:`t_0` and ``N0`` the chatter bound. (The printed constant :math:`\\tilde M`
        carries the printed, invalid sample counts.)
        """
        k = self.scalars
        cost = _switch_cost(k["alpha"], k["alpha_bar"], k["mu_s"], k["mu_c"], k["mu_c_bar"],
                            k["tau_min"], k["delta"])
        return self._overshoot(N0, self.Q0, self.Q1, k["tau_max"], cost, k["mu_c"])

    def Q(self, theta) -> np.ndarray:
        """:math:`Q^i(\\theta) = Q_0^i + \\theta Q_1^i` for ``theta (...)``, shape
        ``(..., L, 2n, 2n)``."""
        return self._clock(self.Q0, self.Q1, theta, "Q")
