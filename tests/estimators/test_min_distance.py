"""Lee, Ping & Shim (002): minimum-distance mode estimation and switching detection.

Oracles: ODE integration with ``scipy.integrate.solve_ivp`` (one smooth piece per
grid interval) for the exact step, for (7) and for the literal replay (15)-(16)
of the paper; composite Simpson with ``scipy.linalg.expm`` for the noise term of
(10); the paper's Theorems 1 and 2 on the demonstration scenario
(:data:`switchest.models.lee.LEE_SCENARIO`), whose assumptions hold
(tests/analysis/test_min_distance_design.py). The only approximation is the first-order hold of
the output between grid points: the smooth output departs from it by at most
``EPS = h^2/8 max|y''|``, which enters every estimate like noise of that size
(Theorem 1: ``|X* - x - w| <= M_max EPS``).
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from switchest import SwitchedLinearSystem
from switchest.analysis.min_distance_design import default_observer_gains, lee_assumptions
from switchest.discretize import mode_steps
from switchest.estimators.min_distance import (
    MinimumDistanceDetector,
    augmented_system,
    exact_step,
    match_detections,
)
from switchest.models.lee import LEE_SCENARIO
from switchest.signals import schedule
from switchest.simulate import simulate

S = LEE_SCENARIO
H = 0.0025  # grid step: delta = 100 H, Delta = 400 H
N_DELTA = round(S.delta / H)
W_MAX = max(S.omega)
X_MAX = np.hypot(*S.x0) + S.input_gain * S.u_max * S.horizon  # |x(t)| <= |x0| + ||b|| u_max t
# |y - FOH(y)|, y'' = A(Ax + bu)
EPS = H**2 / 8 * (W_MAX**2 * X_MAX + W_MAX * S.input_gain * S.u_max)

# a general system (non-normal, one output) for the kernels
A_GEN = np.array([[[-0.4, 1.0], [-1.0, -0.3]], [[-0.1, 0.0], [0.5, -1.2]]])
B_GEN = np.array([[[0.0], [1.0]], [[1.0], [0.0]]])
GEN = SwitchedLinearSystem.continuous(A_GEN, B_GEN, [[1.0, 0.2]])


def detector(v_max=S.v_max, system=None, **kw):
    return MinimumDistanceDetector(S.system() if system is None else system, delta=S.delta,
                                   Delta=S.Delta, v_max=v_max, u_max=S.u_max,
                                   observer_gains=S.observer_gains, **kw)


def scenario(trials, seed, *, signal=None, horizon=S.horizon, noise=S.v_max - EPS):
    """Exact states on the grid, the input, the true signals and bounded noise ``|v| <= noise``."""
    sys = S.system()
    t = H * np.arange(round(horizon / H) + 1)
    rng = np.random.default_rng(seed)
    u = S.input(t, trials, rng)
    traj = simulate(sys, S.signal if signal is None else signal, t, np.array(S.x0), u,
                    trials=trials, rng=rng)
    v = S.noise(t, trials, rng, v_max=noise)
    return t, u, traj, v


def piecewise_ode(rhs, z0, t, y, u):
    """Integrate ``z' = rhs(s, z, y(s), u_k)`` over the grid ``t`` one interval at a time
    (``y`` linear, ``u`` held: each piece is smooth)."""
    z = np.asarray(z0, dtype=float)
    for k in range(t.size - 1):
        slope = (y[k + 1] - y[k]) / (t[k + 1] - t[k])

        def piece(s, w, k=k, slope=slope):
            return rhs(s, w, y[k] + slope * (s - t[k]), u[k])

        sol = solve_ivp(piece, (t[k], t[k + 1]), z, method="DOP853", rtol=1e-12, atol=1e-14)
        z = sol.y[:, -1]
    return z


def noise_term(v, t0_index, A):
    """Oracle for (10): ``U^{-1} int phi' v``, ``C = I``, ``U = delta I`` (Simpson, scipy expm)."""
    s = H * np.arange(N_DELTA + 1)
    mid = s[:-1] + H / 2
    seg = v[t0_index : t0_index + N_DELTA + 1]

    def f(tau, val):
        return np.einsum("kij,kj->ki", expm(np.swapaxes(A * tau[:, None, None], 1, 2)), val)

    ends, middle = f(s, seg), f(mid, 0.5 * (seg[:-1] + seg[1:]))
    integral = (H / 6) * (ends[:-1] + 4 * middle + ends[1:]).sum(axis=0)
    return integral / S.delta


