"""Filter-specific behaviour: textbook equivalence, the clairvoyant bound, switching-time
estimation and refinement, IMM-EV1 on a clean maneuver."""

import numpy as np
import pytest

from switchest import SwitchedLinearSystem
from switchest import signals as sg
from switchest.discretize import interval, switch_grid
from switchest.estimators import IMMEV1Filter, ModeKalmanFilter, SwitchTimeKalmanFilter
from switchest.estimators.kalman import kf_update
from switchest.estimators.switch_time import SwitchTimeState, switch_time_loglik
from switchest.metrics import rmse, switch_time_error
from switchest.models import boost_converter, boost_switching, vehicle_2d, vehicle_maneuver
from switchest.simulate import simulate


def textbook_kf(A, B, C, Q, R, modes, y, u, x0, P0):
    """x_k|k-1 = A x + B u, P = A P A' + Q; K = P C'(C P C' + R)^-1; standard form."""
    x, P, xs = x0, P0, []
    for k in range(y.shape[0]):
        if k:
            m = modes[k - 1]
            x = A[m] @ x + B[m] @ u[k - 1]
            P = A[m] @ P @ A[m].T + Q[m]
        m = modes[k]
        S = C[m] @ P @ C[m].T + R[m]
        K = P @ C[m].T @ np.linalg.inv(S)
        x = x + K @ (y[k] - C[m] @ x)
        P = (np.eye(len(x)) - K @ C[m]) @ P
        xs.append(x)
    return np.array(xs)


def test_mode_kalman_with_true_modes_is_the_textbook_filter():
    rng = np.random.default_rng(0)
    A = rng.standard_normal((3, 3, 3)) * 0.4
    B = rng.standard_normal((3, 3, 1))
    C = rng.standard_normal((3, 2, 3))
    sys = SwitchedLinearSystem.discrete(A, B, C, Q=0.1 * np.eye(3), R=0.2 * np.eye(2), dt=1.0)
    t = np.arange(30.0)
    P = np.array([[0.7, 0.2, 0.1], [0.1, 0.8, 0.1], [0.3, 0.3, 0.4]])
    traj = simulate(sys, sg.markov_at_samples(P, t, rng=1, initial=2), t, np.ones(3),
                    u=rng.standard_normal((30, 1)), rng=2)
    est = ModeKalmanFilter(sys, np.zeros(3), np.eye(3)).run(traj.y, traj.u[0], t, modes=traj.mode)
    ref = textbook_kf(sys.A, sys.B, sys.C, sys.Q, sys.R, traj.mode[0], traj.y[0], traj.u[0],
                      np.zeros(3), np.eye(3))
    np.testing.assert_allclose(est.x[0], ref, rtol=1e-9, atol=1e-10)


@pytest.fixture(scope="module")
def boost_data():
    system = boost_converter()
    t = sg.periodic(0.5e-3, 0.06)
    traj = simulate(system, lambda r: boost_switching(r, t_end=0.06), t, np.array([0.0, 100.0]),
                    u=np.array([100.0]), trials=12, rng=3)
    return system, t, traj


def test_clairvoyant_filter_is_the_best_on_the_boost_converter(boost_data):
    system, t, traj = boost_data
    x0, P0, u = np.array([0.0, 100.0]), np.diag([100.0, 100.0]), [100.0]
    clair = ModeKalmanFilter(system, x0, P0).run(traj.y, u, t, modes=traj.mode,
                                                 segments=traj.segments())
    grid5 = SwitchTimeKalmanFilter(system, x0, P0, grid=5).run(traj.y, u, t, modes=traj.mode)
    at_samples = ModeKalmanFilter(system, x0, P0).run(traj.y, u, t, modes=traj.mode)
    r = [rmse(e.x, traj.x, start=10).overall for e in (clair, grid5, at_samples)]
    # the clairvoyant error is process-noise sized; the others are dominated by switch-time errors
    assert np.all(r[0] < 0.1 * r[1]) and np.all(r[1] < r[2])


