"""IMM against FilterPy step for step, its missing-data behaviour and long-run numerics."""

import numpy as np
import pytest
from numpy_oracle import imm_combine, imm_mix

from switchest import SwitchedLinearSystem
from switchest import signals as sg
from switchest.estimators import IMMFilter
from switchest.simulate import simulate

filterpy = pytest.importorskip("filterpy")
from filterpy.kalman import IMMEstimator, KalmanFilter  # noqa: E402

TRANSITION = np.array([[0.85, 0.10, 0.05], [0.20, 0.70, 0.10], [0.05, 0.25, 0.70]])  # asymmetric


def random_discrete(rng, n=3, m=2, l=1, L=3):
    A = rng.standard_normal((L, n, n))
    A *= 0.95 / np.max(np.abs(np.linalg.eigvals(A)), axis=1)[:, None, None]
    B = rng.standard_normal((L, n, l))
    C = rng.standard_normal((L, m, n))
    W = rng.standard_normal((L, n, n))
    V = rng.standard_normal((L, m, m))
    return SwitchedLinearSystem.discrete(A, B, C, Q=W @ np.swapaxes(W, 1, 2) * 0.1,
                                         R=V @ np.swapaxes(V, 1, 2) + 0.1 * np.eye(m), dt=1.0)


def filterpy_imm(sys, x0, P0, mu0):
    filters = []
    for i in range(sys.n_modes):
        kf = KalmanFilter(dim_x=sys.n_states, dim_z=sys.n_outputs, dim_u=sys.n_inputs)
        kf.F, kf.B, kf.H = sys.A[i].copy(), sys.B[i].copy(), sys.C[i].copy()
        kf.Q, kf.R = sys.Q[i].copy(), sys.R[i].copy()
        kf.x, kf.P = x0.copy(), P0.copy()
        filters.append(kf)
    return IMMEstimator(filters, mu0.copy(), TRANSITION.copy())


