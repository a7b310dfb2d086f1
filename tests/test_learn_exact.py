"""The exact E-step of unknown modes (enumeration of the mode sequences) against a dense joint
Gaussian oracle, EM's monotonicity with it, Kim's E-step against it where the modes are
identified, and Kim's lagged outputs with several modes against a numpy transcription of the
smoother's formulas (Kim 1994 §2.2; :mod:`switchest.engine.smoother`).

Tolerances: compiled or vectorized algebra against plain numpy of the same quantity, 1e-9
relative (rounding of a few hundred flops on O(1) numbers, ~1e-14, with a wide margin).
"""

import itertools
import warnings

import numpy as np
import pytest

from switchest.estimators import ExactMixtureFilter
from switchest.estimators.smoothing import smooth_mode_matched
from switchest.learn import fit
from switchest.learn.data import record
from switchest.learn.expectation import expectation
from switchest.learn.noise_step import step_residual_moments
from switchest.simulate import simulate
from switchest.switching import MarkovAtSamples
from switchest.system import SwitchedLinearSystem

RTOL = 1e-9
PI2 = np.array([[0.8, 0.2], [0.3, 0.7]])  # asymmetric


def two_mode_system(Q_scale=1.0, R_scale=1.0):
    A = np.array([[[0.9, 0.2], [-0.1, 0.7]], [[0.5, 0.0], [0.3, 1.0]]])
    B = np.array([[[1.0], [0.0]], [[0.0], [0.5]]])
    C = np.array([[[1.0, 0.0]], [[1.0, -1.0]]])
    Q = Q_scale * np.array([np.diag([0.2, 0.1]), [[0.3, 0.1], [0.1, 0.2]]])
    R = R_scale * np.array([[[0.3]], [[0.1]]])
    return SwitchedLinearSystem.discrete(A, B, C, Q, R, dt=1.0)


def dense_oracle(system, transition, m0, S0, y, u):
    """Brute force, one trial ``y (K, m)``: for every sequence (``itertools.product``) the joint
    Gaussian of ``x_0..x_{K-1}`` written out densely in the package's timing (``x_k =
    A_{r_{k-1}} x_{k-1} + B_{r_{k-1}} u_{k-1} + w``, ``w ~ N(0, Q_{r_{k-1}})``, ``y_k = C_{r_k}
    x_k + v``), conditioned on the observed ``y`` by the
    Gaussian conditioning formula; sequences weighted by ``p(r) p(y | r)`` (uniform ``r_0``).
    Returns the log-likelihood, mode and pair probabilities and the moments of ``Moments``."""
    K, m = y.shape
    L, n = system.n_modes, system.n_states
    seqs = list(itertools.product(range(L), repeat=K))
    logw, means, covs = [], [], []
    for r in seqs:
        # x = mean + T z with z = (x_0 - m0, w_1, .., w_{K-1}) independent, Cov(z) = Z
        mean, T, Z = np.zeros((K, n)), np.zeros((K * n, K * n)), np.zeros((K * n, K * n))
        mean[0], T[:n, :n], Z[:n, :n] = m0, np.eye(n), S0
        for k in range(1, K):
            drive = r[k - 1]  # the mode of sample k - 1 governs the interval into k
            A, here, before = system.A[drive], slice(k * n, (k + 1) * n), slice((k - 1) * n, k * n)
            mean[k] = A @ mean[k - 1] + system.B[drive] @ u[k - 1]
            T[here] = A @ T[before]
            T[here, here] = np.eye(n)
            Z[here, here] = system.Q[drive]
        Sx = T @ Z @ T.T
        H = np.zeros((K * m, K * n))
        Rb = np.zeros((K * m, K * m))
        for k in range(K):
            H[k * m:(k + 1) * m, k * n:(k + 1) * n] = system.C[r[k]]
            Rb[k * m:(k + 1) * m, k * m:(k + 1) * m] = system.R[r[k]]
        seen = ~np.isnan(y.ravel())
        H, Rb, yo = H[seen], Rb[np.ix_(seen, seen)], y.ravel()[seen]
        S = H @ Sx @ H.T + Rb
        e = yo - H @ mean.ravel()
        gain = Sx @ H.T @ np.linalg.inv(S)
        logp = -0.5 * (e @ np.linalg.solve(S, e) + np.linalg.slogdet(2 * np.pi * S)[1])
        prior = np.log(1.0 / L) + sum(np.log(transition[r[k - 1], r[k]]) for k in range(1, K))
        logw.append(prior + logp)
        means.append((mean.ravel() + gain @ e).reshape(K, n))
        covs.append((Sx - gain @ H @ Sx).reshape(K, n, K, n))
    logw = np.array(logw)
    top = logw.max()
    loglik = top + np.log(np.exp(logw - top).sum())
    w = np.exp(logw - loglik)
    seqs = np.array(seqs)
    out = {"loglik": loglik, "weight": np.zeros((K, L)), "pair": np.zeros((K - 1, L, L)),
           "x": np.zeros((K, L, n)), "P": np.zeros((K, L, n, n))}
    for name in ("x1", "x0"):
        out[name] = np.zeros((K - 1, L, n))
    for name in ("P1", "P0", "cross"):
        out[name] = np.zeros((K - 1, L, n, n))
    means, covs = np.array(means), np.array(covs)
    for k in range(K):
        for j in range(L):
            sel = seqs[:, k] == j
            ws = w[sel] / w[sel].sum()
            out["weight"][k, j] = w[sel].sum()
            mx = ws @ means[sel, k]
            d = means[sel, k] - mx
            out["x"][k, j] = mx
            out["P"][k, j] = (np.einsum("s,sab->ab", ws, covs[sel, k, :, k])
                              + (ws[:, None] * d).T @ d)
            if k == 0:
                continue
            out["pair"][k - 1] += np.array([[w[sel & (seqs[:, k - 1] == i)].sum()
                                             for i in range(L)]]).T * np.eye(L)[j]
            # the interval k-1 -> k, given the mode that drives it (r_{k-1} = j)
            drive = seqs[:, k - 1] == j
            wd = w[drive] / w[drive].sum()
            m1, m0_ = wd @ means[drive, k], wd @ means[drive, k - 1]
            d1, d0 = means[drive, k] - m1, means[drive, k - 1] - m0_
            out["x1"][k - 1, j], out["x0"][k - 1, j] = m1, m0_
            out["P1"][k - 1, j] = (np.einsum("s,sab->ab", wd, covs[drive, k, :, k])
                                   + (wd[:, None] * d1).T @ d1)
            out["P0"][k - 1, j] = (np.einsum("s,sab->ab", wd, covs[drive, k - 1, :, k - 1])
                                   + (wd[:, None] * d0).T @ d0)
            out["cross"][k - 1, j] = (np.einsum("s,sab->ab", wd, covs[drive, k, :, k - 1])
                                      + (wd[:, None] * d1).T @ d0)
    return out


