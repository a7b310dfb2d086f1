"""The Rao-Blackwellized particle filter: against its numpy oracle given the same uniforms, the
Kalman filter with one mode, batching and streaming, and the Monte Carlo rate against the exact
mode posterior by enumeration of every mode sequence."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rbpf_oracle import SCHEMES, rbpf_run, trial_keys, uniforms

from switchest import SwitchedLinearSystem
from switchest.discretize import mode_steps
from switchest.estimators import ModeKalmanFilter
from switchest.estimators._compiled.rbpf import (
    RESAMPLING,
    ancestors,
    resampling_positions,
    uniform,
)
from switchest.estimators._compiled.rbpf import trial_keys as compiled_trial_keys
from switchest.estimators.rbpf import RBPFilter

# a continuous-time pair with an input and two outputs (partly missing samples), sampled
# irregularly: every sample interval gets its own exact transition
A_CT = np.array([[[-0.4, 1.0], [-1.0, -0.3]], [[-0.1, 0.0], [0.5, -1.2]]])
B_CT = np.array([[[0.0], [1.0]], [[1.0], [0.0]]])
C_CT = np.array([[[1.0, 0.2], [0.0, 1.0]], [[1.0, -0.5], [0.3, 1.0]]])
SYS_CT = SwitchedLinearSystem.continuous(A_CT, B_CT, C_CT, Q=0.05 * np.eye(2),
                                         R=[[0.1, 0.02], [0.02, 0.2]])
T_IRREGULAR = np.array([0.0, 0.2, 0.45, 0.6, 0.9, 1.0, 1.3, 1.5, 1.55, 1.9, 2.2])
TRANSITION = np.array([[0.8, 0.2], [0.35, 0.65]])  # asymmetric
X0, P0 = np.array([0.5, -0.5]), np.eye(2)

# a discrete-time pair whose modes the output tells apart only partly: a mode posterior that
# is neither 0 nor 1, for the Monte Carlo rate
SYS_DT = SwitchedLinearSystem.discrete(
    np.array([[[0.9, 0.3], [0.0, 0.6]], [[0.5, -0.4], [0.4, 0.8]]]), np.zeros((2, 2, 1)),
    np.array([[[1.0, 0.0]], [[1.0, 0.5]]]), Q=np.array([0.2 * np.eye(2), 0.5 * np.eye(2)]),
    R=np.array([[[0.3]], [[0.1]]]), dt=1.0)
TRANSITION_DT = np.array([[0.85, 0.15], [0.3, 0.7]])
PROB0_DT = np.array([0.6, 0.4])


def record(seed, trials=2):
    """Measurements of SYS_CT at T_IRREGULAR (any values do: the filters are compared on them),
    one component missing at one sample and every component at another, and inputs."""
    rng = np.random.default_rng(seed)
    K = T_IRREGULAR.size
    y = rng.standard_normal((trials, K, 2)) + np.sin(T_IRREGULAR)[:, None]
    y[0, 3, 0] = np.nan
    y[:, 5] = np.nan
    y[-1, 7, 1] = np.nan
    u = rng.standard_normal((trials, K, 1))
    return y, u


def table(system, t):
    """The exact transitions per mode and distinct step, and ``trans[k, r]``: as IMMFilter.run
    builds them, rebuilt here so that the oracle takes them from an independent path."""
    L, K = system.n_modes, t.size
    steps, which = np.unique(np.diff(t), return_inverse=True)
    table = [mode_steps(system, h) for h in steps]
    F, G, Qd = (np.concatenate([getattr(s, f) for s in table]) for f in ("F", "G", "Qd"))
    trans = np.zeros((K, L), dtype=int)
    trans[1:] = np.arange(L) + L * which[:, None]
    return F, G, Qd, trans


# ------------------------------------------------------------------ the oracle
ORACLE_CASES = [  # proposal, scheme, ess_threshold
    ("prior", "systematic", 0.5),
    ("prior", "multinomial", 1.0),
    ("optimal", "stratified", 1.0),
    ("optimal", "systematic", 0.5),
]


@pytest.mark.parametrize(("proposal", "scheme", "threshold"), ORACLE_CASES)
def test_compiled_equals_the_numpy_oracle(proposal, scheme, threshold):
    Np = 12
    y, u = record(1)
    est = RBPFilter(SYS_CT, TRANSITION, X0, P0, mode_prob0=[0.3, 0.7], particles=Np, rng=5,
                    resample=scheme, ess_threshold=threshold, proposal=proposal)
    out, ess = est.run_with_ess(y, u, T_IRREGULAR)
    keys = est.trial_keys((2,))
    F, G, Qd, trans = table(SYS_CT, T_IRREGULAR)
    ref = rbpf_run(y, u, F, G, Qd, trans, SYS_CT.C, SYS_CT.R, TRANSITION, np.array([0.3, 0.7]),
                   keys, Np, proposal, scheme, threshold, X0, P0)
    # the same draws: modes and flags equal; floats to the rounding of two implementations
    # of the Kalman equations (loops against LAPACK), 1e-9 relative
    np.testing.assert_array_equal(out.mode, ref["mode"])
    np.testing.assert_array_equal(out.outlier, ref["flag"] == 1)
    for name, value in (("x", out.x), ("P", out.P), ("mode_prob", out.mode_prob),
                        ("loglik", out.loglik), ("ess", ess)):
        np.testing.assert_allclose(value, ref[name], rtol=1e-9, atol=1e-12, err_msg=name)
    assert np.all(out.loglik[:, 5] == 0.0)  # nothing observed: no reweighting
    if threshold < 1:  # the case resamples at some samples, not at others
        resampled = ess < threshold * Np
        assert resampled.any() and not resampled.all()


def test_the_uniforms_match_the_oracle_and_look_uniform():
    keys = compiled_trial_keys(np.uint64(2**64 - 3), 4)
    np.testing.assert_array_equal(keys, trial_keys(np.uint64(2**64 - 3), 4))
    draws = np.array([[uniform(keys[1], 7, j) for j in range(2000)]])
    np.testing.assert_array_equal(draws[0], uniforms(keys[1], 7, 2000))
    assert draws.min() >= 0.0 and draws.max() < 1.0
    # Kolmogorov-Smirnov distance of 2000 uniforms: below 1.63 / sqrt(2000) at the 1 % level
    sorted_ = np.sort(draws[0])
    grid = np.arange(1, 2001) / 2000
    assert np.max(np.abs(sorted_ - grid)) < 1.63 / np.sqrt(2000)


@settings(max_examples=60, deadline=None)
@given(weights=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40).filter(
           lambda w: max(w) > 1e-6),
       scheme=st.sampled_from(SCHEMES), key=st.integers(0, 2**64 - 1), k=st.integers(0, 10**6))
def test_resampling_draws_positive_weights_in_their_proportions(weights, scheme, key, k):
    """Douc, Cappé & Moulines (2005), §2: systematic resampling copies particle ``p``
    ``floor(N w_p)`` or ``ceil(N w_p)`` times, stratified within one more of those."""
    w = np.array(weights) / np.sum(weights)
    N = w.size
    pos, anc = np.empty(N), np.empty(N, dtype=np.int64)
    resampling_positions(np.uint64(key), k, RESAMPLING[scheme], N, pos)
    ancestors(w, pos, N, anc)
    assert np.all(np.diff(anc) >= 0) and np.all(w[anc] > 0)
    counts = np.bincount(anc, minlength=N)
    slack = {"systematic": 0, "stratified": 1, "multinomial": N}[scheme]
    assert np.all(counts >= np.floor(N * w - 1e-9) - slack)
    assert np.all(counts <= np.ceil(N * w + 1e-9) + slack)


# ------------------------------------------------------------------ reductions and invariants
@pytest.mark.parametrize("proposal", ["prior", "optimal"])
def test_one_mode_is_the_kalman_filter(proposal):
    one = SwitchedLinearSystem.continuous(A_CT[:1], B_CT[:1], C_CT[:1], Q=0.05 * np.eye(2),
                                          R=[[0.1, 0.02], [0.02, 0.2]])
    y, u = record(2)
    est = RBPFilter(one, [[1.0]], X0, P0, particles=7, rng=0, proposal=proposal,
                    ess_threshold=1.0)
    out = est.run(y, u, T_IRREGULAR)
    ref = ModeKalmanFilter(one, X0, P0).run(y, u, T_IRREGULAR, modes=np.zeros(T_IRREGULAR.size,
                                                                              dtype=int))
    # every particle holds the one Kalman filter: the weighted mean is it, up to the rounding
    # of a sum of 7 equal terms
    for name in ("x", "P", "loglik"):
        np.testing.assert_allclose(getattr(out, name), getattr(ref, name), rtol=1e-9,
                                   atol=1e-12, err_msg=name)
    np.testing.assert_allclose(out.mode_prob, 1.0, rtol=1e-12)


@pytest.mark.parametrize("proposal", ["prior", "optimal"])
def test_the_modes_advance_at_every_sample(proposal):
    """With a chain that always switches and a known first mode, every particle alternates:
    the mode probabilities are exactly 1, 0, 1, 0 ... whatever the data (a filter that never
    advanced its sampled modes would stay at mode 0)."""
    y, u = record(3)
    est = RBPFilter(SYS_CT, [[0.0, 1.0], [1.0, 0.0]], X0, P0, mode_prob0=[1.0, 0.0],
                    particles=9, rng=1, proposal=proposal)
    out = est.run(y, u, T_IRREGULAR)
    expected = np.arange(T_IRREGULAR.size) % 2
    np.testing.assert_array_equal(out.mode, np.broadcast_to(expected, out.mode.shape))
    np.testing.assert_allclose(out.mode_prob[..., 1], out.mode, rtol=1e-12, atol=0)


def test_reproducible_and_independent_of_the_batch():
    y, u = record(4, trials=3)
    make = lambda seed: RBPFilter(SYS_CT, TRANSITION, X0, P0, particles=20, rng=seed,  # noqa: E731
                                  proposal="optimal", resample="stratified")
    est = make(11)
    batched = est.run(y, u, T_IRREGULAR)
    again = make(11).run(y, u, T_IRREGULAR)
    keys = est.trial_keys((3,))
    for name in ("x", "P", "mode_prob", "mode", "loglik", "outlier"):
        np.testing.assert_array_equal(getattr(batched, name), getattr(again, name))
        for i in range(3):  # each trial alone, with the key it got in the batch
            alone = est.run(y[i], u[i], T_IRREGULAR, keys=keys[i])
            np.testing.assert_array_equal(getattr(alone, name), getattr(batched, name)[i],
                                          err_msg=name)
    other = make(12).run(y, u, T_IRREGULAR)
    assert not np.allclose(other.mode_prob, batched.mode_prob)  # the seed matters
    # a batch of shape (3, 1) gets the keys of the flattened batch: the same trials
    shaped = est.run(y[:, None], u[:, None], T_IRREGULAR)
    np.testing.assert_array_equal(shaped.x[:, 0], batched.x)


@pytest.mark.parametrize("proposal", ["prior", "optimal"])
def test_streaming_step_reproduces_run(proposal):
    y, u = record(5)
    est = RBPFilter(SYS_CT, TRANSITION, X0, P0, particles=15, rng=2, proposal=proposal,
                    resample="multinomial")
    whole, ess = est.run_with_ess(y, u, T_IRREGULAR)
    state = est.init((2,))
    for k in range(T_IRREGULAR.size):
        dt = None if k == 0 else T_IRREGULAR[k] - T_IRREGULAR[k - 1]
        state = est.step(state, y[:, k], u[:, max(k - 1, 0)], dt=dt)
        for name, value in (("combined_x", whole.x), ("combined_P", whole.P),
                            ("mode_prob", whole.mode_prob), ("loglik", whole.loglik),
                            ("ess", ess)):
            np.testing.assert_array_equal(getattr(state, name), value[:, k], err_msg=name)
    assert state.k == T_IRREGULAR.size
    np.testing.assert_allclose(np.exp(state.log_weight).sum(-1), 1.0, rtol=1e-12)


def test_step_is_told_where_the_record_starts():
    est = RBPFilter(SYS_CT, TRANSITION, X0, P0, particles=4, rng=0)
    state = est.init((1,))
    with pytest.raises(ValueError, match="dt must be None at the first sample"):
        est.step(state, np.zeros((1, 2)), dt=0.1)
    state = est.step(state, np.zeros((1, 2)))
    with pytest.raises(ValueError, match="dt must be None at the first sample"):
        est.step(state, np.zeros((1, 2)))


def test_an_overflowing_measurement_is_treated_as_missing():
    y, u = record(6, trials=1)
    y[0, 4] = [1e200, -1e200]  # its normalized innovation squared overflows for every particle
    est = RBPFilter(SYS_CT, TRANSITION, X0, P0, particles=10, rng=3)
    out = est.run(y, u, T_IRREGULAR)
    missing = y.copy()
    missing[0, 4] = np.nan
    ref = est.run(missing, u, T_IRREGULAR)
    np.testing.assert_array_equal(out.outlier[0], np.arange(T_IRREGULAR.size) == 4)
    np.testing.assert_array_equal(out.x, ref.x)
    np.testing.assert_array_equal(out.loglik, ref.loglik)


# ------------------------------------------------------------------ the Monte Carlo rate
def simulate_dt(rng, K):
    """One record of SYS_DT under the filter's own model (modes switch at the samples)."""
    sys = SYS_DT
    r = rng.choice(2, p=PROB0_DT)
    x = rng.multivariate_normal(np.zeros(2), np.eye(2))
    y = np.empty((K, 1))
    for k in range(K):
        if k:
            r = rng.choice(2, p=TRANSITION_DT[r])
            x = sys.A[r] @ x + rng.multivariate_normal(np.zeros(2), sys.Q[r])
        y[k] = sys.C[r] @ x + rng.multivariate_normal(np.zeros(1), sys.R[r])
    return y


