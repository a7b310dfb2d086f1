"""The paper's misprinted formulas of Examples 2 and 4, evaluated as printed.

Where Wang et al.'s arithmetic is inconsistent (it mixes ``e^{(a-L)T}`` and
``e^{2(a-L)T}``), the ``wang-examples`` summary shows the printed number (:mod:`.paper`)
beside the correct one and beside the number of the reading that reproduces it; the notes say
which reading is right (tests/analysis/test_subsystem_observers.py checks every reading).
These readings show where a printed number comes from: they are printed values, not
mathematics the library should offer.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar


def printed_gamma(a: float, L: float, p_closed: float, T: float) -> float:
    """The paper's misprinted second-moment factor of a scalar component,
    ``p e^{(a-L) T} + (1-p) e^{2aT}``.

    The right factor has ``e^{2(a-L)T}`` (Examples 1-2's gammas, computed from the
    library's ``Lambda``); this reading is behind Example 2's gain bounds and
    Example 4's gamma^1.
    """
    return p_closed * np.exp((a - L) * T) + (1.0 - p_closed) * np.exp(2.0 * a * T)


def printed_gain_bound(a: float, p_closed: float, T: float) -> float:
    """``L`` at which :func:`printed_gamma` equals 1 (Example 2's printed bounds)."""
    return a - np.log((1.0 - (1.0 - p_closed) * np.exp(2.0 * a * T)) / p_closed) / T


def printed_sigma(a: float, L: float, p_closed: float, T: float, zeta: float) -> float:
    """Example 4's ``sigma_inf = p Q^2 / (1 - gamma)`` as the paper evaluates it:
    :func:`printed_gamma` and ``Q^2 = int_0^inf e^{2(a-L)s} L^2 zeta ds = L^2 zeta / (2(L - a))``
    (Proposition 1 stops at T)."""
    Q2 = L**2 * zeta / (2.0 * (L - a))
    gamma = printed_gamma(a, L, p_closed, T)
    return p_closed * Q2 / (1.0 - gamma) if gamma < 1 else np.inf


def printed_optimum(a: float, p_closed: float, T: float, zeta: float) -> tuple[float, float]:
    """Example 4's optimum ``(L1*, sigma_inf)`` as printed (61.3, 0.9864): :func:`printed_sigma`
    minimized above :func:`printed_gain_bound`."""
    lo = printed_gain_bound(a, p_closed, T) + 1e-6
    r = minimize_scalar(lambda L: printed_sigma(a, L, p_closed, T, zeta), bounds=(lo, 1000.0),
                        method="bounded", options={"xatol": 1e-10})
    return float(r.x), float(r.fun)
