"""Batched exact simulation against moment propagation and looped single-trial oracles."""

import numpy as np
import pytest

from switchest import SwitchedLinearSystem
from switchest import signals as sg
from switchest.discretize import interval
from switchest.simulate import simulate
from switchest.switching import Dwell, MarkovAtSamples


def system(Q=None, R=None):
    A = np.array([[[-0.5, 1.0], [-1.0, -0.2]], [[0.1, 0.0], [0.4, -1.0]]])
    B = np.array([[[0.0], [1.0]], [[1.0], [0.5]]])
    C = np.array([[[1.0, 0.0]], [[0.5, 1.0]]])
    return SwitchedLinearSystem.continuous(A, B, C, Q=Q, R=R)


def test_sample_moments_match_exact_propagation():
    sys = system(Q=np.array([[0.2, 0.05], [0.05, 0.1]]), R=[[0.3]])
    sig = sg.schedule([0.33, 1.07, 1.21], [0, 1, 0, 1])  # switches inside intervals
    t = sg.periodic(0.25, 2.0)
    u = np.sin(t)[:, None]
    m0, P0 = np.array([1.0, -1.0]), np.array([[0.5, 0.1], [0.1, 0.2]])
    N = 20000
    traj = simulate(sys, sig, t, (m0, P0), u=u, trials=N, rng=42)
    m, P = m0.copy(), P0.copy()
    _, modes, offsets = sg.sample_segments([sig], t)
    for k in range(t.size):
        if k:
            tr = interval(sys, t[k] - t[k - 1], modes[0, k - 1], offsets[0, k - 1])
            m = tr.F @ m + tr.G @ u[k - 1]
            P = tr.F @ P @ tr.F.T + tr.Qd
        x = traj.x[:, k]
        se_mean = np.sqrt(np.diag(P) / N)
        assert np.all(np.abs(x.mean(0) - m) < 5 * se_mean), k
        S = np.cov(x.T)
        se_cov = np.sqrt((np.outer(np.diag(P), np.diag(P)) + P**2) / N)
        assert np.all(np.abs(S - P) < 5 * se_cov), k
        mode = sig.at(t[k])
        y_var = sys.C[mode] @ P @ sys.C[mode].T + sys.R[mode]
        resid = traj.y[:, k] - x @ sys.C[mode].T
        assert abs(resid.var() - sys.R[mode][0, 0]) < 5 * sys.R[mode][0, 0] * np.sqrt(2 / N)
        assert abs(traj.y[:, k].var() - y_var[0, 0]) < 5 * y_var[0, 0] * np.sqrt(2 / N)


def test_per_trial_signals_match_a_looped_noise_free_oracle():
    sys = system()
    t = sg.aperiodic(0.2, 0.5, 4.0, rng=0)
    traj = simulate(sys, lambda r: sg.dwell_time(2, 4.0, 0.05, 0.6, rng=r), t, [1.0, 0.0],
                    u=[0.5], trials=6, rng=3)
    assert len({id(s) for s in traj.signals}) == 6
    for n, sig in enumerate(traj.signals):
        x = np.array([1.0, 0.0])
        np.testing.assert_array_equal(traj.mode[n], sig.at(t))
        for k in range(1, t.size):
            times, entered = sig.switches_in(t[k - 1], t[k])
            modes = np.concatenate([[sig.at(t[k - 1])], entered])
            tr = interval(sys, t[k] - t[k - 1], modes, times - t[k - 1])
            x = tr.F @ x + tr.G @ [0.5]
            np.testing.assert_allclose(traj.x[n, k], x, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(traj.y[n, :, 0],
                                   np.einsum("kj,kj->k", sys.C[traj.mode[n], 0], traj.x[n]))


def test_reproducible_from_rng_and_trials_differ():
    sys = system(Q=0.1 * np.eye(2), R=[[0.1]])
    t = sg.periodic(0.1, 1.0)
    gen = lambda r: sg.dwell_time(2, 1.0, 0.15, 0.3, rng=r)  # noqa: E731
    a = simulate(sys, gen, t, np.zeros(2), trials=3, rng=7)
    b = simulate(sys, gen, t, np.zeros(2), trials=3, rng=7)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.y, b.y)
    assert not np.allclose(a.x[0], a.x[1])


