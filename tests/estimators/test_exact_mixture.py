"""The exact mixture filter and smoother against brute force over mode sequences, the Kalman
filter and RTS smoother with one mode, its streaming form, its refusal of too many sequences,
and Kim's smoother measured against it.

Tolerance: RTOL = 1e-9 relative to the largest entry of the oracle's array, the contract of
the compiled kernels: both sides run a Kalman filter per sequence (compiled equilibrated
Cholesky loops against numpy's LAPACK) and sum the same Bayes weights in another order;
observed agreement is ~1e-15.
"""

import numpy as np
import pytest
from smoother_oracle import (
    exact_mixture,
    imm_modes,
    random_system,
    rts_smooth,
    simulate_jump_markov,
    tables,
)

from switchest.estimators import Estimate, ModeKalmanFilter
from switchest.estimators.exact_mixture import ExactMixtureFilter
from switchest.estimators.smoothing import smooth_mode_matched

RTOL = 1e-9
TRANSITIONS = {
    2: np.array([[0.85, 0.15], [0.35, 0.65]]),
    3: np.array([[0.80, 0.15, 0.05], [0.10, 0.70, 0.20], [0.30, 0.10, 0.60]]),
}


def assert_close(actual, expected, rtol=RTOL):
    """Entrywise ``|actual - expected| <= rtol * max |expected|``."""
    expected = np.asarray(expected)
    np.testing.assert_allclose(actual, expected, rtol=0.0, atol=rtol * np.abs(expected).max())


def record(seed, L, K, N=2, domain="continuous"):
    """A system, irregular sample times (continuous) or its steps (discrete), ``y`` with a
    missing sample and a missing component, inputs ``u``, a prior and an asymmetric
    ``mode_prob0``."""
    rng = np.random.default_rng(seed)
    system = random_system(rng, n=2, m=2, l=1, L=L, domain=domain)
    if domain == "continuous":
        t = np.cumsum(np.r_[0.0, rng.choice([0.1, 0.3], K - 1)])
    else:
        t = np.arange(K, dtype=float)
    y = rng.standard_normal((N, K, 2))
    y[0, min(2, K - 1)] = np.nan
    y[-1, min(1, K - 1), 1] = np.nan
    u = rng.standard_normal((N, K, 1))
    p0 = np.arange(1.0, L + 1) / (L * (L + 1) / 2)
    return system, t, y, u, rng.standard_normal(2), 2.0 * np.eye(2), p0


@pytest.mark.parametrize("L, K, domain", [(2, 5, "continuous"), (3, 4, "continuous"),
                                          (2, 5, "discrete")])
def test_equals_brute_force_over_mode_sequences(L, K, domain):
    system, t, y, u, x0, P0, p0 = record(L + K, L, K, domain=domain)
    est = ExactMixtureFilter(system, TRANSITIONS[L], x0, P0, mode_prob0=p0)
    filtered, smoothed = est.run(y, u, t), est.smooth(y, u, t)
    F, G, Qd, trans = tables(system, t)
    ref_f, ref_s = exact_mixture(y, u, F, G, Qd, trans, system.C, system.R, TRANSITIONS[L],
                                 x0, P0, p0)
    for name in ("x", "P", "mode_prob", "loglik"):
        assert_close(getattr(filtered, name), ref_f[name])
    for name in ("x", "P", "mode_prob"):
        assert_close(getattr(smoothed, name), ref_s[name])
    np.testing.assert_array_equal(filtered.mode, np.argmax(ref_f["mode_prob"], axis=-1))
    np.testing.assert_array_equal(smoothed.mode, np.argmax(ref_s["mode_prob"], axis=-1))
    assert not np.allclose(smoothed.x[:, :-1], filtered.x[:, :-1], atol=1e-3)  # it smooths
    for est_ in (filtered, smoothed):
        np.testing.assert_allclose(est_.mode_prob.sum(axis=-1), 1.0, rtol=1e-12)
    assert_close(smoothed.x[:, -1], filtered.x[:, -1], rtol=1e-12)


