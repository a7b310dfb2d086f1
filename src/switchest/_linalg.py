"""Small batched linear-algebra kernels shared by the whole package.

Every function works on stacks: leading axes are batch axes, the last one or two
axes are the vector or matrix.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "cholesky",
    "matvec",
    "transpose",
    "symmetrize",
    "psd_sqrt",
    "solve_lower",
    "solve_upper",
    "cholesky_solve",
    "joseph_update",
    "mixture_moments",
    "log_normalize",
]


def matvec(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``M @ v`` for stacks of matrices ``(..., a, b)`` and vectors ``(..., b)``, broadcast."""
    return (M @ v[..., None])[..., 0]


def transpose(M: np.ndarray) -> np.ndarray:
    """``M'`` over the last two axes as a contiguous array.

    A matrix product with a transposed *view* of a stack takes numpy's slow
    strided path (about 3x slower for 4x4 stacks); one copy is cheaper.
    """
    return np.ascontiguousarray(np.swapaxes(M, -1, -2))


def symmetrize(M: np.ndarray) -> np.ndarray:
    """Return ``(M + M') / 2`` over the last two axes."""
    return 0.5 * (M + np.swapaxes(M, -1, -2))


def psd_sqrt(M: np.ndarray) -> np.ndarray:
    """A square root ``S`` with ``S S' = M`` for a stack of symmetric PSD matrices.

    Uses the symmetric eigendecomposition, so singular matrices (a noise that acts
    on a subspace only, a zero-length interval) are handled exactly where a
    Cholesky factorization would fail. Eigenvalues below zero by round-off are
    treated as zero.
    """
    w, V = np.linalg.eigh(symmetrize(M))
    return V * np.sqrt(np.clip(w, 0.0, None))[..., None, :]


def cholesky(S: np.ndarray) -> np.ndarray:
    """Lower Cholesky factors of a stack of symmetric positive definite matrices.

    For the small innovation covariances of measurement updates (``m <= 8``) the
    factorization runs column by column, vectorized over the whole stack —
    ``numpy.linalg.cholesky`` spends most of its time per matrix on call overhead
    there; larger matrices go to LAPACK. Only the lower triangle of ``S`` is read.
    Raises ``numpy.linalg.LinAlgError`` if a matrix is not positive definite.
    """
    m = S.shape[-1]
    if m > 8:
        return np.linalg.cholesky(S)
    L = np.zeros_like(S)
    for j in range(m):
        d = S[..., j, j] - np.sum(L[..., j, :j] ** 2, axis=-1)
        if not np.all(d > 0):
            raise np.linalg.LinAlgError("Matrix is not positive definite")
        L[..., j, j] = np.sqrt(d)
        if j + 1 < m:
            below = S[..., j + 1 :, j] - (L[..., j + 1 :, :j] @ L[..., j, :j, None])[..., 0]
            L[..., j + 1 :, j] = below / L[..., j, j, None]
    return L


def solve_lower(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Solve ``L X = B`` for stacks of lower-triangular ``L (..., m, m)``, ``B (..., m, k)``.

    Forward substitution, one row at a time but vectorized over the whole stack:
    for the small ``m`` of measurement vectors this is several times faster than
    ``numpy.linalg.solve`` (a general LU per matrix) and exploits the triangle.
    """
    m = L.shape[-1]
    X = np.empty(np.broadcast_shapes(L.shape[:-2], B.shape[:-2]) + B.shape[-2:])
    for i in range(m):
        acc = B[..., i, :] - (L[..., i : i + 1, :i] @ X[..., :i, :])[..., 0, :] if i else B[..., i, :]
        X[..., i, :] = acc / L[..., i, i, None]
    return X


def solve_upper(U: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Solve ``U X = B`` for stacks of upper-triangular ``U`` by back substitution."""
    m = U.shape[-1]
    X = np.empty(np.broadcast_shapes(U.shape[:-2], B.shape[:-2]) + B.shape[-2:])
    for i in range(m - 1, -1, -1):
        acc = B[..., i, :] - (U[..., i : i + 1, i + 1 :] @ X[..., i + 1 :, :])[..., 0, :] if i < m - 1 \
            else B[..., i, :]
        X[..., i, :] = acc / U[..., i, i, None]
    return X


def cholesky_solve(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``(L L') x = b`` for a stack of lower Cholesky factors ``L``.

    ``b`` has shape ``(..., m)`` or ``(..., m, k)`` matching ``L``'s ``(..., m, m)``.
    Two triangular substitutions, no inverse.
    """
    vector = b.ndim == L.ndim - 1
    rhs = b[..., None] if vector else b
    x = solve_upper(transpose(L), solve_lower(L, rhs))
    return x[..., 0] if vector else x


def joseph_update(P: np.ndarray, K: np.ndarray, C: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Covariance after a measurement update with gain ``K`` in Joseph form.

    ``P+ = (I - K C) P (I - K C)' + K R K'`` — valid for any gain, optimal or not,
    and symmetric positive semidefinite by construction (re-symmetrized on return).
    """
    n = P.shape[-1]
    IKC = np.eye(n) - K @ C
    out = IKC @ P @ transpose(IKC) + K @ R @ transpose(K)
    return symmetrize(out)


def mixture_moments(w: np.ndarray, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Moments of Gaussian mixtures: ``m_j = sum_i w_ij x_i``, ``S_j = sum_i w_ij (P_i + (x_i - m_j)(x_i - m_j)')``.

    ``w (..., I, J)`` are weights over components i for each mixture j (columns sum
    to one), ``x (..., I, n)``, ``P (..., I, n, n)``. Computed with matrix products
    as ``sum_i w_ij (P_i + d_i d_i') - e_j e_j'`` around a reference point (the first
    component, ``d_i = x_i - x_0``, ``e_j = m_j - x_0``), which is exact and keeps
    the cancellation to the spread of the components, not their size.
    """
    n = x.shape[-1]
    wt = transpose(w)  # (..., J, I)
    ref = x[..., :1, :]
    d = x - ref
    m = wt @ x
    second = (P + d[..., :, None] * d[..., None, :]).reshape(*P.shape[:-2], n * n)
    e = m - ref
    S = (wt @ second).reshape(*m.shape, n) - e[..., :, None] * e[..., None, :]
    return m, symmetrize(S)


def log_normalize(log_w: np.ndarray, axis: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """Normalize log-weights along ``axis`` with log-sum-exp.

    Returns ``(log_w - lse, lse)`` with ``lse = log(sum(exp(log_w)))`` computed as
    ``max + log(sum(exp(log_w - max)))``, so the weights sum to one without ever
    leaving the log domain. An all ``-inf`` slice stays ``-inf`` with total
    ``-inf`` rather than becoming NaN. (A few numpy lines instead of
    ``scipy.special.logsumexp``, whose per-call overhead dominates a filter step.)
    """
    top = np.max(log_w, axis=axis, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        total = top + np.log(np.sum(np.exp(log_w - top), axis=axis, keepdims=True))
    safe = np.where(np.isfinite(total), total, 0.0)
    return log_w - safe, np.squeeze(total, axis=axis)
