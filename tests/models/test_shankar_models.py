"""Shankar, Yang & Hespanha §V: boost converter and maneuvering vehicle."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from switchest.models.shankar import (
    BOOST_INPUT_VOLTAGE,
    BOOST_SAMPLE_PERIOD,
    boost_converter,
    boost_switching,
    vehicle_2d,
    vehicle_maneuver,
)

# Printed values, Shankar et al. §V (symbolic forms evaluated at the stated parameters).
PAPER = {
    "provenance": "Shankar, Yang, Hespanha, §V.A (boost) and §V.B eq. (24) (vehicle)",
    "boost": {
        "R1": 2.0,
        "L1": 500e-6,
        "R0": 50.0,
        "C0": 470e-6,
        "v_in": 100.0,
        "R": 5.0,
        "T": 0.5e-3,
    },
    # "output voltages ranging between 100 and 120 volts" (§V.A), switches every 1.2 ms (Fig. 2)
    "boost_v0_range": (100.0, 120.0),
    "vehicle": {"T": 0.5, "R": 0.05, "switches": (1.65, 2.75, 3.9), "modes": (0, 1, 2, 0)},
}


def boost_printed(R1, L1, R0, C0):
    """A(1), A(2), B of Shankar et al. §V.A, as printed."""
    A1 = [[-R1 / L1, 0.0], [0.0, -1.0 / (R0 * C0)]]
    A2 = [[-R1 / L1, -1.0 / L1], [1.0 / C0, -1.0 / (R0 * C0)]]
    return np.array([A1, A2]), np.array([[1.0 / L1], [0.0]])


def vehicle_eq24(T):
    """F and G(1..3) of Shankar et al. eq. (24)."""
    F = np.kron(np.eye(2), [[1.0, T], [0.0, 1.0]])
    G = np.array([[0, 0, 0, 0], [-(T**2) / 2, -T, T**2 / 2, T], [T**2 / 2, T, -(T**2) / 2, -T]])
    return F, G


def zoh(A, B, T):
    """Exact ZOH discretization by the augmented exponential expm([[A, B], [0, 0]] T)."""
    n, l = B.shape
    M = np.zeros((n + l, n + l))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M * T)
    return E[:n, :n], E[:n, n:]


# ------------------------------------------------------------------ boost converter


def test_boost_matrices_equal_the_printed_ones():
    p = PAPER["boost"]
    sys = boost_converter()
    A, B = boost_printed(p["R1"], p["L1"], p["R0"], p["C0"])
    np.testing.assert_allclose(sys.A, A, rtol=1e-15)
    np.testing.assert_allclose(sys.B, np.broadcast_to(B, (2, 2, 1)), rtol=1e-15)
    np.testing.assert_array_equal(sys.C, [[[0.0, 1.0]]] * 2)
    np.testing.assert_array_equal(sys.R, [[[p["R"]]]] * 2)
    assert sys.is_continuous and sys.n_modes == 2
    assert BOOST_INPUT_VOLTAGE == p["v_in"] and BOOST_SAMPLE_PERIOD == p["T"]


def test_boost_parameters_are_used():
    sys = boost_converter(R1=1.0, L1=1e-3, R0=10.0, C0=1e-4, measurement_variance=2.0)
    A, B = boost_printed(1.0, 1e-3, 10.0, 1e-4)
    np.testing.assert_allclose(sys.A, A, rtol=1e-15)
    np.testing.assert_allclose(sys.B[1], B, rtol=1e-15)
    assert sys.R[0, 0, 0] == 2.0


def test_boost_equilibria_are_the_circuit_ones():
    p = PAPER["boost"]
    u = p["v_in"]
    sys = boost_converter()
    x = [np.linalg.solve(sys.A[i], -sys.B[i, :, 0] * u) for i in range(2)]
    # switch closed: the inductor shorts the source through R1, the capacitor discharges
    np.testing.assert_allclose(x[0], [u / p["R1"], 0.0], rtol=1e-12, atol=1e-9)
    # switch open: R1 and R0 in series, divider v0 = u R0 / (R0 + R1) = 96.15 V
    total = p["R0"] + p["R1"]
    np.testing.assert_allclose(x[1], [u / total, u * p["R0"] / total], rtol=1e-12)


def test_boost_periodic_orbit_matches_the_stated_voltage_range():
    """Alternating modes every 1.2 ms: v0 stays in the paper's 100-120 V (§V.A).

    The periodic steady state is the fixed point of the exact one-period map.
    """
    sys = boost_converter()
    h, u = 1.2e-3, PAPER["boost"]["v_in"]
    maps = [zoh(sys.A[i], sys.B[i] * u, h) for i in range(2)]
    F = maps[1][0] @ maps[0][0]
    g = maps[1][0] @ maps[0][1][:, 0] + maps[1][1][:, 0]
    x = np.linalg.solve(np.eye(2) - F, g)
    path = []
    for i in range(2):
        for s in np.linspace(0.0, h, 61):
            Fs, gs = zoh(sys.A[i], sys.B[i] * u, s)
            path.append(Fs @ x + gs[:, 0])
        x = maps[i][0] @ x + maps[i][1][:, 0]
    v0 = np.array(path)[:, 1]
    lo, hi = PAPER["boost_v0_range"]
    assert lo <= v0.min() and v0.max() <= hi
    assert v0.max() - v0.min() > 10.0  # the ripple spans most of the stated range


def test_boost_process_noise_default_and_matrix():
    assert np.array_equal(boost_converter().Q, np.broadcast_to(np.eye(2), (2, 2, 2)))
    Q = [[2.0, 0.5], [0.5, 1.0]]
    np.testing.assert_array_equal(boost_converter(process_noise=Q).Q[1], Q)
    assert not np.any(boost_converter(process_noise=0.0).Q)


@pytest.mark.parametrize(
    "kwargs, exc, match",
    [
        ({"R1": -2.0}, ValueError, "R1 must be a finite positive number, got -2.0"),
        ({"C0": 0.0}, ValueError, "C0 must be a finite positive number, got 0.0"),
        ({"L1": "big"}, TypeError, "L1 must be a real scalar"),
        (
            {"measurement_variance": 0.0},
            ValueError,
            "measurement_variance must be a finite positive",
        ),
        (
            {"process_noise": -1.0},
            ValueError,
            "process_noise must be a finite non-negative number, got -1.0",
        ),
        (
            {"process_noise": np.eye(3)},
            ValueError,
            r"process_noise must be a scalar or an \(2, 2\) matrix, got shape \(3, 3\)",
        ),
        (
            {"process_noise": [[1.0, 2.0], [0.0, 1.0]]},
            ValueError,
            "process_noise must be symmetric positive semidefinite",
        ),
        (
            {"process_noise": [[1.0, 0.0], [0.0, -1.0]]},
            ValueError,
            "process_noise must be symmetric positive semidefinite, got eigenvalue -1",
        ),
        (
            {"process_noise": [[np.nan, 0.0], [0.0, 1.0]]},
            ValueError,
            "process_noise must be finite",
        ),
    ],
)
def test_boost_rejects_bad_parameters(kwargs, exc, match):
    with pytest.raises(exc, match=match):
        boost_converter(**kwargs)


# ------------------------------------------------------------------ boost switching


def test_boost_switching_follows_the_scenario():
    sig = boost_switching(np.random.default_rng(3))
    gaps = np.diff(np.concatenate([[0.0], sig.times]))
    early = sig.times < 0.02
    np.testing.assert_allclose(gaps[early], 1.2e-3, rtol=1e-9)  # every 1.2 ms ...
    late = gaps[~early]
    assert np.all((late >= 0.9e-3 - 1e-15) & (late <= 1.2e-3 + 1e-15))  # ... then in [0.9, 1.2] ms
    assert np.std(late) > 0.05e-3  # random, not fixed
    assert sig.modes[0] == 0 and np.all(np.diff(sig.modes) != 0) and set(sig.modes) == {0, 1}
    assert sig.times[-1] < 10.0 and 10.0 - sig.times[-1] <= 1.2e-3
    # about 10 s / 1.05 ms switches
    assert abs(sig.n_switches - 10.0 / 1.05e-3) < 5 * np.sqrt(sig.n_switches)


def test_boost_switching_is_reproducible_from_rng():
    a = boost_switching(np.random.default_rng(7), t_end=0.1)
    b = boost_switching(7, t_end=0.1)
    c = boost_switching(8, t_end=0.1)
    np.testing.assert_array_equal(a.times, b.times)
    np.testing.assert_array_equal(a.modes, b.modes)
    assert not np.array_equal(a.times, c.times)


def test_boost_switching_short_horizon_is_periodic_only():
    sig = boost_switching(0, t_end=0.01)
    np.testing.assert_allclose(sig.times, 1.2e-3 * np.arange(1, 9), rtol=1e-12)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"first_dwell": 0.0}, "first_dwell must be a finite positive number"),
        ({"t_change": -1.0}, "t_change must be a finite positive number"),
        ({"max_dwell": 0.5e-3}, "max_dwell must be >= min_dwell"),
    ],
)
def test_boost_switching_rejects_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        boost_switching(0, t_end=0.05, **kwargs)


# ------------------------------------------------------------------ vehicle


def test_vehicle_matrices_equal_the_printed_ones():
    sys = vehicle_2d()
    A = np.kron(np.eye(2), [[0.0, 1.0], [0.0, 0.0]])
    np.testing.assert_array_equal(sys.A, np.broadcast_to(A, (3, 4, 4)))
    np.testing.assert_array_equal(sys.B[:, :, 0], [[0, 0, 0, 0], [0, -1, 0, 1], [0, 1, 0, -1]])
    np.testing.assert_array_equal(sys.C[0], [[1, 0, 0, 0], [0, 0, 1, 0]])
    np.testing.assert_allclose(sys.R, np.broadcast_to(PAPER["vehicle"]["R"] * np.eye(2), (3, 2, 2)))
    np.testing.assert_allclose(sys.Q, np.broadcast_to(1e-3 * np.eye(4), (3, 4, 4)))


def test_vehicle_zoh_equals_eq24_at_the_paper_period():
    sys = vehicle_2d()
    F24, G24 = vehicle_eq24(PAPER["vehicle"]["T"])
    for i in range(3):
        F, G = zoh(sys.A[i], sys.B[i], PAPER["vehicle"]["T"])
        np.testing.assert_allclose(F, F24, rtol=0, atol=1e-14)
        np.testing.assert_allclose(G[:, 0], G24[i], rtol=0, atol=1e-14)


@settings(max_examples=25, deadline=None)
@given(T=st.floats(1e-3, 5.0))
def test_vehicle_zoh_equals_eq24_for_any_period(T):
    sys = vehicle_2d()
    F24, G24 = vehicle_eq24(T)
    for i in range(3):
        F, G = zoh(sys.A[i], sys.B[i], T)
        np.testing.assert_allclose(F, F24, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(G[:, 0], G24[i], rtol=1e-12, atol=1e-14)


def test_project_discretization_reproduces_eq24():
    """switchest.discretize on the vehicle gives eq. (24) and the documented per-step Q."""
    from switchest.discretize import interval

    T = PAPER["vehicle"]["T"]
    tr = interval(vehicle_2d(), T, [[0], [1], [2]])
    F24, G24 = vehicle_eq24(T)
    np.testing.assert_allclose(tr.F, np.broadcast_to(F24, (3, 4, 4)), atol=1e-14)
    np.testing.assert_allclose(tr.G[:, :, 0], G24, atol=1e-14)
    expected = 1e-3 * np.kron(np.eye(2), [[T + T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    np.testing.assert_allclose(tr.Qd, np.broadcast_to(expected, (3, 4, 4)), rtol=1e-10)


def test_vehicle_process_noise_per_step_covariance():
    """Van Loan: the per-step covariance of the default intensity is the documented one."""
    sys = vehicle_2d()
    T = PAPER["vehicle"]["T"]
    n = 4
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -sys.A[0], sys.Q[0], sys.A[0].T
    E = expm(M * T)
    Qd = E[n:, n:].T @ E[:n, n:]
    expected = 1e-3 * np.kron(np.eye(2), [[T + T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    np.testing.assert_allclose(Qd, expected, rtol=1e-12)


def test_vehicle_maneuver_schedule():
    m = vehicle_maneuver()
    v = PAPER["vehicle"]
    np.testing.assert_array_equal(m.signal.times, v["switches"])
    np.testing.assert_array_equal(m.signal.modes, v["modes"])
    np.testing.assert_array_equal(
        m.signal.at([0.0, 1.6, 1.65, 2.7, 2.75, 3.89, 3.9, 10.0]), [0, 0, 1, 1, 2, 2, 0, 0]
    )
    np.testing.assert_allclose(m.t, 0.5 * np.arange(21))
    assert m.u.shape == (21, 1) and np.all(m.u == 1.0)
    # every switch falls strictly inside a sampling interval (asynchronous)
    assert np.all(np.abs(np.asarray(v["switches"]) / 0.5 % 1.0) > 0)
    assert not m.t.flags.writeable and not m.u.flags.writeable


def test_vehicle_rejects_bad_parameters():
    with pytest.raises(
        ValueError, match="measurement_variance must be a finite positive number, got -0.05"
    ):
        vehicle_2d(measurement_variance=-0.05)
    with pytest.raises(ValueError, match=r"process_noise must be a scalar or an \(4, 4\) matrix"):
        vehicle_2d(process_noise=np.eye(2))
    with pytest.raises(ValueError, match="T must be a finite positive number, got 0"):
        vehicle_maneuver(T=0)
    with pytest.raises(ValueError, match="u must be finite, got inf"):
        vehicle_maneuver(u=np.inf)
