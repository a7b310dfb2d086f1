"""One conformance suite over every estimator (DESIGN.md §4): batched equals looped,
a single-mode model reduces to the Kalman filter, NaN skips the update, bad shapes
are refused, results are reproducible."""

import numpy as np
import pytest

from switchest import SwitchedLinearSystem
from switchest import signals as sg
from switchest.estimators import (
    IMMEV1Filter,
    IMMFilter,
    ModeKalmanFilter,
    SwitchTimeKalmanFilter,
)
from switchest.discretize import mode_steps
from switchest.estimators.kalman import steady_state_gain
from switchest.simulate import simulate

A = np.array([[[-0.4, 1.0], [-1.0, -0.3]], [[-0.1, 0.0], [0.5, -1.2]]])
B = np.array([[[0.0], [1.0]], [[1.0], [0.0]]])
C = np.array([[1.0, 0.2]])
SYS = SwitchedLinearSystem.continuous(A, B, C, Q=0.05 * np.eye(2), R=[[0.1]])
X0, P0 = np.array([0.5, -0.5]), np.eye(2)
TRANSITION = np.array([[0.8, 0.2], [0.35, 0.65]])


def data(trials=3, seed=0, t_end=4.0):
    t = sg.periodic(0.25, t_end)
    traj = simulate(SYS, lambda r: sg.dwell_time(2, t_end, 0.6, 1.2, rng=r), t, (X0, P0),
                    u=np.ones(1), trials=trials, rng=seed)
    return traj


FACTORIES = {
    "mode-kalman": (lambda s: ModeKalmanFilter(s, X0, P0), True),
    "mode-kalman-steady": (lambda s: ModeKalmanFilter(s, X0, P0, steady_state=True), True),
    "switch-time": (lambda s: SwitchTimeKalmanFilter(s, X0, P0, grid=4), True),
    "switch-time-refine": (lambda s: SwitchTimeKalmanFilter(s, X0, P0, grid=2, refine=True), True),
    "imm": (lambda s: IMMFilter(s, TRANSITION, X0, P0), False),
    "imm-ev1": (lambda s: IMMEV1Filter(s, TRANSITION, x0=X0, P0=P0, grid=3), False),
}


def run(name, est, traj, y=None, **kw):
    y = traj.y if y is None else y
    needs_modes = FACTORIES[name][1]
    if needs_modes:
        kw.setdefault("modes", traj.mode)
    return est.run(y, traj.u[0, 0], traj.t, **kw)