def test_exact_e_step_equals_the_dense_joint_gaussian_over_every_sequence():
    rng = np.random.default_rng(4)
    system = two_mode_system()
    K, N = 5, 2
    y = rng.normal(size=(N, K, 1))
    y[1, 2] = np.nan  # a missing sample
    u = rng.normal(size=(N, K, 1))
    m0, S0 = np.array([0.5, -0.2]), np.diag([1.0, 0.5])
    mom = expectation(system, PI2, m0, S0, record(system, y, u, None, None), exact=True)
    loglik, pairs = 0.0, 0.0
    for i in range(N):
        ref = dense_oracle(system, PI2, m0, S0, y[i], u[i])
        loglik += ref["loglik"]
        pairs = pairs + ref["pair"].sum(axis=0)
        for name in ("weight", "x", "P", "x1", "P1", "x0", "P0", "cross"):
            np.testing.assert_allclose(getattr(mom, name)[i], ref[name], rtol=RTOL,
                                       atol=RTOL * np.abs(ref[name]).max(), err_msg=name)
        np.testing.assert_allclose(mom.step_weight[i], ref["weight"][:-1], rtol=RTOL, atol=1e-15)
    np.testing.assert_allclose(mom.loglik, loglik, rtol=RTOL)
    np.testing.assert_allclose(mom.pairs, pairs, rtol=RTOL)
    flt = ExactMixtureFilter(system, PI2, m0, S0, timing="sample").run(y, u)
    np.testing.assert_allclose(mom.loglik, flt.loglik.sum(), rtol=RTOL)


def test_em_with_the_exact_e_step_never_lowers_the_exact_likelihood():
    truth = two_mode_system()
    t = np.arange(6.0)
    traj = simulate(truth, MarkovAtSamples(PI2, initial=0), t, (np.zeros(2), np.eye(2)),
                    np.ones(1), trials=6, rng=3)
    start = two_mode_system(Q_scale=2.5, R_scale=0.3)
    start_pi = np.array([[0.5, 0.5], [0.6, 0.4]])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = fit(start, traj.y, np.ones(1), transition=start_pi, x0=np.zeros(2), P0=np.eye(2),
                  estimate=("transition", "A", "C", "Q", "R"), max_iter=12, tol=1e-12,
                  e_step="exact")
    assert not [w for w in caught if "decreased" in str(w.message)]  # fit warns of a drop
    steps = np.diff(res.loglik)
    assert np.all(steps >= -1e-9 * np.abs(res.loglik[:-1])), steps
    assert res.loglik[-1] > res.loglik[0] + 1.0  # it climbed from the wrong start
    exact = ExactMixtureFilter(res.system, res.transition, np.zeros(2), np.eye(2),
                               timing="sample")
    # the trace is the exact likelihood (the last entry that of the returned parameters)
    np.testing.assert_allclose(res.loglik[-1], exact.run(traj.y, np.ones(1)).loglik.sum(),
                               rtol=RTOL)