# ---------------------------------------------------------------------- kernels
def test_exact_step_integrates_12_13_19_and_16_exactly():
    gains = default_observer_gains(GEN)
    h = 0.3
    rng = np.random.default_rng(0)
    core, u = rng.normal(size=(2, 6)), rng.normal(size=1)
    y0, y1 = rng.normal(size=1), rng.normal(size=1)
    tr = mode_steps(augmented_system(GEN, gains), h)
    out, energy = exact_step(core, u, y0, y1, h, tr.F, tr.Qd)
    for i in range(2):
        A, B, C, L = GEN.A[i], GEN.B[i], GEN.C[i], gains[i]

        def rhs(s, w, y, u_k, A=A, B=B, C=C, L=L):
            xt, z, xh = w[:2], w[2:4], w[4:6]
            r = y - C @ xt
            return np.concatenate([A @ xt + B @ u_k, -A.T @ z + C.T @ r,
                                   (A - L @ C) @ xh + B @ u_k + L @ y, [r @ r]])

        ref = piecewise_ode(rhs, np.concatenate([core[i], [0.0]]), np.array([0.0, h]),
                            np.stack([y0, y1]), [u])
        np.testing.assert_allclose(out[i], ref[:6], rtol=1e-10, atol=1e-12)
        assert energy[i] == pytest.approx(ref[6], rel=1e-10)


def test_window_estimate_is_formula_7_and_its_cost_is_the_replay_15_16():
    """(14) equals the least-squares state (7); (17) equals the replay (15)-(16) on stored data."""
    h, delta = 0.05, 0.5
    det = MinimumDistanceDetector(GEN, delta=delta, Delta=1.0, v_max=0.1)
    t = h * np.arange(11)
    rng = np.random.default_rng(1)
    y, u = rng.normal(size=(11, 1)), rng.normal(size=(11, 1))
    w = det.estimate_window(y, u, t)
    assert w.X.shape == (2, 2) and w.J.shape == (2,) and w.mode.shape == ()
    for i in range(2):
        A, B, C = GEN.A[i], GEN.B[i], GEN.C[i]

        # [x_forced; Phi; int Phi'C'C Phi; int Phi'C'(y - C x_forced)]
        def rhs7(s, z, y_s, u_k, A=A, B=B, C=C):
            xf, Phi = z[:2], z[2:6].reshape(2, 2)
            r = y_s - C @ xf
            return np.concatenate([A @ xf + B @ u_k, (A @ Phi).ravel(),
                                   (Phi.T @ C.T @ C @ Phi).ravel(), Phi.T @ C.T @ r])

        z0 = np.concatenate([np.zeros(2), np.eye(2).ravel(), np.zeros(6)])
        z = piecewise_ode(rhs7, z0, t, y, u)
        X_ref = np.linalg.solve(z[6:10].reshape(2, 2), z[10:12])  # eq. (7)
        np.testing.assert_allclose(w.X[i], X_ref, rtol=1e-8, atol=1e-10)

        def rhs15(s, z, y_s, u_k, A=A, B=B, C=C):  # eqs (15)-(16)
            r = y_s - C @ z[:2]
            return np.concatenate([A @ z[:2] + B @ u_k, [r @ r]])

        J_ref = piecewise_ode(rhs15, np.concatenate([w.X[i], [0.0]]), t, y, u)[2]  # eq. (17)
        assert w.J[i] == pytest.approx(J_ref, rel=1e-8)
    assert w.mode == np.argmin(w.J)  # eq. (5)