def exact_posterior(y):
    """``p(r_k | y_{0:k})`` and ``log p(y_{0:K-1})`` by enumeration: one Kalman filter per
    mode sequence (all 2^K, vectorized), each weighted by its prior probability."""
    sys, K = SYS_DT, y.shape[0]
    seqs = np.array(list(itertools.product(range(2), repeat=K)))
    S = len(seqs)
    log_prior = np.log(PROB0_DT[seqs[:, 0]]) + np.log(
        TRANSITION_DT[seqs[:, :-1], seqs[:, 1:]]).sum(axis=1)
    x, P = np.zeros((S, 2)), np.tile(np.eye(2), (S, 1, 1))
    log_joint = np.empty((K, S))
    acc = log_prior.copy()
    for k in range(K):
        r = seqs[:, k]
        if k:
            A = sys.A[r]
            x = np.einsum("sij,sj->si", A, x)
            P = A @ P @ np.swapaxes(A, 1, 2) + sys.Q[r]
        C, R = sys.C[r], sys.R[r]
        e = y[k] - np.einsum("sij,sj->si", C, x)
        Sv = C @ P @ np.swapaxes(C, 1, 2) + R
        gain = P @ np.swapaxes(C, 1, 2) @ np.linalg.inv(Sv)
        acc = acc - 0.5 * (np.einsum("si,sij,sj->s", e, np.linalg.inv(Sv), e)
                           + np.log(np.linalg.det(2 * np.pi * Sv)))
        log_joint[k] = acc
        x = x + np.einsum("sij,sj->si", gain, e)
        P = P - gain @ C @ P
    top = log_joint.max(axis=1, keepdims=True)
    joint = np.exp(log_joint - top)
    prob1 = np.array([joint[k, seqs[:, k] == 1].sum() / joint[k].sum() for k in range(K)])
    return prob1, top[-1, 0] + np.log(joint[-1].sum())


