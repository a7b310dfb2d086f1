"""Small batched linear-algebra kernels shared by the whole package.

Every function works on stacks: leading axes are batch axes, the last one or two
axes are the vector or matrix.
"""

from __future__ import annotations

import numpy as np

__all__ = ["matvec", "symmetrize", "psd_sqrt", "cholesky_solve", "joseph_update", "log_normalize"]


def matvec(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``M @ v`` for stacks of matrices ``(..., a, b)`` and vectors ``(..., b)``, broadcast."""
    return (M @ v[..., None])[..., 0]


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


def cholesky_solve(L: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``(L L') x = b`` for a stack of lower Cholesky factors ``L``.

    ``b`` has shape ``(..., m)`` or ``(..., m, k)`` matching ``L``'s ``(..., m, m)``.
    Two triangular solves, no inverse.
    """
    vector = b.ndim == L.ndim - 1
    rhs = b[..., None] if vector else b
    z = np.linalg.solve(L, rhs)  # forward substitution on the triangular factor
    x = np.linalg.solve(np.swapaxes(L, -1, -2), z)
    return x[..., 0] if vector else x


def joseph_update(P: np.ndarray, K: np.ndarray, C: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Covariance after a measurement update with gain ``K`` in Joseph form.

    ``P+ = (I - K C) P (I - K C)' + K R K'`` — valid for any gain, optimal or not,
    and symmetric positive semidefinite by construction (re-symmetrized on return).
    """
    n = P.shape[-1]
    IKC = np.eye(n) - K @ C
    out = IKC @ P @ np.swapaxes(IKC, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
    return symmetrize(out)


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
