"""Shared batched kernels against their dense definitions."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from switchest._linalg import cholesky, cholesky_solve, joseph_update, log_normalize, psd_sqrt, symmetrize


def random_psd(rng, shape, n, rank=None):
    W = rng.standard_normal((*shape, n, rank or n))
    return W @ np.swapaxes(W, -1, -2)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 5), rank=st.integers(0, 5))
def test_psd_sqrt_reproduces_even_singular_matrices(seed, n, rank):
    M = random_psd(np.random.default_rng(seed), (3,), n, min(rank, n))
    S = psd_sqrt(M)
    np.testing.assert_allclose(S @ np.swapaxes(S, -1, -2), M, atol=1e-10 * (1 + np.abs(M).max()))


def test_cholesky_solve_matches_solve_for_vectors_and_matrices():
    rng = np.random.default_rng(0)
    M = random_psd(rng, (4,), 3) + np.eye(3)
    L = np.linalg.cholesky(M)
    b = rng.standard_normal((4, 3))
    np.testing.assert_allclose(cholesky_solve(L, b), np.linalg.solve(M, b[..., None])[..., 0], rtol=1e-10)
    B = rng.standard_normal((4, 3, 2))
    np.testing.assert_allclose(cholesky_solve(L, B), np.linalg.solve(M, B), rtol=1e-10)


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


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), m=st.integers(1, 10))
def test_cholesky_matches_lapack_and_refuses_indefinite(seed, m):
    rng = np.random.default_rng(seed)
    S = random_psd(rng, (5,), m) + 0.1 * np.eye(m)
    np.testing.assert_allclose(cholesky(S), np.linalg.cholesky(S), rtol=1e-10, atol=1e-12)
    bad = S.copy()
    bad[2] = -np.eye(m)
    with pytest.raises(np.linalg.LinAlgError):
        cholesky(bad)