# ---------------------------------------------------------------------- Theorem 1
@pytest.mark.parametrize("noisy", [False, True])
def test_theorem_1_mode_exact_and_state_error_is_formula_10(noisy):
    trials = 8
    t, u, traj, v = scenario(trials, 2, horizon=3.0,
                             signal=lambda rng: schedule([], [int(rng.integers(2))]))
    v = v if noisy else np.zeros_like(v)
    det = detector()
    M_max = det.constants.M_max
    for start in [0, 400, 1000]:  # windows [t0, t0 + delta] without a switch
        sl = slice(start, start + N_DELTA + 1)
        w = det.estimate_window(traj.x[:, sl] + v[:, sl], u[:, sl], t[sl])
        truth = traj.mode[:, start]
        np.testing.assert_array_equal(w.mode, truth)  # eq. (9)
        X_hat = w.X[np.arange(trials), w.mode]  # eq. (8)
        for n in range(trials):
            # eq. (10)
            expected = traj.x[n, start] + noise_term(v[n], start, S.system().A[truth[n]])
            assert np.linalg.norm(X_hat[n] - expected) <= M_max * EPS
            if noisy:  # the noise term is far above the tolerance: the test sees it
                assert np.linalg.norm(expected - traj.x[n, start]) > 10 * M_max * EPS
        J_true = w.J[np.arange(trials), truth]  # proof of Theorem 1: J_sigma <= int |v|^2
        bound = (S.v_max**2 if noisy else EPS**2) * S.delta
        assert np.all(J_true <= bound + 1e-12)
    assert set(traj.mode[:, 0]) == {0, 1}  # both modes were tried


def test_theorem_1_in_the_whole_algorithm_and_the_catch_up_of_18_19():
    """At each window end the run's observer equals (19) run from x(t_hat_j) + w_j (eq. (10))."""
    t, u, traj, v = scenario(2, 3, horizon=6.0)
    y = traj.x + v
    det = detector()
    est = det.run(y, u, t)
    sys = S.system()
    A, B, L = sys.A, sys.B, S.observer_gains
    tol = det.constants.M_max * EPS * np.exp(-S.observer_decay * S.delta) + 1e-8
    checked = 0
    for n in range(2):
        starts = np.concatenate([[0], np.flatnonzero(np.isfinite(est.switch_time[n]))])
        for k0 in starts[:3]:
            k1 = k0 + N_DELTA
            if k1 >= t.size:
                continue
            m = traj.mode[n, k0]
            # (9); no estimate inside
            assert est.mode[n, k1] == m and np.all(est.mode[n, k0:k1] == -1)
            x0 = traj.x[n, k0] + noise_term(v[n, :], k0, A[m])  # formula (10)
            sl = slice(k0, k1 + 1)

            def rhs(s, x, y_s, u_k, m=m):
                return (A[m] - L[m]) @ x + B[m] @ u_k + L[m] @ y_s

            ref = piecewise_ode(rhs, x0, t[sl], y[n, sl], u[n, sl])
            # same data, initial states apart by |X* - x - w| <= M EPS, contracted by e^{-a delta}
            assert np.linalg.norm(est.x[n, k1] - ref) <= tol
            checked += 1
    assert checked >= 4


# ---------------------------------------------------------------------- Theorem 2
@pytest.fixture(scope="module")
def fifty():
    t, u, traj, v = scenario(50, 7)
    est = detector().run(traj.x + v, u, t)
    return t, u, traj, v, est


