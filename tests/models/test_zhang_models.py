"""The Zhang & Natarajan models (paper 001): Example 1 (§5.1) and the smart grid (§2.2, Table 1)."""

import numpy as np
import pytest
from scipy.linalg import expm

from switchest.models.zhang import SMART_GRID_TAU, smart_grid, zhang_two_mode

# Zhang & Natarajan, Table 1: k_G, alpha, sigma_G, sigma_D for modes q = 1, 2, 3.
TABLE1 = [(0.1, 0.1, 0.1, 0.1), (3.0, 0.5, 0.8, 0.8), (3.0, 0.49, 1.5, 1.0)]


def _controllable(A, W):
    n = A.shape[0]
    return (
        np.linalg.matrix_rank(np.hstack([np.linalg.matrix_power(A, k) @ W for k in range(n)])) == n
    )


def test_two_mode_matrices_are_the_printed_ones():
    # Zhang §5.1: A_1, A_2, B_1, B_2, C_1 = I, C_2 = 5 I, Q = 0.5 I, R = 0.3 I.
    s = zhang_two_mode()
    B = np.array([[[1.0, 0.0], [0.0, 0.8]], [[1.3, 0.4], [0.2, 0.7]]])
    np.testing.assert_array_equal(s.A, [[[0.9, 0.0], [0.2, 0.8]], [[0.5, 0.2], [0.2, 0.4]]])
    np.testing.assert_array_equal(s.C, [np.eye(2), 5 * np.eye(2)])
    np.testing.assert_allclose(s.Q[1], B[1] @ (0.5 * np.eye(2)) @ B[1].T, rtol=1e-15)
    np.testing.assert_allclose(s.Q[0], np.diag([0.5, 0.32]), rtol=1e-15)
    np.testing.assert_array_equal(s.R, [0.3 * np.eye(2)] * 2)
    assert (s.domain, s.dt, s.n_inputs) == ("discrete", 1.0, 0)


def test_two_mode_meets_assumption_3():
    # Zhang §2.2 assumption 3 / §5.1: (A_q, B_q Q B_q') controllable, (C_q, A_q) observable.
    s = zhang_two_mode()
    for q in range(2):
        assert _controllable(s.A[q], s.Q[q])
        assert _controllable(s.A[q].T, s.C[q].T)


def test_smart_grid_matches_eqs_3_4_by_van_loan():
    # Independent oracle for eqs. (3)-(4): A_q = expm(F tau) and the integral
    # int_0^tau expm(F s) ds = F^{-1}(A_q - I) from the block exponential
    # expm([[F, I], [0, 0]] tau); process-noise covariance B_q (2 I) B_q'.
    tau = 0.37
    s = smart_grid(tau)
    for q, (kG, alpha, sG, sD) in enumerate(TABLE1):
        F = np.diag([kG, -alpha])
        block = expm(np.block([[F, np.eye(2)], [np.zeros((2, 4))]]) * tau)
        Bq = block[:2, 2:] @ np.diag([sG, sD])
        np.testing.assert_allclose(s.A[q], block[:2, :2], rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(s.Q[q], 2.0 * Bq @ Bq.T, rtol=1e-11, atol=1e-15)
    np.testing.assert_array_equal(s.C, [np.eye(2)] * 3)
    np.testing.assert_array_equal(s.R, [np.eye(2)] * 3)
    assert s.dt == tau


def test_smart_grid_default_tau_and_instability():
    s = smart_grid()
    assert SMART_GRID_TAU == 0.1 and s.dt == SMART_GRID_TAU
    assert s.n_modes == 3 and s.n_states == 2
    # k_G > 0 in every mode: P_G is unstable (Zhang §5.2, I = {1}); P_D is stable.
    assert np.all(s.A[:, 0, 0] > 1.0) and np.all(s.A[:, 1, 1] < 1.0)
    for q in range(3):
        assert _controllable(s.A[q], s.Q[q])


@pytest.mark.parametrize(
    ("tau", "error", "match"),
    [
        (0.0, ValueError, r"tau must be a finite positive number, got 0\.0"),
        (-0.1, ValueError, r"tau must be a finite positive number, got -0\.1"),
        (float("inf"), ValueError, r"tau must be a finite positive number, got inf"),
        ("0.1", TypeError, r"tau must be a real scalar, got str"),
        ([0.1], TypeError, r"tau must be a real scalar, got list"),
    ],
)
def test_smart_grid_rejects_bad_tau(tau, error, match):
    with pytest.raises(error, match=match):
        smart_grid(tau)
