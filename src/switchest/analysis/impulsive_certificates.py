"""What the LMIs of the impulsive observer prove: the certificates of Theorems 8 and 10.

Etienne, Motchon, Duviella & Guelton (seed 004). A certificate holds the clock-dependent
Lyapunov matrices ``P^i(theta) = P0^i + theta P1^i`` (eq. (10); ``Q`` on the closed loop's
extended state, eq. (29)) found by :mod:`switchest.analysis.impulsive_lmis`, the scalars they
were found for, the decay rate ``beta`` of :mod:`switchest.analysis.impulsive_rates`, and the
verdict ``holds``; its ``overshoot`` is the constant ``M`` of
``||e(t)|| <= M exp(-beta t) ||e(0+)||``.
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
    Lyapunov matrices, affine in the clock ``theta``."""

    def _clock(self, M0: np.ndarray | None, M1: np.ndarray, theta, name: str) -> np.ndarray:
        """:func:`_clock_affine`, or the error that the LMIs gave no matrix ``name``."""
        if M0 is None:
            raise ValueError(f"the certificate holds no {name}: the LMIs were not feasible")
        return _clock_affine(M0, M1, theta)

    def _overshoot(self, N0: float, M0: np.ndarray, M1: np.ndarray, tau_max: float,
                   switch_cost: float, mu_c: float) -> float:
        """``M = sqrt(exp(N0 c) theta_max / (mu_c' theta_min))`` (proof of Theorem 8, eqs
        (19)-(20)), ``c`` the growth of ``ln V`` charged to a switch.

        ``theta_max`` is the largest eigenvalue of the ``M0^i``, ``theta_min`` the smallest of
        the ``M^i(theta)`` over ``[0, tau_max]`` (attained at an end: the smallest eigenvalue is
        concave), ``mu_c' = mu_c`` when ``mu_c <= 1`` and 1 otherwise, ``N0`` the chatter bound
        of Assumption 1.
        """
        if not self.holds:
            raise ValueError("no overshoot bound: the certificate is not feasible")
        N0 = positive_scalar(N0, "N0", allow_zero=True)
        ends = _clock_affine(M0, M1, np.array([0.0, tau_max]))
        top = float(np.max(max_eigenvalue(M0)))
        low = float(np.min(min_eigenvalue(ends)))
        return math.sqrt(math.exp(N0 * switch_cost) * top / (min(mu_c, 1.0) * low))


def _clock_affine(M0: np.ndarray, M1: np.ndarray, theta) -> np.ndarray:
    """``M0^i + theta M1^i`` for ``theta (...)``: shape ``(..., L, k, k)`` (eq. (10))."""
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
        passed the numpy re-check, and the rate condition (9) holds (``beta > 0``).
    lmi_feasible : bool
        The LMIs alone (verified); ``holds`` also needs ``beta > 0``.
    P0, P1 : ndarray, shape (L, n, n), or None
        ``P^i(theta) = P0[i] + theta P1[i]`` (eq. (10)); ``P1`` is the slope.
        Normalized so that ``P^i(theta) >= I`` at theta in {0, tau_max}.
    L : ndarray, shape (L, n, m), or None
        The LMI variables ``L_i = P0^i G_i``.
    G : ndarray, shape (L, n, m), or None
        Observer gains ``G_i = (P0^i)^-1 L_i``.
    beta : float
        Decay rate of ``||e||`` that the scalars give (eq. (11), corrected for
        ``mu_c > 1``); guaranteed only when ``holds``.
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
        """``M`` in ``||e(t)|| <= M exp(-beta t) ||e(0+)||`` (proof of Theorem 8, eqs (19)-(20)).

        ``M^2 = mu_s^N0 theta_max / (mu_c' theta_min)`` (``_ClockCertificate._overshoot``
        with ``c = ln(mu_s)``). ``e(0+)`` is the error just after the correction at ``t_0``
        (the clock starts there), and ``N0`` the chatter bound of Assumption 1.
        """
        return self._overshoot(N0, self.P0, self.P1, self.tau_max, math.log(self.mu_s),
                               self.mu_c)

    def P(self, theta) -> np.ndarray:
        """``P^i(theta) = P0^i + theta P1^i`` for ``theta (...)``, shape ``(..., L, n, n)``."""
        return self._clock(self.P0, self.P1, theta, "P")


@dataclass(frozen=True)
class ImpulsiveObserverSearch:
    """Outcome of :func:`~switchest.analysis.impulsive_observer_search`.

    Attributes
    ----------
    best : ImpulsiveObserverCertificate
        The certificate with the largest ``beta`` found (``holds=False`` if none).
    mu_s, mu_c : ndarray, shapes (a,), (b,)
        The grids searched.
    alpha : ndarray, shape (a, b)
        Largest ``alpha`` (to ``alpha_tol``) with feasible LMIs for each
        ``(mu_s, mu_c)``, searched above the value where ``beta = 0``; NaN where
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
        with numpy, and ``beta > 0``.
    lmi_feasible : bool
        The LMIs alone.
    Q0, Q1 : ndarray, shape (L, 2n, 2n), or None
        ``Q^i(theta) = Q0[i] + theta Q1[i]`` (eq. (29)), normalized ``>= I`` at the ends.
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
        """``M`` in ``||z(t)|| <= M exp(-beta t) ||z(0+)||`` (proof of Theorem 10, corrected).

        ``M^2 = exp(N0 c) theta_max / (mu_c' theta_min)`` with
        ``c = ln(mu_s) + delta (alpha + alpha_bar)^+ + q ln(mu_c_bar/mu_c)^+`` the
        per-switch cost of :func:`~switchest.analysis.impulsive_closed_loop_decay_rate`,
        ``theta_max``, ``theta_min`` and ``mu_c'`` as in
        :meth:`ImpulsiveObserverCertificate.overshoot`, ``z(0+)`` the state just after the jump
        at ``t_0`` and ``N0`` the chatter bound. (The printed constant ``M~`` carries the
        printed, invalid sample counts.)
        """
        k = self.scalars
        cost = _switch_cost(k["alpha"], k["alpha_bar"], k["mu_s"], k["mu_c"], k["mu_c_bar"],
                            k["tau_min"], k["delta"])
        return self._overshoot(N0, self.Q0, self.Q1, k["tau_max"], cost, k["mu_c"])

    def Q(self, theta) -> np.ndarray:
        """``Q^i(theta) = Q0^i + theta Q1^i`` for ``theta (...)``, shape ``(..., L, 2n, 2n)``."""
        return self._clock(self.Q0, self.Q1, theta, "Q")