def test_theorem_2_every_switch_detected_within_Delta_no_false_alarm(fifty):
    t, _, traj, v, est = fifty
    assert np.max(np.linalg.norm(v, axis=-1)) <= S.v_max
    assert np.min(np.linalg.norm(traj.x, axis=-1)) >= S.x_min()  # the x_min of (3)-(4) is respected
    a = detector().assumptions(S.x_min(), signal=traj.signals)
    assert a.holds and a.condition4.rhs == pytest.approx(
        lee_assumptions(S.system(), u_max=S.u_max, v_max=S.v_max, x_min=S.x_min(), delta=S.delta,
                        Delta=S.Delta, observer_gains=S.observer_gains).condition4.rhs)
    m = match_detections(est.switch_time, traj.signals, Delta=S.Delta, t_end=t[-1])
    assert m.n_switches > 200  # 50 realizations, about 5 switches each
    assert (m.late, m.missed, m.false) == (0, 0, 0)
    assert m.on_time + m.censored == m.n_switches
    assert m.censored <= 10  # only switches within Delta of the end
    ok = np.isfinite(m.delay)
    assert np.all((m.delay[ok] >= 0) & (m.delay[ok] <= S.Delta))


def test_theorem_1_holds_between_detections_in_the_run(fifty):
    """sigma_hat = sigma from each window end to the next switch; between a switch and
    its detection the old mode is kept; the observer error obeys |x - x^| <= v_max E_hat (§IV)."""
    t, _, traj, _, est = fifty
    E_hat = detector().constants.E_hat
    for n in range(50):
        sw = traj.signals[n].times
        last = np.searchsorted(sw, t, side="right") - 1  # index of the last switch at or before t_k
        detections = np.cumsum(np.isfinite(est.switch_time[n]))
        t_last = np.where(last >= 0, sw[np.maximum(last, 0)], -np.inf)
        det_before = np.concatenate([[0], detections])[np.searchsorted(t, t_last, side="left")]
        pending = (last >= 0) & (detections == det_before)  # switched, not yet detected
        known = est.mode[n] >= 0
        assert np.all(est.mode[n][known & ~pending] == traj.mode[n][known & ~pending])
        previous = traj.signals[n].modes[np.maximum(last, 0)]
        assert np.all(est.mode[n][known & pending] == previous[known & pending])
        err = np.linalg.norm(est.x[n] - traj.x[n], axis=-1)[known & ~pending]
        assert np.all(err <= (S.v_max + EPS) * E_hat)  # the interpolation error acts as noise


def test_the_window_of_24_starts_at_the_end_of_the_estimation_window():
    """(24) compares ``s(t) - s(t - Delta)`` with ``s = 0`` up to ``t_hat_j + delta`` (Remark 3 and
    the proof of Lemma 1); with Delta off the grid, ``s(t - Delta)`` is interpolated."""
    t, u, traj, v = scenario(2, 8, horizon=6.0)
    y = traj.x + v
    Delta = S.Delta + 0.37 * H
    det = MinimumDistanceDetector(S.system(), delta=S.delta, Delta=Delta, v_max=S.v_max,
                                  observer_gains=S.observer_gains)
    state = det.init((2,))
    s_rec, est_rec, energy_rec = [], [], []
    for k in range(t.size):
        state = det.step(state, y[:, k], u[:, max(k - 1, 0)], dt=None if k == 0 else H)
        s_rec.append(state.s_hist[:, -1] if state.s_hist.shape[1] else np.zeros(2))
        est_rec.append(state.estimating)
        energy_rec.append(state.window_energy)
    s_rec, est_rec, energy_rec = np.array(s_rec).T, np.array(est_rec).T, np.array(energy_rec).T
    checked = 0
    for n in range(2):
        starts = np.flatnonzero(est_rec[n, :-1] & ~est_rec[n, 1:]) + 1  # window ends t_bar_j
        assert starts.size >= 2 and np.all(s_rec[n, starts] == 0)
        for k0 in starts:
            k = k0 + 1
            while k < t.size and not est_rec[n, k]:
                s_lag = np.interp(t[k] - Delta, t[k0 : k + 1], s_rec[n, k0 : k + 1], left=0.0)
                assert energy_rec[n, k] == pytest.approx(s_rec[n, k] - s_lag, rel=1e-12, abs=1e-14)
                checked += 1
                k += 1
    assert checked > 1000


