"""Moments of the subsystem observers' error (Wang et al., seed 003) against independent oracles.

The oracle is the scalar pair of Examples 1-4 in closed form: a component closed with gain
``L`` maps its error by ``g = e^{(a-L)T}`` and injects ``q^2 = L^2 zeta (1 - e^{-2(L-a)T}) /
(2(L-a))`` (Proposition 1), open loop by ``e^{aT}`` and nothing. Over a short horizon every
mode sequence is enumerated; given one, the errors ``e_0..e_K`` of a component are jointly
Gaussian with a dense mean and covariance, whose quadratic forms give every moment exactly.
"""

import itertools

import numpy as np
import pytest

from switchest import simulate
from switchest.analysis import (
    component_steady_state,
    error_dynamics,
    moment_fixed_point,
    moment_matrix,
    ms_convergence,
    optimal_component_gain,
    scalar_error_moments,
    state_error_moments,
    steady_state,
    window_average_sd,
    window_sums_given_modes,
)
from switchest.estimators.rsls import RSLSObserver
from switchest.models import WANG_EXAMPLES
from switchest.signals import iid_at_samples

EX = WANG_EXAMPLES["example1"]
SYSTEM, P, T = EX.system(), EX.probabilities(), EX.T
GAINS = (40.0, 15.0)
E0 = np.array([2.0, 2.0])
K, START = 5, 2
Z_MAX = 4.0  # |z| of a standardized statistic; P(|z| > 4) ~ 6e-5 under the null


def _gains(L1, L2):
    return np.array([[[L1], [0.0]], [[0.0], [L2]]])


def _closed_form(c):
    """(g, q^2) of component ``c`` in each mode (Wang et al. eqs. (13)-(14), Proposition 1)."""
    a, L = (EX.a1, EX.a2)[c], GAINS[c]
    g, q2 = np.full(2, np.exp(a * T)), np.zeros(2)
    g[c] = np.exp((a - L) * T)
    q2[c] = L**2 * EX.zeta * (1 - np.exp(-2 * (L - a) * T)) / (2 * (L - a))
    return g, q2


def _joint(c, seq):
    """Mean (K+1,) and covariance (K+1, K+1) of component c's errors along the modes ``seq``."""
    g, q2 = _closed_form(c)
    mean, cov = np.zeros(K + 1), np.zeros((K + 1, K + 1))
    mean[0] = E0[c]
    for k, i in enumerate(seq):
        mean[k + 1] = g[i] * mean[k]
        cov[k + 1, : k + 1] = g[i] * cov[k, : k + 1]  # Cov(e_{k+1}, e_j) = g Cov(e_k, e_j)
        cov[: k + 1, k + 1] = cov[k + 1, : k + 1]
        cov[k + 1, k + 1] = g[i] ** 2 * cov[k, k] + q2[i]
    return mean, cov


def _window(mean, cov):
    """E and Var of ``S = sum_{k >= START} e_k^2`` for a Gaussian vector (dense quadratic form)."""
    m, S = mean[START:], cov[START:, START:]
    return m @ m + np.trace(S), 2 * np.trace(S @ S) + 4 * m @ S @ m


def _sequences():
    for seq in itertools.product(range(2), repeat=K):
        yield np.array(seq), np.prod(P[list(seq)])


def test_scalar_moments_and_window_spread_against_enumeration():
    dyn = error_dynamics(SYSTEM, _gains(*GAINS), T)
    moments = scalar_error_moments(dyn, P, E0, K)
    sd = window_average_sd(moments, START)
    for c in range(2):
        E2, E4, ES, ES2 = np.zeros(K + 1), np.zeros(K + 1), 0.0, 0.0
        for seq, w in _sequences():
            mean, cov = _joint(c, seq)
            v = np.diag(cov)
            E2 += w * (mean**2 + v)
            E4 += w * (mean**4 + 6 * mean**2 * v + 3 * v**2)
            es, var = _window(mean, cov)
            ES, ES2 = ES + w * es, ES2 + w * (var + es**2)
        np.testing.assert_allclose(moments.E2[:, c], E2, rtol=1e-12)
        np.testing.assert_allclose(moments.E4[:, c], E4, rtol=1e-12)
        W = K + 1 - START
        assert sd[c] == pytest.approx(np.sqrt(ES2 - ES**2) / W, rel=1e-9)
    np.testing.assert_allclose(state_error_moments(dyn, P, E0, K), moments.E2, rtol=1e-12)


def test_window_sums_given_each_mode_sequence():
    dyn = error_dynamics(SYSTEM, _gains(*GAINS), T)
    seqs = np.array([seq for seq, _ in _sequences()])
    sums = window_sums_given_modes(dyn, E0, seqs, START, np.eye(2))
    for n, seq in enumerate(seqs):
        for c in range(2):
            es, var = _window(*_joint(c, seq))
            assert sums.mean[n, c] == pytest.approx(es, rel=1e-12)
            assert sums.var[n, c] == pytest.approx(var, rel=1e-9)
    weighted = window_sums_given_modes(dyn, E0, seqs, START, [[1.0, 1.0]])
    np.testing.assert_allclose(weighted.mean[:, 0], sums.mean.sum(axis=1), rtol=1e-12)


