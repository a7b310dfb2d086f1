"""The one place where LMIs are assembled, solved and re-verified.

Three pieces shared by every certificate in :mod:`switchest.analysis`:

* :func:`symmetric_block` builds an LMI block matrix from its upper triangle and
  symmetrizes it. cvxpy enforces only the symmetric part of a non-symmetric
  ``>>`` expression without saying so; a block such as :math:`A^\\top P A - P` is symmetric
  in exact arithmetic but not as an expression tree, so every block matrix goes
  through here before it meets ``>>`` or ``<<``.
* :func:`solve_sdp` runs CLARABEL and falls back to CVXOPT when CLARABEL raises or
  returns an inaccurate status. Only ``optimal``, ``infeasible`` and ``unbounded``
  are verdicts; ``*_inaccurate`` (the SCS-style statuses) never are.
* :func:`max_eigenvalue` / :func:`min_eigenvalue`: the numpy re-verification of a
  returned certificate. No caller reports ``feasible=True`` from a solver status
  alone; it checks the returned matrices with these, allowing for their rounding
  (:func:`rounding_allowance`).
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._linalg import symmetrize

__all__ = [
    "SolveOutcome",
    "lmi_nbytes",
    "max_eigenvalue",
    "min_eigenvalue",
    "rounding_allowance",
    "solve_sdp",
    "symmetric_block",
]

#: Solver statuses that decide a problem; anything else (``optimal_inaccurate``,
#: ``infeasible_inaccurate``, ``solver_error``, ...) is not a verdict.


class _Cvxpy:
    """cvxpy, imported at its first use: the import costs seconds, and simulating or
    filtering never solves an LMI (``import switchest.estimators`` stays quick)."""

    def __getattr__(self, name: str):
        return getattr(importlib.import_module("cvxpy"), name)


cp = _Cvxpy()

DECIDED = ("optimal", "infeasible", "unbounded")  # cp.OPTIMAL, cp.INFEASIBLE, cp.UNBOUNDED
_SOLVERS = ("CLARABEL", "CVXOPT")
#: Peak memory of one solve, in bytes per LMI block per n^4: measured 45-62 for the CQLF
#: of n = 20..40 states with L = 1..3 modes through cvxpy and CLARABEL. Its time grows like
#: n^6 (3.5 s at n = 30, 14 s at n = 40, two modes).
_BYTES_PER_BLOCK_N4 = 50


@dataclass(frozen=True)
class SolveOutcome:
    """What :func:`solve_sdp` got.

    Attributes
    ----------
    status : str
        cvxpy status of the last solver run (``"solver_error"`` if every solver
        raised).
    solver : str
        Name of the solver that produced ``status``.
    decided : bool
        True when ``status`` is ``optimal``, ``infeasible`` or ``unbounded``.
    """

    status: str
    solver: str
    decided: bool


def symmetric_block(upper: Sequence[Sequence]) -> cp.Expression:
    """Assemble a symmetric LMI block matrix from its upper triangle.

    Parameters
    ----------
    upper : sequence of sequences
        ``upper[r][c]`` for :math:`c \\ge r` is block (r, c): a cvxpy expression, an
        array, or ``0``/``None`` for a zero block. Entries below the diagonal are
        ignored (pass ``None``); block (c, r) is taken as the transpose of (r, c).
        Every block row must have a block, array or expression on its diagonal
        or somewhere in its row/column that fixes its size.

    Returns
    -------
    cvxpy.Expression
        :math:`(S + S^\\top) / 2` with :math:`S` the full block matrix, so that ``>>`` sees a
        symmetric expression.

    Raises
    ------
    ValueError
        If ``upper`` is not square or a block size cannot be inferred.
    """
    k = len(upper)
    if k == 0 or any(len(row) != k for row in upper):
        raise ValueError(
            f"upper must be a square k x k list of blocks, got rows of lengths "
            f"{[len(row) for row in upper]}"
        )
    rows = [None] * k
    cols = [None] * k
    for r in range(k):
        for c in range(r, k):
            blk = upper[r][c]
            if _is_zero(blk):
                continue
            shape = _shape(blk)
            rows[r] = shape[0] if rows[r] is None else rows[r]
            cols[c] = shape[1] if cols[c] is None else cols[c]
            # block (c, r) = block (r, c)': its rows are c's, its columns r's
            rows[c] = shape[1] if rows[c] is None else rows[c]
            cols[r] = shape[0] if cols[r] is None else cols[r]
    sizes = []
    for r in range(k):
        size = rows[r] if rows[r] is not None else cols[r]
        if size is None:
            raise ValueError(f"upper: cannot infer the size of block row {r}: it holds only zeros")
        sizes.append(size)
    grid = []
    for r in range(k):
        line = []
        for c in range(k):
            blk = upper[r][c] if c >= r else upper[c][r]
            if _is_zero(blk):
                line.append(np.zeros((sizes[r], sizes[c])))
            else:
                line.append(_as_2d(blk) if c >= r else _transpose(_as_2d(blk)))
        grid.append(line)
    full = cp.bmat(grid)
    return 0.5 * (full + full.T)


def solve_sdp(problem: cp.Problem, *, solvers: Sequence[str] = _SOLVERS) -> SolveOutcome:
    """Solve ``problem`` with CLARABEL, falling back to CVXOPT.

    The next solver is tried when one raises ``cvxpy.SolverError`` (or, CVXOPT on
    out-of-range data, ``ArithmeticError``) or returns a
    status that is not a verdict (``optimal_inaccurate``, ``infeasible_inaccurate``,
    ...). The outcome of the first solver that decides is returned, otherwise the
    last one tried.

    Parameters
    ----------
    problem : cvxpy.Problem
        A problem with semidefinite constraints.
    solvers : sequence of str, optional
        Solver names in order of preference (keyword-only).

    Returns
    -------
    SolveOutcome
    """
    outcome = SolveOutcome(status="solver_error", solver="none", decided=False)
    for name in solvers:
        try:
            with warnings.catch_warnings():
                # cvxpy warns on inaccurate solutions; the status below says the same
                warnings.filterwarnings("ignore", message="Solution may be inaccurate")
                problem.solve(solver=name)
        except (cp.SolverError, ArithmeticError):  # CVXOPT's LAPACK raises the latter on huge data
            outcome = SolveOutcome(status="solver_error", solver=name, decided=False)
            continue
        status = str(problem.status)
        outcome = SolveOutcome(status=status, solver=name, decided=status in DECIDED)
        if outcome.decided:
            return outcome
    return outcome


def max_eigenvalue(M: np.ndarray) -> np.ndarray:
    """Largest eigenvalue of the symmetric part of each matrix in a stack (numpy)."""
    return np.linalg.eigvalsh(symmetrize(np.asarray(M, dtype=float)))[..., -1]


def min_eigenvalue(M: np.ndarray) -> np.ndarray:
    """Smallest eigenvalue of the symmetric part of each matrix in a stack (numpy)."""
    return np.linalg.eigvalsh(symmetrize(np.asarray(M, dtype=float)))[..., 0]


def lmi_nbytes(n: int, blocks: int) -> float:
    """Estimated peak memory of one solve of an LMI with ``blocks`` symmetric
    :math:`n \\times n` blocks.

    :math:`50 \\, \\mathrm{blocks} \\, n^4` bytes, measured (cvxpy and CLARABEL,
    :math:`n = 20, \\dots, 40`): the interior-point method factors a dense system in the
    :math:`n^2/2` unknowns of each block.
    """
    return _BYTES_PER_BLOCK_N4 * blocks * float(n) ** 4


def rounding_allowance(magnitude, terms: int):
    """A bound on the rounding error of a floating-point quantity:
    :math:`2 \\, \\mathrm{terms} \\, \\varepsilon \\, \\mathrm{magnitude}`.

    A value formed from sums of ``terms`` products whose absolute values add up to
    ``magnitude`` errs by at most :math:`\\gamma_{\\mathrm{terms}} \\, \\mathrm{magnitude}`,
    :math:`\\gamma_k = k u / (1 - k u)` with :math:`u = \\varepsilon / 2` (Higham, *Accuracy and
    Stability of Numerical Algorithms*, §3.1); a backward-stable eigensolver for an
    :math:`n \\times n` matrix :math:`M` perturbs the eigenvalues of a symmetric (or normal)
    matrix by at most :math:`O(n \\varepsilon \\lVert M \\rVert)`. Twice
    :math:`\\mathrm{terms} \\, \\varepsilon` covers both with room. A verdict compares a computed
    value with its threshold only beyond this allowance, so that it does not depend on the last
    bits (another CPU, another BLAS).

    Parameters
    ----------
    magnitude : float or ndarray
        Size of what was summed (:math:`|A| \\, |B|` for a product, a norm for an eigenvalue).
    terms : int
        Number of operations accumulated (the inner dimension, the matrix size).
    """
    return 2.0 * terms * np.finfo(float).eps * np.asarray(magnitude, dtype=float)


def _is_zero(blk) -> bool:
    return blk is None or (np.isscalar(blk) and blk == 0)


def _shape(blk) -> tuple[int, int]:
    shape = blk.shape if isinstance(blk, cp.Expression) else np.shape(blk)
    if len(shape) == 0:
        return (1, 1)
    if len(shape) == 1:
        raise ValueError(f"upper: blocks must be 2-D, got a vector of shape {shape}")
    return (int(shape[0]), int(shape[1]))


def _as_2d(blk):
    if isinstance(blk, cp.Expression):
        return cp.reshape(blk, (1, 1), order="F") if blk.ndim == 0 else blk
    return np.atleast_2d(np.asarray(blk, dtype=float))


def _transpose(blk):
    return blk.T
