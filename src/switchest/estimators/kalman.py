"""The batched Kalman core every filter in switchest is built from.

Pure functions over stacks: leading axes are batch axes (trials, modes,
hypotheses, grid points), the last one or two are the vector or matrix.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_discrete_are

from .._linalg import congruence, joseph_update, matvec, mul, spd_solve, symmetrize, transpose

__all__ = ["kf_predict", "kf_update", "steady_state_gain"]

_LOG_2PI = np.log(2.0 * np.pi)


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


def kf_update(x, P, y, C, R):
    """Measurement update with innovation log-likelihood; NaN entries of ``y`` are missing.

    ``S = C P C' + R``, ``K = P C' S^-1`` by a Cholesky solve (no inverse),
    ``x+ = x + K (y - C x)``, and the covariance in Joseph form
    ``P+ = (I - K C) P (I - K C)' + K R K'`` (Shankar et al. eqs (8)-(10) in their
    numerically stable form). The log-likelihood is
    ``log N(y; C x, S) = -(e' S^-1 e + log det S + m log 2 pi) / 2``.

    A missing component (NaN) is removed exactly: its row of ``C`` is zeroed and
    its noise decoupled, so the update uses the observed components only and the
    log-likelihood is that of their marginal. An all-NaN ``y`` leaves ``x, P``
    unchanged with log-likelihood 0. A 2-D ``C`` or ``R`` is shared by the whole stack.

    Returns
    -------
    x, P, loglik
        Updated mean ``(..., n)``, covariance ``(..., n, n)`` and log-likelihood ``(...)``.
    """
    missing = np.isnan(y)
    m = y.shape[-1]
    if missing.any():
        C = np.broadcast_to(C, (*np.broadcast_shapes(C.shape[:-2], x.shape[:-1], y.shape[:-1]), *C.shape[-2:]))
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
    try:
        # one solve with S gives both K' = S^-1 C P and S^-1 e
        X, logdet = spd_solve(S, np.concatenate([CP, e[..., None]], axis=-1))
    except np.linalg.LinAlgError as exc:
        raise np.linalg.LinAlgError(
            "innovation covariance C P C' + R is not positive definite: give the system a "
            "measurement noise R or the filter a positive definite P0"
        ) from exc
    K, Sinv_e = transpose(X[..., :-1]), X[..., -1]
    loglik = -0.5 * (np.einsum("...i,...i->...", e, Sinv_e) + logdet + m * _LOG_2PI)
    if missing.any():
        loglik = loglik + 0.5 * missing.sum(axis=-1) * _LOG_2PI  # the decoupled unit blocks
    x_new = x + matvec(PCt, Sinv_e)  # K e = P C' S^-1 e
    P_new = joseph_update(P, K, C, R)
    return x_new, P_new, loglik


def steady_state_gain(F, C, Qd, R):
    """Steady-state filter gain and covariances of ``x+ = F x + w``, ``y = C x + v``.

    Solves the discrete algebraic Riccati equation for the a-priori covariance
    ``P = F P F' - F P C'(C P C' + R)^-1 C P F' + Qd`` and returns
    ``K = P C' (C P C' + R)^-1`` (the filter-form gain of Zhang & Natarajan eq. (6),
    ``x_k|k = x_k|k-1 + K (y_k - C x_k|k-1)``), ``P`` and the a-posteriori
    ``(I - K C) P``. Works on one mode; loop over modes outside (L is small and
    the Riccati solver is not batched).
    """
    P = solve_discrete_are(F.T, C.T, Qd, R)
    S = C @ P @ C.T + R
    K = np.linalg.solve(S, C @ P).T  # S symmetric: K' = S^-1 C P
    P_post = symmetrize((np.eye(F.shape[0]) - K @ C) @ P)
    return K, symmetrize(P), P_post
