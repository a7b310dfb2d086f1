"""RSLSObserver (Wang et al., seed 003 §3): the subsystem observer fed the integrated Ito output.

Oracles: the exact sampled error system of Theorem 1 (switchest.analysis.subsystem_observers) for
noise-free runs, the exact second-moment recursion and its steady state (§5.1) for Monte
Carlo runs (tolerances from the trial count), and the sample covariance for the reported P.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from switchest import SwitchedLinearSystem
from switchest.analysis.subsystem_observers import (
    error_dynamics,
    kalman_bucy_gains,
    place_gains,
    second_moments,
    steady_state,
    subsystem_structure,
)
from switchest.estimators.rsls import RSLSObserver, fine_step_error_system
from switchest.models.wang import (
    IEEE_5BUS_INITIAL_ERROR,
    IEEE_5BUS_POLES,
    IEEE_5BUS_SAMPLE_PERIOD,
    ieee_5bus,
    ieee_5bus_mode_probabilities,
    wang_scalar_pair,
)
from switchest.signals import iid_at_samples
from switchest.simulate import simulate

A1, A2, P, ZETA = 2.0, 4.0, 0.2, 0.01  # Wang et al. Examples 1, 2, 4
PROB = np.array([P, 1 - P])
SYS = wang_scalar_pair(A1, A2, ZETA)
X0, XHAT0 = np.array([1.0, 1.0]), np.array([1.5, 0.5])
N_MC = 400


def scalar_gains(L1, L2):
    return np.array([[[L1], [0.0]], [[0.0], [L2]]])


def observe(system, gains, T, K, *, trials, seed, sub, x0=X0, xhat0=XHAT0, p=PROB, P0=None):
    """Simulate the Ito output exactly on a fine grid, run the observer, return errors at kT."""
    t = T * np.arange(K + 1)
    traj = simulate(
        system,
        lambda r: iid_at_samples(p, t, rng=r),
        t,
        x0,
        trials=trials,
        rng=seed,
        fine_dt=T / sub,
        output="integrated",
    )
    n = system.n_states
    obs = RSLSObserver(system, gains, T, xhat0, np.zeros((n, n)) if P0 is None else P0)
    est = obs.run(traj.y_fine, t=traj.t_fine, modes=traj.mode_fine)
    samples = np.searchsorted(traj.t_fine, t)
    return est.x[:, samples] - traj.x, traj, est


def exact_moments(system, gains, T, K, p=PROB, x0=X0, xhat0=XHAT0):
    dyn = error_dynamics(system, gains, T)
    e0 = dyn.structure.F @ (xhat0 - x0)
    return dyn, second_moments(dyn, p, np.outer(e0, e0), K)


# ---------------------------------------------------------------- noise-free: Theorem 1 exactly
def noise_free_errors(sub):
    nf = SwitchedLinearSystem.continuous(SYS.A, C=SYS.C)
    gains = scalar_gains(40.0, 15.0)
    err, traj, _ = observe(nf, gains, 0.03, 40, trials=3, seed=1, sub=sub)
    dyn = error_dynamics(nf, gains, 0.03)
    e = np.broadcast_to(dyn.structure.F @ (XHAT0 - X0), (3, 2))
    pred = [e]
    for k in range(40):
        e = np.einsum("nij,nj->ni", dyn.Lam[traj.mode[:, k]], e)
        pred.append(e)
    pred = np.stack(pred, axis=1) @ dyn.structure.Phi.T
    assert np.abs(traj.x).max() > 100  # the state grows; the error does not follow it
    return np.max(np.abs(err - pred)) / np.max(np.abs(pred))


def test_noise_free_error_follows_the_sampled_error_system_to_second_order():
    coarse, fine = noise_free_errors(10), noise_free_errors(20)
    assert fine < 2e-4
    assert 3.0 < coarse / fine < 5.0  # O(h^2): halving the fine step divides the error by 4


def test_noise_free_5bus_multi_output_and_lost_channels():
    bus = ieee_5bus()
    nf = SwitchedLinearSystem.continuous(bus.A, C=bus.C)
    p = np.array([0.4, 0.25, 0.25, 0.1])  # visit every mode in a short run
    gains = place_gains(subsystem_structure(nf), [IEEE_5BUS_POLES] * 3 + [None])
    T, K = 0.2, 6
    x0 = np.array([0.1, 0.0, -0.1, 0.05])
    err, traj, _ = observe(
        nf,
        gains,
        T,
        K,
        trials=4,
        seed=3,
        sub=100,
        x0=x0,
        xhat0=x0 + np.array(IEEE_5BUS_INITIAL_ERROR),
        p=p,
    )
    dyn = error_dynamics(nf, gains, T)
    e = np.broadcast_to(np.array(IEEE_5BUS_INITIAL_ERROR), (4, 4))
    pred = [e]
    for k in range(K):
        e = np.einsum("nij,nj->ni", dyn.Lam[traj.mode[:, k]], e)
        pred.append(e)
    assert len(np.unique(traj.mode[:, :K])) == 4
    np.testing.assert_allclose(err, np.stack(pred, axis=1), rtol=0, atol=2e-3 * np.abs(pred).max())


# ---------------------------------------------------------------- the fine-step error system
def test_fine_step_error_system_of_the_scalar_pair_in_closed_form():
    """Per fine step h the closed component's error is multiplied by
    g = e^{ah} - K_h Psi_h, K_h = L (e^{(a-L)h} - 1) / ((a-L) h), Psi_h = (e^{ah} - 1) / a, and
    receives K_h^2 zeta h of noise; the open component follows e^{aT}."""
    L1, L2, T, sub = 40.0, 15.0, 0.03, 20
    Lam, W = fine_step_error_system(SYS, scalar_gains(L1, L2), T, sub)
    h = T / sub
    for mode, (a, L) in enumerate(((A1, L1), (A2, L2))):
        K = L * np.expm1((a - L) * h) / ((a - L) * h)
        g = np.exp(a * h) - K * np.expm1(a * h) / a
        closed = np.zeros((2, 2))
        closed[mode, mode] = g**sub
        other = 1 - mode
        closed[other, other] = np.exp((A1, A2)[other] * T)
        np.testing.assert_allclose(Lam[mode], closed, rtol=1e-11, atol=0)
        noise = np.zeros((2, 2))
        noise[mode, mode] = K**2 * ZETA * h * np.sum(g ** (2 * np.arange(sub)))
        np.testing.assert_allclose(W[mode], noise, rtol=1e-11, atol=1e-20)


def test_fine_step_error_system_tends_to_theorem_1_at_second_order():
    """The 5-bus observer (multi-output mode 1, shared 4-dimensional sub-state): the fine-step
    maps and noise approach Theorem 1's Lambda(i) and W(i) with an O(h^2) gap."""
    bus, T = ieee_5bus(), IEEE_5BUS_SAMPLE_PERIOD
    gains = place_gains(subsystem_structure(bus), [IEEE_5BUS_POLES] * 3 + [None])
    dyn = error_dynamics(bus, gains, T)
    F, Phi = dyn.structure.F, dyn.structure.Phi
    gaps = []
    for sub in (40, 80):
        Lam, W = fine_step_error_system(bus, gains, T, sub)
        gaps.append((np.abs(Lam - Phi @ dyn.Lam @ F).max(), np.abs(W - Phi @ dyn.W @ Phi.T).max()))
    (lam40, w40), (lam80, w80) = gaps
    assert lam80 < 1e-2 * np.abs(dyn.Lam).max() and w80 < 1e-2 * np.abs(dyn.W).max()
    assert 3.5 < lam40 / lam80 < 5.0 and 3.5 < w40 / w80 < 5.0  # 4.15, 4.43


