"""A demonstration system for Lee, Ping & Shim (002), which prints no numerical example.

A frequency-shift-keyed carrier observed in phase and quadrature: the state is a
phasor rotating at :math:`\\omega_1` or :math:`\\omega_2`, both components are measured with
bounded noise, and a small bounded input pushes it:

.. math::

    \\dot{x} = \\omega_i J x + b u, \\qquad y = x + v, \\qquad
    J = \\begin{bmatrix} 0 & 1 \\\\ -1 & 0 \\end{bmatrix}, \\qquad b = [0, 1]^\\top

Why this system
---------------
Conditions (3) and (4) of Lee et al. compare the output distance between modes
(:math:`\\omega_{\\min}`) with noise terms inflated by :math:`\\mu e^{\\lambda \\Delta}`,
:math:`\\hat{E}` and :math:`C_{\\max}`. Each choice below makes one factor as favourable as it
can be, so the assumptions hold at a noise level of about 10 % of the signal:

* :math:`A_i = \\omega_i J` is skew-symmetric: :math:`\\|e^{A_i t}\\| = 1` exactly, so
  :math:`\\check{\\mu} = 1`, :math:`\\check{\\lambda} = 0` and
  :math:`(\\mu e^{\\lambda \\Delta} + 1)^2 = 4`, the smallest value (4) allows. It also makes
  :math:`|x|` change only through the input:
  :math:`|x(t)| \\ge |x(0)| - \\|b\\| u_{\\max} t` for any switching, an explicit
  :math:`x_{\\min}`.
* :math:`C = I` (I/Q measurement): :math:`U_i(t) = t I`, hence :math:`M_{\\max}(\\delta) = 1`,
  and the observer gains :math:`L_i = A_i + a I` give :math:`A_i - L_i C = -a I`:
  :math:`\\hat{\\mu} = 1`, :math:`\\hat{\\lambda} = a`,
  :math:`\\hat{E} = \\sqrt{1 + (\\omega_{\\max} / a)^2}`, close to 1.
* :math:`\\omega_2 - \\omega_1 = 2 \\pi / \\Delta`: the Gramian :math:`W_{12}(t)` has diagonal
  blocks :math:`t I` and off-diagonal block
  :math:`\\int_0^t e^{(\\omega_2 - \\omega_1) J \\tau}\\, d\\tau`, which vanishes at
  :math:`t = \\Delta`, so :math:`\\omega_{\\min}(\\Delta) = \\Delta` — the largest value
  possible. In general :math:`\\omega_{\\min}(t) = t - 2 |\\sin(d\\omega\\, t / 2)| / d\\omega`.

With only the in-phase component measured (:math:`C = [1, 0]`) the same analysis
allows about twenty times less noise (:math:`M_{\\max} \\approx 2`,
:math:`\\hat{\\mu} \\approx 4`, :math:`\\hat{E} \\approx 20`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import as_rng, float_array, positive_int, positive_scalar
from ..signals import SwitchingSignal, dwell_time
from ..system import SwitchedLinearSystem

__all__ = ["LEE_SCENARIO", "LeeScenario", "fsk_oscillator"]

_J = np.array([[0.0, 1.0], [-1.0, 0.0]])


def fsk_oscillator(omega=(2 * np.pi, 4 * np.pi), input_gain: float = 1.0) -> SwitchedLinearSystem:
    """The two-mode phasor :math:`\\dot{x} = \\omega_i J x + b u`, :math:`y = x` (noise added by
    the caller).

    Parameters
    ----------
    omega : pair of float
        Angular frequencies of modes 0 and 1 (rad per time unit), distinct.
    input_gain : float
        :math:`b = [0, \\mathrm{input\\_gain}]^\\top`.

    Returns
    -------
    SwitchedLinearSystem
        Continuous time, 2 modes, 2 states, 1 input, 2 outputs, noise-free
        (:math:`R = 0`: the bounded noise of Lee et al. is not Gaussian; see
        :meth:`LeeScenario.noise`).
    """
    omega = float_array(omega, "omega", ndim=1)
    if omega.shape != (2,) or not np.all(np.isfinite(omega)) or omega[0] == omega[1]:
        raise ValueError(f"omega must be two distinct finite frequencies, got {omega.tolist()}")
    b = positive_scalar(input_gain, "input_gain")
    A = omega[:, None, None] * _J
    B = np.array([[0.0], [b]])
    return SwitchedLinearSystem.continuous(A, B, np.eye(2))


@dataclass(frozen=True)
class LeeScenario:
    """The demonstration scenario for :func:`fsk_oscillator` (Lee et al.'s setting).

    Attributes
    ----------
    omega : tuple of float
        :math:`(2 \\pi, 4 \\pi)`: 1 Hz and 2 Hz, beat period 1.
    input_gain : float
        :math:`\\|b\\|`.
    observer_decay : float
        :math:`a` in :math:`L_i = A_i + a I` (:attr:`observer_gains`).
    delta, Delta : float
        Estimation window 0.25 (condition (3)) and detection delay 1 = one beat
        period (condition (4)).
    u_max, v_max : float
        Input and noise bounds (eq. (2)). ``v_max = 0.1`` is 10 % of :math:`|x(0)|`.
    x0 : tuple of float
        Initial state, :math:`|x_0| = 1`.
    horizon : float
        Length of a run.
    min_dwell, max_dwell : float
        Dwell times of the random switching signal (:meth:`signal`),
        :math:`\\mathrm{min\\_dwell} > \\delta + \\Delta` (Assumption 3).
    input_frequency : tuple of float
        Range of the angular frequency of the sinusoidal input (:meth:`input`).
    """

    omega: tuple[float, float] = (2 * np.pi, 4 * np.pi)
    input_gain: float = 1.0
    observer_decay: float = 40.0
    delta: float = 0.25
    Delta: float = 1.0
    u_max: float = 0.02
    v_max: float = 0.1
    x0: tuple[float, float] = (1.0, 0.0)
    horizon: float = 10.0
    min_dwell: float = 1.3
    max_dwell: float = 2.5
    input_frequency: tuple[float, float] = (0.5, 3.0)

    def system(self) -> SwitchedLinearSystem:
        """:func:`fsk_oscillator` with this scenario's frequencies and input gain."""
        return fsk_oscillator(self.omega, self.input_gain)

    @property
    def observer_gains(self) -> np.ndarray:
        """:math:`L_i = A_i + a I` (shape (2, 2, 2)), so that :math:`A_i - L_i C = -a I`."""
        return np.asarray(self.omega)[:, None, None] * _J + self.observer_decay * np.eye(2)

    def x_min(self, horizon: float | None = None) -> float:
        """:math:`|x_0| - \\|b\\|\\, u_{\\max}\\, \\mathrm{horizon}`: a lower bound on
        :math:`|x(t)|` up to ``horizon``.

        Exact for skew-symmetric :math:`A_i`:
        :math:`d|x|/dt = x^\\top b u / |x| \\ge -\\|b\\|\\, u_{\\max}`.
        """
        T = self.horizon if horizon is None else positive_scalar(horizon, "horizon")
        return float(np.hypot(*self.x0) - self.input_gain * self.u_max * T)

    def interpolation_gap(self, grid_step: float, duration: float) -> float:
        """Largest gap between the noise-free output and its linear interpolation on a grid.

        The detector integrates :math:`y` as linear between grid points; the gap acts like
        noise. With :math:`u` held on each step, :math:`\\ddot{y} = A_i (A_i x + b u)` inside a
        step; a switch inside a step adds a kink where :math:`\\dot{y}` jumps by
        :math:`(A_j - A_i) x`. Linear interpolation of :math:`f` with :math:`|f''| \\le M` and one
        kink of size :math:`J` is off by at most :math:`h^2 M / 8 + h J / 4`, so the gap is at
        most:

        .. math::

            \\frac{h^2}{8} (\\omega_{\\max}^2 x_{\\max} + \\omega_{\\max} \\|b\\|\\, u_{\\max})
            + \\frac{h}{4} |\\omega_1 - \\omega_0|\\, x_{\\max}

        with :math:`x_{\\max} = |x_0| + \\|b\\|\\, u_{\\max} t` (:math:`A_i` skew-symmetric, at most
        one switch per step since dwell times exceed the step).
        """
        h = positive_scalar(grid_step, "grid_step")
        w = max(self.omega)
        x_max = np.hypot(*self.x0) + self.input_gain * self.u_max * positive_scalar(duration,
                                                                                    "duration")
        smooth = h**2 / 8 * (w**2 * x_max + w * self.input_gain * self.u_max)
        return float(smooth + h / 4 * abs(self.omega[1] - self.omega[0]) * x_max)

    def signal(self, rng) -> SwitchingSignal:
        """A random switching signal on ``[0, horizon]`` with dwell in ``[min_dwell, max_dwell]``.

        The first switch comes one dwell after 0, so none falls in :math:`[0, \\delta]`.
        """
        rng = as_rng(rng)
        first = int(rng.integers(2))
        return dwell_time(2, self.horizon, self.min_dwell, self.max_dwell, rng=rng,
                          initial_mode=first)

    def input(self, t, trials: int, rng) -> np.ndarray:
        """:math:`u(t) = u_{\\max} \\sin(w t + \\phi)`, random :math:`w` and :math:`\\phi` per
        trial; (trials, K, 1)."""
        t = float_array(t, "t", ndim=1)
        trials = positive_int(trials, "trials")
        rng = as_rng(rng)
        w = rng.uniform(*self.input_frequency, size=(trials, 1))
        phi = rng.uniform(0, 2 * np.pi, size=(trials, 1))
        return (self.u_max * np.sin(w * t + phi))[..., None]

    def noise(self, t, trials: int, rng, *, v_max: float | None = None) -> np.ndarray:
        """Bounded measurement noise :math:`|v(t)| \\le v_{\\max}`, shape (trials, K, 2).

        Half of the bound is an interfering tone — a phasor of random frequency in
        :math:`[0, 1.5 \\max(\\omega)]` and phase, the most mode-like disturbance — and half
        white noise uniform in the disc, drawn at every grid point. Linear
        interpolation between grid points stays inside the disc.
        """
        t = float_array(t, "t", ndim=1)
        trials = positive_int(trials, "trials")
        v = self.v_max if v_max is None else positive_scalar(v_max, "v_max", allow_zero=True)
        rng = as_rng(rng)
        w = rng.uniform(0, 1.5 * max(self.omega), size=(trials, 1))
        angle = w * t + rng.uniform(0, 2 * np.pi, size=(trials, 1))
        tone = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
        radius = np.sqrt(rng.uniform(size=(trials, t.size, 1)))
        theta = rng.uniform(0, 2 * np.pi, size=(trials, t.size))
        white = radius * np.stack([np.cos(theta), np.sin(theta)], axis=-1)
        return 0.5 * v * (tone + white)


LEE_SCENARIO = LeeScenario()
"""The demonstration scenario (see :class:`LeeScenario`)."""
