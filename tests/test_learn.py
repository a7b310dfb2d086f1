"""Fitting a switched system by EM (switchest.learn.fit) on data simulated from known models.

Statistical checks use fixed seeds and tolerances of 3 reported standard errors (a 3-sigma band
for each entry); a parameter held at zero has NaN standard error and is checked to stay zero.
"""

import re
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from switchest.engine.kalman import kalman_run
from switchest.estimators import IMMFilter, TimingWarning
from switchest.estimators.smoothing import smooth_mode_matched
from switchest.learn import fit, rates_from_transition
from switchest.learn.dynamics_step import fit_C
from switchest.models.catalog import catalog
from switchest.signals import schedule
from switchest.simulate import simulate
from switchest.switching import MarkovAtSamples
from switchest.system import SwitchedLinearSystem

A3 = np.array([[[0.9, 0.1], [0.0, 0.8]], [[0.5, -0.3], [0.2, 0.7]], [[1.0, 0.0], [0.1, 0.6]]])
C3 = np.array([[[1.0, 0.0]], [[1.0, 1.0]], [[0.0, 1.0]]])
Q3 = np.array([np.diag([0.1, 0.05]), np.diag([0.3, 0.1]), np.diag([0.05, 0.2])])
R3 = np.array([[[0.2]], [[0.5]], [[0.1]]])
P3 = np.array([[0.9, 0.07, 0.03], [0.1, 0.8, 0.1], [0.05, 0.15, 0.8]])  # asymmetric


def jump_system(Q=Q3, R=R3):
    return SwitchedLinearSystem.discrete(A3, None, C3, Q, R, dt=1.0)


def within(fitted, truth, se, k=3.0):
    """Every entry with a standard error within ``k`` of them of the truth; the others equal."""
    has = np.isfinite(se)
    assert np.all(np.abs(fitted - truth)[has] <= k * se[has]), (fitted, truth, se)
    np.testing.assert_allclose(fitted[~has], truth[~has], rtol=0, atol=1e-12)