def identified_system(R_scale):
    """Three modes with different A, Q, C, R whose outputs (C = I, -I and a quarter turn, on a
    state of norm 3 to 4.5) name the mode at every sample: with ``R_scale = 0.1`` a wrong mode's
    log-likelihood at a sample is 90 to 400 below the right one's, so the posterior of the modes
    is 0 or 1 to ~1e-39 (and does not underflow to exactly 0), and GPB2 and the smoothers are
    exact to rounding; with ``R_scale = 1e-6`` the wrong modes' filtered probabilities underflow
    to exactly zero."""
    def rot(a, s):
        return s * np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    A = np.array([rot(0.1, 0.99), rot(-0.2, 1.0), [[1.0, 0.1], [0.0, 0.95]]])
    Q = np.array([np.diag([0.01, 0.005]), np.diag([0.03, 0.01]), np.diag([0.005, 0.02])])
    C = np.array([np.eye(2), -np.eye(2), rot(np.pi / 2, 1.0)])
    R = R_scale * np.array([np.eye(2), [[1.0, 0.2], [0.2, 0.8]], np.diag([1.0, 1.5])])
    return SwitchedLinearSystem.discrete(A, None, C, Q, R, dt=1.0)


PI3 = np.array([[0.8, 0.15, 0.05], [0.1, 0.8, 0.1], [0.05, 0.15, 0.8]])  # asymmetric


