"""Decay rates of the impulsive observer and its closed loop under aperiodic sampling.

Etienne, Motchon, Duviella & Guelton (seed 004), the scalar conditions of Theorems 8 and 10:
the rate :math:`\\beta` of
:math:`\\lVert e(t) \\rVert \\le M \\exp(-\\beta t) \\lVert e(0^+) \\rVert` that the scalars of
the LMIs (:mod:`switchest.analysis.impulsive_lmis`) give, with :math:`\\alpha` the flow rate,
:math:`\\mu_s` the growth at a switch, :math:`\\mu_c` at a sample, :math:`s` the average dwell
time and the samples :math:`\\tau_{\\min}` to :math:`\\tau_{\\max}` apart. Plain arithmetic: no
LMI is solved here.

Theorem 8 (synchronous mode knowledge), condition (9): :math:`\\beta > 0` with the rate (11)
:math:`\\beta = (\\alpha - \\ln(\\mu_s)/s - \\ln(\\mu_c)/\\tau_c) / 2`. Discrepancy with the printed
(9)/(11): they use :math:`N_c(0, t) \\ge t/\\tau_{\\max} - 1` (Remark 3), a lower bound on the
number of samples, which bounds :math:`\\mu_c^{N_c}` only when :math:`\\ln(\\mu_c) \\le 0`. For
:math:`\\mu_c > 1` the bound needs :math:`N_c(0, t) \\le t/\\tau_{\\min}`:
:math:`\\tau_c = \\tau_{\\min}` replaces :math:`\\tau_{\\max}`. (The theorem states
:math:`\\mu_c \\le 1`; the scalar search of the LMIs may use either.)

Theorem 10 (mode estimate delayed by at most :math:`\\delta`), condition (28):
:math:`\\beta > 0`, with :math:`\\bar\\alpha` the flow rate and :math:`\\bar\\mu_c` the sample
growth while the mode estimate is wrong. The printed rate (28)/(31) counts the samples that
fall while the estimate is wrong as :math:`\\delta/\\tau_{\\min}` per switch and the correct
ones as :math:`(t - M_{\\mathrm{miss}})/\\tau_{\\max}`. A mismatch window of length
:math:`\\delta` can hold :math:`\\lceil \\delta/\\tau_{\\min} \\rceil` samples (one, not one
half, for :math:`\\delta = 0.15`, :math:`\\tau_{\\min} = 0.3`), and a correct-mode stretch of
length :math:`l` may hold only :math:`\\lfloor l/\\tau_{\\max} \\rfloor` samples, so neither
count is a valid bound. :func:`impulsive_closed_loop_decay_rate` uses
:math:`N_{\\mathrm{miss}} \\le q N_s`, :math:`q = \\lceil \\delta/\\tau_{\\min} \\rceil`, and
:math:`N_{\\mathrm{match}} = N_c - N_{\\mathrm{miss}}`, which gives

.. math::

    2 \\beta = \\alpha - \\ln(\\mu_c)/\\tau_c
        - \\bigl(\\ln(\\mu_s) + \\delta (\\alpha + \\bar\\alpha)^+
        + q \\ln(\\bar\\mu_c/\\mu_c)^+\\bigr) / s

(:math:`x^+ = \\max(x, 0)`; with :math:`\\delta = 0` it is Theorem 8's rate, as Remark 11 says).
This form needs none of the printed restrictions :math:`\\mu_c \\le 1 \\le \\bar\\mu_c` (any
positive values are accepted; :math:`\\mu_s \\ge 1` is required). With the §4 scalars the
printed (28) is already violated (:math:`-2 \\beta = +0.16403`) although §4 reports the
conditions verified.
"""

from __future__ import annotations

import math

import numpy as np

from .._checks import positive_scalar

__all__ = [
    "impulsive_closed_loop_decay_rate",
    "impulsive_observer_decay_rate",
    "largest_tolerable_delay",
]