@pytest.fixture(scope="module")
def monte_carlo():
    """Mode-probability errors against the exact posterior on ``TRIALS`` records, at 100 and
    10 000 particles, both proposals: mean absolute error per record ``(TRIALS,)``."""
    K, trials = 8, 24
    rng = np.random.default_rng(2024)
    y = np.stack([simulate_dt(rng, K) for _ in range(trials)])
    exact = [exact_posterior(yi) for yi in y]
    prob1 = np.stack([e[0] for e in exact])
    errors, loglik_error = {}, {}
    for proposal in ("prior", "optimal"):
        for Np in (100, 10_000):
            est = RBPFilter(SYS_DT, TRANSITION_DT, np.zeros(2), np.eye(2), mode_prob0=PROB0_DT,
                            particles=Np, rng=7, proposal=proposal)
            out = est.run(y)
            errors[proposal, Np] = np.abs(out.mode_prob[..., 1] - prob1).mean(axis=1)
            loglik_error[proposal, Np] = out.loglik.sum(axis=1) - np.array([e[1] for e in exact])
    return errors, loglik_error


@pytest.mark.parametrize("proposal", ["prior", "optimal"])
def test_mode_probability_error_falls_at_the_monte_carlo_rate(monte_carlo, proposal):
    errors, _ = monte_carlo
    small, large = errors[proposal, 100], errors[proposal, 10_000]
    ratio = small.mean() / large.mean()
    # 1/sqrt(N): a 100x increase divides the error by 10. The ratio of two means over 24
    # independent records has a relative standard error (delta method) of
    # sqrt(cv_small^2 + cv_large^2) / sqrt(24), cv the records' coefficient of variation; the
    # band [4, 25] is log(2.5) wide on each side, which the assert below keeps at 3 standard
    # errors or more
    cv = np.hypot(small.std(ddof=1) / small.mean(), large.std(ddof=1) / large.mean())
    assert cv / np.sqrt(small.size) < np.log(2.5) / 3
    assert 4.0 < ratio < 25.0, ratio