def approximate_against_exact(R_scale):
    system = identified_system(R_scale)
    m0, S0 = np.array([3.0, -3.0]), 0.01 * np.eye(2)
    traj = simulate(system, MarkovAtSamples(PI3, initial=0), np.arange(7.0), (m0, S0),
                    trials=6, rng=3)
    data = record(system, traj.y, None, None, None)
    exact = expectation(system, PI3, m0, S0, data, exact=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the divergence warning of the broken case
        approx = expectation(system, PI3, m0, S0, data)
    assert np.all((exact.weight < 1e-30) | (exact.weight > 1 - 1e-15))  # identified
    for name in ("weight", "step_weight", "pairs"):
        np.testing.assert_allclose(getattr(approx, name), getattr(exact, name), rtol=RTOL,
                                   atol=1e-15, err_msg=name)
    # moments given a mode: compared where that mode has the weight (elsewhere each method
    # keeps its own stand-in, multiplied by a weight below 1e-30 in every M-step)
    F, G = exact.table.F[exact.entry], exact.table.G[exact.entry]
    e, k = (step_residual_moments(F, G, data.u, m) for m in (exact, approx))
    pairs = [(getattr(exact, name), getattr(approx, name), exact.weight > 0.5)
             for name in ("x", "P")]
    pairs += [(getattr(exact, name), getattr(approx, name), exact.step_weight > 0.5)
              for name in ("x1", "P1", "x0", "P0", "cross")] + [(e, k, exact.step_weight > 0.5)]
    for name, (a, b, held) in zip(("x", "P", "x1", "P1", "x0", "P0", "cross", "E[w w']"), pairs):
        np.testing.assert_allclose(b[held], a[held], rtol=RTOL, atol=RTOL * np.abs(a).max(),
                                   err_msg=name)
    np.testing.assert_allclose(approx.loglik, exact.loglik, rtol=RTOL)


def test_approximate_e_step_equals_the_exact_one_where_the_modes_are_identified():
    """Where the modes are known from the data, the two-filter E-step must be the exact one,
    quantity by quantity: a convention mismatch (which mode drives the interval into k + 1, lag
    moments conditioned on the wrong mode) would show here at O(1)."""
    approximate_against_exact(0.1)


def test_approximate_e_step_equals_the_exact_one_with_filtered_probabilities_exactly_zero():
    """A mode whose filtered probability is exactly 0 makes its pairs impossible in every lane:
    the smoother's weights and moments of those pairs must still be finite, of weight 0."""
    approximate_against_exact(1e-6)


def kim_lagged_oracle(xf, Pf, pf, u, F, G, Qd, trans, pi):
    """Kim (1994) §2.2 with the lagged outputs, one trial, plain numpy: the pairs' RTS steps
    ``x_ji = x_j + J (x_i(k+1|K) - x_pred)``, ``P_ji = P_j + J (P_i(k+1|K) - P_pred) J'``;
    ``back_ij = mu_j(k|k) pi_ji / sum_j' mu_j'(k|k) pi_j'i``, ``mu_ji(k|K) = mu_i(k+1|K)
    back_ij``; ``x_k | r_{k+1} = i``: the mixture over ``j`` weighted by ``back_ij``;
    ``Cov(x_{k+1}, x_k | i) = P_i(k+1|K) (sum_j back_ij J_ji)'``."""
    K, L, n = xf.shape
    xs, Ps, ps = xf.copy(), Pf.copy(), pf.copy()
    pair, lx = np.zeros((K - 1, L, L)), np.zeros((K - 1, L, n))
    lP, lc = np.zeros((K - 1, L, n, n)), np.zeros((K - 1, L, n, n))
    for k in range(K - 2, -1, -1):
        xji, Pji, Jji = np.zeros((L, L, n)), np.zeros((L, L, n, n)), np.zeros((L, L, n, n))
        for j, i in itertools.product(range(L), repeat=2):
            a = trans[k + 1, i]
            Pp = F[a] @ Pf[k, j] @ F[a].T + Qd[a]
            J = np.linalg.solve(Pp, F[a] @ Pf[k, j]).T
            xji[j, i] = xf[k, j] + J @ (xs[k + 1, i] - F[a] @ xf[k, j] - G[a] @ u[k])
            Pji[j, i] = Pf[k, j] + J @ (Ps[k + 1, i] - Pp) @ J.T
            Jji[j, i] = J
        back = pf[k][:, None] * pi
        back /= back.sum(axis=0, keepdims=True)
        pair[k] = back * ps[k + 1][None, :]
        ps[k] = pair[k].sum(axis=1)
        for j in range(L):
            w = pair[k, j] / ps[k, j]
            xs[k, j] = w @ xji[j]
            d = xji[j] - xs[k, j]
            Ps[k, j] = np.einsum("i,iab->ab", w, Pji[j]) + (w[:, None] * d).T @ d
        for i in range(L):
            w = back[:, i]
            lx[k, i] = w @ xji[:, i]
            d = xji[:, i] - lx[k, i]
            lP[k, i] = np.einsum("j,jab->ab", w, Pji[:, i]) + (w[:, None] * d).T @ d
            lc[k, i] = Ps[k + 1, i] @ np.einsum("j,jab->ab", w, Jji[:, i]).T
    return pair, lx, lP, lc


def test_kim_lagged_outputs_with_three_modes_equal_the_numpy_formulas():
    rng = np.random.default_rng(5)
    K, L, n, N = 6, 3, 2, 3
    xf = rng.normal(size=(N, K, L, n))
    W = rng.normal(size=(N, K, L, n, n))
    Pf = W @ np.swapaxes(W, -1, -2) + 0.1 * np.eye(n)
    pf = rng.dirichlet(np.ones(L), size=(N, K))
    F, G = rng.normal(size=(2 * L, n, n)), rng.normal(size=(2 * L, n, 1))
    V = rng.normal(size=(2 * L, n, n))
    Qd = V @ np.swapaxes(V, -1, -2) + 0.1 * np.eye(n)
    u = rng.normal(size=(N, K, 1))
    trans = np.zeros((K, L), np.int64)  # two distinct steps: rows d L + j
    trans[1:] = np.arange(L) + L * rng.integers(0, 2, size=(K - 1, 1))
    pi = rng.dirichlet(np.ones(L), size=L)
    s = smooth_mode_matched(xf, Pf, pf, u, F, G, Qd, trans, pi, lagged=True, timing="interval")
    for b in range(N):
        ref = kim_lagged_oracle(xf[b], Pf[b], pf[b], u[b], F, G, Qd, trans, pi)
        for got, want in zip((s.pair_prob, s.lag_x, s.lag_P, s.lag_cross), ref):
            np.testing.assert_allclose(got[b], want, rtol=RTOL, atol=RTOL * np.abs(want).max())


@pytest.mark.parametrize("kwargs, match", [
    ({"e_step": "gpb2"}, "e_step must be 'two-filter' or 'exact'"),
    ({"e_step": "exact", "y": np.zeros((17, 1))}, r"L\^K = 2\^17 .* more than 65536"),
])
def test_bad_e_step_is_refused_by_name(kwargs, match):
    args = {"y": np.zeros((5, 1)), "x0": np.zeros(2), "P0": np.eye(2), "transition": PI2}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        fit(two_mode_system(), **args)
