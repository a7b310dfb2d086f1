"""Shared batched kernels against their dense definitions."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from switchest._linalg import (
    congruence,
    joseph_update,
    log_normalize,
    matvec,
    mixture_moments,
    mul,
    psd_sqrt,
    shared,
    spd_factor,
    spd_solve,
    symmetrize,
)


def random_psd(rng, shape, n, rank=None):
    W = rng.standard_normal((*shape, n, rank or n))
    return W @ np.swapaxes(W, -1, -2)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 5), rank=st.integers(0, 5))
def test_psd_sqrt_reproduces_even_singular_matrices(seed, n, rank):
    M = random_psd(np.random.default_rng(seed), (3,), n, min(rank, n))
    S = psd_sqrt(M)
    np.testing.assert_allclose(S @ np.swapaxes(S, -1, -2), M, atol=1e-10 * (1 + np.abs(M).max()))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), m=st.integers(1, 10), k=st.integers(1, 4))
def test_spd_solve_matches_lapack_and_refuses_indefinite(seed, m, k):
    rng = np.random.default_rng(seed)
    S = random_psd(rng, (5,), m) + 0.1 * np.eye(m)
    B = rng.standard_normal((5, m, k))
    X, logdet = spd_solve(S, B)
    np.testing.assert_allclose(S @ X, B, atol=1e-9 * (1 + np.abs(B).max()) * np.linalg.cond(S).max())
    np.testing.assert_allclose(logdet, np.linalg.slogdet(S)[1], rtol=1e-10, atol=1e-10)
    bad = S.copy()
    bad[2] = -np.eye(m)
    with pytest.raises(np.linalg.LinAlgError):
        spd_solve(bad, B)


def test_spd_solve_broadcasts_and_reads_the_lower_triangle_only():
    rng = np.random.default_rng(3)
    S = random_psd(rng, (), 3) + np.eye(3)
    B = rng.standard_normal((2, 4, 3, 2))
    upper_garbage = S + np.triu(np.full((3, 3), 7.0), 1)
    X, logdet = spd_solve(upper_garbage, B)
    assert X.shape == (2, 4, 3, 2) and logdet.shape == (2, 4)
    np.testing.assert_allclose(X, np.linalg.solve(S, B), rtol=1e-10)


def test_shared_factor_products_equal_the_stacked_ones():
    rng = np.random.default_rng(4)
    A = rng.standard_normal((6, 3, 4, 2))
    B = rng.standard_normal((2, 5))
    v = rng.standard_normal((6, 3, 5))
    M = rng.standard_normal((4, 5))
    P = random_psd(rng, (6, 3), 5)
    F = rng.standard_normal((5, 5))
    np.testing.assert_allclose(mul(A, B), A @ np.broadcast_to(B, (3, 2, 5)), rtol=1e-12)
    np.testing.assert_allclose(matvec(M, v), (np.broadcast_to(M, (3, 4, 5)) @ v[..., None])[..., 0], rtol=1e-12)
    np.testing.assert_allclose(congruence(F, P), congruence(np.broadcast_to(F, (3, 5, 5)), P), rtol=1e-11)
    np.testing.assert_allclose(congruence(F, P), F @ P @ F.T, rtol=1e-11)


def test_shared_collapses_only_identical_stacks():
    same = np.broadcast_to(np.arange(4.0).reshape(2, 2), (3, 2, 2))
    assert shared(same).shape == (2, 2)
    different = same.copy()
    different[2, 0, 0] = 1.0
    assert shared(different) is different


def test_mixture_moments_match_the_definition_far_from_the_origin():
    rng = np.random.default_rng(5)
    x = 1e6 + rng.standard_normal((2, 3, 4))
    P = random_psd(rng, (2, 3), 4)
    w = rng.dirichlet(np.ones(3), size=(2, 2)).transpose(0, 2, 1)  # (2, I=3, J=2), columns sum to 1
    m, S = mixture_moments(w, x, P)
    for b in range(2):
        for j in range(2):
            mean = w[b, :, j] @ x[b]
            d = x[b] - mean
            cov = sum(w[b, i, j] * (P[b, i] + np.outer(d[i], d[i])) for i in range(3))
            np.testing.assert_allclose(m[b, j], mean, rtol=1e-14)
            np.testing.assert_allclose(S[b, j], cov, rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(S, np.swapaxes(S, -1, -2))


def test_joseph_form_equals_standard_form_at_the_optimal_gain_and_stays_psd_otherwise():
    rng = np.random.default_rng(1)
    P = random_psd(rng, (5,), 3)
    C = rng.standard_normal((5, 2, 3))
    R = random_psd(rng, (5,), 2) + np.eye(2)
    S = C @ P @ np.swapaxes(C, -1, -2) + R
    K = P @ np.swapaxes(C, -1, -2) @ np.linalg.inv(S)
    standard = P - K @ C @ P
    np.testing.assert_allclose(joseph_update(P, K, C, R), standard, rtol=1e-9, atol=1e-10)
    bad = joseph_update(P, 3.0 * K, C, R)
    assert np.linalg.eigvalsh(bad).min() > -1e-10
    np.testing.assert_array_equal(bad, np.swapaxes(bad, -1, -2))


def test_log_normalize_is_stable_and_keeps_dead_rows_finite():
    w = np.array([[-1e6, -1e6 + np.log(3.0)], [-np.inf, -np.inf]])
    out, total = log_normalize(w)
    np.testing.assert_allclose(np.exp(out[0]), [0.25, 0.75])
    assert np.all(np.isneginf(out[1])) and np.isneginf(total[1])
    np.testing.assert_allclose(total[0], -1e6 + np.log(4.0))


def test_symmetrize():
    M = np.arange(8.0).reshape(2, 2, 2)
    np.testing.assert_array_equal(symmetrize(M), np.swapaxes(symmetrize(M), -1, -2))


def test_log_normalize_over_a_long_axis_and_a_middle_axis():
    rng = np.random.default_rng(6)
    for shape, axis in [((3, 40), -1), ((4, 5, 6), 1)]:
        w = rng.standard_normal(shape) * 50
        out, total = log_normalize(w, axis=axis)
        ref = np.log(np.sum(np.exp(w - w.max()), axis=axis)) + w.max()
        np.testing.assert_allclose(total, ref, rtol=1e-12)
        np.testing.assert_allclose(np.exp(out).sum(axis=axis), 1.0, rtol=1e-12)


def test_joseph_form_does_not_overflow_where_the_result_is_representable():
    # States on scales 2^500 apart: D P D has entries up to 2^1000 and the covariance after
    # the update is D P+ D, representable; the unscaled products reach 2^1500 on the way.
    rng = np.random.default_rng(7)
    P = random_psd(rng, (), 2) + np.eye(2)
    K, C, R = rng.standard_normal((2, 1)), rng.standard_normal((1, 2)), np.array([[0.3]])
    D = np.diag([2.0**500, 1.0])
    with np.errstate(over="raise"):
        ref = joseph_update(P, K, C, R)
    big = joseph_update(D @ P @ D, D @ K, C @ np.linalg.inv(D), R)
    assert np.all(np.isfinite(big))
    # powers of two scale exactly: only the rounding of the unscaled update remains
    D_inv = np.linalg.inv(D)
    np.testing.assert_allclose(D_inv @ big @ D_inv, ref, rtol=8 * np.finfo(float).eps)


def test_spd_factor_is_scale_free():
    # S entries of 1e300 and 1e-300 in one matrix: no overflow or underflow, the
    # log-determinant exact to rounding, the whitened vector's norm is b' S^-1 b
    rng = np.random.default_rng(8)
    S0 = random_psd(rng, (), 3) + np.eye(3)
    D = np.diag([1e150, 1.0, 1e-150])
    S = D @ S0 @ D
    b = D @ rng.standard_normal(3)
    factor = spd_factor(S)
    X, q = factor.solve_quadratic(b[:, None])
    eps = np.finfo(float).eps
    cond = np.linalg.cond(S0)
    # log det (D S0 D) = log det S0 + 2 log det D
    np.testing.assert_allclose(factor.logdet,
                               np.linalg.slogdet(S0)[1] + 2 * np.log(D.diagonal()).sum(),
                               rtol=0, atol=16 * eps * cond)
    np.testing.assert_allclose(D @ X[:, 0], np.linalg.solve(S0, np.linalg.solve(D, b)),
                               rtol=16 * eps * cond)
    np.testing.assert_allclose(q[0], b @ np.linalg.solve(S, b), rtol=16 * eps * cond)
    assert q[0] >= 0
