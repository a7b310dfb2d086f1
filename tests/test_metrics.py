"""Metrics against direct formulas."""

import numpy as np
import pytest

from switchest.metrics import mode_accuracy, rmse, switch_time_error


def test_rmse_per_step_and_overall():
    truth = np.zeros((2, 3, 2))
    est = np.array([[[1.0, 0.0], [2.0, 0.0], [3.0, 1.0]], [[1.0, 0.0], [0.0, 0.0], [1.0, 1.0]]])
    r = rmse(est, truth, start=1)
    np.testing.assert_allclose(r.per_step[:, 0], [1.0, np.sqrt(2.0), np.sqrt(5.0)])
    np.testing.assert_allclose(r.overall, [np.sqrt((4 + 0 + 9 + 1) / 4), np.sqrt(0.5)])
    with pytest.raises(ValueError, match="share a shape"):
        rmse(est[0], truth)


@pytest.mark.parametrize("scale", [1e-200, 1.0, 1e200])
def test_rmse_neither_overflows_nor_underflows(scale):
    """Errors of 1e200 (or 1e-200) give their RMSE, not inf (or 0); an infinite error gives
    inf in its component only."""
    rng = np.random.default_rng(1)
    x, y = rng.normal(size=(2, 4, 6, 2))
    direct = np.sqrt(np.mean((x - y) ** 2, axis=(0, 1)))
    np.testing.assert_allclose(rmse(scale * x, scale * y).overall, scale * direct, rtol=1e-13)
    x[1, 2, 0] = np.inf
    out = rmse(scale * x, scale * y)
    assert out.overall[0] == np.inf and out.per_step[2, 0] == np.inf
    np.testing.assert_allclose(out.overall[1], scale * direct[1], rtol=1e-13)


def test_mode_accuracy_and_switch_time_error():
    assert mode_accuracy([[0, 1, 1, 0]], [[0, 1, 0, 0]]) == 0.75
    assert mode_accuracy([[0, 1, 1, 0]], [[1, 1, 0, 0]], start=1) == pytest.approx(2 / 3)
    err = switch_time_error([np.nan, 1.2, 2.0, np.nan], [np.nan, 1.0, np.nan, 3.0])
    np.testing.assert_allclose(err, [0.2])


def test_innovation_consistency_recovers_the_filters_own_nis():
    """A plain numpy Kalman filter records e' S^-1 e at every update; the NIS recovered from
    its posterior means and covariances alone equals it (one output missing at times)."""
    from switchest import SwitchedLinearSystem
    from switchest.metrics import innovation_consistency

    rng = np.random.default_rng(5)
    n, m, K = 3, 2, 60
    A = 0.9 * np.linalg.qr(rng.normal(size=(n, n)))[0]
    C = rng.normal(size=(m, n))
    Q, R = 0.1 * np.eye(n), np.array([[0.5, 0.1], [0.1, 0.3]])
    system = SwitchedLinearSystem.discrete(A[None], C=C[None], Q=Q[None], R=R[None], dt=1.0)
    x_true, x, P = np.zeros(n), np.zeros(n), np.eye(n)
    y, xs, Ps, nis = np.empty((K, m)), np.empty((K, n)), np.empty((K, n, n)), []
    for k in range(K):
        x_true = A @ x_true + rng.multivariate_normal(np.zeros(n), Q)
        y[k] = C @ x_true + rng.multivariate_normal(np.zeros(m), R)
        if k % 7 == 3:
            y[k, 1] = np.nan
        x, P = A @ x, A @ P @ A.T + Q
        seen = np.isfinite(y[k])
        Cs, Rs = C[seen], R[np.ix_(seen, seen)]
        S = Cs @ P @ Cs.T + Rs
        e = y[k, seen] - Cs @ x
        nis.append(e @ np.linalg.solve(S, e))
        gain = P @ Cs.T @ np.linalg.inv(S)
        x, P = x + gain @ e, P - gain @ S @ gain.T
        xs[k], Ps[k] = x, P
    check = innovation_consistency(system, y, xs, Ps, np.zeros(K, dtype=int))
    assert check.samples == K
    assert check.mean_nis == pytest.approx(np.mean(nis), rel=1e-9)
    expected = np.mean([2 - (k % 7 == 3) for k in range(K)])
    assert check.expected == pytest.approx(expected)
    assert abs(check.z) < 4  # the model fits: a consistent filter
    with pytest.raises(ValueError, match="same number of samples"):
        innovation_consistency(system, y, xs[:-1], Ps, np.zeros(K, dtype=int))