def test_sample_errors_follow_the_fine_step_error_system_exactly():
    """Noise free, the errors at kT are products of the fine-step maps along each run's modes."""
    nf = SwitchedLinearSystem.continuous(SYS.A, C=SYS.C)
    gains, T, K, sub = scalar_gains(40.0, 15.0), 0.03, 30, 10
    t = T * np.arange(K + 1)
    traj = simulate(nf, lambda r: iid_at_samples(PROB, t, rng=r), t, X0, trials=3, rng=11,
                    fine_dt=T / sub, output="integrated")
    err = RSLSObserver(nf, gains, T, XHAT0, np.zeros((2, 2))).sample_errors(traj)
    Lam, W = fine_step_error_system(nf, gains, T, sub)
    assert np.all(W == 0.0)
    e = np.broadcast_to(XHAT0 - X0, (3, 2))
    pred = [e]
    for k in range(K):
        e = np.einsum("nij,nj->ni", Lam[traj.mode[:, k]], e)
        pred.append(e)
    assert err.shape == (3, K + 1, 2) and len(np.unique(traj.mode[:, :K])) == 2
    np.testing.assert_allclose(err, np.stack(pred, axis=1), rtol=0,
                               atol=1e-12 * np.abs(XHAT0 - X0).max())


def test_fine_step_error_system_and_sample_errors_refuse_what_they_cannot_do():
    stacked = wang_scalar_pair(A1, A2, ZETA)
    with pytest.raises(TypeError, match="system must be a SwitchedLinearSystem"):
        fine_step_error_system("sys", scalar_gains(40.0, 15.0), 0.03, 10)
    with pytest.raises(ValueError, match="substeps must be a positive int"):
        fine_step_error_system(stacked, scalar_gains(40.0, 15.0), 0.03, 0)
    # mode 1 observes the whole state, mode 2 only x_2: three sub-states for two states
    nested = SwitchedLinearSystem.continuous(SYS.A, C=[[[1.0, 1.0]], [[0.0, 1.0]]], R=SYS.R)
    with pytest.raises(ValueError, match=r"one sub-state per state \(n_s = n\), got n_s = 3"):
        fine_step_error_system(nested, np.zeros((2, 2, 1)), 0.03, 10)
    t = 0.03 * np.arange(4)
    coarse = simulate(stacked, lambda r: iid_at_samples(PROB, t, rng=r), t, X0, trials=2, rng=0)
    observer = RSLSObserver(stacked, scalar_gains(40.0, 15.0), 0.03, XHAT0, np.eye(2))
    with pytest.raises(ValueError, match="integrated output on a fine grid"):
        observer.sample_errors(coarse)


