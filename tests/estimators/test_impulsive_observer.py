"""Impulsive observer of Etienne, Motchon, Duviella & Guelton (seed 004), eqs (2)-(3), (21)-(23):
the jump, the exact flow between aperiodic samples (ODE oracle), the error covariance
(Monte Carlo), delayed mode estimates, and the observer-based closed loop."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from threadpoolctl import threadpool_limits

from switchest import SwitchedLinearSystem
from switchest import signals as sg
from switchest.analysis.impulsive_lmis import closed_loop_matrices
from switchest.estimators.impulsive import (
    ImpulsiveObserver,
    delayed_replica,
    impulsive_update,
    simulate_observer_control,
)
from switchest.models import ETIENNE_SCENARIO, etienne_academic
from switchest.simulate import simulate

# Observer gains of Theorem 8 at the §4 scalars (alpha = 0.2, mu_s = 5, mu_c = 0.98), as
# returned by switchest.analysis.impulsive_observer_synthesis (Clarabel), rounded; inputs here.
G_THEOREM8 = np.array([[[1.0003], [-0.0572]], [[1.0323], [2.1905]]])

# A two-mode system whose output matrices differ, so that the mismatch block of (22b) acts.
A2 = np.array([[[0.2, -0.5], [0.5, -0.3]], [[0.2, 0.3], [-1.0, 0.4]]])
B2 = np.array([[[-0.4], [1.8]], [[0.1], [1.5]]])
C2 = np.array([[[1.0, 0.0]], [[1.0, 0.5]]])
SYS_C = SwitchedLinearSystem.continuous(A2, B2, C2)


@pytest.fixture(autouse=True)
def single_threaded_blas():
    """Tiny matrices: threaded BLAS only adds contention (measured 100x slower expm on 2 cores)."""
    with threadpool_limits(1):
        yield


def piecewise_ode(rhs, jumps, t, breaks, z0):
    """Integrate ``dz/dt = rhs(mode_time, z)`` between all breakpoints with tight tolerances,
    applying ``jumps(t_k, z)`` at each sample ``t_k`` (t_0 included). Returns z after each jump."""
    events = np.union1d(t, breaks[(breaks > t[0]) & (breaks < t[-1])])
    z = jumps(t[0], np.asarray(z0, float))
    out = [z]
    for a, b in itertools.pairwise(events):
        sol = solve_ivp(
            lambda s, v, a=a: rhs(a, v), (a, b), z, rtol=1e-11, atol=1e-13, method="DOP853"
        )
        z = sol.y[:, -1]
        if np.any(np.isclose(b, t, rtol=0, atol=1e-14)):
            z = jumps(b, z)
            out.append(z)
    return np.array(out)


# ------------------------------------------------------------------ the jump
def test_update_is_the_jump_of_eq2_with_joseph_covariance():
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(4, 3)), rng.normal(size=(4, 2))
    C, G = rng.normal(size=(4, 2, 3)), rng.normal(size=(4, 3, 2))
    R = np.broadcast_to(np.diag([0.3, 0.7]), (4, 2, 2))
    P = np.broadcast_to(np.eye(3), (4, 3, 3))
    xp, Pp = impulsive_update(x, P, y, C, G, R)
    np.testing.assert_allclose(
        xp, x + np.einsum("nij,nj->ni", G, y - np.einsum("nij,nj->ni", C, x))
    )
    IGC = np.eye(3) - G @ C
    np.testing.assert_allclose(Pp, IGC @ P @ IGC.transpose(0, 2, 1) + G @ R @ G.transpose(0, 2, 1))
    y_nan = y.copy()
    y_nan[0] = np.nan  # all components missing: no jump
    y_nan[1, 1] = np.nan  # one component missing: only the other corrects
    xn, Pn = impulsive_update(x, P, y_nan, C, G, R)
    np.testing.assert_allclose(xn[0], x[0])
    np.testing.assert_allclose(Pn[0], P[0])
    np.testing.assert_allclose(xn[1], x[1] + G[1][:, 0] * (y[1, 0] - C[1, 0] @ x[1]))
    assert np.all(np.isfinite(xn)) and np.all(np.isfinite(Pn))


# ------------------------------------------------------------------ exact flow
def test_flow_with_a_delayed_mode_estimate_matches_an_ode_oracle():
    """sigma_hat switches inside sample intervals; the input is held between aperiodic samples."""
    t = sg.aperiodic(0.3, 0.4, 6.0, rng=3)
    sigma = sg.schedule([1.05, 2.61, 4.0], [0, 1, 0, 1])
    delay = 0.17
    u = np.sin(np.arange(t.size))[:, None]
    traj = simulate(SYS_C, sigma, t, np.array([1.0, -2.0]), u)
    obs = ImpulsiveObserver(SYS_C, G_THEOREM8, mode_estimate=delay, x0=[0.3, 0.1])
    est = obs.run(traj.y[0], u, t, signals=sigma)
    hat = delayed_replica(sigma, delay)
    np.testing.assert_array_equal(est.mode, hat.at(t))
    y = traj.y[0, :, 0]

    def rhs(a, v):  # eq. (2) first line, modes held on the segment starting at a
        m, k = int(hat.at(a)), np.searchsorted(t, a, side="right") - 1
        return A2[m] @ v + B2[m][:, 0] * u[k, 0]

    def jump(tk, v):  # eq. (2) third line with sigma_hat(t_k)
        m, k = int(hat.at(tk)), int(np.argmin(np.abs(t - tk)))
        return v + G_THEOREM8[m][:, 0] * (y[k] - C2[m, 0] @ v)

    oracle = piecewise_ode(rhs, jump, t, hat.times, [0.3, 0.1])
    np.testing.assert_allclose(est.x, oracle, rtol=1e-8, atol=1e-9)


def test_synchronous_error_follows_eq4_whatever_the_input_and_state():
    """With sigma_hat = sigma the error obeys (4): it does not depend on u or on x itself."""
    sys = etienne_academic()
    t = sg.aperiodic(0.3, 0.4, 8.0, rng=5)
    sigma = sg.schedule([2.2, 5.5], [1, 0, 1])
    e0 = np.array([0.5, -0.25])
    errors = []
    for x0, u in (([1.0, 1.0], 0.0), ([3.0, -2.0], 5.0)):
        traj = simulate(sys, sigma, t, np.array(x0), np.full(1, u))
        obs = ImpulsiveObserver(sys, G_THEOREM8, x0=np.array(x0) - e0)
        errors.append(traj.x[0] - obs.run(traj.y[0], np.full(1, u), t, signals=sigma).x)
    np.testing.assert_allclose(errors[0], errors[1], rtol=1e-9, atol=1e-11)
    assert np.linalg.norm(errors[0][-1]) < 0.2 * np.linalg.norm(errors[0][0])


def test_reported_covariance_matches_the_monte_carlo_error_covariance():
    """P = exact error covariance for e(0) ~ N(0, P0) with process and measurement noise."""
    noisy = SwitchedLinearSystem.continuous(A2, B2, C2, Q=0.05 * np.eye(2), R=[[0.02]])
    t = sg.aperiodic(0.3, 0.4, 5.0, rng=7)
    sigma = sg.schedule([1.7, 3.3], [0, 1, 0])
    P0 = np.array([[1.0, 0.3], [0.3, 0.5]])
    N = 4000
    traj = simulate(noisy, sigma, t, (np.zeros(2), P0), trials=N, rng=11)
    est = ImpulsiveObserver(noisy, G_THEOREM8, P0=P0).run(traj.y, None, t, signals=sigma)
    e = traj.x[:, -1] - est.x[:, -1]
    P = est.P[0, -1]
    np.testing.assert_allclose(est.P[1:, -1], np.broadcast_to(P, (N - 1, 2, 2)))
    sample = e.T @ e / N  # the mean is zero: unbiased without centering
    se = np.sqrt(
        (np.outer(np.diag(P), np.diag(P)) + P**2) / N
    )  # sd of each sample-covariance entry
    assert np.all(np.abs(sample - P) < 4.5 * se), (sample, P, se)
    assert np.all(np.abs(e.mean(axis=0)) < 4.5 * np.sqrt(np.diag(P) / N))


# ------------------------------------------------------------------ protocol
def trajectories(trials=3, seed=0):
    t = sg.aperiodic(0.3, 0.4, 20.0, rng=seed)
    traj = simulate(
        SYS_C,
        lambda r: sg.dwell_time(2, 20.0, 7.0, 9.0, rng=r),
        t,
        (np.zeros(2), np.eye(2)),
        u=np.ones(1),
        trials=trials,
        rng=seed + 1,
    )
    return traj


def test_batched_equals_looped_and_is_reproducible():
    traj = trajectories()
    obs = ImpulsiveObserver(SYS_C, G_THEOREM8, mode_estimate=0.1)
    batched = obs.run(traj.y, np.ones(1), traj.t, signals=traj.signals)
    again = obs.run(traj.y, np.ones(1), traj.t, signals=traj.signals)
    np.testing.assert_array_equal(batched.x, again.x)
    assert batched.x.shape == (3, traj.t.size, 2) and batched.P.shape == (3, traj.t.size, 2, 2)
    for n in range(3):
        single = obs.run(traj.y[n], np.ones(1), traj.t, signals=traj.signals[n])
        assert single.x.shape == (traj.t.size, 2) and single.mode.shape == (traj.t.size,)
        np.testing.assert_allclose(batched.x[n], single.x, rtol=1e-12, atol=1e-14)
        np.testing.assert_array_equal(batched.mode[n], single.mode)
    y4 = np.stack([traj.y[:2], traj.y[1:]])  # a (2, 2, K, m) batch, one signal per flattened trial
    four = obs.run(y4, np.ones(1), traj.t, signals=[traj.signals[i] for i in (0, 1, 1, 2)])
    np.testing.assert_allclose(four.x[1, 1], batched.x[2], rtol=1e-12, atol=1e-14)


def test_nan_measurement_skips_the_jump():
    traj = trajectories(trials=2)
    y = traj.y.copy()
    y[:, 6] = np.nan
    obs = ImpulsiveObserver(SYS_C, G_THEOREM8)
    full = obs.run(y, np.ones(1), traj.t, signals=traj.signals)
    assert np.all(np.isfinite(full.x)) and np.all(np.isfinite(full.P))
    # without the jump at t_6, x_hat(t_6) is the flow of x_hat(t_5+) (no switch there: dwell >= 7)
    state = obs.init((2,))
    for k in range(6):
        state = obs.step(
            state,
            traj.y[:, k],
            np.ones((2, 1)),
            dt=None if k == 0 else traj.t[k] - traj.t[k - 1],
            mode=traj.mode[:, k],
        )
    flowed = obs.step(
        state,
        np.full((2, 1), np.nan),
        np.ones((2, 1)),
        dt=traj.t[6] - traj.t[5],
        mode=traj.mode[:, 6],
    )
    np.testing.assert_allclose(full.x[:, 6], flowed.x, rtol=1e-12)
    np.testing.assert_array_equal(flowed.mode, traj.mode[:, 6])


def test_delayed_replica_shifts_every_switch():
    sigma = sg.schedule([1.0, 3.0, 4.0], [0, 1, 0, 1])
    hat = delayed_replica(sigma, 0.15)
    np.testing.assert_allclose(hat.times, [1.15, 3.15, 4.15])
    np.testing.assert_array_equal(hat.modes, sigma.modes)
    assert hat.at(1.1) == 0 and hat.at(1.2) == 1  # the true mode is 1 from t = 1 on
    varied = delayed_replica(sigma, [0.0, 0.1, 0.2])
    np.testing.assert_allclose(varied.times, [1.0, 3.1, 4.2])
    with pytest.raises(ValueError, match="delay must be non-negative"):
        delayed_replica(sigma, -0.1)
    with pytest.raises(ValueError, match=r"one entry per switch \(3,\)"):
        delayed_replica(sigma, [0.1, 0.2])
    with pytest.raises(ValueError, match="reorders the switches"):
        delayed_replica(sigma, [2.5, 0.0, 0.0])
    with pytest.raises(TypeError, match="signal must be a SwitchingSignal"):
        delayed_replica([1.0], 0.1)


def test_mode_estimate_options():
    traj = trajectories(trials=2)
    rng = np.random.default_rng(4)
    delays = {id(s): rng.uniform(0, 0.15, s.n_switches) for s in traj.signals}
    random_rule = ImpulsiveObserver(
        SYS_C, G_THEOREM8, mode_estimate=lambda s: delayed_replica(s, delays[id(s)])
    )
    est = random_rule.run(traj.y, np.ones(1), traj.t, signals=traj.signals)
    for n, s in enumerate(traj.signals):
        np.testing.assert_array_equal(est.mode[n], delayed_replica(s, delays[id(s)]).at(traj.t))
    sync = ImpulsiveObserver(SYS_C, G_THEOREM8).run(
        traj.y, np.ones(1), traj.t, signals=traj.signals
    )
    np.testing.assert_array_equal(sync.mode, traj.mode)
    zero = ImpulsiveObserver(SYS_C, G_THEOREM8, mode_estimate=0.0).run(
        traj.y, np.ones(1), traj.t, signals=traj.signals
    )
    np.testing.assert_array_equal(zero.x, sync.x)


def test_constructor_and_run_validate():
    with pytest.raises(
        ValueError, match=r"gains must have shape \(L, n, m\) = \(2, 2, 1\), got \(2, 1, 2\)"
    ):
        ImpulsiveObserver(SYS_C, np.zeros((2, 1, 2)))
    with pytest.raises(ValueError, match="mode_estimate must be 'synchronous'"):
        ImpulsiveObserver(SYS_C, G_THEOREM8, mode_estimate="delayed")
    with pytest.raises(ValueError, match=r"finite and >= 0, got -0\.1"):
        ImpulsiveObserver(SYS_C, G_THEOREM8, mode_estimate=-0.1)
    with pytest.raises(TypeError, match="mode_estimate must be"):
        ImpulsiveObserver(SYS_C, G_THEOREM8, mode_estimate=[0.1])
    with pytest.raises(TypeError, match="system must be a SwitchedLinearSystem"):
        ImpulsiveObserver(A2, G_THEOREM8)
    with pytest.raises(ValueError, match="system must be continuous-time"):
        ImpulsiveObserver(SwitchedLinearSystem.discrete(A2, B2, C2, dt=0.1), G_THEOREM8)
    with pytest.raises(ValueError, match=r"x0 must have shape \(n,\)"):
        ImpulsiveObserver(SYS_C, G_THEOREM8, x0=np.zeros(3))
    traj = trajectories(trials=2)
    obs = ImpulsiveObserver(SYS_C, G_THEOREM8)
    with pytest.raises(ValueError, match=r"one SwitchingSignal per trial \(N = 2\), got 1"):
        obs.run(traj.y, None, traj.t, signals=traj.signals[:1])
    with pytest.raises(TypeError, match="signals must be a SwitchingSignal"):
        obs.run(traj.y, None, traj.t, signals=[0, 1])
    with pytest.raises(ValueError, match=r"mode beyond the system's modes 0..1"):
        obs.run(traj.y, None, traj.t, signals=sg.schedule([3.0], [0, 2]))
    with pytest.raises(ValueError, match="t must have shape"):
        obs.run(traj.y, None, traj.t[:-1], signals=traj.signals)
    with pytest.raises(TypeError, match=r"mode_estimate\(signal\) must return a SwitchingSignal"):
        ImpulsiveObserver(SYS_C, G_THEOREM8, mode_estimate=lambda s: None).run(
            traj.y, None, traj.t, signals=traj.signals
        )
    with pytest.raises(ValueError, match="step needs segment_modes"):
        obs.step(obs.init((2,)), traj.y[:, 1], None, dt=0.3, mode=np.zeros(2, int))


# ------------------------------------------------------------------ closed loop (21)-(23)
def test_closed_loop_matrices_are_the_plant_and_observer_equations():
    """(22a) against (1)-(2) with u = K x_hat; (22b) with the corrected sign (printed: +G C_ji)."""
    rng = np.random.default_rng(1)
    K = ETIENNE_SCENARIO.K
    Acl, J = closed_loop_matrices(SYS_C, K, G_THEOREM8)
    assert Acl.shape == J.shape == (2, 2, 4, 4)
    x, xh = rng.normal(size=2), rng.normal(size=2)
    z = np.concatenate([x, x - xh])
    for j in range(2):  # true mode
        for i in range(2):  # estimated mode
            dx = A2[j] @ x + B2[j] @ K[i] @ xh
            dxh = A2[i] @ xh + B2[i] @ K[i] @ xh
            np.testing.assert_allclose(Acl[j, i] @ z, np.concatenate([dx, dx - dxh]), atol=1e-12)
            xh_plus = xh + G_THEOREM8[i] @ (C2[j] @ x - C2[i] @ xh)
            np.testing.assert_allclose(J[j, i] @ z, np.concatenate([x, x - xh_plus]), atol=1e-12)
            printed = J[j, i].copy()
            printed[2:, :2] = G_THEOREM8[i] @ (C2[j] - C2[i])  # (22b) as printed
            if i != j:
                assert not np.allclose(printed @ z, J[j, i] @ z)


def test_closed_loop_matrices_stay_importable_from_the_estimators():
    """The design moved to the analysis (the lower layer); its old addresses give the same
    function."""
    from switchest import estimators
    from switchest.estimators import impulsive

    assert impulsive.closed_loop_matrices is estimators.closed_loop_matrices is closed_loop_matrices


@settings(max_examples=40, deadline=None)
@given(
    L=st.integers(1, 3),
    n=st.integers(1, 4),
    m=st.integers(1, 3),
    n_in=st.integers(1, 2),
    seed=st.integers(0, 2**32 - 1),
)
def test_closed_loop_matrices_hold_for_any_dimensions(L, n, m, n_in, seed):
    """(21)-(23) against the plant and observer equations for random systems of any size."""
    rng = np.random.default_rng(seed)
    A, B, C = rng.normal(size=(L, n, n)), rng.normal(size=(L, n, n_in)), rng.normal(size=(L, m, n))
    K, G = rng.normal(size=(L, n_in, n)), rng.normal(size=(L, n, m))
    Acl, J = closed_loop_matrices(SwitchedLinearSystem.continuous(A, B, C), K, G)
    x, xh = rng.normal(size=n), rng.normal(size=n)
    z = np.concatenate([x, x - xh])
    for j in range(L):
        for i in range(L):
            dx = A[j] @ x + B[j] @ K[i] @ xh
            dxh = A[i] @ xh + B[i] @ K[i] @ xh
            np.testing.assert_allclose(Acl[j, i] @ z, np.concatenate([dx, dx - dxh]), atol=1e-10)
            xh_plus = xh + G[i] @ (C[j] @ x - C[i] @ xh)
            np.testing.assert_allclose(J[j, i] @ z, np.concatenate([x, x - xh_plus]), atol=1e-10)


def test_closed_loop_simulation_matches_an_ode_oracle():
    t = sg.aperiodic(0.3, 0.4, 6.0, rng=2)
    sigma = sg.schedule([1.3, 3.9], [1, 0, 1])
    K = ETIENNE_SCENARIO.K
    out = simulate_observer_control(
        SYS_C, K, G_THEOREM8, sigma, t, [1.0, -1.0], [0.2, 0.0], mode_estimate=0.15
    )
    hat = delayed_replica(sigma, 0.15)

    def rhs(a, v):  # plant (1) and observer (2) with the continuous feedback u = K_hat x_hat
        j, i = int(sigma.at(a)), int(hat.at(a))
        x, xh = v[:2], v[2:]
        u = K[i] @ xh
        return np.concatenate([A2[j] @ x + B2[j] @ u, A2[i] @ xh + B2[i] @ u])

    def jump(tk, v):
        j, i = int(sigma.at(tk)), int(hat.at(tk))
        x, xh = v[:2], v[2:]
        return np.concatenate([x, xh + G_THEOREM8[i] @ (C2[j] @ x - C2[i] @ xh)])

    oracle = piecewise_ode(rhs, jump, t, np.union1d(sigma.times, hat.times), [1.0, -1.0, 0.2, 0.0])
    np.testing.assert_allclose(out.x[0], oracle[:, :2], rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(out.x_hat[0], oracle[:, 2:], rtol=1e-8, atol=1e-10)
    np.testing.assert_array_equal(out.mode_hat[0], hat.at(t))
    np.testing.assert_array_equal(out.mode[0], sigma.at(t))


def test_closed_loop_with_delayed_mode_estimate_converges():
    """§4 'Analyse': the paper's K, Theorem 8 gains, delta = 0.15, dwell >= 7,
    t_{k+1} - t_k in [0.3, 0.4]."""
    s = ETIENNE_SCENARIO
    sys = etienne_academic()
    t = sg.aperiodic(s.tau_min, s.tau_max, 60.0, rng=8)
    rng = np.random.default_rng(9)
    x0 = rng.normal(size=(40, 2))
    out = simulate_observer_control(
        sys,
        s.K,
        G_THEOREM8,
        lambda r: sg.dwell_time(2, 60.0, s.dwell, 2 * s.dwell, rng=r),
        t,
        x0,
        mode_estimate=s.delta,
        rng=10,
    )
    assert out.x.shape == out.x_hat.shape == (40, t.size, 2)
    assert np.any(out.mode != out.mode_hat)  # some samples fall while the estimate is wrong
    z0 = np.linalg.norm(np.concatenate([out.x[:, 0], out.error[:, 0]], axis=1), axis=1)
    zT = np.linalg.norm(np.concatenate([out.x[:, -1], out.error[:, -1]], axis=1), axis=1)
    assert np.all(zT < 1e-4 * z0)


def test_closed_loop_validates():
    t = sg.periodic(0.3, 3.0)
    sigma = sg.schedule([], [0])
    K = ETIENNE_SCENARIO.K
    with pytest.raises(ValueError, match=r"K must have shape \(L, l, n\) = \(2, 1, 2\)"):
        simulate_observer_control(SYS_C, K[:, :, :1], G_THEOREM8, sigma, t, [1.0, 0.0])
    with pytest.raises(ValueError, match="disagree on the number of trials"):
        simulate_observer_control(SYS_C, K, G_THEOREM8, [sigma] * 2, t, np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"x0 must have shape \(n,\) or \(N, n\)"):
        simulate_observer_control(SYS_C, K, G_THEOREM8, sigma, t, [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="signals uses mode 2"):
        simulate_observer_control(SYS_C, K, G_THEOREM8, sg.schedule([1.0], [0, 2]), t, [1.0, 0.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        simulate_observer_control(SYS_C, K, G_THEOREM8, sigma, t[::-1], [1.0, 0.0])