@pytest.mark.parametrize("output", ["sampled", "integrated"])
def test_a_switching_model_draws_one_signal_per_trial_as_its_sample_does(output):
    sys = system(Q=0.1 * np.eye(2), R=[[0.1]])
    t = sg.periodic(0.1, 2.0)
    model = Dwell(2, 0.15, 0.4, initial_mode=1)
    a = simulate(sys, model, t, np.zeros(2), trials=4, rng=5, output=output)
    b = simulate(sys, lambda r: model.sample(r, t), t, np.zeros(2), trials=4, rng=5, output=output)
    assert len({id(s) for s in a.signals}) == 4
    for sa, sb in zip(a.signals, b.signals):
        np.testing.assert_allclose(sa.times, sb.times, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(sa.modes, sb.modes)
    np.testing.assert_allclose(a.x, b.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(a.y, b.y, rtol=1e-12, atol=1e-12)


class _Sampler:  # any object with sample(rng, t), not a SwitchingModel
    def sample(self, rng, t):
        return sg.schedule([t[1]], [0, 1])


def test_anything_with_sample_is_a_switching_model():
    t = sg.periodic(0.1, 0.5)
    traj = simulate(system(), _Sampler(), t, np.zeros(2), trials=2, rng=0)
    np.testing.assert_array_equal(traj.mode, [[0, 1, 1, 1, 1, 1]] * 2)


def test_a_sample_that_is_not_a_signal_is_refused():
    bad = type("Bad", (), {"sample": lambda self, rng, t: "abc"})()
    with pytest.raises(TypeError, match=r"signal\.sample\(rng, t\) must return a SwitchingSignal, "
                                        r"got str for trial 0"):
        simulate(system(), bad, sg.periodic(0.1, 0.5), np.zeros(2))


def test_fine_grid_contains_the_samples_and_is_exact():
    sys = system()
    sig = sg.schedule([0.37], [0, 1])
    t = sg.periodic(0.2, 1.0)
    traj = simulate(sys, sig, t, [1.0, 1.0], u=[1.0], trials=2, rng=0, fine_dt=0.03)
    assert traj.x_fine.shape == (2, traj.t_fine.size, 2)
    idx = np.searchsorted(traj.t_fine, t)
    np.testing.assert_allclose(traj.t_fine[idx], t)
    np.testing.assert_allclose(traj.x_fine[:, idx], traj.x, rtol=1e-12)
    assert np.diff(traj.t_fine).max() <= 0.03 + 1e-12
    np.testing.assert_array_equal(traj.mode_fine[0], sig.at(traj.t_fine))
    coarse = simulate(sys, sig, t, [1.0, 1.0], u=[1.0], trials=1, rng=0)
    np.testing.assert_allclose(traj.x[0], coarse.x[0], rtol=1e-11)


def test_discrete_system_recursion():
    A = np.array([[[0.9, 0.2], [0.0, 0.7]], [[0.5, 0.0], [0.3, 1.01]]])
    sys = SwitchedLinearSystem.discrete(A, B=[[1.0], [0.0]], dt=0.5)
    t = 0.5 * np.arange(8)
    sig = sg.markov_at_samples([[0.6, 0.4], [0.3, 0.7]], t, rng=1, initial=0)
    u = np.arange(8.0)[:, None]
    traj = simulate(sys, sig, t, [1.0, 2.0], u=u, rng=0)
    x = np.array([1.0, 2.0])
    for k in range(1, 8):
        x = A[sig.at(t[k - 1])] @ x + np.array([1.0, 0.0]) * u[k - 1, 0]
        np.testing.assert_allclose(traj.x[0, k], x, rtol=1e-13)
    with pytest.raises(ValueError, match="spaced by the discrete system's dt"):
        simulate(sys, sig, np.arange(8.0), [1.0, 2.0])


def test_input_shapes():
    sys = system()
    sig = sg.schedule([], [0])
    t = sg.periodic(0.1, 0.5)
    const = simulate(sys, sig, t, np.zeros(2), u=[2.0], trials=2, rng=0)
    per_k = simulate(sys, sig, t, np.zeros(2), u=np.full((6, 1), 2.0), trials=2, rng=0)
    per_trial = simulate(sys, sig, t, np.zeros(2), u=np.full((2, 6, 1), 2.0), trials=2, rng=0)
    np.testing.assert_array_equal(const.x, per_k.x)
    np.testing.assert_array_equal(const.x, per_trial.x)
    assert const.u.shape == (2, 6, 1)


@pytest.mark.parametrize(
    "kwargs, err, match",
    [
        (dict(u=np.zeros((6, 2))), ValueError, r"u must have shape"),
        (dict(u=[np.nan]), ValueError, "u must be finite"),
        (dict(x0=np.zeros(3)), ValueError, r"x0 must have shape \(n,\)"),
        (dict(x0=(np.zeros(2), -np.eye(2))), ValueError,
         "x0 cov must be symmetric positive semidefinite"),
        (dict(trials=0), ValueError, "trials must be a positive int"),
        (dict(t=[0.0, 0.2, 0.1]), ValueError, "strictly increasing"),
        (dict(signal=sg.schedule([0.1], [0, 2])), ValueError, "signal uses mode 2"),
        (dict(signal=lambda r: 3), TypeError, "must return a SwitchingSignal"),
        (dict(signal="abc"), TypeError, "signal must be a SwitchingSignal"),
        (dict(signal=MarkovAtSamples(np.full((3, 3), 1 / 3))), ValueError, "signal uses mode 2"),
        (dict(fine_dt=-1.0), ValueError, "fine_dt must be a finite positive"),
    ],
)
def test_bad_input(kwargs, err, match):
    args = dict(system=system(), signal=sg.schedule([], [0]), t=sg.periodic(0.1, 0.5),
                x0=np.zeros(2))
    args.update(kwargs)
    with pytest.raises(err, match=match):
        simulate(**args)


def test_integrated_output_has_the_ito_moments():
    """dz = C x dt + dv: for x constant (A = 0, Q = 0), z(T) ~ N(C x T, R T)."""
    sys = SwitchedLinearSystem.continuous(np.zeros((2, 2)), C=[[1.0, 2.0]], R=[[0.3]])
    t = sg.periodic(0.5, 2.0)
    N = 20000
    traj = simulate(sys, sg.schedule([], [0]), t, [1.0, -1.0], trials=N, rng=0, output="integrated",
                    fine_dt=0.25)
    z = traj.y[:, :, 0]
    np.testing.assert_array_equal(z[:, 0], 0.0)
    mean, var = -1.0 * t, 0.3 * t
    assert np.all(np.abs(z.mean(0) - mean) < 5 * np.sqrt(var / N) + 1e-12)
    assert np.all(np.abs(z[:, 1:].var(0) - var[1:]) < 5 * var[1:] * np.sqrt(2 / N))
    np.testing.assert_allclose(traj.y_fine[:, ::2], traj.y)  # the fine grid halves each interval
    inc = np.diff(z, axis=1)  # independent increments
    assert abs(np.corrcoef(inc[:, 0], inc[:, 1])[0, 1]) < 5 / np.sqrt(N)