def test_one_mode_is_the_kalman_filter_and_the_rts_smoother():
    system, t, y, u, x0, P0, _ = record(1, 1, 6)
    est = ExactMixtureFilter(system, np.ones((1, 1)), x0, P0)
    filtered, smoothed = est.run(y, u, t), est.smooth(y, u, t)
    kf = ModeKalmanFilter(system, x0, P0).run(y, u, t, modes=np.zeros(6, int))
    for name in ("x", "P", "loglik"):
        assert_close(getattr(filtered, name), getattr(kf, name))
    F, G, Qd, trans = tables(system, t)
    for i in range(y.shape[0]):
        xs, Ps = rts_smooth(kf.x[i], kf.P[i], u[i], F, G, Qd, trans[:, 0])
        assert_close(smoothed.x[i], xs)
        assert_close(smoothed.P[i], Ps)
    np.testing.assert_array_equal(smoothed.mode_prob, 1.0)


def test_a_single_sample():
    system, t, y, u, x0, P0, p0 = record(9, 3, 1)
    est = ExactMixtureFilter(system, TRANSITIONS[3], x0, P0, mode_prob0=p0)
    filtered, smoothed = est.run(y, u, t), est.smooth(y, u, t)
    F, G, Qd, trans = tables(system, t)
    ref_f, _ = exact_mixture(y, u, F, G, Qd, trans, system.C, system.R, TRANSITIONS[3], x0, P0,
                             p0)
    for name in ("x", "P", "mode_prob", "loglik"):
        assert_close(getattr(filtered, name), ref_f[name])
    for name in ("x", "P", "mode_prob"):
        assert_close(getattr(smoothed, name), ref_f[name])


def test_streaming_step_equals_run():
    system, t, y, u, x0, P0, p0 = record(3, 2, 5)
    est = ExactMixtureFilter(system, TRANSITIONS[2], x0, P0, mode_prob0=p0)
    whole = est.run(y, u, t)
    state = est.init((y.shape[0],))
    for k in range(t.size):
        state = est.step(state, y[:, k], u[:, k - 1] if k else None,
                         dt=None if k == 0 else t[k] - t[k - 1])
        assert state.log_weight.shape == (y.shape[0], 2 ** (k + 1))
        assert_close(state.combined_x, whole.x[:, k])
        assert_close(state.combined_P, whole.P[:, k])
        assert_close(state.mode_prob, whole.mode_prob[:, k])
        assert_close(state.loglik, whole.loglik[:, k])


def test_batch_axes_and_a_single_trial():
    system, t, y, u, x0, P0, p0 = record(4, 2, 4, N=4)
    est = ExactMixtureFilter(system, TRANSITIONS[2], x0, P0, mode_prob0=p0)
    flat = est.smooth(y, u, t)
    batched = est.smooth(y.reshape(2, 2, 4, 2), u.reshape(2, 2, 4, 1), t)
    assert isinstance(batched, Estimate) and batched.P.shape == (2, 2, 4, 2, 2)
    assert_close(batched.x.reshape(flat.x.shape), flat.x, rtol=1e-12)
    single = est.run(y[1], u[1], t)
    assert single.x.shape == (4, 2) and single.loglik.shape == (4,)
    assert_close(single.P, est.run(y, u, t).P[1], rtol=1e-12)


def test_an_overflowing_measurement_is_an_outlier_treated_as_missing():
    system, t, y, u, x0, P0, p0 = record(8, 2, 4)
    est = ExactMixtureFilter(system, TRANSITIONS[2], x0, P0, mode_prob0=p0)
    y_bad = y.copy()
    y_bad[1, 3] = 1e300  # its normalized innovation squared overflows under every sequence
    y_nan = y.copy()
    y_nan[1, 3] = np.nan
    bad, nan = est.run(y_bad, u, t), est.run(y_nan, u, t)
    assert bad.outlier[1, 3] and bad.outlier.sum() == 1
    for name in ("x", "P", "mode_prob", "loglik"):
        assert_close(getattr(bad, name), getattr(nan, name), rtol=1e-14)
    state = est.init((2,))
    for k in range(t.size):
        state = est.step(state, y_bad[:, k], u[:, k - 1], dt=None if k == 0 else t[k] - t[k - 1])
    np.testing.assert_array_equal(state.outlier, [False, True])
    assert_close(state.combined_x, nan.x[:, -1])


