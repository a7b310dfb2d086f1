"""The systems of Wang, Yin, Lin, Polis & Chen (seed 003).

* the pair of decoupled scalar systems of Examples 1-4 (each mode observes one
  of the two states);
* the IEEE 5-bus power system of §6 (Example 5) with four sensor/packet-loss
  modes.

Wang et al. use a continuous output, eq. (1):

.. math::

    dx = A(\\alpha)\\, x\\, dt, \\qquad dy = C(\\alpha)\\, x\\, dt + \\Xi(\\alpha)\\, dw

with :math:`w` a standard Brownian motion and modes :math:`\\alpha_k` i.i.d. at the
instants :math:`kT` (their Assumption 1). A :class:`SwitchedLinearSystem` stores the
output-noise intensity :math:`\\Xi \\Xi^\\top` in ``R``: for these systems :math:`R` is the
intensity of the Brownian increment :math:`dy - C x\\, dt` (covariance :math:`R\\, dt` over
:math:`dt`), not the covariance of a sampled measurement. There is no process noise
(:math:`Q = 0`) and no input.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from .._checks import check_finite, float_array, positive_scalar
from ..system import SwitchedLinearSystem

__all__ = [
    "IEEE_5BUS_A",
    "IEEE_5BUS_INITIAL_ERROR",
    "IEEE_5BUS_POLES",
    "IEEE_5BUS_POLES_AGGRESSIVE",
    "IEEE_5BUS_SAMPLE_PERIOD",
    "WANG_EXAMPLES",
    "ScalarPairExample",
    "ieee_5bus",
    "ieee_5bus_from_tables",
    "ieee_5bus_mode_probabilities",
    "wang_scalar_pair",
    "wang_scalar_pair_probabilities",
]


def _real(value, name: str) -> float:
    arr = float_array(value, name, ndim=0)
    check_finite(arr, name)
    return float(arr)


# ---------------------------------------------------------------- Examples 1-4


def wang_scalar_pair(
    a1: float = 2.0, a2: float = 4.0, zeta: float = 0.01, *, c1: float = 1.0, c2: float = 1.0
) -> SwitchedLinearSystem:
    """The two decoupled scalar systems of Wang et al. Example 1 (also Examples 2-4).

    .. math::

        \\begin{aligned}
        dx_1 &= a_1 x_1\\, dt, \\qquad dx_2 = a_2 x_2\\, dt, \\\\
        dy &= (\\mathbf{1}\\{\\alpha = 1\\}\\, c_1 x_1
               + \\mathbf{1}\\{\\alpha = 2\\}\\, c_2 x_2)\\, dt + \\sqrt{\\zeta}\\, dw
        \\end{aligned}

    so :math:`A = \\operatorname{diag}(a_1, a_2)` in both modes, :math:`C(1) = [c_1, 0]` (mode 0
    in code), :math:`C(2) = [0, c_2]` (mode 1), and the output-noise intensity
    :math:`R = \\Xi \\Xi^\\top = \\zeta` in both modes. Neither mode is observable on its own
    (Example 1: :math:`W(1) = \\begin{bmatrix} 1 & 0 \\\\ a_1 & 0 \\end{bmatrix}`,
    :math:`W(2) = \\begin{bmatrix} 0 & 1 \\\\ 0 & a_2 \\end{bmatrix}`).

    Parameters
    ----------
    a1, a2 : float
        The two open-loop rates (Examples 1, 2, 4: 2 and 4; Example 3: 10 and 10).
    zeta : float
        Output-noise intensity. Example 1 does not state it; the default 0.01 is
        Example 4's value for "the system in Example 1" (Example 3 uses 1).
    c1, c2 : float
        Output gains; 1 in every example (Example 3 states :math:`c_1 = c_2 = 1`).

    Notes
    -----
    The mode probabilities :math:`\\Pr(\\alpha_k = 1) = p` are not part of the system:
    see :func:`wang_scalar_pair_probabilities` and :data:`WANG_EXAMPLES`.
    """
    a1, a2 = _real(a1, "a1"), _real(a2, "a2")
    c1, c2 = _real(c1, "c1"), _real(c2, "c2")
    zeta = positive_scalar(zeta, "zeta")
    return SwitchedLinearSystem.continuous(
        A=np.diag([a1, a2]),
        C=np.array([[[c1, 0.0]], [[0.0, c2]]]),
        R=np.array([[zeta]]),
    )


def wang_scalar_pair_probabilities(p: float = 0.2) -> np.ndarray:
    """Mode probabilities :math:`[p, 1 - p]` with :math:`p = \\Pr(\\alpha_k = 1)` (Wang et al.
    Example 1).

    ``p`` must lie in :math:`(0, 1)` (Assumption 1(b): every :math:`p_i > 0`).
    """
    p = positive_scalar(p, "p")
    if p >= 1.0:
        raise ValueError(f"p must lie in (0, 1) (Wang et al. Assumption 1(b)), got {p!r}")
    return np.array([p, 1.0 - p])


@dataclass(frozen=True)
class ScalarPairExample:
    """The numbers of one of Wang et al.'s Examples 1-4 for :func:`wang_scalar_pair`.

    Attributes
    ----------
    a1, a2, zeta : float
        System parameters (see :func:`wang_scalar_pair`).
    p : float
        :math:`\\Pr(\\alpha_k = 1)`.
    T : float or None
        Switching interval; ``None`` where the example fixes no value.
    """

    a1: float
    a2: float
    zeta: float
    p: float
    T: float | None

    def system(self) -> SwitchedLinearSystem:
        """The example's system."""
        return wang_scalar_pair(self.a1, self.a2, self.zeta)

    def probabilities(self) -> np.ndarray:
        """The example's mode probabilities :math:`[p, 1 - p]`."""
        return wang_scalar_pair_probabilities(self.p)


