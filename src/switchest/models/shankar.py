"""The two systems of Shankar, Yang & Hespanha (seed 000), §V.

* the boost converter of §V.A (two modes, continuous time, output :math:`v_0`
  sampled every 0.5 ms) and its switching scenario;
* the two-dimensional maneuvering vehicle of §V.B (three modes differing by
  their input) and its maneuver.

Both are continuous-time systems in the sense of Shankar et al. eqs (1)-(2):
:math:`dx/dt = A(\\sigma) x + B(\\sigma) u + w`, :math:`y_k = H x(t_k) + v_k`. The paper
states no process noise; each function takes it as an argument with a small
documented default.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import as_rng, check_symmetric_psd, float_array, positive_scalar
from ..signals import SwitchingSignal, dwell_time, periodic, schedule
from ..simulate import Trajectory, simulate
from ..system import SwitchedLinearSystem

__all__ = [
    "BOOST_INPUT_VOLTAGE",
    "BOOST_SAMPLE_PERIOD",
    "BoostTable1",
    "VehicleManeuver",
    "boost_converter",
    "boost_switching",
    "vehicle_2d",
    "vehicle_maneuver",
]

BOOST_INPUT_VOLTAGE = 100.0
"""Input voltage :math:`v_\\mathrm{in}` of the boost converter, volts (Shankar et al. §V.A)."""

BOOST_SAMPLE_PERIOD = 0.5e-3
"""Sampling period of the boost converter experiments, seconds (Shankar et al. §V.A, Table I)."""


def _intensity(value, n: int, name: str) -> np.ndarray:
    """A noise intensity given as a scalar :math:`q` (meaning :math:`q I_n`) or an (n, n)
    matrix."""
    arr = float_array(value, name, ndim=(0, 2))
    if arr.ndim == 0:
        return positive_scalar(float(arr), name, allow_zero=True) * np.eye(n)
    if arr.shape != (n, n):
        raise ValueError(f"{name} must be a scalar or an ({n}, {n}) matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return check_symmetric_psd(arr, name)


def boost_converter(
    *,
    R1: float = 2.0,
    L1: float = 500e-6,
    R0: float = 50.0,
    C0: float = 470e-6,
    process_noise=1.0,
    measurement_variance: float = 5.0,
) -> SwitchedLinearSystem:
    """The boost converter of Shankar et al. §V.A (after their ref. [19]).

    State :math:`x = [i_L, v_0]` (inductor current in A, output voltage in V), input
    :math:`u = v_\\mathrm{in}` (the paper uses :data:`BOOST_INPUT_VOLTAGE` = 100 V), output
    :math:`y = v_0` (:math:`H = [0 \\;\\; 1]`):

    .. math::

        \\begin{aligned}
        A(1) &= \\begin{bmatrix} -R_1/L_1 & 0 \\\\ 0 & -1/(R_0 C_0) \\end{bmatrix}
            && \\text{(mode 0 in code)}, \\\\
        A(2) &= \\begin{bmatrix} -R_1/L_1 & -1/L_1 \\\\ 1/C_0 & -1/(R_0 C_0) \\end{bmatrix}
            && \\text{(mode 1 in code)}, \\\\
        B(1) &= B(2) = [1/L_1, 0]^\\top
        \\end{aligned}

    Mode 0 is the switch closed (the source charges the inductor, the capacitor
    discharges into the load), mode 1 the switch open (the inductor feeds the
    output). The model is linear: it has no diode, so :math:`i_L` may go negative in
    mode 1 (it does, down to about -6 A, on the paper's 1.2 ms alternation).

    Parameters
    ----------
    R1, L1, R0, C0 : float
        Inductor resistance (ohm), inductance (H), load resistance (ohm) and
        output capacitance (F); defaults are the paper's 2 ohm, 500 uH, 50 ohm,
        470 uF.
    process_noise : float or array_like, shape (2, 2)
        Continuous-time process-noise intensity :math:`Q` (a scalar :math:`q` means
        :math:`q I`, units :math:`\\mathrm{A}^2/\\mathrm{s}` and :math:`\\mathrm{V}^2/\\mathrm{s}`).
        **Not stated in the paper**; our default ``1.0`` gives a per-sample standard deviation
        of about 0.02 A and 0.02 V at :math:`T = 0.5` ms, a hundred times below the
        measurement noise.
    measurement_variance : float
        :math:`R` in :math:`\\mathrm{V}^2`; the paper's 5 :math:`\\mathrm{V}^2`.

    Returns
    -------
    SwitchedLinearSystem
        Continuous time, 2 modes, 2 states, 1 input, 1 output.
    """
    R1 = positive_scalar(R1, "R1")
    L1 = positive_scalar(L1, "L1")
    R0 = positive_scalar(R0, "R0")
    C0 = positive_scalar(C0, "C0")
    r = positive_scalar(measurement_variance, "measurement_variance")
    closed = [[-R1 / L1, 0.0], [0.0, -1.0 / (R0 * C0)]]
    open_ = [[-R1 / L1, -1.0 / L1], [1.0 / C0, -1.0 / (R0 * C0)]]
    return SwitchedLinearSystem.continuous(
        A=np.array([closed, open_]),
        B=np.array([[1.0 / L1], [0.0]]),
        C=np.array([[0.0, 1.0]]),
        Q=_intensity(process_noise, 2, "process_noise"),
        R=np.array([[r]]),
    )


def boost_switching(
    rng,
    *,
    t_end: float = 10.0,
    first_dwell: float = 1.2e-3,
    t_change: float = 0.02,
    min_dwell: float = 0.9e-3,
    max_dwell: float = 1.2e-3,
    initial_mode: int = 0,
) -> SwitchingSignal:
    """The switching scenario of Shankar et al. §V.A (Fig. 2 and Table I).

    "Starting with switches every 1.2 ms then increasing to every 0.9 ms at
    0.02 seconds" (Fig. 2) and "switch frequencies ranging from 1.2 to 0.9
    ms/switch" over 10 s (§V.A). We read it as: the two modes alternate; switch
    instants are ``first_dwell`` apart while they fall before ``t_change``; from
    the last of them on, the gaps are drawn i.i.d. uniformly in
    ``[min_dwell, max_dwell]``. Every gap therefore lies in
    ``[min(min_dwell, first_dwell), max(max_dwell, first_dwell)]``.

    Parameters
    ----------
    rng : numpy.random.Generator, int or None
        Source of the random gaps; the function can be passed as a per-trial
        signal generator ``(rng) -> SwitchingSignal``.
    t_end : float
        End of the signal, seconds (the paper simulates 10 s).
    first_dwell : float
        Gap of the initial periodic phase (1.2 ms).
    t_change : float
        Time at which the random phase starts (0.02 s).
    min_dwell, max_dwell : float
        Range of the random gaps (0.9 ms and 1.2 ms).
    initial_mode : int
        Mode at :math:`t = 0` (0-based; the paper's Fig. 2 starts in mode 1, i.e. 0).
    """
    first_dwell = positive_scalar(first_dwell, "first_dwell")
    t_change = positive_scalar(t_change, "t_change")
    t_end = positive_scalar(t_end, "t_end")
    rng = as_rng(rng)  # one stream for both phases, also when given a seed
    periodic_part = dwell_time(
        2, min(t_change, t_end), first_dwell, first_dwell, rng=rng, initial_mode=initial_mode
    )
    if t_change >= t_end:
        return periodic_part
    start = float(periodic_part.times[-1]) if periodic_part.n_switches else 0.0
    random_part = dwell_time(
        2,
        t_end,
        min_dwell,
        max_dwell,
        rng=rng,
        t_start=start,
        initial_mode=int(periodic_part.modes[-1]),
    )
    if periodic_part.n_switches == 0:
        return random_part
    return periodic_part.then(random_part, at=start)


@dataclass(frozen=True)
class BoostTable1:
    """The setting of Shankar et al. Table I (§V.A), with what the paper leaves unstated.

    The one recipe of the Table I reproduction, ``switchest demo`` and
    ``examples/shankar_table1.py``: the boost converter (:func:`boost_converter`) driven by
    :math:`v_\\mathrm{in}` = :data:`BOOST_INPUT_VOLTAGE`, sampled every
    :data:`BOOST_SAMPLE_PERIOD`, switching as :func:`boost_switching`. Unstated in the paper and
    chosen here: the process-noise intensity, the prior :math:`\\mathcal{N}(x_0, P_0)` (the true
    initial state is drawn from it and every
    filter starts from it), the IMM's transition matrix and the transient left out of the
    RMSE.

    Attributes
    ----------
    process_noise : float
        Process-noise intensity :math:`q` (:math:`Q = q I`).
    x0 : tuple of float
        Prior mean :math:`[i_L, v_0]`: 0 A, 100 V.
    P0_diagonal : tuple of float
        Prior variances.
    transition : tuple of tuple of float
        The IMM's ``transition[i, j]``: a switch with probability about :math:`T` over the mean
        gap, 0.5 ms / 1.05 ms.
    transient : int
        Samples left out of the RMSE (10 ms).
    min_dwell, max_dwell : float
        Range of the random gaps between switches after 0.02 s (:func:`boost_switching`):
        0.9 ms and 1.2 ms ("switch frequencies ranging from 1.2 to 0.9 ms/switch", §V.A);
        ``min_dwell = max_dwell = 0.9e-3`` is the constant 0.9 ms of the Fig. 2 caption.
    """

    process_noise: float = 1.0
    x0: tuple[float, float] = (0.0, 100.0)
    P0_diagonal: tuple[float, float] = (25.0, 25.0)
    transition: tuple[tuple[float, float], ...] = ((0.52, 0.48), (0.48, 0.52))
    transient: int = 20
    min_dwell: float = 0.9e-3
    max_dwell: float = 1.2e-3

    @property
    def prior(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x0 (2,), P0 (2, 2))``."""
        return np.array(self.x0), np.diag(self.P0_diagonal)

    @property
    def input(self) -> np.ndarray:
        """The constant input :math:`u = [v_\\mathrm{in}]`."""
        return np.array([BOOST_INPUT_VOLTAGE])

    def system(self) -> SwitchedLinearSystem:
        """The boost converter with this process noise."""
        return boost_converter(process_noise=self.process_noise)

    def simulate(self, duration: float, trials: int, rng) -> Trajectory:
        """``trials`` runs over ``duration`` seconds, initial states drawn from the prior."""
        t = periodic(BOOST_SAMPLE_PERIOD, duration)
        def switching(r):
            return boost_switching(r, t_end=duration, min_dwell=self.min_dwell,
                                   max_dwell=self.max_dwell)

        return simulate(self.system(), switching, t, self.prior, u=self.input, trials=trials,
                        rng=rng)


def vehicle_2d(*, measurement_variance: float = 0.05, process_noise=1e-3) -> SwitchedLinearSystem:
    """The maneuvering vehicle of Shankar et al. §V.B.

    State :math:`x = [x_1, dx_1/dt, x_2, dx_2/dt]`, scalar input :math:`u`:

    .. math::

        \\begin{aligned}
        A(1) &= A(2) = A(3) = I_2 \\otimes \\begin{bmatrix} 0 & 1 \\\\ 0 & 0 \\end{bmatrix}, \\\\
        B(1) &= [0, 0, 0, 0]^\\top && \\text{(mode 0: straight)}, \\\\
        B(2) &= [0, -1, 0, 1]^\\top && \\text{(mode 1)}, \\\\
        B(3) &= [0, 1, 0, -1]^\\top && \\text{(mode 2)}, \\\\
        H &= \\begin{bmatrix} 1 & 0 & 0 & 0 \\\\ 0 & 0 & 1 & 0 \\end{bmatrix}, \\qquad
            R = 0.05\\, I_2
        \\end{aligned}

    Its exact ZOH discretization is the paper's eq. (24).

    Parameters
    ----------
    measurement_variance : float
        Variance of each position measurement (the paper's 0.05).
    process_noise : float or array_like, shape (4, 4)
        Continuous-time process-noise intensity :math:`Q` (a scalar :math:`q` means
        :math:`q I_4`). **Not stated in the paper**; the default :math:`10^{-3} I_4` is the
        value of the switchest IMM benchmark (issue 3). Over one sample
        :math:`T = 0.5` s it gives the per-step covariance
        :math:`10^{-3}\\, I_2 \\otimes \\begin{bmatrix} T + T^3/3 & T^2/2 \\\\ T^2/2 & T
        \\end{bmatrix}`.

    Returns
    -------
    SwitchedLinearSystem
        Continuous time, 3 modes, 4 states, 1 input, 2 outputs.
    """
    r = positive_scalar(measurement_variance, "measurement_variance")
    A = np.kron(np.eye(2), [[0.0, 1.0], [0.0, 0.0]])
    B = np.array([[0.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 1.0], [0.0, 1.0, 0.0, -1.0]])[:, :, None]
    H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
    return SwitchedLinearSystem.continuous(
        A=A, B=B, C=H, Q=_intensity(process_noise, 4, "process_noise"), R=r * np.eye(2)
    )


@dataclass(frozen=True, eq=False)
class VehicleManeuver:
    """The maneuver of Shankar et al. §V.B (Figs 3-4).

    Attributes
    ----------
    signal : SwitchingSignal
        Mode 1 (0 in code) until 1.65 s, mode 2 (1) until 2.75 s, mode 3 (2)
        until 3.9 s, then mode 1 (0) again.
    t : ndarray, shape (K,)
        Sample times :math:`0, T, \\dots, t_\\mathrm{end}`.
    u : ndarray, shape (K, 1)
        The constant input :math:`u(t) = 1` held over each sample interval.
    """

    signal: SwitchingSignal
    t: np.ndarray
    u: np.ndarray


def vehicle_maneuver(*, T: float = 0.5, t_end: float = 10.0, u: float = 1.0) -> VehicleManeuver:
    """The single maneuver of Shankar et al. §V.B for :func:`vehicle_2d`.

    "A single trajectory over 10 seconds, with u(t) = 1, starting in mode 1,
    switching to mode 2 at 1.65 seconds, to mode 3 at 2.75 seconds, and back to
    mode 1 at 3.9 seconds", measured every 0.5 s. The switches fall strictly
    inside sample intervals (asynchronous switching). The initial state is not
    stated in the paper and is left to the caller.

    Parameters
    ----------
    T : float
        Sampling period (0.5 s).
    t_end : float
        Horizon (10 s); the samples are :math:`0, T, \\dots, t_\\mathrm{end}`.
    u : float
        The constant input (1).
    """
    t = periodic(T, t_end)
    u = float_array(u, "u", ndim=0)
    if not np.isfinite(u):
        raise ValueError(f"u must be finite, got {float(u)}")
    signal = schedule([1.65, 2.75, 3.9], [0, 1, 2, 0])
    inputs = np.full((t.size, 1), float(u))
    t.setflags(write=False)
    inputs.setflags(write=False)
    return VehicleManeuver(signal=signal, t=t, u=inputs)
