"""Shared batched kernels against their dense definitions."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from switchest._linalg import (
    joseph_update,
    log_normalize,
    mixture_moments,
    psd_sqrt,
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


