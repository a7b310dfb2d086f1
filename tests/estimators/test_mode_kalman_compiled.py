"""ModeKalmanFilter on the compiled engine against the numpy oracle (numpy_oracle.py, beside this).

The filter builds its table of exact transitions (one per distinct step and mode, one per
distinct switch pattern of the clairvoyant segments) and runs the compiled Kalman kernel; the
oracle here discretizes every interval of every trial on its own with
:func:`switchest.discretize.interval` and filters trial by trial in numpy. Agreement to 1e-9
of each array's largest entry: the same equations in another summation order.
"""

import numpy as np
import pytest
from numpy_oracle import kalman_run as oracle_kalman_run
from numpy_oracle import kalman_steady_run as oracle_steady_run

from switchest.discretize import interval, mode_steps
from switchest.engine import GATED
from switchest.estimators import ModeKalmanFilter
from switchest.estimators.mode_kalman import _steady_gains
from switchest.models import boost_converter, boost_switching, vehicle_2d
from switchest.signals import markov_continuous, periodic, schedule
from switchest.simulate import simulate
from switchest.system import SwitchedLinearSystem

RTOL = 1e-9


def assert_close(actual, expected, rtol=RTOL):
    expected = np.asarray(expected)
    np.testing.assert_allclose(actual, expected, rtol=0.0, atol=rtol * np.abs(expected).max())


def three_mode_system():
    A = [[[0.0, 1.0], [-2.0, -0.3]], [[-0.5, 0.2], [0.0, -1.0]], [[0.1, -1.0], [1.0, -0.2]]]
    B = [[[0.0], [1.0]], [[1.0], [0.0]], [[0.5], [0.5]]]
    C = [[[1.0, 0.0]], [[0.0, 1.0]], [[1.0, 1.0]]]
    return SwitchedLinearSystem.continuous(A, B, C, Q=0.05 * np.eye(2), R=[[0.1]])


def trajectory(system, t, trials, seed):
    """Simulated trials with several switches inside sample intervals."""
    if system.n_modes == 2:
        def signal(r):
            return boost_switching(r, t_end=t[-1])
    else:
        rates = np.full((3, 3), 8.0)
        np.fill_diagonal(rates, -16.0)

        def signal(r):
            return markov_continuous(rates, t[-1], rng=r)
    x0 = (np.zeros(system.n_states), np.eye(system.n_states))
    return simulate(system, signal, t, x0, u=np.ones(system.n_inputs), trials=trials,
                    rng=np.random.default_rng(seed))


def oracle_clairvoyant(system, y, mode, segments, t, u, x0, P0):
    """Discretize every interval of every trial alone, then filter with the numpy oracle."""
    seg_m, seg_o = segments
    N, K = mode.shape
    F, G, Qd = [], [], []
    trans = np.zeros((N, K), dtype=np.int64)
    for i in range(N):
        for k in range(1, K):
            tr = interval(system, t[k] - t[k - 1], seg_m[i, k - 1], seg_o[i, k - 1])
            trans[i, k] = len(F)
            F.append(tr.F)
            G.append(tr.G)
            Qd.append(tr.Qd)
    uu = np.broadcast_to(u, (N, K, system.n_inputs))
    return oracle_kalman_run(y, uu, np.array(F), np.array(G), np.array(Qd), trans, system.C,
                             system.R, mode, x0, P0)


@pytest.mark.parametrize("make", [boost_converter, three_mode_system])
def test_clairvoyant_run_matches_the_oracle_with_holes_and_irregular_times(make):
    system = make()
    rng = np.random.default_rng(3)
    T = 5e-4 if make is boost_converter else 0.1
    t = np.cumsum(rng.uniform(0.5, 1.5, 40)) * T  # irregular sample times
    traj = trajectory(system, t, 5, 4)
    y = traj.y.copy()
    y[rng.random(y.shape) < 0.1] = np.nan
    u = np.ones(system.n_inputs)
    x0, P0 = np.zeros(system.n_states), np.eye(system.n_states)
    est = ModeKalmanFilter(system, x0, P0).run(y, u, t, modes=traj.mode,
                                               segments=traj.segments())
    x, P, ll, flag = oracle_clairvoyant(system, y, traj.mode, traj.segments(), t, u, x0, P0)
    seg_m = traj.segments()[0]
    assert np.isnan(y).any() and np.any(seg_m[..., 1:] != seg_m[..., :1])  # switches inside
    assert_close(est.x, x)
    assert_close(est.P, P)
    assert_close(est.loglik, ll)
    np.testing.assert_array_equal(est.outlier, flag == GATED)