def _simulated_errors(rng):
    """300 runs of 40 intervals of the simulated observer with gains (40, 15), and their modes."""
    t = T * np.arange(41)
    traj = simulate(SYSTEM, lambda r: iid_at_samples(P, t, rng=r), t, np.zeros(2), trials=300,
                    rng=rng, fine_dt=T / 10, output="integrated")
    est = RSLSObserver(SYSTEM, _gains(*GAINS), T, E0, np.zeros((2, 2))).run(
        traj.y_fine, t=traj.t_fine, modes=traj.mode_fine)
    return est.x[:, np.searchsorted(traj.t_fine, t)] - traj.x, traj.mode[:, :-1]


def test_given_modes_check_accepts_the_right_gain_and_detects_a_wrong_one():
    """Simulated runs: standardized window sums are N(0, 1) summed; another gain's are far off."""
    err, modes = _simulated_errors(np.random.default_rng(7))
    observed = np.einsum("nkc->nc", err[:, 20:] ** 2)
    # L1 = 20 has almost the same steady state as 40 (0.4878 vs 0.4874): only this check sees it
    for gains, ok in ((GAINS, True), ((20.0, 30.0), False)):
        sums = window_sums_given_modes(error_dynamics(SYSTEM, _gains(*gains), T), E0, modes, 20,
                                       np.eye(2))
        z = np.abs((observed - sums.mean).sum(axis=0) / np.sqrt(sums.var.sum(axis=0)))
        assert np.all(z < Z_MAX) if ok else np.all(z > Z_MAX)


def test_steady_states_agree():
    dyn = error_dynamics(SYSTEM, _gains(*GAINS), T)
    exact = steady_state(dyn, P)
    np.testing.assert_allclose(moment_fixed_point(dyn.Lam, dyn.W, P), exact.V, rtol=1e-12)
    np.testing.assert_allclose(component_steady_state(dyn, P), np.diag(exact.V_x), rtol=1e-12)
    far = state_error_moments(dyn, P, E0, 2000)[-1]
    np.testing.assert_allclose(far, np.diag(exact.V_x), rtol=1e-9)
    M = moment_matrix(dyn, P)
    eig = ms_convergence(dyn, P).moment_eigenvalues
    np.testing.assert_allclose(np.linalg.eigvalsh(M)[::-1], eig, rtol=1e-12)
    for c in range(2):  # diagonal: each component's factor E[g^2] of the closed form
        g, _ = _closed_form(c)
        assert M[c, c] == pytest.approx(P @ g**2, rel=1e-12)


def test_a_diverging_component_has_no_steady_state():
    kb = _gains(2 * EX.a1, 2 * EX.a2)  # Example 1: Kalman-Bucy gains, e^1 diverges in MS
    steady = component_steady_state(error_dynamics(SYSTEM, kb, T), P)
    assert np.isnan(steady[0]) and np.isfinite(steady[1])


def test_optimal_component_gain_against_the_closed_form():
    """Example 4: sigma_inf^1 = p q^2 / (1 - E[g^2]) minimized on a fine grid: the same optimum."""
    opt = optimal_component_gain(SYSTEM, P, T, _gains(0.0, GAINS[1]), 0)
    a, p, zeta = EX.a1, EX.p, EX.zeta
    L = np.linspace(20.0, 35.0, 15001)
    gamma = p * np.exp(2 * (a - L) * T) + (1 - p) * np.exp(2 * a * T)
    sigma = p * L**2 * zeta * (1 - np.exp(-2 * (L - a) * T)) / (2 * (L - a)) / (1 - gamma)
    assert opt.holds
    assert opt.gain == pytest.approx(L[np.argmin(sigma)], abs=2e-3)  # grid step 1e-3
    assert opt.steady_state == pytest.approx(sigma.min(), rel=1e-8)


@pytest.mark.parametrize(("call", "match"), [
    (lambda d: state_error_moments(d, P, [1.0], 3), r"e0 must have shape \(2,\)"),
    (lambda d: scalar_error_moments(d, P, E0, -1), "steps must be a non-negative int"),
    (lambda d: moment_matrix(d, [0.5, 0.6]), "p must sum to 1"),
    (lambda d: window_sums_given_modes(d, E0, np.zeros((2, 3)), 1, np.eye(2)),
     r"modes must be an \(N, K\) integer array"),
    (lambda d: window_sums_given_modes(d, E0, np.zeros((2, 3), int), 4, np.eye(2)),
     r"start must be in \[0, 3\]"),
    (lambda d: window_average_sd(scalar_error_moments(d, P, E0, 3), 4),
     r"start must be in \[0, 3\]"),
    (lambda d: moment_fixed_point(d.Lam, d.W[:1], P), "Lam and W must both have shape"),
    (lambda d: optimal_component_gain(SYSTEM, P, T, _gains(1.0, 1.0), 2),
     r"component must be in \[0, 1\]"),
])
def test_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call(error_dynamics(SYSTEM, _gains(*GAINS), T))