def test_grid_switch_time_and_refinement_on_low_noise_data():
    system = boost_converter(measurement_variance=1e-4, process_noise=1e-6)
    t = sg.periodic(0.5e-3, 0.03)
    traj = simulate(system, lambda r: boost_switching(r, t_end=0.03), t, np.array([0.0, 100.0]),
                    u=np.array([100.0]), trials=4, rng=5)
    x0, P0 = traj.x[0, 0], 1e-6 * np.eye(2)
    true_switch = traj.switch_times()
    grid = SwitchTimeKalmanFilter(system, x0, P0, grid=5).run(traj.y, [100.0], t, modes=traj.mode)
    err_grid = switch_time_error(grid.switch_time, true_switch)
    assert err_grid.size > 40
    # on clean data the right cell is found almost always: the error is then at most half a cell
    assert np.median(err_grid) <= 0.5e-3 / (2 * 5) + 1e-12
    refined = SwitchTimeKalmanFilter(system, x0, P0, grid=5, refine=True).run(traj.y, [100.0], t,
                                                                              modes=traj.mode)
    err_ref = switch_time_error(refined.switch_time, true_switch)
    assert np.median(err_ref) < 0.2 * np.median(err_grid)


def test_refinement_never_lowers_the_likelihood_of_the_chosen_time():
    system = boost_converter()
    rng = np.random.default_rng(2)
    T = 0.5e-3
    x = np.array([5.0, 110.0]) + rng.standard_normal((6, 2))
    P = np.broadcast_to(np.diag([4.0, 4.0]), (6, 2, 2)).copy()
    y = rng.normal(110.0, 3.0, (6, 1))
    u = np.full((6, 1), 100.0)
    prev, mode = np.zeros(6, int), np.ones(6, int)
    for refine in (False, True):
        f = SwitchTimeKalmanFilter(system, np.zeros(2), np.eye(2), grid=3, refine=refine)
        tau, (F, G, Qd) = f._estimate(x, P, y, u, prev, mode, T)
        tr = interval(system, T, np.stack([prev, mode], 1), tau[:, None])
        np.testing.assert_allclose(F, tr.F, rtol=1e-12)
        xp = np.einsum("nij,nj->ni", F, x) + G[..., 0] * 100.0
        Pp = F @ P @ np.swapaxes(F, 1, 2) + Qd
        ll = switch_time_loglik(xp, Pp, y, system.C[mode], system.R[mode])
        if not refine:
            grid_ll = ll
            assert np.all(np.isin(tau, switch_grid(T, 3)))
        else:
            assert np.all(ll >= grid_ll - 1e-9)


def test_marginal_switch_time_step_is_the_moment_matched_posterior_mixture():
    # oracle: one textbook Kalman prediction and update per grid instant, weights
    # p(y | tau_i) / sum, merged by their definition (mean, covariance of the mixture), likelihood
    # the grid mean
    system = boost_converter()
    T, g, u0 = 0.5e-3, 4, 100.0
    rng = np.random.default_rng(8)
    x, P = np.array([5.0, 110.0]) + rng.standard_normal(2), np.diag([4.0, 9.0])
    y = np.array([113.0])
    f = SwitchTimeKalmanFilter(system, np.zeros(2), np.eye(2), grid=g, switch_time="marginal")
    prior = SwitchTimeState(x[None], P[None], np.zeros(1), np.full(1, np.nan), np.zeros(1, bool))
    state = f.step(prior, y[None], np.array([[u0]]), dt=T, mode=np.array([1]),
                   prev_mode=np.array([0]))
    tau = switch_grid(T, g)
    C, R = system.C[1], system.R[1]
    means, covs, lik = [], [], []
    for k in range(g):
        tr = interval(system, T, np.array([0, 1]), np.array([tau[k]]))
        xp, Pp = tr.F @ x + tr.G[:, 0] * u0, tr.F @ P @ tr.F.T + tr.Qd
        S = C @ Pp @ C.T + R
        K = Pp @ C.T @ np.linalg.inv(S)
        e = y - C @ xp
        means.append(xp + K @ e)
        covs.append((np.eye(2) - K @ C) @ Pp)
        lik.append(np.exp(-0.5 * e @ np.linalg.solve(S, e)) / np.sqrt(np.linalg.det(2 * np.pi * S)))
    w = np.array(lik) / np.sum(lik)
    mean = w @ np.array(means)
    cov = sum(w[k] * (covs[k] + np.outer(means[k] - mean, means[k] - mean)) for k in range(g))
    np.testing.assert_allclose(state.x[0], mean, rtol=1e-10)
    np.testing.assert_allclose(state.P[0], cov, rtol=1e-8)
    np.testing.assert_allclose(state.loglik[0], np.log(np.mean(lik)), rtol=1e-10)
    np.testing.assert_allclose(state.switch_offset[0], w @ tau, rtol=1e-12)


