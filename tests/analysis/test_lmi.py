"""The LMI helpers: block assembly from the upper triangle, solver fallback, numpy checks."""

import cvxpy as cp
import numpy as np
import pytest

from switchest.analysis._lmi import (
    SolveOutcome,
    max_eigenvalue,
    min_eigenvalue,
    solve_sdp,
    symmetric_block,
)


def test_block_from_upper_triangle_matches_np_block():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(2, 2))
    Y = rng.normal(size=(2, 3))
    Z = rng.normal(size=(3, 3))
    Z = Z + Z.T
    got = symmetric_block([[X, Y], [None, Z]]).value
    Xs = 0.5 * (X + X.T)
    want = np.block([[Xs, Y], [Y.T, Z]])
    np.testing.assert_allclose(got, want, atol=1e-15)


def test_zero_blocks_take_their_size_from_the_row_and_column():
    Y = np.arange(6.0).reshape(2, 3)
    got = symmetric_block([[np.eye(2), 0, Y], [None, np.eye(4), None], [None, None, np.eye(3)]])
    assert got.shape == (9, 9)
    np.testing.assert_array_equal(
        got.value[2:6, :],
        0 * got.value[2:6, :] + np.block([np.zeros((4, 2)), np.eye(4), np.zeros((4, 3))]),
    )
    np.testing.assert_array_equal(got.value[6:, :2], Y.T)


def test_scalar_blocks_are_accepted():
    t = cp.Variable()
    t.value = 2.0
    got = symmetric_block([[t, np.ones((1, 2))], [None, np.eye(2)]]).value
    np.testing.assert_array_equal(got, [[2.0, 1, 1], [1, 1, 0], [1, 0, 1]])


def test_non_symmetric_expression_is_symmetrized():
    # A' P A - P is symmetric only in exact arithmetic; the helper makes the
    # expression symmetric so that ">>" constrains the whole matrix.
    A = np.array([[0.5, 1.0], [0.0, 0.3]])
    P = cp.Variable((2, 2))  # deliberately not declared symmetric
    P.value = np.array([[1.0, 2.0], [0.0, 1.0]])
    raw = A.T @ P @ A - P
    assert not np.allclose(raw.value, raw.value.T)
    block = symmetric_block([[raw]]).value
    np.testing.assert_allclose(block, block.T)
    np.testing.assert_allclose(block, 0.5 * (raw.value + raw.value.T))


def test_bad_layouts_raise():
    with pytest.raises(ValueError, match="square k x k"):
        symmetric_block([[np.eye(2), np.eye(2)]])
    with pytest.raises(ValueError, match="block row 1: it holds only zeros"):
        symmetric_block([[np.eye(2), None], [None, 0]])
    with pytest.raises(ValueError, match="blocks must be 2-D"):
        symmetric_block([[np.ones(2)]])


def test_feasible_and_infeasible_problems_are_decided_by_clarabel():
    P = cp.Variable((2, 2), symmetric=True)
    ok = cp.Problem(cp.Minimize(cp.trace(P)), [symmetric_block([[P - np.eye(2)]]) >> 0])
    out = solve_sdp(ok)
    assert out == SolveOutcome(status="optimal", solver="CLARABEL", decided=True)
    np.testing.assert_allclose(P.value, np.eye(2), atol=1e-6)
    bad = cp.Problem(cp.Minimize(0), [symmetric_block([[P]]) >> np.eye(2), cp.trace(P) <= 1])
    assert solve_sdp(bad) == SolveOutcome(status="infeasible", solver="CLARABEL", decided=True)


def test_falls_back_when_a_solver_raises():
    x = cp.Variable()
    prob = cp.Problem(cp.Minimize(x), [x >= 1])
    out = solve_sdp(prob, solvers=("NOT_A_SOLVER", "CVXOPT"))
    assert out.solver == "CVXOPT" and out.decided
    assert x.value == pytest.approx(1.0, abs=1e-6)


class _Scripted:
    """A stand-in problem whose solvers answer with given statuses."""

    def __init__(self, statuses):
        self.statuses = dict(statuses)
        self.status = None
        self.calls = []

    def solve(self, solver):
        self.calls.append(solver)
        self.status = self.statuses[solver]


def test_inaccurate_status_is_never_a_verdict():
    prob = _Scripted({"CLARABEL": "optimal_inaccurate", "CVXOPT": "optimal"})
    assert solve_sdp(prob) == SolveOutcome("optimal", "CVXOPT", True)
    assert prob.calls == ["CLARABEL", "CVXOPT"]
    prob = _Scripted({"CLARABEL": "optimal_inaccurate", "CVXOPT": "infeasible_inaccurate"})
    assert solve_sdp(prob) == SolveOutcome("infeasible_inaccurate", "CVXOPT", False)


def test_everything_raising_is_a_solver_error():
    prob = cp.Problem(cp.Minimize(cp.Variable()), [])
    assert solve_sdp(prob, solvers=("NOPE",)) == SolveOutcome("solver_error", "NOPE", False)


def test_eigenvalue_checks_are_batched_and_use_the_symmetric_part():
    rng = np.random.default_rng(1)
    M = rng.normal(size=(4, 3, 3))
    S = 0.5 * (M + np.swapaxes(M, 1, 2))
    want = np.array([np.linalg.eigvalsh(s) for s in S])
    np.testing.assert_allclose(max_eigenvalue(M), want[:, -1])
    np.testing.assert_allclose(min_eigenvalue(M), want[:, 0])
