"""The Kalman core in numpy, as switchest ran it before the compiled engine: the test oracle.

``kf_predict`` and ``kf_update`` over stacks (leading axes are batch axes), written with
numpy's batched linear algebra; the oracles of the compiled filters (``imm_ev1_oracle.py``,
``switch_time_oracle.py``) are built on them, so the compiled kernels are checked against an
implementation that shares none of their code.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from switchest._linalg import joseph_update, matvec, mul, pow2_scale, symmetrize, transpose

__all__ = ["kf_predict", "kf_update"]

_LOG_2PI = np.log(2.0 * np.pi)
_EPS = np.finfo(float).eps


def kf_predict(x, P, F, G, u, Qd, *, inflation: float = 0.0):
    """Time update ``x- = F x + G u``, ``P- = F P F' + Qd (+ inflation I)``.

    Shankar et al. eqs (6)-(7) with the process noise of the exact discretization
    added; ``inflation`` is the ``epsilon I`` of their Algorithm 1 (§IV). Shapes
    broadcast over leading axes (a 2-D ``F`` or ``Qd`` is shared by the whole
    stack); ``u`` may have a zero-length last axis.
    """
    x_pred = matvec(F, x)
    if u.shape[-1]:
        x_pred = x_pred + matvec(G, u)
    P_pred = congruence(F, P) + Qd
    if inflation:
        P_pred = P_pred + inflation * np.eye(P.shape[-1])
    return x_pred, symmetrize(P_pred)


def kf_update(x, P, y, C, R, *, gate: float | None = None):
    """Measurement update with innovation log-likelihood; NaN entries of ``y`` are missing.

    ``S = C P C' + R``, ``K = P C' S^-1`` by a Cholesky solve (no inverse),
    ``x+ = x + K (y - C x)``, and the covariance in Joseph form
    ``P+ = (I - K C) P (I - K C)' + K R K'`` (Shankar et al. eqs (8)-(10) in their
    numerically stable form). The log-likelihood is
    ``log N(y; C x, S) = -(e' S^-1 e + log det S + m log 2 pi) / 2``, with the
    normalized innovation squared ``e' S^-1 e = |L^-1 D^-1 e|^2`` and ``log det S``
    taken from the equilibrated factor ``S = D L L' D`` (:func:`~switchest._linalg.spd_factor`),
    so that neither depends on the scale of the measurements.

    A missing component (NaN) is removed exactly: its row of ``C`` is zeroed and
    its noise decoupled, so the update uses the observed components only and the
    log-likelihood is that of their marginal. An all-NaN ``y`` leaves ``x, P``
    unchanged with log-likelihood 0. A 2-D ``C`` or ``R`` is shared by the whole stack.

    A measurement is *rejected* when its normalized innovation squared is not
    finite (a measurement so far off that it overflows, e.g. ``1e300``) or exceeds
    ``gate``: ``x, P`` are left unchanged, as for a missing measurement, and the
    log-likelihood is ``-inf`` (the likelihood truncated to zero outside the gate),
    so that a caller tells a rejected measurement (``-inf``) from a missing one (0).

    Parameters
    ----------
    x, P : ndarray
        Prior mean ``(..., n)`` and covariance ``(..., n, n)``.
    y : ndarray, shape (..., m)
    C, R : ndarray
        ``(..., m, n)`` and ``(..., m, m)``.
    gate : float, optional
        Largest normalized innovation squared accepted (keyword-only); ``None``
        rejects only measurements whose innovation overflows.

    Returns
    -------
    x, P, loglik
        Updated mean ``(..., n)``, covariance ``(..., n, n)`` and log-likelihood ``(...)``.

    Raises
    ------
    numpy.linalg.LinAlgError
        If ``S`` is not positive definite, or ``S`` or ``P`` is not finite (overflowed).

    Notes
    -----
    Where Joseph's form loses its digits (a diffuse prior) the posterior is taken in
    information form (:func:`_posterior`). A state covariance can still lose positive
    semidefiniteness to round-off when its condition number exceeds ``1/eps`` (a prior
    of ``1e300`` on a state observed only through the dynamics, a mixture of
    estimates ``1e50`` apart): its small variances are then below the rounding error
    of the large ones. Such a covariance — a posterior found indefinite, or a prior
    whose ``S`` fails its factorization — is repaired: its eigenvalues are raised to
    at least its rounding level ``n eps max|eig P|``, as much as is known about the
    small ones, with a ``RuntimeWarning`` (and the update is retried once).
    """
    try:
        return _update(x, P, y, C, R, gate)
    except np.linalg.LinAlgError as exc:
        if not np.all(np.isfinite(P)):
            raise np.linalg.LinAlgError(
                "the state covariance P is not finite: it overflowed (a prior P0, a process noise "
                "or dynamics too large for the floating-point range)"
            ) from exc
        P_fixed, repaired = _psd_repair(P)
        if not repaired.any():
            raise
        _warn_repair(P)
        return _update(x, P_fixed, y, C, R, gate)


def _update(x, P, y, C, R, gate):
    """:func:`kf_update` on a covariance taken as it is."""
    missing = np.isnan(y)
    m = y.shape[-1]
    if missing.any():
        batch = np.broadcast_shapes(C.shape[:-2], x.shape[:-1], y.shape[:-1])
        C = np.broadcast_to(C, (*batch, *C.shape[-2:]))
        R = np.broadcast_to(R, (*C.shape[:-2], m, m))
        keep = ~missing
        y = np.where(missing, 0.0, y)
        C = C * keep[..., :, None]
        pair = keep[..., :, None] & keep[..., None, :]
        R = np.where(pair, R, 0.0) + np.where(missing, 1.0, 0.0)[..., None] * np.eye(m)
    e = y - matvec(C, x)
    PCt = mul(P, transpose(C))
    CP = transpose(PCt)  # P symmetric
    S = mul(CP, transpose(C)) + R  # the Cholesky factorization reads its lower triangle only
    factor = _innovation_factor(S, CP, e)
    # one factorization of S gives K' = S^-1 C P, S^-1 e and e' S^-1 e; an innovation that
    # overflows is rejected below
    with np.errstate(over="ignore", invalid="ignore"):
        X, quad = factor.solve_quadratic(np.concatenate([CP, e[..., None]], axis=-1))
    nis = quad[..., -1]
    accepted = nis < np.inf if gate is None else nis <= gate  # False for inf and NaN
    K, Sinv_e = transpose(X[..., :-1]), X[..., -1]
    loglik = -0.5 * (nis + factor.logdet + m * _LOG_2PI)
    if missing.any():
        loglik = loglik + 0.5 * missing.sum(axis=-1) * _LOG_2PI  # the decoupled unit blocks
    everything = accepted.all()
    if not everything:
        Sinv_e = np.where(accepted[..., None], Sinv_e, 0.0)  # x+ = x exactly
        loglik = np.where(accepted, loglik, -np.inf)
    x_new = x + matvec(PCt, Sinv_e)  # K e = P C' S^-1 e
    P_new = _posterior(P, K, C, R)
    if not everything:
        P_new = np.where(accepted[..., None, None], P_new, P)
    return x_new, P_new, loglik


def _posterior(P, K, C, R):
    """Posterior covariance for the optimal gain ``K``: Joseph form, or where that loses its digits
    the information form.

    Joseph's ``M = I - K C`` is accurate to ``eps |K C|`` only, so ``M P M'`` carries an error
    of about ``eps^2 |K C|^2 P``. Where the update removes nearly all the prior variance of a
    state (``P+_ii < eps P_ii``: a diffuse prior, a nearly noise-free measurement, ``K C ~ I``)
    or the result is no longer a covariance (a correlation beyond ``1 + sqrt(eps)``), that
    error has swamped ``P+``; there, if ``P`` and ``R`` are positive definite,
    ``P+ = (P^-1 + C' R^-1 C)^-1 = L (I + L' C' R^-1 C L)^-1 L'`` (``P = L L'``) is taken
    instead: a Gram matrix ``Z' Z``, accurate to the conditioning of ``C' R^-1 C``. Where
    neither form resolves ``P+`` (its condition number is beyond ``1/eps``: a diffuse prior on
    states the measurement does not see) an indefinite result is repaired (:func:`_psd_repair`).
    """
    P_new = joseph_update(P, K, C, R)
    prior = np.diagonal(P, axis1=-2, axis2=-1)
    post = np.diagonal(P_new, axis1=-2, axis2=-1)
    root = np.sqrt(np.abs(post))
    bound = (1.0 + np.sqrt(_EPS)) * root[..., :, None] * root[..., None, :]
    kept = np.all(post >= _EPS * prior, axis=-1) & np.all(np.abs(P_new) <= bound, axis=(-2, -1))
    if kept.all():
        return P_new
    n = P.shape[-1]
    shape = kept.shape
    P_new = np.array(np.broadcast_to(P_new, (*shape, n, n)))  # a writable copy
    P_b, C_b, R_b = (np.broadcast_to(a, (*shape, *a.shape[-2:])) for a in (P, C, R))
    repaired = []
    for idx in zip(*np.nonzero(~kept)):  # rare: one small problem at a time
        try:
            L = spd_factor(P_b[idx]).lower()  # P = L L'
            Cw = spd_factor(R_b[idx]).whiten(C_b[idx] @ L)  # R^-1/2 C L
            Z = spd_factor(np.eye(n) + Cw.T @ Cw).whiten(L.T)  # (I + Cw'Cw)^-1/2 L'
            P_new[idx] = symmetrize(Z.T @ Z)
        except np.linalg.LinAlgError:  # P or R singular, or P+ beyond 1/eps: Joseph's, repaired
            P_new[idx], changed = _psd_repair(P_new[idx], indefinite_only=True)
            if changed:
                repaired.append(P_new[idx])
    if repaired:
        _warn_repair(np.stack(repaired))
    return P_new


def _innovation_factor(S, CP, e):
    """The equilibrated Cholesky factor of ``S``, broadcast with ``C P`` and ``e``; clear errors."""
    shape = np.broadcast_shapes(S.shape[:-2], CP.shape[:-2], e.shape[:-1])
    try:
        return spd_factor(np.broadcast_to(S, (*shape, *S.shape[-2:])))
    except np.linalg.LinAlgError as exc:
        if not np.all(np.isfinite(S)):
            raise np.linalg.LinAlgError(
                "innovation covariance C P C' + R is not finite: it overflowed (C P C' or R beyond "
                "the floating-point range)"
            ) from exc
        raise np.linalg.LinAlgError(
            "innovation covariance C P C' + R is not positive definite: give the system a "
            "measurement noise R or the filter a positive definite P0"
        ) from exc


def _psd_repair(P, *, indefinite_only=False):
    """``(P', repaired)``: each covariance with an eigenvalue below its rounding level
    ``n eps max|eig|`` (which cannot be told from zero; with ``indefinite_only``, below minus
    that level: negative beyond rounding) gets its eigenvalues raised to that level, as much as
    is known about them; the others are returned as they are. ``repaired (...)`` marks the
    changed ones."""
    P = symmetrize(P)
    w, V = np.linalg.eigh(P)
    level = P.shape[-1] * _EPS * np.max(np.abs(w), axis=-1, keepdims=True)
    repaired = w[..., 0] < (-level if indefinite_only else level)[..., 0]
    fixed = symmetrize((V * np.maximum(w, level)[..., None, :]) @ transpose(V))
    return np.where(repaired[..., None, None], fixed, P), repaired


def _warn_repair(P) -> None:
    warnings.warn(
        "the state covariance P is singular or indefinite to working precision (condition "
        "number beyond 1/eps): its eigenvalues were raised to its rounding level (its smallest "
        f"eigenvalue was {float(np.min(np.linalg.eigvalsh(symmetrize(P)))):.3g})",
        RuntimeWarning,
        stacklevel=2,
    )


# ---------------------------------------------------------------- the batched numpy helpers
def shared(M: np.ndarray) -> np.ndarray:
    """``M[0]`` when every matrix of a stack ``M (L, a, b)`` is the same, else ``M``.

    Filters pass a matrix all modes share (an output matrix, the dynamics of modes
    that differ only in their input) as one 2-D matrix, which :func:`mul`,
    :func:`matvec` and :func:`congruence` apply to a whole stack at once.
    """
    return M[0] if M.ndim == 3 and np.all(M == M[:1]) else M


def congruence(F: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``F P F'`` for a stack of symmetric ``P`` (not re-symmetrized).

    A 2-D ``F`` shared by the stack takes two shared-factor products,
    ``(F P) F' = (P F')' F'`` (``P`` symmetric); otherwise ``F @ P @ F'``.
    """
    Ft = transpose(F)
    if F.ndim == 2:
        return mul(transpose(mul(P, Ft)), Ft)
    return F @ P @ Ft


@dataclass(frozen=True, eq=False)
class SPDFactor:
    """Cholesky factor of a stack of symmetric positive definite matrices, equilibrated.

    ``S = D L L' D`` with ``D = diag(d)``, ``d_i`` a power of two near
    ``sqrt(S_ii)`` (:func:`pow2_scale`), and ``L`` the lower Cholesky factor of
    ``D^-1 S D^-1``, whose diagonal lies in ``[0.5, 2)``: entries of ``S`` of ``1e300`` or
    ``1e-300`` neither overflow nor underflow in the factorization. Made by
    :func:`spd_factor`. The stack is stored last (``L (m, m, N)``, ``d (m, N)``)
    so that the loops over matrix entries operate on whole contiguous stacks.

    Attributes
    ----------
    L : ndarray, shape (m, m, N)
    d : ndarray, shape (m, N)
    shape : tuple of int
        The batch shape of the stack.
    """

    L: np.ndarray
    d: np.ndarray
    shape: tuple[int, ...]

    def lower(self) -> np.ndarray:
        """The lower-triangular factor ``D L`` of ``S = (D L)(D L)'``, shape ``(..., m, m)``."""
        m = self.L.shape[0]
        return self._unstack(self.d[:, None, :] * self.L, m)

    @property
    def logdet(self) -> np.ndarray:
        """``log det S = 2 sum log L_ii + 2 sum log d_i``, shape ``shape``."""
        m = self.L.shape[0]
        diag = self.L[np.arange(m), np.arange(m)] * self.d  # about sqrt(S_ii): no overflow
        return (2.0 * np.sum(np.log(diag), axis=0)).reshape(self.shape)

    def whiten(self, B: np.ndarray) -> np.ndarray:
        """``W = L^-1 D^-1 B`` for ``B (..., m, k)`` (forward substitution): ``W'W = B' S^-1 B``."""
        return self._unstack(self._forward(self._stack(B)), B.shape[-1])

    def solve(self, B: np.ndarray) -> np.ndarray:
        """``X = S^-1 B`` for ``B (..., m, k)`` by forward and back substitution, no inverse."""
        return self._unstack(self._back(self._forward(self._stack(B))), B.shape[-1])

    def solve_quadratic(self, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``X = S^-1 B`` and the quadratic forms ``q_j = b_j' S^-1 b_j = |L^-1 D^-1 b_j|^2``
        of the columns of ``B (..., m, k)``: ``q (..., k)`` is a sum of squares, never
        negative however ill-conditioned ``S`` is (``inf`` where it overflows)."""
        W = self._forward(self._stack(B))
        q = np.einsum("ikn,ikn->nk", W, W).reshape(*self.shape, B.shape[-1])
        return self._unstack(self._back(W), B.shape[-1]), q

    def _stack(self, B: np.ndarray) -> np.ndarray:
        m = self.L.shape[0]
        return _stack_last(np.broadcast_to(B, (*self.shape, m, B.shape[-1]))).copy()

    def _unstack(self, X: np.ndarray, k: int) -> np.ndarray:
        m = self.L.shape[0]
        return np.ascontiguousarray(np.moveaxis(X, -1, 0)).reshape(*self.shape, m, k)

    def _forward(self, X: np.ndarray) -> np.ndarray:
        """``L^-1 D^-1 X`` in place on a stack-last ``X (m, k, N)``."""
        L = self.L
        X /= self.d[:, None, :]
        for i in range(L.shape[0]):
            for p in range(i):
                X[i] -= L[i, p] * X[p]
            X[i] /= L[i, i]
        return X

    def _back(self, X: np.ndarray) -> np.ndarray:
        """``D^-1 L'^-1 X`` in place on a stack-last ``X (m, k, N)``."""
        L = self.L
        m = L.shape[0]
        for i in reversed(range(m)):
            for p in range(i + 1, m):
                X[i] -= L[p, i] * X[p]
            X[i] /= L[i, i]
        X /= self.d[:, None, :]
        return X


def spd_factor(S: np.ndarray) -> SPDFactor:
    """Equilibrated Cholesky factorization of a stack of symmetric positive definite ``S``.

    ``S (..., m, m)``; only its lower triangle and diagonal are read. The stack is
    scaled by powers of two to unit diagonal (exact), then ``L`` is computed column
    by column with every operation vectorized over the whole stack: for the small
    ``m`` of measurement vectors that is several times faster than one LAPACK call
    per matrix. See :class:`SPDFactor`.

    Raises ``numpy.linalg.LinAlgError`` if a matrix is not positive definite or
    holds a non-finite entry.
    """
    m = S.shape[-1]
    shape = S.shape[:-2]
    St = _stack_last(S)  # (m, m, N)
    diag = St[np.arange(m), np.arange(m)]
    if not np.all(diag > 0):
        raise np.linalg.LinAlgError("Matrix is not positive definite")
    d = pow2_scale(diag)
    St = St / d[:, None, :] / d[None, :, :]  # exact: powers of two
    L = np.zeros_like(St)
    for j in range(m):
        piv = St[j, j].copy()
        for p in range(j):
            piv -= L[j, p] ** 2
        if not np.all(piv > 0):
            raise np.linalg.LinAlgError("Matrix is not positive definite")
        L[j, j] = np.sqrt(piv)
        for i in range(j + 1, m):
            L[i, j] = St[i, j]
            for p in range(j):
                L[i, j] -= L[i, p] * L[j, p]
            L[i, j] /= L[j, j]
    if not np.all(np.isfinite(L)):  # an infinite entry of S (a NaN one fails a pivot above)
        raise np.linalg.LinAlgError("Matrix has non-finite entries")
    return SPDFactor(L=L, d=d, shape=shape)


def spd_solve(S: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve ``S X = B`` for a stack of symmetric positive definite ``S``; return ``X, log det S``.

    ``S (..., m, m)`` (only its lower triangle is read), ``B (..., m, k)``;
    leading axes broadcast. By the equilibrated Cholesky factorization of
    :func:`spd_factor` and forward and back substitution — no inverse.
    Raises ``numpy.linalg.LinAlgError`` if a matrix is not positive definite.
    """
    m = S.shape[-1]
    shape = np.broadcast_shapes(S.shape[:-2], B.shape[:-2])
    factor = spd_factor(np.broadcast_to(S, (*shape, m, m)))
    return factor.solve(B), factor.logdet


def _stack_last(M: np.ndarray) -> np.ndarray:
    """A stack ``(..., a, b)`` as one contiguous array ``(a, b, N)`` with the stack last."""
    return np.ascontiguousarray(np.moveaxis(M.reshape(-1, *M.shape[-2:]), 0, -1))