@pytest.mark.parametrize("name", FACTORIES)
def test_batched_equals_looped(name):
    traj = data()
    est = FACTORIES[name][0](SYS)
    batched = run(name, est, traj)
    for n in range(traj.n_trials):
        kw = {"modes": traj.mode[n]} if FACTORIES[name][1] else {}
        single = est.run(traj.y[n], traj.u[0, 0], traj.t, **kw)
        assert single.x.shape == (traj.t.size, 2)  # no batch axis in, none out
        np.testing.assert_allclose(batched.x[n], single.x, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(batched.P[n], single.P, rtol=1e-10, atol=1e-12)
        if batched.mode_prob is not None:
            np.testing.assert_allclose(batched.mode_prob[n], single.mode_prob, rtol=1e-9, atol=1e-14)


@pytest.mark.parametrize("name", FACTORIES)
def test_reproducible_and_finite(name):
    traj = data()
    a = run(name, FACTORIES[name][0](SYS), traj)
    b = run(name, FACTORIES[name][0](SYS), traj)
    np.testing.assert_array_equal(a.x, b.x)
    assert np.all(np.isfinite(a.x)) and np.all(np.isfinite(a.P))


@pytest.mark.parametrize("name", FACTORIES)
def test_single_mode_reduces_to_the_kalman_filter(name):
    one = SwitchedLinearSystem.continuous(A[:1], B[:1], C, Q=0.05 * np.eye(2), R=[[0.1]])
    t = sg.periodic(0.25, 3.0)
    traj = simulate(one, sg.schedule([], [0]), t, (X0, P0), u=np.ones(1), trials=2, rng=4)
    prior = P0
    if name == "mode-kalman-steady":
        # started at the Riccati fixed point, the time-varying filter IS the steady-state one
        steps = mode_steps(one, 0.25)
        prior = steady_state_gain(steps.F[0], one.C[0], steps.Qd[0], one.R[0])[1]
    ref = ModeKalmanFilter(one, X0, prior).run(traj.y, np.ones(1), t, modes=np.zeros(t.size, int))
    factory, needs_modes = FACTORIES[name]
    if name.startswith("imm"):
        est = (IMMFilter(one, [[1.0]], X0, P0) if name == "imm"
               else IMMEV1Filter(one, x0=X0, P0=P0, grid=3, epsilon=0.0))
    else:
        est = factory(one)
    out = run(name, est, traj, modes=np.zeros(t.size, int)) if needs_modes else est.run(traj.y, np.ones(1), t)
    np.testing.assert_allclose(out.x, ref.x, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(out.P, ref.P, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("name", FACTORIES)
def test_nan_measurement_skips_the_update(name):
    traj = data(trials=2)
    y = traj.y.copy()
    y[:, 5] = np.nan
    est = FACTORIES[name][0](SYS)
    full = run(name, est, traj, y=y)
    assert np.all(np.isfinite(full.x)) and np.all(np.isfinite(full.P))
    kw = {"modes": traj.mode[:, :6]} if FACTORIES[name][1] else {}
    head = est.run(traj.y[:, :5], traj.u[0, 0], traj.t[:5], **{k: v[:, :5] for k, v in kw.items()})
    np.testing.assert_allclose(full.x[:, :5], head.x, rtol=1e-12)
    if name == "mode-kalman":
        # no update at sample 5: the estimate is the one-step prediction of sample 4's
        steps = mode_steps(SYS, 0.25)
        m = traj.mode[:, 4]
        x_pred = np.einsum("nij,nj->ni", steps.F[m], full.x[:, 4]) + steps.G[m][..., 0]
        P_pred = steps.F[m] @ full.P[:, 4] @ np.swapaxes(steps.F[m], 1, 2) + steps.Qd[m]
        np.testing.assert_allclose(full.x[:, 5], x_pred, rtol=1e-12)
        np.testing.assert_allclose(full.P[:, 5], P_pred, rtol=1e-12)


@pytest.mark.parametrize("name", FACTORIES)
def test_bad_shapes_are_refused(name):
    traj = data(trials=2)
    est = FACTORIES[name][0](SYS)
    with pytest.raises(ValueError, match=r"y must have shape \(\.\.\., K, m\)"):
        run(name, est, traj, y=np.concatenate([traj.y, traj.y], axis=-1))
    with pytest.raises(ValueError, match="t must have shape"):
        est.run(traj.y, None, traj.t[:-1], **({"modes": traj.mode} if FACTORIES[name][1] else {}))
    with pytest.raises(ValueError, match="u must have shape"):
        est.run(traj.y, np.ones(3), traj.t, **({"modes": traj.mode} if FACTORIES[name][1] else {}))
    with pytest.raises(ValueError, match="infinities"):
        bad = traj.y.copy()
        bad[0, 0, 0] = np.inf
        run(name, est, traj, y=bad)
    if FACTORIES[name][1]:
        with pytest.raises(ValueError, match="modes must be in 0..1"):
            est.run(traj.y, None, traj.t, modes=np.full(traj.t.size, 2))


def test_constructors_validate():
    with pytest.raises(ValueError, match="x0 must have shape"):
        ModeKalmanFilter(SYS, np.zeros(3), P0)
    with pytest.raises(ValueError, match="P0 must be symmetric"):
        IMMFilter(SYS, TRANSITION, X0, np.array([[1.0, 2.0], [0.0, 1.0]]))
    with pytest.raises(ValueError, match=r"rows must sum to 1 \(P\[i, j\] = P\(j next \| i now\)\)"):
        IMMFilter(SYS, TRANSITION.T, X0, P0)
    with pytest.raises(ValueError, match="g must be a positive int"):
        SwitchTimeKalmanFilter(SYS, X0, P0, grid=0)
    with pytest.raises(ValueError, match="predecessor must be"):
        IMMEV1Filter(SYS, x0=X0, P0=P0, predecessor="best")
    with pytest.raises(TypeError, match="SwitchedLinearSystem"):
        ModeKalmanFilter(A, X0, P0)
    disc = SwitchedLinearSystem.discrete(A, dt=0.1)
    with pytest.raises(ValueError, match="continuous-time system"):
        IMMEV1Filter(disc, x0=X0, P0=P0)
