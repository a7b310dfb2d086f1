"""The numpy helpers of the Kalman oracle (numpy_kalman.py, beside this) against LAPACK and
the definitions: the oracle the compiled kernels are held to must itself be right."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy_kalman import congruence, shared, spd_factor, spd_solve

from switchest._linalg import matvec, mul


def random_psd(rng, shape, n, rank=None):
    W = rng.standard_normal((*shape, n, rank or n))
    return W @ np.swapaxes(W, -1, -2)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), m=st.integers(1, 10), k=st.integers(1, 4))
def test_spd_solve_matches_lapack_and_refuses_indefinite(seed, m, k):
    rng = np.random.default_rng(seed)
    S = random_psd(rng, (5,), m) + 0.1 * np.eye(m)
    B = rng.standard_normal((5, m, k))
    X, logdet = spd_solve(S, B)
    np.testing.assert_allclose(S @ X, B,
                               atol=1e-9 * (1 + np.abs(B).max()) * np.linalg.cond(S).max())
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
    np.testing.assert_allclose(matvec(M, v), (np.broadcast_to(M, (3, 4, 5)) @ v[..., None])[..., 0],
                               rtol=1e-12)
    np.testing.assert_allclose(congruence(F, P), congruence(np.broadcast_to(F, (3, 5, 5)), P),
                               rtol=1e-11)
    np.testing.assert_allclose(congruence(F, P), F @ P @ F.T, rtol=1e-11)


def test_shared_collapses_only_identical_stacks():
    same = np.broadcast_to(np.arange(4.0).reshape(2, 2), (3, 2, 2))
    assert shared(same).shape == (2, 2)
    different = same.copy()
    different[2, 0, 0] = 1.0
    assert shared(different) is different


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