# ---------------------------------------------------------------------- beyond the assumptions
def _record(signal, seed=11):
    t, u, traj, _ = scenario(1, seed, horizon=8.0, signal=signal)
    return t, u, traj


def test_noise_that_mimics_the_old_mode_hides_the_switch():
    """|v| up to 2|x| after the switch makes the record that of no switch: missed."""
    t, u, real = _record(schedule([3.0], [0, 1]))
    _, _, ghost = _record(schedule([], [0]))
    v = ghost.x - real.x  # zero before 3.0
    det = detector()
    est = det.run(real.x + v, u, t)
    m = match_detections(est.switch_time, real.signals, Delta=S.Delta, t_end=t[-1])
    assert (m.missed, m.on_time, m.false) == (1, 0, 0)
    assert np.all(est.mode[0, N_DELTA:] == 0)
    v_needed = np.max(np.linalg.norm(v, axis=-1))
    a = lee_assumptions(S.system(), u_max=S.u_max, v_max=v_needed, x_min=S.x_min(), delta=S.delta,
                        Delta=S.Delta, observer_gains=S.observer_gains)
    assert v_needed > 1.0 and not a.holds and v_needed > 10 * a.v_max_allowed


def test_noise_that_masks_the_switch_for_longer_than_Delta_makes_it_late():
    t, u, real = _record(schedule([3.0], [0, 1]))
    _, _, ghost = _record(schedule([], [0]))
    mask = (t >= 3.0) & (t < 3.0 + 1.5 * S.Delta)
    v = np.where(mask[None, :, None], ghost.x - real.x, 0.0)
    est = detector().run(real.x + v, u, t)
    m = match_detections(est.switch_time, real.signals, Delta=S.Delta, t_end=t[-1])
    assert (m.late, m.missed, m.on_time, m.false) == (1, 0, 0, 0)
    assert m.delay[0] >= 1.5 * S.Delta


def test_noise_that_mimics_a_switch_raises_a_false_alarm():
    t, u, real = _record(schedule([], [0]))
    _, _, fake = _record(schedule([3.0], [0, 1]))
    est = detector().run(fake.x, u, t)  # = real.x + (fake.x - real.x)
    m = match_detections(est.switch_time, real.signals, Delta=S.Delta, t_end=t[-1])
    assert m.false == 1 and m.n_switches == 0
    fired = t[np.isfinite(est.switch_time[0])]
    assert fired.size == 1 and 3.0 <= fired[0] <= 3.0 + S.Delta  # Theorem 2 on the faked record


def test_random_noise_above_the_configured_bound_breaks_the_no_false_alarm_guarantee():
    """Noise 3x the v_max given to the detector: false alarms appear (reported, not hidden)."""
    t, u, traj, v = scenario(10, 5, horizon=5.0, noise=3 * S.v_max)
    est = detector().run(traj.x + v, u, t)
    m = match_detections(est.switch_time, traj.signals, Delta=S.Delta, t_end=t[-1])
    a = lee_assumptions(S.system(), u_max=S.u_max, v_max=3 * S.v_max, x_min=S.x_min(),
                        delta=S.delta, Delta=S.Delta, observer_gains=S.observer_gains)
    assert not a.holds and not a.condition4.holds
    assert m.false > 0


# ---------------------------------------------------------------------- protocol
def test_batched_equals_looped_and_single_trajectory_shapes():
    t, u, traj, v = scenario(3, 4, horizon=4.0)
    y = traj.x + v
    det = detector()
    batched = det.run(y, u, t)
    assert batched.P is None and batched.mode_prob is None
    for n in range(3):
        single = det.run(y[n], u[n], t)
        assert single.x.shape == (t.size, 2) and single.mode.shape == (t.size,)
        np.testing.assert_allclose(single.x, batched.x[n], rtol=1e-12, atol=1e-14)
        np.testing.assert_array_equal(single.mode, batched.mode[n])
        np.testing.assert_array_equal(single.switch_time, batched.switch_time[n])
    again = det.run(y, u, t)
    np.testing.assert_array_equal(again.x, batched.x)
    nested = det.run(y.reshape(1, 3, *y.shape[1:]), u.reshape(1, 3, *u.shape[1:]), t)
    np.testing.assert_array_equal(nested.mode[0], batched.mode)
    assert np.all(batched.mode[:, :N_DELTA] == -1) and np.all(np.isnan(batched.x[:, :N_DELTA]))
    assert np.all(batched.mode[:, N_DELTA] >= 0)


