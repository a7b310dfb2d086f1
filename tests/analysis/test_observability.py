"""Observability: PBH with deflation, Kalman decomposition, Lee's joint observability,
Wang's combined observability, Shankar's uniform observability under sampling."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad_vec
from scipy.linalg import expm
from scipy.stats import ortho_group

from switchest import SwitchedLinearSystem
from switchest.analysis.observability import (
    combined_observability,
    dwell_time_observability,
    is_observable,
    joint_gramian,
    joint_observability,
    kalman_decomposition,
    mode_decompositions,
    mode_observability,
    observability_matrix,
    omega_min,
    uniform_observability,
)


def _pbh_min_singular(A, C):
    """Oracle: min over eigenvalues of sigma_min([A - lambda I; C])."""
    n = A.shape[0]
    return min(
        np.linalg.svd(np.vstack([A - lam * np.eye(n), C]), compute_uv=False)[-1]
        for lam in np.linalg.eigvals(A)
    )


def _planted(rng, n, n_obs, m):
    """(A, C) = T-similar to [[A11, A12], [0, A22]], [0, C2]: unobservable dimension n - n_obs."""
    d = n - n_obs
    Ah = rng.normal(size=(n, n))
    Ah[d:, :d] = 0.0
    Ch = np.zeros((m, n))
    Ch[:, d:] = rng.normal(size=(m, n_obs))
    T = rng.normal(size=(n, n)) + n * np.eye(n)
    Ti = np.linalg.inv(T)
    return T @ Ah @ Ti, Ch @ Ti


# ------------------------------------------------------------------ n = 30
N30 = 30
Q30 = ortho_group.rvs(N30, random_state=0)
A30 = Q30 @ np.diag(-np.arange(1.0, N30 + 1)) @ Q30.T
C30 = np.ones((1, N30)) @ Q30.T


def test_n30_observable_where_the_rank_of_the_observability_matrix_fails():
    O = observability_matrix(A30, C30)
    assert np.linalg.matrix_rank(O) < N30  # the naive test says "unobservable" (rank 6 here)
    assert is_observable(A30, C30)
    assert _pbh_min_singular(A30, C30) > 0.1  # oracle: far from unobservable
    dec = kalman_decomposition(A30, C30)
    assert dec.n_observable == N30 and dec.margin > 0.1


@pytest.mark.parametrize("hidden", [0, 5, 15, 29])
def test_n30_with_one_hidden_eigenvector(hidden):
    # C v_k = 0 for the eigenvector of eigenvalue -(hidden + 1): unobservable dimension 1
    c = np.ones((1, N30))
    c[0, hidden] = 0.0
    C = c @ Q30.T
    assert not is_observable(A30, C)
    dec = kalman_decomposition(A30, C)
    assert dec.n_observable == N30 - 1
    assert abs(dec.M[:, 0] @ Q30[:, hidden]) == pytest.approx(1.0, abs=1e-10)
    assert np.abs(dec.A_hat[1:, :1]).max() < 1e-12


# ------------------------------------------------------------------ small systems
@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 5),
    m=st.integers(1, 2),
    data=st.data(),
)
def test_planted_unobservable_dimension_is_found(seed, n, m, data):
    n_obs = data.draw(st.integers(0, n))
    rng = np.random.default_rng(seed)
    A, C = _planted(rng, n, n_obs, m)
    dec = kalman_decomposition(A, C)
    rank = np.linalg.matrix_rank(observability_matrix(A, C), tol=1e-8 * np.linalg.norm(A) ** n)
    # a random observable block is observable almost surely, so rank = n_obs
    assert dec.n_observable == n_obs == rank
    T = dec.T
    np.testing.assert_allclose(T.T @ T, np.eye(n), atol=1e-12)
    d = n - n_obs
    scale = np.linalg.norm(A) + np.linalg.norm(C)
    assert np.abs(dec.A_hat[d:, :d]).max(initial=0) < 1e-9 * scale
    assert np.abs(dec.C_hat[:, :d]).max(initial=0) < 1e-9 * scale
    np.testing.assert_allclose(observability_matrix(A, C) @ dec.M, 0, atol=1e-8 * scale**n)
    if n_obs:
        assert is_observable(dec.A22, dec.C2)


@pytest.mark.parametrize(("c", "n_obs"), [([1, 0, 0], 3), ([0, 1, 0], 2), ([0, 0, 1], 1)])
def test_jordan_block_chains(c, n_obs):
    # J upper Jordan block: e1 is the eigenvector; C = e_k' observes the chain from e_k down
    J = np.array([[2.0, 1, 0], [0, 2, 1], [0, 0, 2]])
    U = ortho_group.rvs(3, random_state=1)
    dec = kalman_decomposition(U @ J @ U.T, np.array([c], dtype=float) @ U.T)
    assert dec.n_observable == n_obs


def test_complex_pair_and_repeated_eigenvalue():
    A = np.zeros((4, 4))
    A[:2, :2] = [[0.0, 1.0], [-1.0, 0.0]]
    A[2:, 2:] = -np.eye(2)
    dec = kalman_decomposition(A, np.array([[0.0, 0, 1, 1]]))
    # the rotation is unseen (2 dims) and one output sees one direction of -I
    assert dec.n_observable == 1
    np.testing.assert_allclose(
        dec.M[:2].T @ dec.M[:2] + dec.M[2:].T @ dec.M[2:], np.eye(3), atol=1e-12
    )


def test_observability_matrix_values_and_batching():
    A = np.array([[1.0, 2.0], [3.0, 4.0]])
    C = np.array([[1.0, 0.0]])
    np.testing.assert_array_equal(observability_matrix(A, C), [[1, 0], [1, 2]])
    np.testing.assert_array_equal(observability_matrix(A, C, order=3)[2], (C @ A @ A)[0])
    stack = observability_matrix(np.stack([A, 2 * A]), np.stack([C, C]))
    assert stack.shape == (2, 2, 2)
    np.testing.assert_array_equal(stack[1], observability_matrix(2 * A, C))


@pytest.mark.parametrize(
    ("args", "kwargs", "exc", "match"),
    [
        ((np.ones((2, 3)), np.ones((1, 3))), {}, ValueError, "A must be a non-empty square"),
        ((np.eye(2), np.ones((1, 3))), {}, ValueError, r"C must have shape \(m, 2\)"),
        ((np.eye(2), [[np.inf, 0]]), {}, ValueError, "C must be finite"),
        (
            (np.eye(2), np.ones((1, 2))),
            {"rtol": -1.0},
            ValueError,
            "rtol must be a finite positive",
        ),
    ],
)
def test_pair_validation(args, kwargs, exc, match):
    with pytest.raises(exc, match=match):
        kalman_decomposition(*args, **kwargs)


def test_order_validation():
    with pytest.raises(ValueError, match="order must be a positive int, got 0"):
        observability_matrix(np.eye(2), np.ones((1, 2)), order=0)


# ------------------------------------------------------------------ Lee et al.
def _lee_pair():
    A = np.stack([[[0.0, 1.0], [-2.0, -3.0]], [[0.0, 1.0], [-1.0, -1.0]]])
    return SwitchedLinearSystem.continuous(A, C=np.array([[1.0, 0.0]]))


def test_joint_observability_holds_for_a_jointly_observable_pair():
    sys = _lee_pair()
    res = joint_observability(sys)
    assert res.holds and res.failing_pairs == ()
    # oracle: the rank condition of Assumption 1 on this well-conditioned 4-state pair
    O = np.hstack(
        [observability_matrix(sys.A[0], sys.C[0], 4), observability_matrix(sys.A[1], sys.C[1], 4)]
    )
    assert np.linalg.matrix_rank(O) == 4
    assert mode_observability(sys).holds


def test_joint_observability_fails_for_identical_modes_and_names_the_pair():
    A = np.array([[0.0, 1.0], [-2.0, -3.0]])
    B = np.array([[0.0, 1.0], [-1.0, -1.0]])
    sys = SwitchedLinearSystem.continuous(np.stack([A, B, A]), C=np.array([[1.0, 0.0]]))
    res = joint_observability(sys, t=1.0)
    assert not res.holds
    assert res.failing_pairs == ((0, 2),)
    assert res.margin[0, 2] == 0.0 and res.margin[0, 1] > 0
    assert res.omega_min == pytest.approx(0.0, abs=1e-12)


def test_joint_gramian_matches_quadrature():
    sys = _lee_pair()
    t = 1.3

    def integrand(tau):
        phi = np.hstack([sys.C[0] @ expm(sys.A[0] * tau), sys.C[1] @ expm(sys.A[1] * tau)])
        return phi.T @ phi

    want, _err = quad_vec(integrand, 0.0, t, epsabs=1e-13, epsrel=1e-12)
    got = joint_gramian(sys, 0, 1, t)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    lam = np.linalg.eigvalsh(want)[0]
    assert omega_min(sys, 0, 1, t) == pytest.approx(lam, rel=1e-6)
    assert joint_observability(sys, t=t).omega_min == pytest.approx(lam, rel=1e-6)


def test_joint_gramian_remark1_identity():
    # int_0^t |y_i(x0) - y_j(x0')|^2 = [x0; -x0']' W_ij(t) [x0; -x0']  (Lee et al. Remark 1)
    sys = _lee_pair()
    x0, x1 = np.array([1.0, -0.5]), np.array([0.3, 2.0])
    t = 0.7
    val, _ = quad_vec(
        lambda s: float(
            np.sum((sys.C[0] @ expm(sys.A[0] * s) @ x0 - sys.C[1] @ expm(sys.A[1] * s) @ x1) ** 2)
        ),
        0.0,
        t,
        epsabs=1e-13,
    )
    z = np.concatenate([x0, -x1])
    assert z @ joint_gramian(sys, 0, 1, t) @ z == pytest.approx(val, rel=1e-9)


def test_joint_gramian_batched_over_horizons():
    sys = _lee_pair()
    ts = np.array([0.1, 0.5, 2.0])
    W = joint_gramian(sys, 0, 1, ts)
    assert W.shape == (3, 4, 4)
    for k, t in enumerate(ts):
        np.testing.assert_allclose(W[k], joint_gramian(sys, 0, 1, float(t)), rtol=1e-12)
    lam = omega_min(sys, 0, 1, ts)
    assert lam.shape == (3,) and np.all(np.diff(lam) > 0)  # W(t) grows with t


def test_gramian_validation():
    sys = _lee_pair()
    with pytest.raises(ValueError, match="t must be positive"):
        joint_gramian(sys, 0, 1, 0.0)
    with pytest.raises(ValueError, match=r"j must be a mode index in 0..1, got 2"):
        joint_gramian(sys, 0, 2, 1.0)
    disc = SwitchedLinearSystem.discrete(np.stack([np.eye(2), 0.5 * np.eye(2)]), dt=1.0)
    with pytest.raises(ValueError, match="system must be continuous-time"):
        joint_gramian(disc, 0, 1, 1.0)
    with pytest.raises(TypeError, match="system must be a SwitchedLinearSystem"):
        joint_observability(np.eye(2))


# ------------------------------------------------------------------ Wang et al.
def _wang_system(C1, C2):
    A = np.stack([np.diag([-1.0, -2.0]), np.array([[-1.0, 0.0], [0.0, -3.0]])])
    return SwitchedLinearSystem.continuous(A, C=np.stack([C1, C2]))


def test_wang_decomposition_blocks_and_lemma3a():
    sys = _wang_system(np.array([[1.0, 0.0]]), np.array([[0.0, 1.0]]))
    for i, dec in enumerate(mode_decompositions(sys)):
        A, C = sys.A[i], sys.C[i]
        assert dec.n_observable == 1
        np.testing.assert_allclose(np.vstack([dec.G, dec.F]), np.linalg.inv(dec.T), atol=1e-14)
        np.testing.assert_allclose(dec.A_hat, np.linalg.inv(dec.T) @ A @ dec.T, atol=1e-14)
        assert abs(dec.A_hat[1, 0]) < 1e-14 and abs(dec.C_hat[0, 0]) < 1e-14
        # Lemma 3(a): ker F_i = ker W(i)
        W = observability_matrix(A, C)
        np.testing.assert_allclose(W @ dec.M, 0, atol=1e-14)
        np.testing.assert_allclose(dec.F @ dec.M, 0, atol=1e-14)
    assert not mode_observability(sys).holds


def test_wang_assumption2_holds_when_modes_cover_the_state():
    sys = _wang_system(np.array([[1.0, 0.0]]), np.array([[0.0, 1.0]]))
    res = combined_observability(sys)
    assert res.holds and res.rank == 2 == np.linalg.matrix_rank(res.W_S)
    assert res.W_S.shape == (2 * 2 * 1, 2)
    np.testing.assert_array_equal(res.n_observable, [1, 1])
    np.testing.assert_allclose(res.Phi @ res.F, np.eye(2), atol=1e-14)  # x = Phi z


def test_wang_assumption2_fails_when_both_modes_see_the_same_direction():
    sys = _wang_system(np.array([[1.0, 0.0]]), np.array([[2.0, 0.0]]))
    res = combined_observability(sys)
    assert not res.holds and res.rank == 1 == np.linalg.matrix_rank(res.W_S)
    assert res.Phi is None


def test_wang_total_sensor_loss_mode():
    # n_i = 0 (Wang et al. Remark 4): C(2) = 0
    sys = _wang_system(np.array([[1.0, 1.0]]), np.zeros((1, 2)))
    res = combined_observability(sys)
    np.testing.assert_array_equal(res.n_observable, [2, 0])
    assert res.holds


# ------------------------------------------------------------------ Shankar et al.
def test_uniform_observability_double_integrator_by_hand():
    # F = e^{AT} = [[1, T], [0, 1]] with T = 1; h = 1: H'H + F'H'HF = [[2, 1], [1, 1]]
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    res = uniform_observability(A, np.array([[1.0, 0.0]]), 1.0)
    assert res.holds and res.h == 1
    assert res.rho == pytest.approx((3 - np.sqrt(5)) / 2, rel=1e-12)
    # R scales the Gramian by R^{-1}
    res2 = uniform_observability(A, np.array([[1.0, 0.0]]), 1.0, R=[[4.0]])
    assert res2.rho == pytest.approx(res.rho / 4, rel=1e-12)


def test_uniform_observability_needs_longer_windows_for_chains():
    # triple integrator seen through its first state: rank needs H, HF, HF^2 -> h = 2
    A = np.diag([1.0, 1.0], k=1)
    res = uniform_observability(A, np.array([[1.0, 0.0, 0.0]]), 0.5)
    assert res.holds and res.h == 2
    F = expm(A * 0.5)
    H = np.array([[1.0, 0.0, 0.0]])
    gram = sum(
        np.linalg.matrix_power(F, i).T @ H.T @ H @ np.linalg.matrix_power(F, i) for i in range(3)
    )
    assert res.rho == pytest.approx(np.linalg.eigvalsh(gram)[0], rel=1e-10)


def test_sampling_can_destroy_observability():
    # oscillator sampled at half its period: F = -I, (F, [1, 0]) is unobservable
    w = 2.0
    A = np.array([[0.0, w], [-w, 0.0]])
    H = np.array([[1.0, 0.0]])
    assert is_observable(A, H)
    res = uniform_observability(A, H, np.pi / w)
    assert not res.holds and res.h is None and res.rho == 0.0


def test_dwell_time_lemma1_constants():
    A = np.stack([[[0.0, 1.0], [0.0, 0.0]], [[-1.0, 0.0], [0.0, -2.0]]])
    sys = SwitchedLinearSystem.continuous(A, C=np.array([[1.0, 1.0]]))
    T = 0.5
    per = [uniform_observability(A[i], sys.C[i], T) for i in range(2)]
    res = dwell_time_observability(sys, T, tau_d=1.0)
    h_bar = max(p.h for p in per)
    assert h_bar == 1 and res.h_modes == (1, 1)
    assert res.h == 2 * h_bar - 1 and res.h_corrected == 2 * h_bar
    assert res.rho == pytest.approx(min(p.rho for p in per))
    assert res.holds and res.printed_lemma_holds  # tau_d = 1.0 >= (h_bar + 1) T = 1.0
    nu = min(np.linalg.eigvalsh(0.5 * (a + a.T))[0] for a in A)
    assert res.rho_corrected == pytest.approx(res.rho * min(1.0, np.exp(2 * nu * h_bar * T)))
    tight = dwell_time_observability(sys, T, tau_d=h_bar * T)  # tau_d = h_bar T: not >
    assert not tight.holds and not tight.printed_lemma_holds


def _window_gramian(A, H, T, h, switch_times, modes, k=0):
    """Oracle: sum_{i=k}^{k+h} Phi_{i,k}' H' H Phi_{i,k} for a piecewise-constant signal.

    ``modes[q]`` is active on ``[switch_times[q-1], switch_times[q])``; each interval's
    transition is composed from exact segment exponentials.
    """
    edges = np.concatenate([[-np.inf], switch_times, [np.inf]])

    def mode_at(t):
        return modes[np.searchsorted(edges, t, side="right") - 1]

    def F(i):
        a, b = i * T, (i + 1) * T
        cuts = [a] + [s for s in switch_times if a < s < b] + [b]
        out = np.eye(A.shape[1])
        for lo, hi in itertools.pairwise(cuts):
            out = expm(A[mode_at(lo)] * (hi - lo)) @ out
        return out

    G = np.zeros((A.shape[1],) * 2)
    Phi = np.eye(A.shape[1])
    for i in range(k, k + h + 1):
        Hi = H[mode_at(i * T)]
        G += Phi.T @ Hi.T @ Hi @ Phi
        Phi = F(i) @ Phi
    return G


LEMMA1_COUNTEREXAMPLE = {
    "provenance": "constructed; Shankar et al. (000) Lemma 1 claims rho_1 = min rho_1^i",
    "A": [[[-3.0, 0.0], [0.0, -0.1]], [[-0.1, 0.0], [0.0, -3.0]]],
    "H": [[1.0, 1.0]],
    "T": 1.0,
}


def test_lemma1_printed_constants_fail_and_corrected_ones_hold():
    ex = LEMMA1_COUNTEREXAMPLE
    A, H, T = np.array(ex["A"]), np.array(ex["H"]), ex["T"]
    sys = SwitchedLinearSystem.continuous(A, C=H)
    res = dwell_time_observability(sys, T, tau_d=2.0)
    assert res.h_modes == (1, 1) and res.h == 1 and res.holds and res.printed_lemma_holds
    Hs = np.stack([H, H])
    # printed: window of h + 1 = 2 samples, one switch inside it (allowed by tau_d > T)
    worst = min(
        np.linalg.eigvalsh(_window_gramian(A, Hs, T, res.h, [s, s + 10.0], [0, 1, 0]))[0]
        for s in np.linspace(0.05, 0.95, 19)
    )
    assert worst < 1e-3 * res.rho  # Lemma 1's rho is violated by orders of magnitude
    # corrected: window 2 h_bar, dwell >= (h_bar + 1) T, over random admissible signals
    rng = np.random.default_rng(7)
    lowest = np.inf
    for _ in range(200):
        gaps = 2.0 + rng.exponential(1.0, size=4)  # dwell times >= tau_d = 2 = (h_bar + 1) T
        times = rng.uniform(-2.0, 0.0) + np.cumsum(gaps)
        first = int(rng.integers(2))
        modes = [(first + q) % 2 for q in range(len(times) + 1)]  # alternate
        G = _window_gramian(A, Hs, T, res.h_corrected, times, modes)
        lowest = min(lowest, np.linalg.eigvalsh(G)[0])
    assert lowest >= res.rho_corrected * (1 - 1e-9)


def test_dwell_time_validation():
    sys = _lee_pair()
    with pytest.raises(ValueError, match="tau_d must be a finite positive"):
        dwell_time_observability(sys, 0.5, tau_d=-1.0)
    with pytest.raises(ValueError, match=r"R must have shape \(1, 1\)"):
        uniform_observability(sys.A[0], sys.C[0], 0.5, R=np.eye(2))


def test_window_gramian_matches_the_segment_oracle():
    from switchest.analysis import window_gramian

    ex = LEMMA1_COUNTEREXAMPLE
    A, H, T = np.array(ex["A"]), np.array(ex["H"]), ex["T"]
    sys = SwitchedLinearSystem.continuous(A, C=H)
    rng = np.random.default_rng(3)
    for _ in range(20):
        times = np.sort(rng.uniform(-1.0, 6.0, size=3))
        modes = rng.integers(0, 2, size=4)
        expected = _window_gramian(A, np.stack([H, H]), T, 4, times, modes)
        got = window_gramian(sys, T, 4, times, modes)
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-14)
    with pytest.raises(ValueError, match="strictly increasing"):
        window_gramian(sys, T, 2, [1.0, 0.5], [0, 1, 0])
    with pytest.raises(ValueError, match=r"modes must have shape \(3,\)"):
        window_gramian(sys, T, 2, [0.5, 1.0], [0, 1])
    with pytest.raises(ValueError, match="mode index"):
        window_gramian(sys, T, 2, [0.5], [0, 2])
