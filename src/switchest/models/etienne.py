"""The academic example of Etienne, Motchon, Duviella & Guelton (seed 004), §4.

A two-mode, second-order switched system with one sampled output, observed by an
impulsive observer under aperiodic sampling (Etienne et al. eqs (1)-(3)), and
the scalars of the paper's two syntheses (Theorem 8, synchronous; Theorem 10,
delayed mode knowledge with an observer-based controller).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..system import SwitchedLinearSystem

__all__ = ["ETIENNE_SCENARIO", "EtienneScenario", "etienne_academic"]


def etienne_academic() -> SwitchedLinearSystem:
    """The academic example of Etienne et al. §4 (also Zhang & Gao 2010)::

        A_1 = [[0.2, -0.5], [0.5, -0.3]],  B_1 = [-0.4, 1.8]',  C_1 = [1, 0]   (mode 0)
        A_2 = [[0.2, 0.3], [-1, 0.4]],     B_2 = [0.1, 1.5]',   C_2 = [1, 0]   (mode 1)

    Deterministic, as in the paper's eq. (1): no process noise, noise-free
    samples ``y(t_k) = C x(t_k)`` (``R = 0``). ``A_1`` is stable (eigenvalues
    ``-0.05 +/- 0.433j``), ``A_2`` is not (``0.3 +/- 0.539j``); both pairs
    ``(A_i, C_i)`` are observable.

    Returns
    -------
    SwitchedLinearSystem
        Continuous time, 2 modes, 2 states, 1 input, 1 output.
    """
    A = np.array([[[0.2, -0.5], [0.5, -0.3]], [[0.2, 0.3], [-1.0, 0.4]]])
    B = np.array([[[-0.4], [1.8]], [[0.1], [1.5]]])
    return SwitchedLinearSystem.continuous(A=A, B=B, C=np.array([[1.0, 0.0]]))


@dataclass(frozen=True)
class EtienneScenario:
    """The parameters of Etienne et al. §4 (defaults are the paper's).

    Attributes
    ----------
    tau_min, tau_max : float
        Sampling intervals ``t_{k+1} - t_k`` lie in ``[tau_min, tau_max]``
        (Assumption 2): 0.3 and 0.4.
    dwell : float
        Average dwell time ``s`` of the switching signal (Assumption 1): 7.
    N0 : float
        Chatter bound of Assumption 1. **Not printed**; our choice 1 is met by
        every signal whose switches are at least ``dwell`` apart. It enters only
        the overshoot of the bounds, not the rate ``beta``.
    alpha, mu_s, mu_c : float
        Theorem 8's fixed scalars ``alpha_`` (underlined alpha), ``mu_s`` and
        ``mu_c_`` (underlined mu_c): 0.2, 5, 0.98.
    delta : float
        Maximum delay of the mode estimate (Assumption 5), Theorem 10: 0.15.
    mu_c_bar, alpha_bar : float
        Theorem 10's ``mu_c`` (overlined) and ``alpha`` (overlined): 5 and 3.
    controller : tuple of tuple of float
        The "emulation based" state-feedback gains ``K_1 = [2.1124, -0.9336]``,
        ``K_2 = [-1.3111, -1.3158]``, applied as ``u = K_{sigma_hat} x_hat``
        (§3.2); :attr:`K` gives them as an array.

    Notes
    -----
    Theorem 8's scalar condition (9), ``alpha > ln(mu_s)/s + ln(mu_c)/tau_max``,
    holds for these values (0.2 > 0.1794, rate ``beta`` of (11) = 0.0103). Theorem
    10's scalar condition (28), however, evaluates to +0.1640 > 0 with the same
    values and ``delta = 0.15, mu_c_bar = 5, alpha_bar = 3``: it is violated,
    although §4 reports that "the condition of Theorem 10 are verified".
    """

    tau_min: float = 0.3
    tau_max: float = 0.4
    dwell: float = 7.0
    N0: float = 1.0
    alpha: float = 0.2
    mu_s: float = 5.0
    mu_c: float = 0.98
    delta: float = 0.15
    mu_c_bar: float = 5.0
    alpha_bar: float = 3.0
    controller: tuple[tuple[float, ...], ...] = ((2.1124, -0.9336), (-1.3111, -1.3158))

    @property
    def K(self) -> np.ndarray:
        """Controller gains stacked per mode, shape (L, l, n) = (2, 1, 2)."""
        return np.asarray(self.controller, dtype=float)[:, None, :]


ETIENNE_SCENARIO = EtienneScenario()
"""The paper's scenario (Etienne et al. §4)."""