def test_matches_filterpy_step_for_step():
    rng = np.random.default_rng(0)
    sys = random_discrete(rng)
    x0, P0, mu0 = rng.standard_normal(3), np.eye(3), np.array([0.5, 0.3, 0.2])
    t = np.arange(40.0)
    traj = simulate(sys, sg.markov_at_samples(TRANSITION, t, rng=1, initial=0), t, x0,
                    u=rng.standard_normal((40, 1)), rng=2)
    ours = IMMFilter(sys, TRANSITION, x0, P0, mode_prob0=mu0)
    state = ours.init((1,))
    # sample 0 is an update of every mode-matched filter from the prior; FilterPy weights that
    # first update by cbar = mu0 @ M, so give it cbar = mu0 to state the same prior at sample 0
    theirs = filterpy_imm(sys, x0, P0, mu0)
    theirs.cbar = mu0.copy()
    for k in range(t.size):
        if k:
            theirs.predict(traj.u[0, k - 1])
        theirs.update(traj.y[0, k])
        state = ours.step(state, traj.y[:, k], traj.u[:, k - 1] if k else None,
                          dt=None if k == 0 else 1.0)
        mu = np.exp(state.log_prob)
        x, P = state.combined_x, state.combined_P
        np.testing.assert_allclose(mu[0], theirs.mu, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(x[0], theirs.x, rtol=1e-9, atol=1e-10)
        np.testing.assert_allclose(P[0], theirs.P, rtol=1e-9, atol=1e-10)
        for j, f in enumerate(theirs.filters):
            np.testing.assert_allclose(state.x[0, j], f.x, rtol=1e-9, atol=1e-10)


def test_missing_measurement_gives_the_predicted_mode_probabilities_and_mixed_prediction():
    rng = np.random.default_rng(3)
    sys = random_discrete(rng)
    est = IMMFilter(sys, TRANSITION, np.zeros(3), np.eye(3))
    state = est.step(est.init((2,)), rng.standard_normal((2, 2)), dt=None)
    mu = np.exp(state.log_prob)
    u = np.ones((2, 1))
    after = est.step(state, np.full((2, 2), np.nan), u, dt=1.0)
    # mu_k = P' mu_{k-1}
    np.testing.assert_allclose(np.exp(after.log_prob), mu @ TRANSITION, rtol=1e-12)
    x0j = np.stack([imm_mix(*a, np.log(TRANSITION))[0]
                    for a in zip(state.x, state.P, state.log_prob)])
    x_pred = np.einsum("jab,njb->nja", sys.A, x0j) + np.einsum("jab,nb->nja", sys.B, u)
    np.testing.assert_allclose(after.x, x_pred, rtol=1e-12)
    out = est.run(np.stack([np.zeros((2, 2)), np.full((2, 2), np.nan)], axis=1), np.ones(1),
                  np.arange(2.0))
    state0 = est.step(est.init((2,)), np.zeros((2, 2)), dt=None)
    x0j = np.stack([imm_mix(*a, np.log(TRANSITION))[0]
                    for a in zip(state0.x, state0.P, state0.log_prob)])
    x_pred0 = np.einsum("jab,njb->nja", sys.A, x0j) + np.einsum("jab,nb->nja", sys.B, u)
    mu_pred = np.exp(state0.log_prob) @ TRANSITION
    np.testing.assert_allclose(out.mode_prob[:, 1], mu_pred, rtol=1e-12)
    P_pred0 = est.step(state0, np.full((2, 2), np.nan), u, dt=1.0).P
    x_comb = np.stack([imm_combine(*a)[0] for a in zip(x_pred0, P_pred0, np.log(mu_pred))])
    np.testing.assert_allclose(out.x[:, 1], x_comb, rtol=1e-12)


def test_filterpy_update_none_differs_and_ours_does_not_reuse_the_old_innovation():
    """FilterPy's IMM update(None) keeps each filter's last likelihood; ours uses none."""
    rng = np.random.default_rng(5)
    sys = random_discrete(rng)
    x0, P0, mu0 = np.zeros(3), np.eye(3), np.full(3, 1 / 3)
    theirs = filterpy_imm(sys, x0, P0, mu0)
    theirs.cbar = mu0.copy()  # same prior at sample 0 as ours (see the step-for-step test)
    y = rng.standard_normal(2) * 5
    theirs.update(y)
    theirs.predict(np.zeros(1))
    cbar = theirs.mu @ TRANSITION
    theirs.update(None)
    ours = IMMFilter(sys, TRANSITION, x0, P0, mode_prob0=mu0)
    s = ours.step(ours.init((1,)), y[None], dt=None)
    s = ours.step(s, np.full((1, 2), np.nan), np.zeros((1, 1)), dt=1.0)
    np.testing.assert_allclose(np.exp(s.log_prob[0]), cbar, rtol=1e-12)
    assert not np.allclose(theirs.mu, cbar, rtol=1e-6)


def test_long_run_with_a_huge_outlier_stays_finite_and_psd():
    A = np.array([[[0.99]], [[0.5]]])
    sys = SwitchedLinearSystem.discrete(A, C=[[1.0]], Q=[[0.01]], R=[[0.04]], dt=1.0)
    K = 100_000
    rng = np.random.default_rng(0)
    y = 0.2 * rng.standard_normal((1, K, 1))
    y[0, K // 2, 0] = 1e6 * 0.2  # 10^6 sigma
    est = IMMFilter(sys, [[0.99, 0.01], [0.02, 0.98]], np.zeros(1), np.eye(1))
    out = est.run(y)
    assert np.all(np.isfinite(out.mode_prob)) and np.all(np.isfinite(out.x))
    np.testing.assert_allclose(out.mode_prob.sum(-1), 1.0, rtol=1e-12)
    assert out.P.min() > 0
    assert abs(out.x[0, -1, 0]) < 2.0  # recovered after the outlier


def test_imm_identifies_well_separated_modes():
    A = np.array([[[0.0, 1.0], [0.0, 0.0]]] * 2)
    B = np.array([[[0.0], [1.0]], [[0.0], [-1.0]]])
    sys = SwitchedLinearSystem.continuous(A, B, [[1.0, 0.0]], Q=1e-4 * np.eye(2), R=[[1e-4]])
    t = sg.periodic(0.5, 30.0)
    P = np.array([[0.95, 0.05], [0.05, 0.95]])
    traj = simulate(sys, lambda r: sg.markov_at_samples(P, t, rng=r, initial=0), t, np.zeros(2),
                    u=[2.0], trials=20, rng=1)
    out = IMMFilter(sys, P, np.zeros(2), 1e-4 * np.eye(2)).run(traj.y, [2.0], t)
    # the mode of interval k-1 shows in y_k: compare with the mode one sample earlier
    acc = np.mean(out.mode[:, 2:] == traj.mode[:, 1:-1])
    assert acc > 0.95