def test_refuses_more_sequences_than_max_sequences():
    system, t, y, u, x0, P0, _ = record(5, 2, 5)
    est = ExactMixtureFilter(system, TRANSITIONS[2], x0, P0, max_sequences=16)
    message = r"L\^K = 2\^5 \(L = 2 modes, K = 5 samples\) = 32 mode sequences exceed " \
              r"max_sequences = 16"
    with pytest.raises(ValueError, match=message):
        est.run(y, u, t)
    with pytest.raises(ValueError, match=message):
        est.smooth(y, u, t)
    est.run(y[:, :4], u[:, :4], t[:4])  # 16 sequences: allowed
    state = est.init((2,))
    for k in range(4):
        state = est.step(state, y[:, k], u[:, k - 1], dt=None if k == 0 else t[k] - t[k - 1])
    with pytest.raises(ValueError, match=r"16 prefixes times L = 2 modes = 32 .* = 16"):
        est.step(state, y[:, 4], u[:, 3], dt=t[4] - t[3])


@pytest.mark.parametrize("kwargs, error, message", [
    ({"max_sequences": 0}, ValueError, "max_sequences must be a positive int"),
    ({"max_sequences": 2.5}, TypeError, "max_sequences must be an int"),
    ({"mode_prob0": [0.5, 0.6]}, ValueError, "mode_prob0 must sum to 1"),
])
def test_bad_options_are_refused(kwargs, error, message):
    system, *_ = record(6, 2, 3)
    with pytest.raises(error, match=message):
        ExactMixtureFilter(system, TRANSITIONS[2], np.zeros(2), np.eye(2), **kwargs)
    with pytest.raises(ValueError, match="transition rows must sum to 1"):
        ExactMixtureFilter(system, TRANSITIONS[2].T, np.zeros(2), np.eye(2))


def test_kim_smoothed_estimates_are_closer_to_the_exact_smoothed_means_than_filtered_ones():
    """On random two-mode systems (simulated from the IMM's own jump-Markov model), Kim's
    smoother of the IMM's mode-matched posteriors lands closer to the exact smoothed mean than
    the IMM's filtered estimate does, trial by trial, in mean squared distance over samples
    0..K-2 (at K-1 the two coincide).

    80 trials (4 systems of 20). Observed with seed 7: Kim closer on 96 % of the trials,
    median ratio (Kim / filtered) 0.11; over seeds 0-11: 86-100 % and 0.05-0.26. Asserted: at
    least 75 % of the trials (were Kim no better than even, 60 of 80 would have probability
    below 1e-5) and a median ratio below 0.5. Not asserted: the ratio of the pooled means,
    which a few trials where the IMM's collapse goes astray dominate (0.2-0.9 over seeds 0-9,
    whose 40 systems include two with a ratio above 1)."""
    rng = np.random.default_rng(7)
    transition, p0 = np.array([[0.9, 0.1], [0.2, 0.8]]), np.array([0.5, 0.5])
    N, K = 20, 10
    t = np.arange(K, dtype=float)
    kim_d, filtered_d = [], []
    for _ in range(4):
        system = random_system(rng, n=2, m=1, l=1, L=2, domain="discrete")
        x0, P0 = np.zeros(2), np.eye(2)
        y = simulate_jump_markov(rng, system, transition, x0, P0, p0, N, K)
        F, G, Qd, trans = tables(system, t)
        xm, Pm, pm, filtered = imm_modes(y, np.zeros((N, K, 1)), F, G, Qd, trans, system.C,
                                         system.R, transition, x0, P0, p0)
        kim = smooth_mode_matched(xm, Pm, pm, None, F, G, Qd, trans, transition)
        exact = ExactMixtureFilter(system, transition, x0, P0, mode_prob0=p0).smooth(y, t=t)
        kim_d.append(np.mean(np.sum((kim.x - exact.x) ** 2, axis=-1)[:, :-1], axis=1))
        filtered_d.append(np.mean(np.sum((filtered - exact.x) ** 2, axis=-1)[:, :-1], axis=1))
    kim_d, filtered_d = np.concatenate(kim_d), np.concatenate(filtered_d)
    assert np.mean(kim_d < filtered_d) >= 0.75
    assert np.median(kim_d / filtered_d) < 0.5
