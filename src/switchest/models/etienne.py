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
    """The academic example of Etienne et al. §4 (also Zhang & Gao 2010):

    .. math::

        \\begin{aligned}
        A_1 &= \\begin{bmatrix} 0.2 & -0.5 \\\\ 0.5 & -0.3 \\end{bmatrix}, &
        B_1 &= [-0.4, 1.8]^\\top, & C_1 &= [1, 0] && \\text{(mode 0)}, \\\\
        A_2 &= \\begin{bmatrix} 0.2 & 0.3 \\\\ -1 & 0.4 \\end{bmatrix}, &
        B_2 &= [0.1, 1.5]^\\top, & C_2 &= [1, 0] && \\text{(mode 1)}.
        \\end{aligned}

    Deterministic, as in the paper's eq. (1): no process noise, noise-free
    samples :math:`y(t_k) = C x(t_k)` (:math:`R = 0`). :math:`A_1` is stable (eigenvalues
    :math:`-0.05 \\pm 0.433j`), :math:`A_2` is not (:math:`0.3 \\pm 0.539j`); both pairs
    :math:`(A_i, C_i)` are observable.

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
        Sampling intervals :math:`t_{k+1} - t_k` lie in :math:`[\\tau_{\\min}, \\tau_{\\max}]`
        (Assumption 2): 0.3 and 0.4.
    dwell : float
        Average dwell time :math:`s` of the switching signal (Assumption 1): 7.
    N0 : float
        Chatter bound of Assumption 1. **Not printed**; our choice 1 is met by
        every signal whose switches are at least ``dwell`` apart. It enters only
        the overshoot of the bounds, not the rate :math:`\\beta`.
    alpha, mu_s, mu_c : float
        Theorem 8's fixed scalars :math:`\\underline{\\alpha}`, :math:`\\mu_s` and
        :math:`\\underline{\\mu}_c`: 0.2, 5, 0.98.
    delta : float
        Maximum delay of the mode estimate (Assumption 5), Theorem 10: 0.15.
    mu_c_bar, alpha_bar : float
        Theorem 10's :math:`\\overline{\\mu}_c` and :math:`\\overline{\\alpha}`: 5 and 3.
    controller : tuple of tuple of float
        The "emulation based" state-feedback gains :math:`K_1 = [2.1124, -0.9336]`,
        :math:`K_2 = [-1.3111, -1.3158]`, applied as :math:`u = K_{\\hat{\\sigma}} \\hat{x}`
        (§3.2); :attr:`K` gives them as an array.

    Notes
    -----
    Theorem 8's scalar condition (9),
    :math:`\\underline{\\alpha} > \\ln(\\mu_s)/s + \\ln(\\underline{\\mu}_c)/\\tau_{\\max}`,
    holds for these values (0.2 > 0.1794, rate :math:`\\beta` of (11) = 0.0103). Theorem
    10's scalar condition (28), however, evaluates to +0.1640 > 0 with the same
    values and :math:`\\delta = 0.15`, :math:`\\overline{\\mu}_c = 5`,
    :math:`\\overline{\\alpha} = 3`: it is violated,
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