def test_marginal_switch_time_equals_the_grid_maximum_with_one_instant(boost_data):
    system, t, traj = boost_data
    x0, P0, u = np.array([0.0, 100.0]), np.diag([100.0, 100.0]), [100.0]
    runs = [SwitchTimeKalmanFilter(system, x0, P0, grid=1, switch_time=how).run(traj.y, u, t,
                                                                                modes=traj.mode)
            for how in ("max", "marginal")]
    np.testing.assert_allclose(runs[1].x, runs[0].x, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(runs[1].P, runs[0].P, rtol=1e-10, atol=1e-10)
    np.testing.assert_array_equal(np.isnan(runs[1].switch_time), np.isnan(runs[0].switch_time))


def test_marginal_switch_time_beats_the_grid_maximum_on_the_boost_converter(boost_data):
    # Table I's setting (R = 5 V^2): one sample weighs the candidate instants better than it picks
    # one. Paired per-trial comparison of the mean squared error of v_0 at g = 5 over 12 trials:
    # the mean improvement must exceed 3 standard errors of the paired differences.
    system, t, traj = boost_data
    x0, P0, u = np.array([0.0, 100.0]), np.diag([100.0, 100.0]), [100.0]
    mse = []
    for how in ("max", "marginal"):
        filt = SwitchTimeKalmanFilter(system, x0, P0, grid=5, switch_time=how)
        est = filt.run(traj.y, u, t, modes=traj.mode)
        mse.append(np.mean((est.x[:, 10:, 1] - traj.x[:, 10:, 1]) ** 2, axis=1))
    gain = mse[0] - mse[1]
    assert gain.mean() > 3 * gain.std(ddof=1) / np.sqrt(gain.size)


def test_marginal_switch_time_refuses_refine_and_the_printed_likelihood():
    system = boost_converter()
    with pytest.raises(ValueError, match="switch_time must be 'max' or 'marginal'"):
        SwitchTimeKalmanFilter(system, np.zeros(2), np.eye(2), switch_time="mean")
    for bad in ({"refine": True}, {"likelihood": "printed"}):
        with pytest.raises(ValueError, match="likelihood='innovation' and refine=False"):
            SwitchTimeKalmanFilter(system, np.zeros(2), np.eye(2), switch_time="marginal", **bad)


def test_imm_ev1_first_step_is_the_brute_force_best_path():
    """After one prediction, destination i holds max_{j, tau} p0_j L_0(j) L_1(i | j, tau)."""
    system = vehicle_2d(measurement_variance=1e-2, process_noise=1e-2)
    rng = np.random.default_rng(4)
    y = rng.normal(0.0, 0.3, (2, 2))
    u, T, g = np.array([3.0]), 0.5, 4
    transition = np.array([[0.8, 0.15, 0.05], [0.1, 0.7, 0.2], [0.3, 0.3, 0.4]])
    f = IMMEV1Filter(system, transition, x0=np.zeros(4), P0=np.eye(4), grid=g, epsilon=1e-3)
    state = f.step(f.init((1,)), y[None, 0], dt=None)
    state = f.step(state, y[None, 1], u[None], dt=T)
    best = np.full(3, -np.inf)
    for i in range(3):
        for j in range(3):
            x0, P0, ll0 = kf_update(np.zeros(4), np.eye(4), y[0], system.C[j], system.R[j])
            taus = [None] if i == j else switch_grid(T, g)
            for tau in taus:
                tr = interval(system, T, [j] if tau is None else [j, i],
                              [] if tau is None else [tau])
                xp = tr.F @ x0 + tr.G @ u
                Pp = tr.F @ P0 @ tr.F.T + tr.Qd + 1e-3 * np.eye(4)
                x1, P1, ll1 = kf_update(xp, Pp, y[1], system.C[i], system.R[i])
                score = np.log(1 / 3) + ll0 + ll1 + np.log(transition[j, i])
                if score > best[i]:
                    best[i], x_best = score, x1
        np.testing.assert_allclose(state.x[0, i], x_best, rtol=1e-9, atol=1e-12)
    expected = np.exp(best - best.max()) / np.exp(best - best.max()).sum()
    np.testing.assert_allclose(np.exp(state.log_weight[0]), expected, rtol=1e-9)


def test_imm_ev1_switch_times_fall_in_their_intervals_on_the_maneuver():
    man = vehicle_maneuver()
    system = vehicle_2d()
    traj = simulate(system, man.signal, man.t, np.zeros(4), u=man.u, trials=5, rng=0)
    est = IMMEV1Filter(system, x0=np.zeros(4), P0=0.1 * np.eye(4), grid=5).run(traj.y, man.u, man.t)
    for n, k in np.argwhere(np.isfinite(est.switch_time)):
        assert man.t[k - 1] < est.switch_time[n, k] < man.t[k]
    np.testing.assert_allclose(est.mode_prob.sum(-1), 1.0, rtol=1e-12)


def test_marginal_switch_time_variant_runs_and_weights_sum_to_one():
    man = vehicle_maneuver()
    system = vehicle_2d()
    traj = simulate(system, man.signal, man.t, np.zeros(4), u=man.u, trials=3, rng=1)
    est = IMMEV1Filter(system, x0=np.zeros(4), P0=np.eye(4), grid=4, switch_time="marginal").run(
        traj.y, man.u, man.t)
    np.testing.assert_allclose(est.mode_prob.sum(-1), 1.0, rtol=1e-12)
    finite = est.switch_time[np.isfinite(est.switch_time)]
    k = np.searchsorted(man.t, finite)  # each estimate lies inside its own interval
    assert np.all((finite > man.t[k - 1]) & (finite < man.t[k]))


def test_steady_state_filter_keeps_no_state_between_runs():
    # a run at T = 1 ms after one at T = 0.5 ms gives what a fresh filter gives (the gains of the
    # first period used to be reused at the next run's first sample)
    system = boost_converter()
    x0, P0, u = np.zeros(2), np.eye(2), [30.0]
    runs = {}
    for T in (0.5e-3, 1e-3):
        t = sg.periodic(T, 40 * T)
        traj = simulate(system, lambda r, t=t, T=T: sg.dwell_time(2, t[-1], 3 * T, 6 * T, rng=r),
                        t, x0, u=u, trials=2, rng=0)
        runs[T] = (t, traj)
    t, traj = runs[1e-3]
    fresh = ModeKalmanFilter(system, x0, P0, steady_state=True).run(traj.y, u, t, modes=traj.mode)
    reused = ModeKalmanFilter(system, x0, P0, steady_state=True)
    t_other, other = runs[0.5e-3]
    reused.run(other.y, u, t_other, modes=other.mode)
    again = reused.run(traj.y, u, t, modes=traj.mode)
    # same computation on the same input in one process: equal to rounding (a few ulps)
    np.testing.assert_allclose(again.P, fresh.P, rtol=1e-14, atol=0)
    np.testing.assert_allclose(again.x, fresh.x, rtol=1e-14, atol=1e-12)


def test_steady_state_step_needs_the_period_at_a_first_sample():
    f = ModeKalmanFilter(boost_converter(), np.zeros(2), np.eye(2), steady_state=True)
    with pytest.raises(ValueError, match="needs the sampling period at the first sample"):
        f.step(f.init((1,)), np.zeros((1, 1)), dt=None, mode=np.zeros(1, int))
    state = f.step(f.init((1,)), np.zeros((1, 1)), dt=None, mode=np.zeros(1, int), period=1e-3)
    assert np.all(np.isfinite(state.P))