# ---------------------------------------------------------------- Monte Carlo, 400 runs
def test_ms_error_converges_to_the_steady_state():
    """Example 2's design L = (40, 15), T = 0.03: sample MS error vs eq. (21) (corrected)."""
    gains, T, K = scalar_gains(40.0, 15.0), 0.03, 100
    err, _, _ = observe(SYS, gains, T, K, trials=N_MC, seed=0, sub=20)
    dyn, V = exact_moments(SYS, gains, T, K)
    sq = np.sum(err**2, axis=-1)
    exact = np.trace(V, axis1=1, axis2=2)
    for k in (10, 30):  # transient, sample by sample
        se = sq[:, k].std(ddof=1) / np.sqrt(N_MC)
        assert abs(sq[:, k].mean() - exact[k]) < 4 * se
    window = slice(60, K + 1)  # steady state: per-trial time averages are i.i.d. over trials
    per_trial = sq[:, window].mean(axis=1)
    se = per_trial.std(ddof=1) / np.sqrt(N_MC)
    mu = steady_state(dyn, PROB).mu
    assert exact[window].mean() == pytest.approx(mu, rel=5e-3)
    assert abs(per_trial.mean() - mu) < 4 * se
    assert se < 0.1 * mu  # the check has power


def test_ms_error_diverges_above_the_critical_interval():
    """Example 2, Fig. 3: the same gains with T = 0.25 > T_max = 0.0558."""
    gains, T, K = scalar_gains(40.0, 15.0), 0.25, 12
    err, _, _ = observe(SYS, gains, T, K, trials=N_MC, seed=2, sub=20)
    _, V = exact_moments(SYS, gains, T, K)
    sq = np.sum(err**2, axis=-1)
    exact = np.trace(V, axis1=1, axis2=2)
    assert exact[K] > 1000 * exact[0]
    se = sq[:, K].std(ddof=1) / np.sqrt(N_MC)
    assert abs(sq[:, K].mean() - exact[K]) < 5 * se  # heavy-tailed: 5 standard errors
    assert sq[:, K].mean() > 1000 * sq[:, 0].mean()


def test_kalman_bucy_design_diverges_in_mean_square():
    """Example 1, Fig. 1: gains 2 a_i, T = 0.03; e^1 diverges (1.0794 per step), e^2 converges."""
    gains, T, K = kalman_bucy_gains(SYS), 0.03, 100
    err, _, _ = observe(SYS, gains, T, K, trials=N_MC, seed=4, sub=20)
    dyn, V = exact_moments(SYS, gains, T, K)
    F = dyn.structure.F  # |F| = I: component i of the state error is +-e^i
    sq = (err @ F.T) ** 2
    for c in (0, 1):
        se = sq[:, K, c].std(ddof=1) / np.sqrt(N_MC)
        assert abs(sq[:, K, c].mean() - V[K, c, c]) < 4 * se
    assert sq[:, K, 0].mean() > 500 * sq[:, 0, 0].mean()  # 1.0794^100 ~ 2000
    assert sq[:, K, 1].mean() < sq[:, 0, 1].mean()