def test_missing_samples_hold_the_last_output():
    t, u, traj, v = scenario(2, 6, horizon=2.0)
    y = traj.x + v
    holed = y.copy()
    holed[:, 150] = np.nan
    held = y.copy()
    held[:, 150] = y[:, 149]
    det = detector()
    a, b = det.run(holed, u, t), det.run(held, u, t)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.mode, b.mode)
    # no NaN leaks before any switch
    assert np.all(np.isfinite(a.x[:, N_DELTA : round(S.min_dwell / H)]))
    holed[:, 0] = np.nan
    with pytest.raises(ValueError, match="y must be finite at the first sample"):
        det.run(holed, u, t)


def test_bad_input_is_refused_with_a_message():
    t, u, traj, v = scenario(1, 0, horizon=1.0)
    y = traj.x[0] + v[0]
    with pytest.raises(TypeError, match="system must be a SwitchedLinearSystem"):
        MinimumDistanceDetector("sys", delta=0.25, Delta=1.0, v_max=0.1)
    with pytest.raises(ValueError, match="v_max must be a finite positive number"):
        detector(v_max=0.0)
    with pytest.raises(ValueError,
                       match=r"delta must be a positive multiple of the grid step 0.003"):
        detector().run(y, u[0], t * 1.2)
    bent = t.copy()
    bent[5:] += 1e-4
    with pytest.raises(ValueError, match=r"t must be a uniform grid: sample 5 is 0.0026 after "
                                         r"the previous one"):
        detector().run(y, u[0], bent)
    d = detector()
    state = d.step(d.step(d.init(()), y[0], dt=None), y[1], u[0, 0], dt=t[1] - t[0])
    with pytest.raises(ValueError, match="dt must stay equal to the first grid step"):
        d.step(state, y[2], u[0, 1], dt=1.5 * (t[1] - t[0]))
    with pytest.raises(ValueError, match=r"y must have shape \(\.\.\., K, m\) with m = 2"):
        detector().run(y[:, :1], u[0], t)
    with pytest.raises(ValueError, match="t must span exactly delta"):
        detector().estimate_window(y[:50], u[0, :50], t[:50])
    with pytest.raises(ValueError, match="t .the sample times. is required"):
        detector().run(y, u[0])


# ---------------------------------------------------------------------- bookkeeping
def test_match_detections_counts_on_time_late_missed_censored_and_false():
    signals = [schedule([1.0, 3.0, 6.0, 9.5], [0, 1, 0, 1, 0])]
    st = np.full((1, 8), np.nan)
    st[0, :4] = [0.5, 1.2, 4.5, 4.7]  # false, on time (0.2), late (1.5), false (second in segment)
    m = match_detections(st, signals, Delta=1.0, t_end=10.0)
    np.testing.assert_allclose(m.delay[:2], [0.2, 1.5])
    assert np.isnan(m.delay[2]) and np.isnan(m.delay[3])
    assert (m.on_time, m.late, m.missed, m.censored, m.false, m.n_switches) == (1, 1, 1, 1, 2, 4)
    lead = match_detections(np.array([0.95, np.nan]), signals[0], Delta=1.0, t_end=10.0, lead=0.1)
    assert lead.delay[0] == pytest.approx(-0.05) and lead.on_time == 1 and lead.false == 0
    with pytest.raises(ValueError, match="signals must hold one signal per trial"):
        match_detections(st, signals * 2, Delta=1.0, t_end=10.0)
