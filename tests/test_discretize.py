"""Exact transitions against independent oracles: ODE integration and simulated noise."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.linalg import expm, solve_continuous_lyapunov

from switchest import SwitchedLinearSystem
from switchest.discretize import (
    STEP_ULPS,
    distinct_steps,
    interval,
    mode_steps,
    pairwise_grid,
    switch_grid,
)


def random_system(rng, n=3, l=2, L=3):
    A = rng.standard_normal((L, n, n))
    B = rng.standard_normal((L, n, l))
    W = rng.standard_normal((L, n, n))
    return SwitchedLinearSystem.continuous(A, B, Q=W @ np.swapaxes(W, 1, 2))


def ode_transition(sys, T, modes, offsets):
    """F and G by integrating dX/dt = A X, dG/dt = A G + B piece by piece (DOP853, tight)."""
    n, l = sys.n_states, sys.n_inputs
    z = np.concatenate([np.eye(n).ravel(), np.zeros(n * l)])
    bounds = np.concatenate([[0.0], offsets, [T]])
    for m, a, b in zip(modes, bounds[:-1], bounds[1:]):
        if b <= a:
            continue

        def rhs(_, z, m=m):
            X, G = z[: n * n].reshape(n, n), z[n * n :].reshape(n, l)
            return np.concatenate([(sys.A[m] @ X).ravel(), (sys.A[m] @ G + sys.B[m]).ravel()])

        z = solve_ivp(rhs, (a, b), z, method="DOP853", rtol=1e-13, atol=1e-15).y[:, -1]
    return z[: n * n].reshape(n, n), z[n * n :].reshape(n, l)


@pytest.mark.parametrize("n_switches", [0, 1, 3])
def test_F_G_match_ode_integration(n_switches):
    rng = np.random.default_rng(n_switches)
    for _ in range(3):
        sys = random_system(rng)
        T = rng.uniform(0.2, 1.0)
        offsets = np.sort(rng.uniform(0, T, n_switches))
        modes = rng.integers(0, 3, n_switches + 1)
        tr = interval(sys, T, modes, offsets)
        F, G = ode_transition(sys, T, modes, offsets)
        assert np.linalg.norm(tr.F - F) <= 1e-9 * np.linalg.norm(F)
        assert np.linalg.norm(tr.G - G) <= 1e-9 * np.linalg.norm(G)


def test_one_switch_is_shankar_eq_4_and_5():
    rng = np.random.default_rng(7)
    sys = random_system(rng, L=2)
    T, tb = 0.5, 0.2
    tr = interval(sys, T, [0, 1], [tb])
    F = expm(sys.A[1] * (T - tb)) @ expm(sys.A[0] * tb)  # eq. (4)
    np.testing.assert_allclose(tr.F, F, rtol=1e-12, atol=1e-13)


def test_Qd_matches_sample_covariance_of_euler_maruyama_paths():
    """20 000 noise paths integrated on a fine grid, independent of the Van Loan formula."""
    rng = np.random.default_rng(11)
    A = np.array([[[-1.0, 2.0], [-2.0, -0.5]], [[0.3, 1.0], [0.0, -2.0]]])
    Q = np.array([[1.0, 0.3], [0.3, 0.5]])
    sys = SwitchedLinearSystem.continuous(A, Q=Q)
    T, tb, steps, N = 1.0, 0.4, 2000, 20000
    dt = T / steps
    x = np.zeros((N, 2))
    Lq = np.linalg.cholesky(Q)
    for i in range(steps):
        m = 0 if (i + 0.5) * dt < tb else 1
        x = x + dt * x @ A[m].T + np.sqrt(dt) * rng.standard_normal((N, 2)) @ Lq.T
    S = x.T @ x / N
    Qd = interval(sys, T, [0, 1], [tb]).Qd
    # std of a sample covariance entry: sqrt((S_ii S_jj + S_ij^2) / N); 5 standard errors
    se = np.sqrt((np.outer(np.diag(Qd), np.diag(Qd)) + Qd**2) / N)
    assert np.all(np.abs(S - Qd) < 5 * se), (S, Qd)


def test_Qd_is_symmetric_psd_and_composes():
    rng = np.random.default_rng(3)
    sys = random_system(rng)
    T = 0.8
    whole = interval(sys, T, [0, 2], [0.3])
    a = interval(sys, 0.3, [0])
    b = interval(sys, 0.5, [2])
    np.testing.assert_allclose(whole.F, b.F @ a.F, rtol=1e-11)
    np.testing.assert_allclose(whole.G, b.F @ a.G + b.G, rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(whole.Qd, b.F @ a.Qd @ b.F.T + b.Qd, rtol=1e-11, atol=1e-12)
    np.testing.assert_array_equal(whole.Qd, whole.Qd.T)
    assert np.linalg.eigvalsh(whole.Qd).min() > 0


def test_batched_equals_looped_and_broadcasts_leading_axes():
    rng = np.random.default_rng(5)
    sys = random_system(rng)
    T = np.array([0.3, 0.7])[:, None]  # (2, 1) broadcast with offsets' (4,)
    offsets = rng.uniform(0, 0.3, (4, 2))
    offsets.sort(axis=-1)
    modes = rng.integers(0, 3, (4, 3))
    tr = interval(sys, T, modes, offsets)
    assert tr.F.shape == (2, 4, 3, 3) and tr.G.shape == (2, 4, 3, 2)
    for i in range(2):
        for j in range(4):
            one = interval(sys, float(T[i, 0]), modes[j], offsets[j])
            np.testing.assert_allclose(tr.F[i, j], one.F, rtol=1e-12, atol=1e-14)
            np.testing.assert_allclose(tr.Qd[i, j], one.Qd, rtol=1e-12, atol=1e-14)


def test_zero_length_segments_change_nothing():
    sys = random_system(np.random.default_rng(9))
    plain = interval(sys, 0.6, [1])
    padded = interval(sys, 0.6, [1, 1, 2], [0.6, 0.6])
    np.testing.assert_allclose(padded.F, plain.F, rtol=1e-13)


def test_badly_scaled_noise_keeps_relative_accuracy():
    A = np.array([[-3000.0, -2000.0], [2100.0, -40.0]])  # boost-converter scale
    sys_small = SwitchedLinearSystem.continuous(A, Q=1e-10 * np.eye(2))
    sys_unit = SwitchedLinearSystem.continuous(A, Q=np.eye(2))
    small = interval(sys_small, 5e-4, [0]).Qd
    unit = interval(sys_unit, 5e-4, [0]).Qd
    np.testing.assert_allclose(small * 1e10, unit, rtol=1e-10)


def test_grid_and_pairwise_cache():
    np.testing.assert_allclose(switch_grid(0.5, 5), [0.05, 0.15, 0.25, 0.35, 0.45])
    sys = random_system(np.random.default_rng(1))
    pg = pairwise_grid(sys, 0.5, 4)
    assert pg.F.shape == (3, 3, 4, 3, 3)
    assert pairwise_grid(sys, 0.5, 4) is pg  # cached
    one = interval(sys, 0.5, [2, 0], [switch_grid(0.5, 4)[1]])
    np.testing.assert_allclose(pg.F[2, 0, 1], one.F, rtol=1e-13)
    np.testing.assert_allclose(pg.F[1, 1, 3], mode_steps(sys, 0.5).F[1], rtol=1e-13)


def test_discrete_system_passes_through():
    A = np.array([[[0.9, 0.1], [0.0, 0.8]], [[1.0, 0.0], [0.2, 0.5]]])
    sys = SwitchedLinearSystem.discrete(A, B=np.ones((2, 1)), Q=0.1 * np.eye(2), dt=0.5)
    tr = interval(sys, 0.5, [[1], [0]])
    np.testing.assert_array_equal(tr.F, A[[1, 0]])
    np.testing.assert_array_equal(tr.G[0], np.ones((2, 1)))
    np.testing.assert_array_equal(tr.Qd[1], 0.1 * np.eye(2))
    with pytest.raises(ValueError, match="cannot switch inside a step"):
        interval(sys, 0.5, [0, 1], [0.2])
    with pytest.raises(ValueError, match="T must equal"):
        interval(sys, 1.0, [0])


@pytest.mark.parametrize(
    "args, match",
    [
        ((0.5, [0, 1], [0.6]), r"offsets must lie within \[0, T\]"),
        ((0.5, [0, 1, 0], [0.3, 0.2]), "non-decreasing"),
        ((0.5, [0, 3], [0.2]), "modes must be in 0..2"),
        ((0.5, [0, 1], [0.1, 0.2]), "last axis of length S = 1"),
        ((-0.5, [0]), "T must be positive"),
        ((0.5, [0, 1], [np.nan]), "offsets must be finite"),
    ],
)
def test_bad_arguments(args, match):
    sys = random_system(np.random.default_rng(0))
    with pytest.raises(ValueError, match=match):
        interval(sys, *args)
    with pytest.raises(TypeError, match="SwitchedLinearSystem"):
        interval(np.eye(2), 0.5, [0])


@pytest.mark.parametrize("speed", [1e2, 1e3, 1e5])
def test_fast_non_normal_modes_keep_an_accurate_psd_noise_covariance(speed):
    # oracle: Qd = X - F X F' with A X + X A' + Q = 0 (A Hurwitz), G = A^-1 (F - I) B. The Van Loan
    # block alone holds e^{-A h} ~ e^{3 speed h} here and loses every digit of Qd from speed ~ 1e3
    V = np.random.default_rng(0).standard_normal((3, 3))
    A = V @ np.diag([-1.0, -2.0, -3.0]) @ np.linalg.inv(V) * speed
    Q, B, h = np.eye(3), np.ones((3, 1)), 0.05
    tr = mode_steps(SwitchedLinearSystem.continuous(A[None], B=B[None], Q=Q[None]), h)
    F = expm(A * h)
    X = solve_continuous_lyapunov(A, -Q)
    Qd = X - F @ X @ F.T
    np.testing.assert_allclose(tr.F[0], F, rtol=1e-12, atol=1e-13 * np.abs(F).max())
    np.testing.assert_allclose(tr.Qd[0], Qd, rtol=1e-12, atol=1e-12 * np.abs(Qd).max())
    np.testing.assert_allclose(tr.G[0], np.linalg.solve(A, (F - np.eye(3)) @ B), rtol=1e-12)
    assert np.linalg.eigvalsh(tr.Qd[0]).min() > 0


def test_rounded_steps_are_one_step():
    """The boost converter's 0.1 s at 0.5 ms: ``np.arange`` rounding gives steps a few units in
    the last place apart, which are one step (one discretization, not seven)."""
    t = np.cumsum(np.full(200, 5e-4))
    t = np.concatenate([[0.0], t])
    assert np.unique(np.diff(t)).size > 1
    steps, which = distinct_steps(t)
    assert steps.size == 1 and np.all(which == 0)
    np.testing.assert_allclose(steps, 5e-4, rtol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from([0.1, 0.25, 0.4, 1.0]), min_size=1, max_size=40),
       st.floats(0.0, 1e4))
def test_distinct_steps_group_only_rounding(choices, start):
    """Sample times accumulated from a few lengths (rounded as they add up): every interval's
    step is within the rounding tolerance of its own length, the steps are ascending and
    further apart than it, and intervals of one length share one step, of different lengths
    never."""
    t = start + np.concatenate([[0.0], np.cumsum(choices)])
    steps, which = distinct_steps(t)
    tol = STEP_ULPS * np.spacing(np.abs(t).max())
    assert np.all(np.abs(steps[which] - np.diff(t)) <= tol)
    assert np.all(np.diff(steps) > tol)
    for c in set(choices):
        assert np.unique(which[np.isclose(np.diff(t), c, rtol=1e-6)]).size == 1
    assert steps.size == len(set(choices))


def test_one_sample_has_no_step():
    steps, which = distinct_steps([3.0])
    assert steps.size == 0 and which.size == 0