def test_step_streams_the_same_filter_as_run():
    system = three_mode_system()
    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(0.05, 0.15, 25))
    traj = trajectory(system, t, 3, 6)
    y = traj.y.copy()
    y[rng.random(y.shape) < 0.1] = np.nan
    u = np.ones(1)
    f = ModeKalmanFilter(system, np.zeros(2), np.eye(2), gate=9.0)
    seg_m, seg_o = traj.segments()
    est = f.run(y, u, t, modes=traj.mode, segments=(seg_m, seg_o))
    state = f.init((3,))
    for k in range(t.size):
        kw = {} if k == 0 else {"dt": t[k] - t[k - 1], "segment_modes": seg_m[:, k - 1],
                                 "segment_offsets": seg_o[:, k - 1]}
        state = f.step(state, y[:, k], np.ones((3, 1)), mode=traj.mode[:, k], **kw)
        assert_close(state.x, est.x[:, k], rtol=1e-12)
        assert_close(state.P, est.P[:, k], rtol=1e-12)
        np.testing.assert_array_equal(state.outlier, est.outlier[:, k])


@pytest.mark.parametrize("gate", [None, 4.0])
def test_steady_state_run_matches_the_oracle(gate):
    system = boost_converter()
    T = 5e-4
    t = periodic(T, 40 * T)
    traj = trajectory(system, t, 4, 8)
    y = traj.y.copy()
    y[np.random.default_rng(9).random(y.shape) < 0.1] = np.nan
    x0, P0 = np.array([0.0, 100.0]), 25.0 * np.eye(2)
    est = ModeKalmanFilter(system, x0, P0, steady_state=True, gate=gate).run(
        y, np.ones(1), t, modes=traj.mode)
    steps = mode_steps(system, T)
    gain, P_prior, P_post, whiten = _steady_gains(system, T)
    N, K = traj.mode.shape
    trans = np.concatenate([traj.mode[:, :1], traj.mode[:, :-1]], axis=1)
    x, P, flag = oracle_steady_run(y, np.ones((N, K, 1)), steps.F, steps.G, trans, system.C,
                                   traj.mode, gain, P_prior, P_post, whiten, x0,
                                   np.inf if gate is None else gate)
    assert_close(est.x, x)
    assert_close(est.P, P)
    np.testing.assert_array_equal(est.outlier, flag == GATED)
    if gate is not None:
        assert est.outlier.any()


def test_run_after_the_covariance_reaches_its_fixed_point_matches_the_oracle():
    """A long record in one mode, whose covariance settles to a fixed point (after about 120
    samples here: the kernel then skips the repeated covariance equations), broken after it
    settles by a missing component of one trial, an outlier every trial's gate rejects and a
    change of believed mode: the same filter as the oracle's."""
    system = vehicle_2d(measurement_variance=0.05, process_noise=1e-3)
    T, K, N = 0.5, 480, 3
    t = T * np.arange(K)
    traj = simulate(system, schedule([], [1]), t, (np.zeros(4), np.eye(4)), u=np.ones(1),
                    trials=N, rng=np.random.default_rng(11))
    y = traj.y.copy()
    y[0, 160, 0] = np.nan  # one trial parts from the others' covariance
    y[:, 320] += 1e3  # every trial gates it: the settled covariances are not updated
    modes = np.where(np.arange(K) < 400, 1, 0)  # and then another (mismatched) mode
    est = ModeKalmanFilter(system, np.zeros(4), np.eye(4), gate=25.0).run(
        y, np.ones(1), t, modes=modes)
    for k in (159, 319, 399):  # settled before each event
        assert_close(est.P[:, k], est.P[:, k - 1], rtol=1e-12)
    steps = mode_steps(system, T)
    trans = np.broadcast_to(np.concatenate([[1], modes[:-1]]), (N, K))
    x, P, loglik, flag = oracle_kalman_run(y, np.ones((N, K, 1)), steps.F, steps.G, steps.Qd,
                                           trans, system.C, system.R,
                                           np.broadcast_to(modes, (N, K)), np.zeros(4),
                                           np.eye(4), 25.0)
    assert_close(est.x, x)
    assert_close(est.P, P)
    assert_close(est.loglik, loglik)
    np.testing.assert_array_equal(est.outlier, flag == GATED)
    assert est.outlier[:, 320].all() and not est.outlier[:, :320].any()
