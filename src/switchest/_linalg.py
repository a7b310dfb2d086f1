"""Small batched linear-algebra kernels shared by the whole package.

Every function works on stacks: leading axes are batch axes, the last one or two
axes are the vector or matrix.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "matvec",
    "mul",
    "transpose",
    "symmetrize",
    "psd_sqrt",
    "pow2_scale",
    "joseph_update",
    "mixture_moments",
    "log_normalize",
]


def matvec(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``M @ v`` for stacks of matrices ``(..., a, b)`` and vectors ``(..., b)``, broadcast.

    A 2-D ``M`` shared by the whole stack of vectors is applied by one matrix
    product; one matrix per vector goes through ``einsum``, which for the small
    matrices of a filter costs about half of numpy's matrix-by-matrix ``matmul``.
    """
    if M.ndim == 2:
        return (v.reshape(-1, v.shape[-1]) @ M.T).reshape(*v.shape[:-1], M.shape[0])
    if M.shape[:-2] == v.shape[:-1]:
        return np.einsum("...ij,...j->...i", M, v)
    return (M @ v[..., None])[..., 0]


def mul(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A @ B`` for a stack ``A (..., a, b)``; a 2-D ``B`` shared by the stack is one GEMM.

    numpy multiplies a stack matrix by matrix, with a fixed cost per matrix that
    dominates for the small matrices of a filter; a right factor common to the
    whole stack is applied to all rows of ``A`` at once instead.
    """
    if B.ndim == 2 and A.ndim > 2:
        return (A.reshape(-1, A.shape[-1]) @ B).reshape(*A.shape[:-1], B.shape[-1])
    return A @ B


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


def pow2_scale(v: np.ndarray) -> np.ndarray:
    """A power of two ``d`` with ``v / d^2`` in ``[0.5, 2)`` for each ``v > 0``; 1 where ``v <= 0``.

    Dividing a matrix by such scales is exact in floating point (only exponents
    change), so an equilibrated computation rounds exactly as the raw one would,
    but cannot overflow or underflow where the raw one would.
    """
    _, exponent = np.frexp(np.where(v > 0, v, 1.0))
    return np.ldexp(1.0, exponent // 2)


def joseph_update(P: np.ndarray, K: np.ndarray, C: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Covariance after a measurement update with gain ``K`` in Joseph form.

    ``P+ = (I - K C) P (I - K C)' + K R K'`` — valid for any gain, optimal or not,
    and symmetric positive semidefinite by construction (re-symmetrized on return).
    ``C`` and ``R`` may be 2-D, shared by the stack.

    Should an intermediate product overflow, the update is evaluated again in state
    coordinates equilibrated by ``D = diag(d)``, ``d_i`` a power of two near
    ``sqrt(P_ii)`` (:func:`pow2_scale`): ``P+ = D (M P~ M' + K~ R K~') D`` with
    ``P~ = D^-1 P D^-1``, ``K~ = D^-1 K``, ``M = I - K~ (C D)``. That scaling is exact,
    so both evaluations round alike, but the second overflows only where ``P+``
    itself is beyond the floating-point range (states of wildly different scales,
    priors of ``1e300``).
    """
    n = P.shape[-1]
    with np.errstate(over="ignore", invalid="ignore"):
        IKC = np.eye(n) - mul(K, C)
        out = IKC @ P @ transpose(IKC) + mul(K, R) @ transpose(K)
    if np.all(np.isfinite(out)):
        return symmetrize(out)
    d = pow2_scale(np.diagonal(P, axis1=-2, axis2=-1))  # (..., n)
    K_s = K / d[..., :, None]
    IKC = np.eye(n) - K_s @ (C * d[..., None, :])
    P_s = P / d[..., :, None] / d[..., None, :]
    out = IKC @ P_s @ transpose(IKC) + mul(K_s, R) @ transpose(K_s)
    return symmetrize(out) * d[..., :, None] * d[..., None, :]


def mixture_moments(w: np.ndarray, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Moments of Gaussian mixtures.

    ``m_j = sum_i w_ij x_i`` and ``S_j = sum_i w_ij (P_i + d_ij d_ij')``.

    ``w (..., I, J)`` are weights over components i for each mixture j (columns sum
    to one), ``x (..., I, n)``, ``P (..., I, n, n)``; ``d_ij = x_i - m_j`` are the
    deviations from each mixture's own mean, so nothing cancels however large the
    means are. Every sum over components is a matrix product.
    """
    n = x.shape[-1]
    wt = transpose(w)  # (..., J, I)
    m = wt @ x
    d = x[..., None, :, :] - m[..., :, None, :]  # (..., J, I, n)
    spread = transpose(d * wt[..., None]) @ d
    S = (wt @ P.reshape(*P.shape[:-2], n * n)).reshape(*m.shape, n) + spread
    return m, symmetrize(S)


def log_normalize(log_w: np.ndarray, axis: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """Normalize log-weights along ``axis`` with log-sum-exp.

    Returns ``(log_w - lse, lse)`` with ``lse = log(sum(exp(log_w)))`` computed as
    ``max + log(sum(exp(log_w - max)))``, so the weights sum to one without ever
    leaving the log domain. An all ``-inf`` slice stays ``-inf`` with total
    ``-inf`` rather than becoming NaN. (A few numpy lines instead of
    ``scipy.special.logsumexp``, whose per-call overhead dominates a filter step.)
    """
    a = np.moveaxis(log_w, axis, 0)
    top = _fold(np.maximum, a)
    if not np.all(np.isfinite(top)):
        top = np.where(np.isfinite(top), top, 0.0)
    shifted = a - top
    with np.errstate(divide="ignore"):
        log_sum = np.log(_fold(np.add, np.exp(shifted)))
    out = shifted - np.where(np.isfinite(log_sum), log_sum, 0.0)
    return np.moveaxis(out, 0, axis), top + log_sum


def _fold(ufunc: np.ufunc, a: np.ndarray) -> np.ndarray:
    """``ufunc.reduce(a, axis=0)``; slice by slice for a short axis (the few modes or
    grid points of a filter), where a numpy reduction costs several times more."""
    if a.shape[0] > 16:
        return ufunc.reduce(a, axis=0)
    out = a[0]
    for row in a[1:]:
        out = ufunc(out, row)
    return out