def impulsive_observer_decay_rate(
    alpha: float, mu_s: float, mu_c: float, tau_min: float, tau_max: float, dwell: float
) -> float:
    """Decay rate of the observer error, Etienne et al. Theorem 8 (synchronous mode knowledge).

    Eq. (11): :math:`\\beta = (\\alpha - \\ln(\\mu_s)/s - \\ln(\\mu_c)/\\tau_c) / 2`.

    :math:`\\tau_c = \\tau_{\\max}` for :math:`\\mu_c \\le 1` (as printed) and :math:`\\tau_{\\min}`
    for :math:`\\mu_c > 1` (the printed form assumes :math:`\\ln(\\mu_c) \\le 0`; see the module
    notes). Condition (9) is :math:`\\beta > 0`.
    """
    alpha, mu_s, mu_c, tau_min, tau_max, dwell = _scalars8(
        alpha, mu_s, mu_c, tau_min, tau_max, dwell
    )
    return 0.5 * (alpha - math.log(mu_s) / dwell - _sample_rate(mu_c, tau_min, tau_max))


def impulsive_closed_loop_decay_rate(alpha: float, alpha_bar: float, mu_s: float, mu_c: float,
                                     mu_c_bar: float, tau_min: float, tau_max: float,
                                     dwell: float, delta: float) -> float:
    """Decay rate of the closed loop :math:`\\lVert z \\rVert`, Etienne et al. Theorem 10 (delayed
    mode estimate).

    The mode estimate lags the true switches by at most :math:`\\delta`.

    Re-derived from the proof of Etienne et al. Theorem 10 (eqs (32)-(40)) with
    valid sample counts:

    .. math::

        2 \\beta = \\alpha - \\ln(\\mu_c)/\\tau_c
            - \\bigl(\\ln(\\mu_s) + \\delta (\\alpha + \\bar\\alpha)^+
            + q \\ln(\\bar\\mu_c/\\mu_c)^+\\bigr) / s

    with :math:`q = \\lceil \\delta/\\tau_{\\min} \\rceil` (the most samples a mismatch window of
    length :math:`\\delta` holds), :math:`\\tau_c` as in :func:`impulsive_observer_decay_rate`,
    :math:`x^+ = \\max(x, 0)`. Condition (28) is :math:`\\beta > 0`. The printed (31) differs; see
    the module notes.
    """
    alpha, mu_s, mu_c, tau_min, tau_max, dwell = _scalars8(
        alpha, mu_s, mu_c, tau_min, tau_max, dwell
    )
    alpha_bar = _real(alpha_bar, "alpha_bar")
    mu_c_bar = positive_scalar(mu_c_bar, "mu_c_bar")
    delta = positive_scalar(delta, "delta", allow_zero=True)
    per_switch = _switch_cost(alpha, alpha_bar, mu_s, mu_c, mu_c_bar, tau_min, delta)
    return 0.5 * (alpha - _sample_rate(mu_c, tau_min, tau_max) - per_switch / dwell)


def largest_tolerable_delay(alpha: float, alpha_bar: float, mu_s: float, mu_c: float,
                            mu_c_bar: float, tau_min: float, tau_max: float, dwell: float) -> float:
    """Supremum of the mode-estimate delays :math:`\\delta` with condition (28) (Etienne et al.
    Theorem 10, as re-derived in :func:`impulsive_closed_loop_decay_rate`): :math:`\\beta > 0`.

    With :math:`b = \\alpha - \\ln(\\mu_c)/\\tau_c - \\ln(\\mu_s)/s` (twice
    :func:`impulsive_observer_decay_rate`),
    :math:`2 \\beta = b - (\\delta (\\alpha + \\bar\\alpha)^+ + q \\ln(\\bar\\mu_c/\\mu_c)^+) / s`
    is affine in :math:`\\delta` on each :math:`((q - 1) \\tau_{\\min}, q \\tau_{\\min}]`,
    :math:`q = \\lceil \\delta/\\tau_{\\min} \\rceil`: the supremum is where it reaches zero, or the
    left end of the first piece that starts at or below zero. NaN when even :math:`\\delta = 0`
    fails, ``inf`` when no delay does.
    """
    budget = dwell * 2 * impulsive_observer_decay_rate(alpha, mu_s, mu_c, tau_min, tau_max,
                                                       dwell)  # s b
    if budget <= 0:
        return math.nan
    slope = max(_real(alpha, "alpha") + _real(alpha_bar, "alpha_bar"), 0.0)
    per_sample = max(math.log(positive_scalar(mu_c_bar, "mu_c_bar") / mu_c), 0.0)
    if slope == 0 and per_sample == 0:
        return math.inf
    q = 1
    while True:
        room = budget - q * per_sample  # what the delayed flow may spend with q wrong samples
        end = room / slope if slope > 0 else (math.inf if room > 0 else -math.inf)
        if end <= (q - 1) * tau_min:
            return (q - 1) * tau_min
        if end <= q * tau_min:
            return end
        q += 1