def test_reported_P_is_the_error_covariance_given_the_modes():
    """One switching path for all trials, x0 ~ N(x_hat0, P0): P = sample covariance of the error."""
    T, K = 0.03, 30
    t = T * np.arange(K + 1)
    signal = iid_at_samples(PROB, t, rng=7)
    P0 = np.diag([0.3, 0.2])
    traj = simulate(
        SYS, signal, t, (XHAT0, P0), trials=N_MC, rng=8, fine_dt=T / 10, output="integrated"
    )
    est = RSLSObserver(SYS, scalar_gains(40.0, 15.0), T, XHAT0, P0).run(
        traj.y_fine, t=traj.t_fine, modes=traj.mode_fine
    )
    np.testing.assert_allclose(est.P, np.broadcast_to(est.P[:1], est.P.shape), rtol=1e-12)
    for j in (0, 7, 150, traj.t_fine.size - 1):  # includes instants inside intervals
        e = est.x[:, j] - traj.x_fine[:, j]
        sample = e.T @ e / N_MC  # the error mean is zero
        var = np.diag(est.P[0, j])
        assert np.all(np.abs(np.diag(sample) - var) < 4 * np.sqrt(2 / N_MC) * var)


# ---------------------------------------------------------------- protocol
def test_batched_equals_looped_and_single_trajectory():
    gains = scalar_gains(40.0, 15.0)
    _, traj, _ = observe(SYS, gains, 0.03, 8, trials=3, seed=5, sub=5)
    obs = RSLSObserver(SYS, gains, 0.03, XHAT0, 0.1 * np.eye(2))
    batch = obs.run(traj.y_fine, t=traj.t_fine, modes=traj.mode_fine)
    for n in range(3):
        one = obs.run(traj.y_fine[n], t=traj.t_fine, modes=traj.mode_fine[n])
        assert one.x.shape == (traj.t_fine.size, 2) and one.P.shape == (traj.t_fine.size, 2, 2)
        np.testing.assert_allclose(one.x, batch.x[n], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(one.P, batch.P[n], rtol=1e-12, atol=1e-14)
    stacked = RSLSObserver(SYS, gains, 0.03, XHAT0, 0.1 * np.eye(2), shared=False)
    # the same sub-observers, built and indexed another way: a few ulps of rounding per fine
    # step may differ (order of 2-term sums, FMA or not), carried without growth by the
    # contracting observer over its K steps
    K = traj.t_fine.size
    np.testing.assert_allclose(
        stacked.run(traj.y_fine, t=traj.t_fine, modes=traj.mode_fine).x, batch.x,
        rtol=4 * K * np.finfo(float).eps, atol=4 * K * np.finfo(float).eps * np.abs(batch.x).max(),
    )
    np.testing.assert_array_equal(batch.x[:, 0], np.broadcast_to(XHAT0, (3, 2)))


def test_missing_samples_skip_the_correction():
    gains = scalar_gains(40.0, 15.0)
    _, traj, est = observe(SYS, gains, 0.03, 8, trials=2, seed=6, sub=5)
    y = traj.y_fine.copy()
    y[:, 7] = np.nan
    obs = RSLSObserver(SYS, gains, 0.03, XHAT0, np.eye(2))
    holed = obs.run(y, t=traj.t_fine, modes=traj.mode_fine)
    assert np.all(np.isfinite(holed.x)) and np.all(np.isfinite(holed.P))
    np.testing.assert_array_equal(holed.x[:, :7], est.x[:, :7])
    assert np.all(np.any(holed.x[:, 7] != est.x[:, 7], axis=-1))  # the closed-loop block differs
    # no output at all: the observer runs open loop, as with zero gains
    blind = obs.run(np.full_like(y, np.nan), t=traj.t_fine, modes=traj.mode_fine)
    zero = RSLSObserver(SYS, np.zeros((2, 2, 1)), 0.03, XHAT0, np.eye(2)).run(
        traj.y_fine, t=traj.t_fine, modes=traj.mode_fine
    )
    np.testing.assert_allclose(blind.x, zero.x, rtol=1e-12)
    np.testing.assert_allclose(blind.P, zero.P, rtol=1e-12)


def test_bad_input():
    gains = scalar_gains(40.0, 15.0)
    obs = RSLSObserver(SYS, gains, 0.03, XHAT0, np.eye(2))
    t = np.linspace(0.0, 0.09, 10)
    y = np.zeros((10, 1))
    with pytest.raises(ValueError, match="u must be None"):
        obs.run(y, np.zeros(0), t, modes=np.zeros(10, dtype=int))
    modes = np.zeros(10, dtype=int)
    modes[4] = 1  # a switch inside [0.03, 0.06)
    with pytest.raises(ValueError, match=r"modes must be constant on each switching interval"):
        obs.run(y, t=t, modes=modes)
    with pytest.raises(ValueError, match="the fine grid must contain every switching instant"):
        obs.run(np.zeros((3, 1)), t=[0.0, 0.02, 0.04], modes=[0, 0, 0])
    with pytest.raises(ValueError, match=r"modes must be in 0..1, got 2..2"):
        obs.run(y, t=t, modes=np.full(10, 2))
    with pytest.raises(ValueError, match=r"gains must have shape \(L, n, m\) = \(2, 2, 1\)"):
        RSLSObserver(SYS, np.zeros((2, 2, 2)), 0.03, XHAT0, np.eye(2))
    with pytest.raises(ValueError, match="T must be a finite positive number"):
        RSLSObserver(SYS, gains, 0.0, XHAT0, np.eye(2))
    with pytest.raises(TypeError, match="system must be a SwitchedLinearSystem"):
        RSLSObserver("sys", gains, 0.03, XHAT0, np.eye(2))
    with pytest.raises(ValueError, match=r"x0 must have shape \(n,\) = \(2,\)"):
        RSLSObserver(SYS, gains, 0.03, np.zeros(3), np.eye(2))


def test_5bus_short_monte_carlo_matches_the_exact_second_moment():
    """The shared 4-state observer of §6 (T = 0.6997), 400 runs over 3 intervals (small version of
    examples/wang_ieee5bus.py). Mode 4 (p_4 = 5e-5, open loop, ||e^{AT}||^2 ~ 1.4e4) contributes
    about 40% of the exact MS error through events that 400 runs of 3 intervals almost never
    see; the runs are compared with the moments conditional on no mode-4 event (i.i.d. modes
    with probabilities p_i / (1 - p_4))."""
    bus, p = ieee_5bus(), ieee_5bus_mode_probabilities()
    gains = place_gains(subsystem_structure(bus), [IEEE_5BUS_POLES] * 3 + [None])
    T, K = IEEE_5BUS_SAMPLE_PERIOD, 3
    x0 = np.zeros(4)
    xhat0 = np.array(IEEE_5BUS_INITIAL_ERROR)
    err, traj, _ = observe(bus, gains, T, K, trials=N_MC, seed=9, sub=40, x0=x0, xhat0=xhat0, p=p)
    no_blind = np.append(p[:3], 0.0) / p[:3].sum()
    _, V = exact_moments(bus, gains, T, K, p=no_blind, x0=x0, xhat0=xhat0)
    _, V_all = exact_moments(bus, gains, T, K, p=p, x0=x0, xhat0=xhat0)
    assert np.trace(V_all[K]) > 1.2 * np.trace(V[K])
    sq = np.sum(err**2, axis=-1)
    assert np.all(traj.mode[:, :K] != 3)
    for k in range(1, K + 1):
        se = sq[:, k].std(ddof=1) / np.sqrt(N_MC)
        assert abs(sq[:, k].mean() - np.trace(V[k])) < 4 * se


def test_example_script_runs_small(capsys):
    """examples/wang_ieee5bus.py at small size (the full 400-run study is run by hand)."""
    path = Path(__file__).parents[2] / "examples" / "wang_ieee5bus.py"
    spec = importlib.util.spec_from_file_location("wang_ieee5bus", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    res = module.main(trials=20, intervals=3, substeps=10, seed=0)
    out = capsys.readouterr().out
    assert "T_max" in out and "aggressive design" in out
    assert abs(res["T_max"] - 0.7365) < 1e-4
    for name in ("first", "aggressive"):
        assert res[name]["mc_mean"].shape == res[name]["exact"].shape == (4,)
        assert res[name]["mc_mean"][0] == pytest.approx(5.0)  # ||e(0)||^2 = 2.2361^2
        assert res[name]["radius"] < 0.08