def test_the_optimal_proposal_is_no_worse_than_the_prior(monte_carlo):
    errors, _ = monte_carlo
    diff = errors["optimal", 100] - errors["prior", 100]  # the same records: paired
    # on average over the records, within two standard errors of the paired mean difference
    assert diff.mean() < 2 * diff.std(ddof=1) / np.sqrt(diff.size)


def test_the_likelihood_estimate_approaches_the_exact_likelihood(monte_carlo):
    _, loglik_error = monte_carlo
    for proposal in ("prior", "optimal"):
        err = loglik_error[proposal, 10_000]
        # the log of an unbiased estimate: bias -var/2, standard deviation O(sqrt(K / N)),
        # a few hundredths at 10 000 particles
        assert np.abs(err).max() < 0.1, err
        assert abs(err.mean()) < 4 * err.std(ddof=1) / np.sqrt(err.size) + 1e-3


# ------------------------------------------------------------------ arguments
@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"particles": 0}, ValueError, "particles must be a positive int"),
    ({"particles": 10.0}, TypeError, "particles must be an int"),
    ({"resample": "residual"}, ValueError, "resample must be one of 'systematic'"),
    ({"resample": 1}, TypeError, "resample must be one of"),
    ({"ess_threshold": 1.5}, ValueError, r"ess_threshold must be in \[0, 1\]"),
    ({"ess_threshold": -0.1}, ValueError, "ess_threshold must be a finite non-negative"),
    ({"ess_threshold": "half"}, TypeError, "ess_threshold must be a real scalar"),
    ({"proposal": "auxiliary"}, ValueError, "proposal must be one of 'prior', 'optimal'"),
    ({"rng": "seed"}, TypeError, "rng must be a numpy Generator"),
    ({"mode_prob0": [0.5, 0.6]}, ValueError, "mode_prob0 must sum to 1"),
])
def test_bad_options_are_refused(kwargs, error, match):
    with pytest.raises(error, match=match):
        RBPFilter(SYS_CT, TRANSITION, X0, P0, **kwargs)


def test_bad_keys_are_refused():
    est = RBPFilter(SYS_CT, TRANSITION, X0, P0, particles=4, rng=0)
    y, u = record(7)
    with pytest.raises(ValueError, match=r"keys must have the batch shape \(2,\)"):
        est.run(y, u, T_IRREGULAR, keys=np.arange(3))
    with pytest.raises(TypeError, match="keys must be integers"):
        est.run(y, u, T_IRREGULAR, keys=np.array([0.5, 1.5]))
    with pytest.raises(ValueError, match="keys must be non-negative"):
        est.run(y, u, T_IRREGULAR, keys=np.array([1, -1]))
    with pytest.raises(ValueError, match="transition rows must sum to 1"):
        RBPFilter(SYS_CT, [[0.5, 0.4], [0.5, 0.5]], X0, P0)