def _switch_cost(alpha, alpha_bar, mu_s, mu_c, mu_c_bar, tau_min, delta) -> float:
    """Growth of :math:`\\ln V` charged to one switch: the jump :math:`\\mu_s`, at most
    :math:`\\delta` of wrong-mode flow, at most :math:`q = \\lceil \\delta/\\tau_{\\min} \\rceil`
    wrong-mode samples."""
    q = math.ceil(delta / tau_min - 1e-12) if delta > 0 else 0
    return (
        math.log(mu_s)
        + delta * max(alpha + alpha_bar, 0.0)
        + q * max(math.log(mu_c_bar / mu_c), 0.0)
    )


def _printed_theorem10_rate(alpha, alpha_bar, mu_s, mu_c, mu_c_bar, tau_min, tau_max, dwell, delta):
    """Equation (31) exactly as printed (for comparison only)."""
    r = delta / dwell
    return 0.5 * (
        alpha * (1 - r)
        - alpha_bar * r
        - math.log(mu_s) / dwell
        - math.log(mu_c) / tau_max * (1 - r)
        - delta * math.log(mu_c_bar) / (tau_min * dwell)
    )


def _sample_rate(mu_c: float, tau_min: float, tau_max: float) -> float:
    """:math:`\\ln(\\mu_c)` per unit time from the samples: over :math:`\\tau_{\\max}` when
    :math:`\\mu_c \\le 1` (fewest samples), over :math:`\\tau_{\\min}` when :math:`\\mu_c > 1` (most
    samples)."""
    return math.log(mu_c) / (tau_max if mu_c <= 1 else tau_min)


def _scalars8(alpha, mu_s, mu_c, tau_min, tau_max, dwell):
    """The scalars of Theorem 8, checked: :math:`\\alpha` real, :math:`\\mu_s \\ge 1`,
    :math:`\\mu_c` positive, :math:`0 < \\tau_{\\min} \\le \\tau_{\\max}` and a positive dwell
    time; as floats, in that order."""
    alpha = _real(alpha, "alpha")
    mu_s = positive_scalar(mu_s, "mu_s")
    if mu_s < 1:
        raise ValueError(f"mu_s must be >= 1 (switching cannot shrink every P^i), got {mu_s:g}")
    mu_c = positive_scalar(mu_c, "mu_c")
    tau_min = positive_scalar(tau_min, "tau_min")
    tau_max = positive_scalar(tau_max, "tau_max")
    if tau_max < tau_min:
        raise ValueError(f"tau_max must be >= tau_min = {tau_min:g}, got {tau_max:g}")
    dwell = positive_scalar(dwell, "dwell")
    return alpha, mu_s, mu_c, tau_min, tau_max, dwell


def _real(value, name: str) -> float:
    """``value`` as a float: a finite real scalar of any sign."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.integer, np.floating)
    ):
        raise TypeError(f"{name} must be a real scalar, got {type(value).__name__}")
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return float(value)
