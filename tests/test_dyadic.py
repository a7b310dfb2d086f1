"""Transitions composed from the dyadic table equal the Van Loan exponentials of discretize."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from switchest.discretize import interval
from switchest.dyadic import dyadic_table, interval_transitions
from switchest.models import BOOST_SAMPLE_PERIOD, boost_converter, vehicle_2d
from switchest.system import SwitchedLinearSystem

# Both sides are exact to rounding: discretize takes one block exponential per segment, the
# table a few dozen products of matrices within a factor e of the identity's norm. 1e-12 of
# each array's largest entry leaves three orders of magnitude for the sums' rounding.
RTOL = 1e-12


def assert_transitions_close(actual, expected):
    for a, b in zip((actual.F, actual.G, actual.Qd), (expected.F, expected.G, expected.Qd)):
        scale = max(np.abs(b).max(initial=0.0), 1e-300)  # initial: no interval, or no input
        np.testing.assert_allclose(a, b, rtol=0.0, atol=RTOL * scale)


def stiff_system():
    A = [[[-2000.0, 10.0], [0.0, -0.5]], [[0.0, 1.0], [-40.0, -0.1]]]  # ||A|| T far above 1
    return SwitchedLinearSystem.continuous(A, [[[1.0], [0.0]], [[0.0], [1.0]]],
                                           [[[1.0, 0.0]], [[1.0, 0.0]]], Q=np.diag([1.0, 1e-6]),
                                           R=[[1.0]])


@pytest.mark.parametrize("make, T", [(boost_converter, BOOST_SAMPLE_PERIOD), (vehicle_2d, 0.5),
                                     (stiff_system, 0.3)])
def test_random_switches_match_discretize(make, T):
    system = make()
    rng = np.random.default_rng(1)
    M = 200
    modes = rng.integers(0, system.n_modes, (M, 3))
    offsets = np.sort(rng.uniform(0.0, T, (M, 2)), axis=1)
    offsets[:4] = [[0.0, 0.0], [T, T], [0.0, T], [0.5 * T, 0.5 * T]]  # segments of length 0, T
    table = dyadic_table(system, T)
    assert table.depth >= 1
    assert_transitions_close(interval_transitions(table, modes, offsets),
                             interval(system, T, modes, offsets))


def random_system(rng, n, l, L, scale, decay):
    """L modes of n states and l inputs, ``||A||`` about ``scale``: rotations at that rate and
    a decay at rate ``decay``, so that a large ``||A|| T`` neither overflows nor decays the
    flow to where the oracle's expm keeps only a few digits (``exp(-50)``: 1e-12 relative)."""
    K = rng.standard_normal((L, n, n))
    A = scale * 0.5 * (K - np.swapaxes(K, 1, 2)) - decay * np.eye(n)
    B = rng.standard_normal((L, n, l)) if l else None
    H = rng.standard_normal((L, n, n))
    return SwitchedLinearSystem.continuous(A, B, rng.standard_normal((L, 1, n)),
                                           Q=H @ np.swapaxes(H, 1, 2), R=[[1.0]])


@pytest.mark.parametrize("n, l, L, S, M, reach", [
    (1, 0, 1, 0, 1, 1e-9),  # a single segment, ||A|| T far below the remainder's reach
    (1, 1, 2, 1, 1000, 0.3),
    (2, 2, 3, 4, 1000, 50.0),
    (3, 0, 2, 2, 1, 300.0),  # ||A|| T far above 1 (a deep table), below 1e3 (conditioning)
    (4, 1, 3, 3, 1000, 1.0),
    (2, 1, 2, 2, 0, 1.0),  # no interval
    (2, 1, 1, 1, 20, 0.0),  # A = 0: depth 0, the flow a polynomial (Taylor exact)
])
def test_random_shapes_match_discretize(n, l, L, S, M, reach):
    rng = np.random.default_rng(n + 10 * l + 100 * S)
    T = 0.7
    system = random_system(rng, n, l, L, reach / T, min(reach, 1.0) / T)
    modes = rng.integers(0, L, (M, S + 1))
    offsets = np.sort(rng.uniform(0.0, T, (M, S)), axis=1)
    if M >= 4 and S:
        offsets[:4] = [np.zeros(S), np.full(S, T), np.full(S, 0.5 * T), np.linspace(0.0, T, S)]
    tr = interval_transitions(dyadic_table(system, T), modes, offsets)
    assert tr.F.shape == (M, n, n) and tr.G.shape == (M, n, l) and tr.Qd.shape == (M, n, n)
    assert_transitions_close(tr, interval(system, T, modes, offsets))
    np.testing.assert_array_equal(tr.Qd, np.swapaxes(tr.Qd, 1, 2))


@settings(max_examples=40, deadline=None)
@given(st.floats(0.0, 1.0), st.integers(0, 1), st.integers(0, 1))
def test_any_instant_matches_discretize(fraction, first, second):
    system = boost_converter()
    T = BOOST_SAMPLE_PERIOD
    tau = np.array([[fraction * T]])
    modes = np.array([[first, second]])
    assert_transitions_close(interval_transitions(dyadic_table(system, T), modes, tau),
                             interval(system, T, modes, tau))


def test_covariances_come_back_symmetric():
    system = vehicle_2d()
    rng = np.random.default_rng(2)
    tr = interval_transitions(dyadic_table(system, 0.5), rng.integers(0, 3, (50, 2)),
                              rng.uniform(0, 0.5, (50, 1)))
    np.testing.assert_array_equal(tr.Qd, np.swapaxes(tr.Qd, 1, 2))  # symmetrized by assignment
    assert np.linalg.eigvalsh(tr.Qd).min() >= 0.0


def test_bad_input_is_refused_by_name():
    system = boost_converter()
    table = dyadic_table(system, 1e-3)
    with pytest.raises(ValueError, match="offsets must be non-decreasing within"):
        interval_transitions(table, [[0, 1]], [[2e-3]])
    with pytest.raises(ValueError, match="modes must be in 0..1"):
        interval_transitions(table, [[0, 2]], [[1e-4]])
    with pytest.raises(ValueError, match="modes must have shape"):
        interval_transitions(table, [[0, 1]], [[1e-4, 2e-4]])
    with pytest.raises(TypeError, match="table must be a DyadicTable"):
        interval_transitions(None, [[0, 1]], [[1e-4]])
    discrete = SwitchedLinearSystem.discrete([[[0.5]]], C=[[1.0]], Q=[[1.0]], R=[[1.0]], dt=1.0)
    with pytest.raises(ValueError, match="continuous-time"):
        dyadic_table(discrete, 1.0)