WANG_EXAMPLES: dict[str, ScalarPairExample] = {
    # Example 1 states a1, a2, T, p; zeta only in Example 4 ("the system in Example 1").
    "example1": ScalarPairExample(a1=2.0, a2=4.0, zeta=0.01, p=0.2, T=0.03),
    # Example 2, Fig. 3: the same system with T = 0.25 > T_max = 0.0558.
    "example2-large-T": ScalarPairExample(a1=2.0, a2=4.0, zeta=0.01, p=0.2, T=0.25),
    # Example 3: a1 = a2 = 10, p = 0.5, zeta = 1; T only bounded, T < ln(2)/20.
    "example3": ScalarPairExample(a1=10.0, a2=10.0, zeta=1.0, p=0.5, T=None),
    "example4": ScalarPairExample(a1=2.0, a2=4.0, zeta=0.01, p=0.2, T=0.03),
}
"""Wang et al. Examples 1-4 (§4.1, §4.3, §5.2)."""


# ---------------------------------------------------------------- IEEE 5-bus, §6

IEEE_5BUS_A = np.array(
    [
        [0.0, 1.0, 0.0, 0.0],
        [7.7926, -0.1053, -7.7926, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [-20.3866, 0.0, 20.3866, -0.1778],
    ]
)
IEEE_5BUS_A.setflags(write=False)
"""The linearized 5-bus ``A`` as printed in Wang et al. §6, state
:math:`[\\delta_1, \\omega_1, \\delta_2, \\omega_2]`.

Its eigenvalues are the printed {-5.3880, 5.2302, 0, -0.1253} to the last digit.
The paper computed with more digits than it printed: its gain for the :math:`\\delta_1`-only
mode, :math:`[20.7170, 187.0468, -123.7698, -568.3264]`, is reproduced to the printed
digits only with the exact damping :math:`b_1/M_1 = 0.105263`, :math:`b_2/M_2 = 0.177778` and
couplings ``7.79261``, ``20.38663`` (least-squares fit, within the rounding of the
printed entries); this rounded ``A`` gives it to about 4e-3
(tests/analysis/test_subsystem_observers.py).
"""

IEEE_5BUS_SAMPLE_PERIOD = 0.6997
"""The switching interval :math:`T` Wang et al. §6 select (below their
:math:`T_\\mathrm{max} = 0.7365`)."""

IEEE_5BUS_INITIAL_ERROR = (2.0, 0.0, 1.0, 0.0)
"""The initial estimation error :math:`e(0)` of Wang et al. §6 (norm 2.2361)."""

IEEE_5BUS_POLES = (-6.0, -4.5, -5.0, -5.5)
"""Observer closed-loop poles of the first design, Wang et al. §6."""

IEEE_5BUS_POLES_AGGRESSIVE = (-12.0, -9.0, -10.0, -11.0)
"""Observer closed-loop poles of the aggressive design ("Design Tradeoff"), Wang et al. §6."""


def ieee_5bus(
    *,
    std_normal: float = 0.01,
    std_delta1_only: float = 0.011,
    std_delta2_only: float = 0.012,
    std_lost: float = 0.01,
) -> SwitchedLinearSystem:
    """The IEEE 5-bus system of Wang et al. §6 (Example 5) with its four sensor modes.

    State :math:`x = [\\delta_1, \\omega_1, \\delta_2, \\omega_2]` (generator angle and speed
    deviations), ``A`` = the printed linearization :data:`IEEE_5BUS_A` in every
    mode (see :func:`ieee_5bus_from_tables` for why the printed one is used).
    Sensors measure :math:`\\delta_1` (sensor 1) and :math:`\\delta_2` (sensor 2), the first
    row of Table 3; their packets may be lost, which gives the modes:

    .. math::

        \\begin{aligned}
        C(1) &= \\begin{bmatrix} 1 & 0 & 0 & 0 \\\\ 0 & 0 & 1 & 0 \\end{bmatrix}
            && \\text{both delivered (mode 0)}, \\\\
        C(2) &= \\begin{bmatrix} 1 & 0 & 0 & 0 \\\\ 0 & 0 & 0 & 0 \\end{bmatrix}
            && \\text{sensor 2 lost (mode 1)}, \\\\
        C(3) &= \\begin{bmatrix} 0 & 0 & 0 & 0 \\\\ 0 & 0 & 1 & 0 \\end{bmatrix}
            && \\text{sensor 1 lost (mode 2)}, \\\\
        C(4) &= 0 && \\text{both lost (mode 3)}.
        \\end{aligned}

    The paper writes :math:`C(2) = [1, 0, 0, 0]`, :math:`C(3) = [0, 0, 1, 0]` and
    :math:`C(4) = [0, 0, 0, 0]` as single rows; all modes of a switched system share
    one output size, so a lost channel is kept as a zero row of ``C`` (its output
    is pure noise and carries no information about :math:`x`). Probabilities: see
    :func:`ieee_5bus_mode_probabilities`.

    ``R`` holds the output-noise intensity :math:`\\Xi \\Xi^\\top` (the output is
    :math:`dy = C x\\, dt + \\Xi\\, dw`, Wang et al. eq. (1)). The paper gives the standard
    deviations :math:`\\Xi(1) = 0.01 [1, 1]^\\top`, :math:`\\Xi(2) = 0.011`,
    :math:`\\Xi(3) = 0.012`. Read literally, :math:`\\Xi(1)` is one Brownian motion driving
    both channels, whose intensity
    :math:`10^{-4} \\begin{bmatrix} 1 & 1 \\\\ 1 & 1 \\end{bmatrix}` is singular (and a
    singular :math:`R` would let :math:`\\delta_1 - \\delta_2` be read without noise); we read
    it as a standard deviation of 0.01 on each of two independent channels,
    :math:`R(1) = 10^{-4} I_2`.
    :math:`\\Xi(4)` and the intensity of a lost channel are not stated; ``std_lost``
    sets it (it does not affect any estimate, since the channel's row of ``C``
    is zero).

    Parameters
    ----------
    std_normal : float
        Per-channel standard deviation in mode 0 (the paper's 0.01).
    std_delta1_only : float
        Standard deviation of the :math:`\\delta_1` channel in mode 1 (0.011).
    std_delta2_only : float
        Standard deviation of the :math:`\\delta_2` channel in mode 2 (0.012).
    std_lost : float
        Standard deviation of a lost channel (our choice, 0.01).

    Returns
    -------
    SwitchedLinearSystem
        Continuous time, 4 modes, 4 states, no input, 2 output channels, no
        process noise.
    """
    s0 = positive_scalar(std_normal, "std_normal")
    s1 = positive_scalar(std_delta1_only, "std_delta1_only")
    s2 = positive_scalar(std_delta2_only, "std_delta2_only")
    lost = positive_scalar(std_lost, "std_lost")
    d1 = np.array([1.0, 0.0, 0.0, 0.0])
    d2 = np.array([0.0, 0.0, 1.0, 0.0])
    zero = np.zeros(4)
    C = np.array([[d1, d2], [d1, zero], [zero, d2], [zero, zero]])
    std = np.array([[s0, s0], [s1, lost], [lost, s2], [lost, lost]])
    R = np.einsum("li,ij->lij", std**2, np.eye(2))
    return SwitchedLinearSystem.continuous(A=IEEE_5BUS_A, C=C, R=R)


def ieee_5bus_mode_probabilities(delivery1: float = 0.99, delivery2: float = 0.995) -> np.ndarray:
    """Mode probabilities of the 5-bus sensor modes (Wang et al. §6).

    With packet delivery ratios :math:`\\xi_1` (sensor 1, :math:`\\delta_1`) and :math:`\\xi_2`
    (sensor 2, :math:`\\delta_2`), independent:

    .. math::

        p_1 = \\xi_1 \\xi_2, \\quad p_2 = \\xi_1 (1 - \\xi_2), \\quad p_3 = (1 - \\xi_1) \\xi_2,
        \\quad p_4 = (1 - \\xi_1)(1 - \\xi_2)

    returned 0-based as :math:`[p_1, p_2, p_3, p_4]`. For the paper's 0.99 and 0.995
    this is :math:`[0.98505, 0.00495, 0.00995, 0.00005]`; the paper prints the
    rounded :math:`0.985, 0.005, 0.01, 5 \\cdot 10^{-5}`, which sum to 1.00005, not 1.
    """
    xi1 = positive_scalar(delivery1, "delivery1")
    xi2 = positive_scalar(delivery2, "delivery2")
    for name, xi in (("delivery1", xi1), ("delivery2", xi2)):
        if xi >= 1.0:
            raise ValueError(
                f"{name} must lie in (0, 1) so that every mode has p_i > 0 "
                f"(Wang et al. Assumption 1(b)), got {xi!r}"
            )
    return np.array([xi1 * xi2, xi1 * (1 - xi2), (1 - xi1) * xi2, (1 - xi1) * (1 - xi2)])


# Table 1: line (i, j) -> (R, X, |Z|, theta), p.u. and rad, as printed (rounded).
_LINES = {
    (1, 2): (0.02, 0.06, 0.06, 1.25),
    (1, 3): (0.08, 0.24, 0.25, 1.25),
    (2, 3): (0.06, 0.25, 0.26, 1.33),
    (2, 4): (0.06, 0.18, 0.19, 1.25),
    (2, 5): (0.04, 0.12, 0.13, 1.25),
    (3, 4): (0.01, 0.03, 0.03, 1.25),
    (4, 5): (0.08, 0.24, 0.25, 1.25),
}
# Table 2: bus voltage magnitudes (p.u.) and angles (the printed numbers), generation P, Q and
# loads P_L, Q_L (MW, MVAr; base 100 MVA).
_BUS_V = np.array([1.06, 1.0474, 1.0242, 1.0236, 1.0179])
_BUS_ANGLE = np.array([0.0, -2.8063, -4.997, -5.3291, -6.1503])
_BUS_GEN = np.array([129.0 - 7.42j, 40.0 + 30.0j, 0.0, 0.0, 0.0])
_BUS_LOAD = np.array([0.0, 20.0 + 10.0j, 45.0 + 15.0j, 40.0 + 5.0j, 60.0 + 10.0j])
_BASE_MVA = 100.0
_GEN, _LOADS = [0, 1], [2, 3, 4]


def ieee_5bus_from_tables(
    *,
    angle_unit: Literal["deg", "rad"] = "deg",
    M: tuple[float, float] = (1.9, 0.9),
    b: tuple[float, float] = (0.2, 0.16),
    impedance: Literal["X", "Z"] = "X",
    line_angle: Literal["printed", "exact", "lossless"] = "printed",
    flow: Literal["printed", "reversed"] = "printed",
    loads: Literal["power", "impedance"] = "power",
    generator_voltage: Literal["table", "flat"] = "table",
    internal_reactance: float | None = None,
    bus2_load: bool = True,
) -> np.ndarray:
    """The 5-bus ``A`` rebuilt from Wang et al.'s Tables 1-2 and equation (26).

    Generators at buses 1-2,
    :math:`M_i\\, d\\omega_i/dt + b_i \\omega_i = P_\\mathrm{in}^i - P_L^i + \\sum_j P_{ji}^i`
    (§6), line flows by eq. (26) exactly as printed:

    .. math::

        P_{ij}^j = \\frac{V_j^2}{|Z_{ij}|} \\cos(\\theta_{ij})
            - \\frac{V_i V_j}{X_{ij}} \\cos(\\theta_{ij} + \\delta_i - \\delta_j)

    with :math:`|Z|, \\theta, X` from Table 1 and :math:`V, \\delta` from Table 2; the load
    buses 3-5 hold their power (:math:`0 = H_1 x_\\mathrm{nd} + H_2 x_d`), which eliminates
    their angles: :math:`x_\\mathrm{nd} = H x_d` with :math:`H = -H_1^{-1} H_2` (the paper
    misprints it :math:`H_1 = -H_1^{-1} H_2`), :math:`A = A_1 + A_2 H`.

    Deviation from the printed :data:`IEEE_5BUS_A` (measured in the tests):

    * the damping entries :math:`-b_1/M_1 = -0.1053` and :math:`-b_2/M_2 = -0.1778` agree
      to the printed digits, and every row sums to zero as in the print (a
      common angle shift is an equilibrium: the eigenvalue 0);
    * the couplings do not: with Table 2's angles in degrees (the standard
      Stagg 5-bus load flow, whose values these are) we get ``A[1, 0] = -10.64``
      and ``A[3, 0] = +23.21`` against the printed ``+7.7926`` and ``-20.3866`` —
      opposite signs, a stable (oscillatory) system instead of the printed
      unstable one. Read in radians, as Table 2's header says, the signs agree
      with the print but not the values: ``+8.49`` and ``-16.57``.

    The keywords other than ``angle_unit``, ``M`` and ``b`` are other readings of
    the section, each defaulting to the text as printed. No reading we tried
    reproduces the printed couplings (the ``wang-ieee5bus`` report lists them
    with their couplings); :func:`ieee_5bus` uses the printed ``A``.

    Parameters
    ----------
    angle_unit : {"deg", "rad"}
        Unit of Table 2's angles.
    M, b : tuple of float
        Inertias and damping of generators 1 and 2 (§6: 1.9, 0.9 and 0.2, 0.16;
        the paper misprints :math:`b_2` as a second :math:`b_1`).
    impedance : {"X", "Z"}
        Denominator of eq. (26)'s angle term: :math:`X_{ij}` as printed, or :math:`|Z_{ij}|`
        (Table 1's), as in the textbook line flow. Constant-power loads only.
    line_angle : {"printed", "exact", "lossless"}
        :math:`\\theta_{ij}`: Table 1's rounded angle, :math:`\\arctan(X/R)` from Table 1's
        :math:`R` and :math:`X`, or :math:`\\pi/2` (lossless lines, :math:`R = 0`). With
        impedance loads the line impedance is :math:`|Z| e^{j \\theta}` (printed),
        :math:`R + jX` (exact) or :math:`jX` (lossless).
    flow : {"printed", "reversed"}
        The sign of the angle difference in eq. (26): :math:`\\delta_i - \\delta_j` as
        printed, or :math:`\\delta_j - \\delta_i` (the flow that leaves bus :math:`j`).
        Constant-power loads only.
    loads : {"power", "impedance"}
        Load buses holding their power (the text), or loads as constant
        admittances :math:`(P_L - j Q_L) / V^2` from Table 2, the load buses
        eliminated by Kron reduction of the network's admittance matrix and the
        generators' electrical power :math:`\\operatorname{Re}(E_i \\bar{I}_i)` linearized.
    generator_voltage : {"table", "flat"}
        Generator voltage magnitudes from Table 2, or 1 p.u.
    internal_reactance : float, optional
        A reactance (p.u.) between each generator's internal voltage and its
        bus, the internal voltage set by Table 2's generation :math:`P + jQ`; not in
        the paper (impedance loads only).
    bus2_load : bool
        Whether bus 2's own load (Table 2: 20 MW, 10 MVAr) is a shunt admittance
        (impedance loads only; with constant-power loads it is a constant and
        drops out of the linearization).

    Returns
    -------
    ndarray, shape (4, 4)
        :math:`A` for the state :math:`[\\delta_1, \\omega_1, \\delta_2, \\omega_2]`.
    """
    choices = {"angle_unit": (angle_unit, ("deg", "rad")), "impedance": (impedance, ("X", "Z")),
               "line_angle": (line_angle, ("printed", "exact", "lossless")),
               "flow": (flow, ("printed", "reversed")), "loads": (loads, ("power", "impedance")),
               "generator_voltage": (generator_voltage, ("table", "flat"))}
    for name, (value, allowed) in choices.items():
        if value not in allowed:
            raise ValueError(f"{name} must be " + " or ".join(repr(a) for a in allowed)
                             + f", got {value!r}")
    M = float_array(M, "M", ndim=1)
    b = float_array(b, "b", ndim=1)
    for name, arr in (("M", M), ("b", b)):
        if arr.shape != (2,) or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
            raise ValueError(f"{name} must hold two finite positive numbers, got {arr.tolist()}")
    if loads == "power" and (internal_reactance is not None or not bus2_load):
        raise ValueError("internal_reactance and bus2_load=False need loads='impedance'")
    if loads == "impedance" and (impedance != "X" or flow != "printed"):
        raise ValueError("impedance and flow are readings of eq. (26): they need loads='power'")
    if internal_reactance is not None:
        internal_reactance = positive_scalar(internal_reactance, "internal_reactance")
    delta = np.deg2rad(_BUS_ANGLE) if angle_unit == "deg" else _BUS_ANGLE
    V = _BUS_V.copy()
    if generator_voltage == "flat":
        V[_GEN] = 1.0
    if loads == "power":
        coupling = _coupling_constant_power(delta, V, impedance, line_angle, flow)
    else:
        coupling = _coupling_constant_impedance(delta, V, line_angle, internal_reactance,
                                                bus2_load)
    A = np.zeros((4, 4))
    A[0, 1] = A[2, 3] = 1.0
    A[1, [0, 2]] = coupling[0] / M[0]
    A[3, [0, 2]] = coupling[1] / M[1]
    A[1, 1] = -b[0] / M[0]
    A[3, 3] = -b[1] / M[1]
    return A


def _line_angle(R: float, X: float, theta: float, reading: str) -> float:
    return {"printed": theta, "exact": float(np.arctan2(X, R)), "lossless": np.pi / 2}[reading]


def _coupling_constant_power(delta, V, impedance: str, line_angle: str, flow: str) -> np.ndarray:
    """:math:`\\partial (\\text{power into generator } i) / \\partial \\delta_k` ``(2, 2)`` by
    equation (26), load buses at constant power."""
    sign = 1.0 if flow == "printed" else -1.0
    # J[j, k] = d(sum_i P_ij^j)/d(delta_k): sensitivity of the power flowing into bus j.
    J = np.zeros((5, 5))
    for (p, q), (R, X, Z, theta) in _LINES.items():
        theta = _line_angle(R, X, theta, line_angle)
        denominator = X if impedance == "X" else Z
        for i, j in ((p - 1, q - 1), (q - 1, p - 1)):
            # d/d(delta_i) of eq. (26) = V_i V_j / X sin(theta + delta_i - delta_j) = -d/d(delta_j)
            s = sign * V[i] * V[j] / denominator * np.sin(theta + sign * (delta[i] - delta[j]))
            J[j, i] += s
            J[j, j] -= s
    H = -np.linalg.solve(J[np.ix_(_LOADS, _LOADS)], J[np.ix_(_LOADS, _GEN)])
    return J[np.ix_(_GEN, _GEN)] + J[np.ix_(_GEN, _LOADS)] @ H


def _coupling_constant_impedance(delta, V, line_angle: str, internal_reactance: float | None,
                                 bus2_load: bool) -> np.ndarray:
    """:math:`-\\partial (\\text{electrical power of generator } i) / \\partial \\delta_k`
    ``(2, 2)`` of the Kron-reduced network with the loads as constant admittances."""
    Y = np.zeros((5, 5), dtype=complex)
    for (p, q), (R, X, Z, theta) in _LINES.items():
        z = {"printed": Z * np.exp(1j * theta), "exact": complex(R, X),
             "lossless": complex(0.0, X)}[line_angle]
        i, j = p - 1, q - 1
        Y[[i, j], [i, j]] += 1.0 / z
        Y[i, j] -= 1.0 / z
        Y[j, i] -= 1.0 / z
    load = np.conj(_BUS_LOAD / _BASE_MVA) / V**2  # (P_L - j Q_L) / V^2
    if not bus2_load:
        load[1] = 0.0
    Y += np.diag(load)
    E = V[_GEN] * np.exp(1j * delta[_GEN])
    if internal_reactance is not None:  # internal buses 0, 1 behind j x; network buses 2..6
        current = np.conj(_BUS_GEN[_GEN] / _BASE_MVA / E)
        E = E + 1j * internal_reactance * current
        y = 1.0 / (1j * internal_reactance)
        big = np.zeros((7, 7), dtype=complex)
        big[2:, 2:] = Y
        for g in _GEN:
            big[[g, g + 2], [g, g + 2]] += y
            big[g, g + 2] -= y
            big[g + 2, g] -= y
        Y, keep, drop = big, [0, 1], [2, 3, 4, 5, 6]
    else:
        keep, drop = _GEN, _LOADS
    reduced = Y[np.ix_(keep, keep)] - Y[np.ix_(keep, drop)] @ np.linalg.solve(
        Y[np.ix_(drop, drop)], Y[np.ix_(drop, keep)])
    # P_i = sum_k |E_i||E_k||Y_ik| cos(angle_i - angle_k - phase(Y_ik)); M w' = P_in - P_i
    magnitude, angle = np.abs(E), np.angle(E)
    coupling = np.zeros((2, 2))
    for i, k in ((0, 1), (1, 0)):
        dP = magnitude[i] * magnitude[k] * np.abs(reduced[i, k]) * np.sin(
            angle[i] - angle[k] - np.angle(reduced[i, k]))  # dP_i / d(angle_k)
        coupling[i, k], coupling[i, i] = -dP, dP
    return coupling