def test_lag_one_moments_match_the_dense_joint_gaussian():
    rng = np.random.default_rng(0)
    n, K = 2, 6
    F, G, Qd = rng.normal(size=(1, n, n)) * 0.5, np.zeros((1, n, 0)), 0.3 * np.eye(n)[None]
    C, R = rng.normal(size=(1, 1, n)), 0.5 * np.eye(1)[None]
    y, u, trans = rng.normal(size=(1, K, 1)), np.zeros((1, K, 0)), np.zeros((1, K), np.int64)
    out = kalman_run(y, u, F, G, Qd, trans, C, R, trans, np.zeros(n), np.eye(n))
    s = smooth_mode_matched(out.x[:, :, None], out.P[:, :, None], np.ones((1, K, 1)), u, F, G,
                            Qd, trans[:, :, None], np.ones((1, 1)), lagged=True,
                            timing="interval")  # one mode: the timings agree
    cov = np.zeros((K, K, n, n))  # prior Cov(x_k, x_l) of the chain
    cov[0, 0] = np.eye(n)
    for k in range(1, K):
        cov[k, k] = F[0] @ cov[k - 1, k - 1] @ F[0].T + Qd[0]
        for j in range(k):
            cov[k, j] = F[0] @ cov[k - 1, j]
            cov[j, k] = cov[k, j].T
    Sx = cov.transpose(0, 2, 1, 3).reshape(K * n, K * n)
    H = np.kron(np.eye(K), C[0])
    gain = Sx @ H.T @ np.linalg.inv(H @ Sx @ H.T + 0.5 * np.eye(K))
    mean = (gain @ y[0].ravel()).reshape(K, n)
    post = (Sx - gain @ H @ Sx).reshape(K, n, K, n)
    for k in range(K - 1):  # compiled vs dense algebra: rounding only
        np.testing.assert_allclose(s.lag_x[0, k, 0], mean[k], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(s.lag_P[0, k, 0], post[k, :, k], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(s.lag_cross[0, k, 0], post[k + 1, :, k], rtol=1e-9,
                                   atol=1e-12)
    np.testing.assert_allclose(s.pair_prob, 1.0)


@pytest.fixture(scope="module")
def jump_fit():
    t = np.arange(2000.0)
    traj = simulate(jump_system(), MarkovAtSamples(P3, initial=0), t,
                    (np.zeros(2), np.eye(2)), rng=1)
    start = jump_system(Q=2 * Q3, R=0.5 * R3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning on identifiable data
        res = fit(start, traj.y[0], t=t, x0=np.zeros(2), P0=np.eye(2), modes=traj.mode[0],
                  max_iter=200)
    return traj, res


def test_three_mode_jump_system_known_modes_within_three_standard_errors(jump_fit):
    _, res = jump_fit
    within(res.transition, P3, res.se["transition"])
    within(res.system.Q, Q3, res.se["Q"])
    within(res.system.R, R3, res.se["R"])


def test_known_modes_log_likelihood_never_decreases(jump_fit):
    _, res = jump_fit
    steps = np.diff(res.loglik)
    assert np.all(steps >= -1e-9 * np.abs(res.loglik[:-1])), steps.min()
    assert res.loglik[-1] > res.loglik[0] + 10  # it did climb from the wrong start


@pytest.mark.parametrize("regression", ["A", "C"])
def test_regression_matrices_get_observed_information_standard_errors(jump_fit, regression):
    """A with Q and R (or C with R) fitted from the known modes: within 3 of its standard
    errors (the observed information, jointly with the noises) of the truth. (C with Q is
    identified only through the prior P0, which fixes the state's scale: its information is
    nearly singular.) With both A and C fitted the state's coordinates are not identified and
    A, C get none."""
    traj, _ = jump_fit
    t, y, modes = np.arange(2000.0), traj.y[0], traj.mode[0]
    start = SwitchedLinearSystem.discrete(A3 + 0.1 * (regression == "A"), None,
                                          C3 + 0.2 * (regression == "C"),
                                          Q3 * (2.0 if regression == "A" else 1.0), 0.5 * R3,
                                          dt=1.0)  # Q not fitted with C: the true one
    res = fit(start, y, t=t, x0=np.zeros(2), P0=np.eye(2), modes=modes,
              estimate=(regression, "Q", "R") if regression == "A" else ("C", "R"),
              max_iter=200)
    fitted, truth = getattr(res.system, regression), {"A": A3, "C": C3}[regression]
    assert np.all(np.isfinite(res.se[regression]))
    within(fitted, truth, res.se[regression])
    within(res.system.R, R3, res.se["R"])
    both = fit(start, y[:300], t=t[:300], x0=np.zeros(2), P0=np.eye(2), modes=modes[:300],
               estimate=("A", "C", "R"), max_iter=3)
    assert np.all(np.isnan(both.se["A"])) and np.all(np.isnan(both.se["C"]))
    assert np.all(np.isfinite(both.se["R"]))


def test_imm_with_fitted_parameters_is_as_good_as_with_the_true_ones(jump_fit):
    traj, res = jump_fit
    test = simulate(jump_system(), MarkovAtSamples(P3, initial=0), np.arange(400.0),
                    (np.zeros(2), np.eye(2)), trials=20, rng=7)

    def sq_errors(system, transition):
        # Bar-Shalom's timing, which the IMM approximates better (docs/conventions.rst): in the
        # data's ("sample") the fitted model's excess was 0.0060 against 3 x 0.0014
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TimingWarning)
            est = IMMFilter(system, transition, np.zeros(2), np.eye(2),
                            timing="interval").run(test.y)
        return np.sum((est.x - test.x) ** 2, axis=-1).mean(axis=1)  # per trial

    true_mse = sq_errors(jump_system(), P3)
    diff = sq_errors(res.system, res.transition) - true_mse
    # paired trials: the mean difference within 3 of its standard error, beyond the excess a
    # plug-in filter pays for its parameters' estimation error, O(p / K) of the MSE (18
    # parameters from K = 2000 samples: 1 %; allowed 2 %; the converged fit's was 3.9 % with
    # 3 SE = 3.2 %)
    assert abs(diff.mean()) <= 3 * diff.std(ddof=1) / np.sqrt(diff.size) + 0.02 * true_mse.mean()


A2 = np.array([[[0.95, 0.2], [-0.2, 0.95]], [[0.5, 0.0], [0.3, 0.4]]])
C2 = np.array([[[1.0, 0.0]], [[0.0, 1.0]]])
Q2 = np.array([np.diag([0.05, 0.05]), np.diag([0.2, 0.1])])
R2 = np.array([[[0.05]], [[0.1]]])
P2 = np.array([[0.95, 0.05], [0.1, 0.9]])


def test_unknown_modes_fit_ends_at_a_maximum_within_three_standard_errors():
    """The approximate EM of unknown modes, then the direct ascent of the same log-likelihood:
    the trace never decreases, the information at its end is positive definite (every standard
    error finite), and each entry is within 3 standard errors of the truth; the IMM with the
    fitted parameters estimates the state as well as with the true ones, within sampling error."""
    truth = SwitchedLinearSystem.discrete(A2, None, C2, Q2, R2, dt=1.0)
    t = np.arange(1000.0)
    traj = simulate(truth, MarkovAtSamples(P2, initial=0), t, (np.zeros(2), np.eye(2)), rng=3)
    start = SwitchedLinearSystem.discrete(A2, None, C2, 2 * Q2, 0.5 * R2, dt=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # identifiable data: no warning
        res = fit(start, traj.y[0], t=t, transition=np.array([[0.8, 0.2], [0.2, 0.8]]),
                  x0=np.zeros(2), P0=np.eye(2), max_iter=100)
    assert res.converged and res.ascent_from is not None
    assert np.all(np.diff(res.loglik) >= 0)
    em, ascent = res.loglik[:res.ascent_from], res.loglik[res.ascent_from:]
    # EM stalled below the maximum (0.37 nats here: the E-step's merging), the ascent climbs on
    assert ascent.size and ascent[-1] > em[-1] + 0.1
    for fitted, true, name in ((res.transition, P2, "transition"), (res.system.Q, Q2, "Q"),
                               (res.system.R, R2, "R")):
        assert np.all(np.isfinite(res.se[name]))
        within(fitted, true, res.se[name])
    test = simulate(truth, MarkovAtSamples(P2, initial=0), np.arange(300.0),
                    (np.zeros(2), np.eye(2)), trials=20, rng=8)

    def sq_errors(system, transition):
        # Bar-Shalom's timing, which the IMM approximates better (docs/conventions.rst): in the
        # data's ("sample") the fitted model's excess was 0.0060 against 3 x 0.0014
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TimingWarning)
            est = IMMFilter(system, transition, np.zeros(2), np.eye(2),
                            timing="interval").run(test.y)
        return np.sum((est.x - test.x) ** 2, axis=-1).mean(axis=1)  # per trial

    diff = sq_errors(res.system, res.transition) - sq_errors(truth, P2)
    # paired trials: the IMM with the fitted parameters within 3 standard errors of the true
    # (observed: 0.0030 against 3 x 0.0016, of an MSE of 0.37)
    assert abs(diff.mean()) <= 3 * diff.std(ddof=1) / np.sqrt(diff.size)


def test_ascent_parameters_round_trip():
    """The ascent's unconstrained parameters give back the system and transition matrix they
    were taken from: zero transition entries, a matrix tied across the modes, noise-free
    components."""
    from switchest.learn.ascent import _Layout

    Q = np.array([[[0.3, 0.1, 0.0], [0.1, 0.2, 0.0], [0.0, 0.0, 0.0]]] * 2)  # shared, 3rd free
    R = np.array([[[0.5]], [[0.2]]])
    sys = SwitchedLinearSystem.discrete(np.eye(3)[None].repeat(2, 0), None,
                                        np.ones((2, 1, 3)), Q, R, dt=1.0)
    pi = np.array([[0.0, 1.0], [0.3, 0.7]])
    layout = _Layout(sys, pi, ("transition", "Q", "R"), frozenset({"Q"}))
    theta = layout.pack(sys, pi)
    assert theta.size == 1 + 3 + 2  # one probability (row 0 has no free entry), Q's block, two R
    back, pi_back = layout.unpack(theta)
    np.testing.assert_allclose(pi_back, pi, rtol=0, atol=1e-15)
    np.testing.assert_allclose(back.Q, Q, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(back.R, R, rtol=1e-14, atol=0)
    moved, pi_moved = layout.unpack(theta + 0.1)
    np.testing.assert_allclose(pi_moved.sum(axis=1), 1.0, rtol=0, atol=1e-15)
    assert pi_moved[0, 0] == 0.0 and np.all(moved.Q[:, 2] == 0) and np.all(moved.Q[:, :, 2] == 0)
    assert np.all(moved.Q == moved.Q[:1])  # still tied


def _ascent_toy(pi01_max: float, q1_max: float, level: float = 0.0):
    """A 2-mode system of scalar states and a quadratic log-likelihood (``level`` at its
    maximum) over pi_01, pi_10, Q and R with its unconstrained maximum at ``pi_01 = pi01_max``,
    ``Q_1 = q1_max`` (below their bounds when negative), pi_10 = 0.3, Q_0 = 0.5, R = (0.2,
    0.3); returns the ascent's start ``(system, transition)`` and the log-likelihood."""
    def system(Q0, Q1, R0, R1):
        return SwitchedLinearSystem.discrete([[[0.9]], [[0.5]]], None, [[[1.0]], [[1.0]]],
                                             [[[Q0]], [[Q1]]], [[[R0]], [[R1]]], dt=1.0)

    def loglik(candidates):
        return np.array([level - ((pi[0, 1] - pi01_max) / 0.02) ** 2
                         - ((pi[1, 0] - 0.3) / 0.05) ** 2 - ((s.Q[0, 0, 0] - 0.5) / 0.1) ** 2
                         - ((s.Q[1, 0, 0] - q1_max) / 0.1) ** 2
                         - ((s.R[0, 0, 0] - 0.2) / 0.03) ** 2 - ((s.R[1, 0, 0] - 0.3) / 0.04) ** 2
                         for s, pi in candidates])

    return system(0.4, 0.2, 0.25, 0.35), np.array([[0.9, 0.1], [0.2, 0.8]]), loglik


def test_ascent_reaches_a_maximum_on_the_boundary():
    """A log-likelihood whose maximum over the simplex has pi_01 = 0 (its unconstrained one is
    at -0.05) and Q of mode 1 singular (at -0.1): the ascent ends with both bounds active and
    every other entry at its maximizer, in a few iterations."""
    from switchest.learn.ascent import ascend

    start, pi, loglik = _ascent_toy(-0.05, -0.1)
    trace = []
    fitted, pi_fit, converged = ascend(start, pi, ("transition", "Q", "R"), loglik,
                                       start_loglik=loglik([(start, pi)])[0], max_iter=60,
                                       tol=1e-14, report=trace.append)
    assert converged and len(trace) < 30 and np.all(np.diff(trace) >= 0)
    assert pi_fit[0, 1] == 0.0 and fitted.Q[1, 0, 0] == 0.0  # the bounds, exactly
    np.testing.assert_allclose([pi_fit[1, 0], fitted.Q[0, 0, 0], fitted.R[0, 0, 0],
                                fitted.R[1, 0, 0]], [0.3, 0.5, 0.2, 0.3], rtol=1e-5)
    np.testing.assert_allclose(pi_fit.sum(axis=1), 1.0, rtol=0, atol=1e-15)


def test_ascent_stopped_short_of_a_bound_ends_on_it():
    """A maximum just beyond two bounds (pi_01 at -0.0005, Q of mode 1 at -0.001) of a
    log-likelihood near -1000: with tol 1e-6 (1e-3 nats) L-BFGS-B alone stops with Q of mode
    1 still about 1e-3 above zero, where the information is indefinite; the step onto the
    bounds the gradient points at ends the fit on both, the trace still non-decreasing."""
    from switchest.learn.ascent import ascend

    start, pi, loglik = _ascent_toy(-5e-4, -1e-3, level=-1000.0)
    trace = []
    fitted, pi_fit, converged = ascend(start, pi, ("transition", "Q", "R"), loglik,
                                       start_loglik=loglik([(start, pi)])[0], max_iter=60,
                                       tol=1e-6, report=trace.append)
    assert converged and np.all(np.diff(trace) >= 0)
    assert pi_fit[0, 1] == 0.0 and fitted.Q[1, 0, 0] == 0.0
    # the others within what 1e-3 nats allows: |delta| <= sd sqrt(1e-3), sd 0.03 - 0.1
    np.testing.assert_allclose([pi_fit[1, 0], fitted.Q[0, 0, 0], fitted.R[0, 0, 0],
                                fitted.R[1, 0, 0]], [0.3, 0.5, 0.2, 0.3],
                               atol=0.1 * np.sqrt(1e-3))
    for budget in range(1, len(trace) + 1):  # within any budget: the last point reported
        trace = []
        fitted, pi_fit, _ = ascend(start, pi, ("transition", "Q", "R"), loglik,
                                   start_loglik=loglik([(start, pi)])[0], max_iter=budget,
                                   tol=1e-6, report=trace.append)
        assert 1 <= len(trace) <= budget
        assert loglik([(fitted, pi_fit)])[0] == pytest.approx(trace[-1], rel=1e-12)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning",
                            "ignore:invalid value encountered:RuntimeWarning")
@pytest.mark.parametrize("known", [False, True])
def test_log_likelihoods_of_many_candidates_are_each_ones_own(known):
    """The candidates' pair-chain IMMs in one compiled call (unknown modes; known modes: one
    Kalman filter each) give each candidate's log_likelihood, with missing samples, two
    trials, irregular times and more candidates than one call takes; a candidate whose filter
    fails gets NaN."""
    from switchest.learn.data import record
    from switchest.learn.expectation import log_likelihood, log_likelihoods

    def system(Q, R):  # continuous time, so that the samples may be irregular
        return SwitchedLinearSystem.continuous(A3 - np.eye(2), None, C3, Q, R)

    t = np.cumsum(np.r_[0.0, np.random.default_rng(4).choice([0.5, 1.0, 1.5], 59)])
    traj = simulate(system(Q3, R3), MarkovAtSamples(P3, initial=0), t,
                    (np.zeros(2), np.eye(2)), trials=2, rng=5)
    y = traj.y.copy()
    y[0, 5:9] = np.nan
    data = record(system(Q3, R3), y, None, t, traj.mode if known else None)
    rng = np.random.default_rng(6)
    candidates = [(system(Q3 * rng.uniform(0.5, 2), R3 * rng.uniform(0.5, 2)),
                   rng.dirichlet(np.ones(3) * 4, size=3)) for _ in range(40)]
    unstable = A3 + 4 * np.eye(2)  # e^4 per unit time: its covariance, then its transition
    for Q, error in ((1e300, np.linalg.LinAlgError), (1e307, ValueError)):  # overflow
        bad = SwitchedLinearSystem.continuous(unstable, None, C3, Q * Q3, R3)
        with pytest.raises(error, match="overflow"):
            log_likelihood(bad, P3, np.zeros(2), np.eye(2), data)
        candidates.insert(7, (bad, P3))
    each = [log_likelihood(s, pi, np.zeros(2), np.eye(2), data) for s, pi in candidates
            if s.Q.max() < 1e299]
    together = log_likelihoods(candidates, np.zeros(2), np.eye(2), data)
    assert np.all(np.isnan(together[7:9]))
    np.testing.assert_allclose(np.delete(together, [7, 8]), each, rtol=1e-12, atol=0)


def test_vehicle_tied_continuous_intensity_is_a_maximum_within_three_standard_errors():
    """One intensity Q tied across the three modes (``shared``). Q = 1e-3 I beside R = 0.05 I
    is weakly identified from 2400 samples: at this seed its maximum is singular, on the
    boundary (named, no standard errors; the relative tolerance of old stopped EM far from
    it, Q[0, 0] at 2.7e-3 where the maximum has 1.4e-3); R within 3 standard errors, and the
    fit at least as likely as the truth (a maximum: EM, slow here, then the direct ascent)."""
    from switchest.learn.data import record
    from switchest.learn.expectation import log_likelihood

    spec = catalog()["shankar-vehicle"]
    sys = spec.system
    t = np.arange(0.0, 60.0, 0.5)
    signal = schedule([10.0, 25.0, 40.0], [0, 1, 2, 0])
    traj = simulate(sys, signal, t, (np.zeros(4), 0.01 * np.eye(4)), np.ones(1), trials=20,
                    rng=3)
    start = SwitchedLinearSystem.continuous(sys.A, sys.B, sys.C, 3 * sys.Q, 0.3 * sys.R)
    with pytest.warns(RuntimeWarning, match=r"on the boundary .* at Q all modes \[0,0\]"):
        res = fit(start, traj.y, np.ones(1), t, x0=np.zeros(4), P0=0.01 * np.eye(4),
                  modes=traj.mode, estimate=("Q", "R"), shared=("Q",), max_iter=200)
    assert res.converged and res.ascent_from is not None
    assert np.all(np.diff(res.loglik) >= -1e-9 * np.abs(res.loglik[:-1]))
    assert np.all(np.isnan(res.se["Q"])) and np.linalg.eigvalsh(res.system.Q[0])[0] >= 0
    within(res.system.R, sys.R, res.se["R"])
    assert np.all(res.system.Q == res.system.Q[:1])  # tied (shared=("Q",)): one Q
    data = record(sys, traj.y, np.ones(1), t, traj.mode)
    truth = log_likelihood(sys, res.transition, np.zeros(4), 0.01 * np.eye(4), data)
    assert res.loglik[-1] >= truth


def test_boost_converter_warns_of_its_unobservable_mode_and_fits_R():
    spec = catalog()["shankar-boost"]
    sys = spec.system
    t = np.arange(0.0, 0.2, 5e-4)
    # switches at the samples (the known-modes model); the catalog's dwell switching falls
    # inside intervals of a converter whose dynamics are faster than the sampling
    chain = MarkovAtSamples(np.array([[0.6, 0.4], [0.4, 0.6]]), initial=0)
    traj = simulate(sys, chain, t, spec.initial, np.array([100.0]), trials=4, rng=5)
    start = SwitchedLinearSystem.continuous(sys.A, sys.B, sys.C, sys.Q, 2 * sys.R)
    with pytest.warns(RuntimeWarning) as caught:
        res = fit(start, traj.y[:1, :50], np.array([100.0]), t[:50], x0=spec.initial[0],
                  P0=spec.initial[1], modes=traj.mode[:1, :50], estimate=("Q",), max_iter=2)
    said = [str(w.message) for w in caught]
    assert any(re.match(r"mode 0: the pair \(C, A\) is unobservable", m) for m in said)
    # and mode 0's Q, unidentifiable, leaves the observed information singular: no standard
    # error for it that claims any precision (which entries keep a vast one turns on the last
    # bits of curvatures near zero; the true Q is I)
    assert any("observed information" in m and "is not positive definite" in m for m in said)
    assert not np.any(res.se["Q"][0] < 10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # Q is not estimated: no observability warning
        res = fit(start, traj.y, np.array([100.0]), t, x0=spec.initial[0], P0=spec.initial[1],
                  modes=traj.mode, estimate=("R",), max_iter=30)
    within(res.system.R, sys.R, res.se["R"])


def test_a_mode_never_visited_is_named_and_kept():
    t = np.arange(300.0)
    P = np.array([[0.9, 0.1, 0.0], [0.1, 0.9, 0.0], [0.5, 0.5, 0.0]])
    traj = simulate(jump_system(), MarkovAtSamples(P, initial=0), t, (np.zeros(2), np.eye(2)),
                    rng=2)
    start = jump_system(Q=2 * Q3)
    with pytest.warns(RuntimeWarning) as caught:
        res = fit(start, traj.y[0], t=t, x0=np.zeros(2), P0=np.eye(2), modes=traj.mode[0],
                  max_iter=5)
    said = [str(w.message) for w in caught]
    assert any(m.startswith("mode 2 was never visited") for m in said)
    assert any("not positive definite at the fit along Q mode 2" in m
               for m in said)  # mode 2's Q: no information
    np.testing.assert_array_equal(res.system.Q[2], start.Q[2])
    assert np.all(np.isnan(res.se["transition"][2]))


def test_rates_from_transition_inverts_expm():
    from scipy.linalg import expm
    rates = np.array([[-2.0, 1.5, 0.5], [1.0, -1.0, 0.0], [0.3, 0.7, -1.0]])
    np.testing.assert_allclose(rates_from_transition(expm(0.1 * rates), 0.1), rates,
                               rtol=1e-8, atol=1e-10)
    assert rates_from_transition(np.array([[0.0, 1.0], [1.0, 0.0]]), 1.0) is None


@pytest.mark.parametrize("kwargs, match", [
    ({"estimate": "Q"}, "collection of names"),
    ({"estimate": ("Q", "D")}, "estimate must name"),
    ({"modes": np.full(50, 3)}, r"modes must be in 0\.\.2"),
    ({"y": np.zeros((50, 2))}, r"y must have shape \(K, m\)"),
])
def test_bad_arguments_are_refused_by_name(kwargs, match):
    args = {"y": np.zeros((50, 1)), "x0": np.zeros(2), "P0": np.eye(2), "transition": P3}
    args.update(kwargs)
    with pytest.raises((ValueError, TypeError), match=match):
        fit(jump_system(), **args)


def test_continuous_A_is_refused():
    sys = catalog()["shankar-vehicle"].system
    with pytest.raises(ValueError, match="'A' and 'B' can be fitted only"):
        fit(sys, np.zeros((5, 2)), t=np.arange(5.0), x0=np.zeros(4), P0=np.eye(4),
            modes=np.zeros(5, int), estimate=("A",))


@pytest.mark.parametrize("correlated", [False, True])
def test_the_C_step_uses_every_observed_component_when_R_is_diagonal(correlated):
    """Row a of C is regressed on the samples that observe component a when every R is
    diagonal (the rows then separate), on the fully observed samples otherwise; checked
    against the least-squares formula written out per row (1e-9: the same sums in another
    order)."""
    rng = np.random.default_rng(8)
    N, K, n, m = 2, 150, 3, 2
    x = rng.normal(size=(N, K, 1, n))
    W = 0.1 * rng.normal(size=(N, K, 1, n, n))
    P = W @ np.swapaxes(W, -1, -2)
    y = np.einsum("ab,nkb->nka", np.array([[1.0, -0.5, 0.2], [0.3, 0.8, -1.0]]), x[:, :, 0])
    y = y + 0.1 * rng.normal(size=y.shape)
    y[rng.random((N, K, m)) < 0.3] = np.nan  # each component missing at its own samples
    R = np.array([[[0.1, 0.04], [0.04, 0.2]]]) if correlated else np.array([np.diag([0.1, 0.2])])
    mom = SimpleNamespace(weight=np.ones((N, K, 1)), x=x, P=P, y=y)
    got = fit_C(np.zeros((1, m, n)), R, mom, tied=False)
    full = ~np.isnan(y).any(axis=-1)
    for a in range(m):
        use = full if correlated else ~np.isnan(y[..., a])
        xs, Ps, ys = x[use][:, 0], P[use][:, 0], y[use][:, a]
        want = np.linalg.solve(Ps.sum(axis=0) + xs.T @ xs, xs.T @ ys)
        np.testing.assert_allclose(got[0, a], want, rtol=1e-9)
    assert full.mean() < 0.6  # the two rules differ: many samples are partly observed
