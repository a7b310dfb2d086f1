"""Maximization steps of the mode dynamics ``A``, ``B`` (discrete time) and the output map ``C``.

Conditional maximization (Meng & Rubin 1993, Biometrika 80, ECM) of the expected complete-data
log-likelihood, before the noise steps that then use the new matrices: a weighted least-squares
regression of :math:`x_{k+1}` on :math:`z_k = (x_k, u_k)` per mode (or pooled where the fit ties
the matrices), :math:`[A\\ B] = (\\sum w\\, \\mathbb{E}[x_{k+1} z_k^\\top])
(\\sum w\\, \\mathbb{E}[z_k z_k^\\top])^{-1}` (Shumway & Stoffer 1982, eq. (13); Ghahramani &
Hinton 1996, "Parameter estimation for linear dynamical systems", eq. (12)), and
:math:`C = (\\sum w\\, y_k \\mathbb{E}[x_k]^\\top) (\\sum w\\, \\mathbb{E}[x_k x_k^\\top])^{-1}`
over the samples observed in full (Ghahramani & Hinton 1996, eq. (14); a partly observed sample
is left out of this regression).
The generalized least-squares solution equals the ordinary one because every row shares the
regressors, so neither depends on ``Q`` or ``R``. ``B`` is fitted only where the inputs are not
all zero (otherwise it is not identifiable and kept).
"""

from __future__ import annotations

import numpy as np

from .moments import Moments
from .noise_step import groups

__all__ = ["fit_AB", "fit_C"]


def fit_AB(A: np.ndarray, B: np.ndarray, u: np.ndarray, mom: Moments, *, with_B: bool,
           tied: bool) -> tuple[np.ndarray, np.ndarray]:
    """New ``A (L, n, n)`` and ``B (L, n, l)``, per mode or pooled over all (``tied``); ``B``
    kept unless ``with_B``. A mode whose regressor moment is singular (too few intervals)
    keeps its matrices. The E-step's components are the modes (a discrete-time system
    switches at its steps)."""
    n, l = A.shape[1], B.shape[2]
    w = mom.step_weight
    uk = u[:, :-1]
    Sxx = np.einsum("nkj,nkjab->jab", w, mom.P0 + mom.x0[..., :, None] * mom.x0[..., None, :])
    Sxu = np.einsum("nkj,nkja,nkb->jab", w, mom.x0, uk)
    Suu = np.einsum("nkj,nka,nkb->jab", w, uk, uk)
    S1x = np.einsum("nkj,nkjab->jab", w, mom.cross + mom.x1[..., :, None] * mom.x0[..., None, :])
    S1u = np.einsum("nkj,nkja,nkb->jab", w, mom.x1, uk)
    newA, newB = A.copy(), B.copy()
    for group in groups(A.shape[0], tied):
        zz = Sxx[group].sum(axis=0)
        xz = S1x[group].sum(axis=0)
        if with_B:
            zz = np.block([[zz, Sxu[group].sum(axis=0)],
                           [Sxu[group].sum(axis=0).T, Suu[group].sum(axis=0)]])
            xz = np.concatenate([xz, S1u[group].sum(axis=0)], axis=1)
        else:  # x_{k+1} - B u_k regressed on x_k
            xz = xz - B[group[0]] @ Sxu[group].sum(axis=0).T
        if np.linalg.cond(zz) > 1e12:
            continue
        sol = np.linalg.solve(zz, xz.T).T
        newA[group] = sol[:, :n]
        if with_B:
            newB[group] = sol[:, n:n + l]
    return newA, newB


def fit_C(C: np.ndarray, R: np.ndarray, mom: Moments, *, tied: bool) -> np.ndarray:
    """New ``C (L, m, n)``: the regression of the E-step's measurements ``mom.y`` on the
    smoothed state (Ghahramani & Hinton 1996, eq. (14); Shumway & Stoffer 1982 take the output
    map as known),
    :math:`C_j = (\\sum w\\, y x^\\top) (\\sum w\\, \\mathbb{E}[x x^\\top])^{-1}` per mode, or
    pooled over all (``tied``).

    With every :math:`R_j` diagonal the expected complete-data log-likelihood separates by
    output component, so row ``a`` of ``C`` is fitted from every sample that observes component
    ``a``. Otherwise the rows are coupled through :math:`R^{-1}` wherever a sample misses some
    of its components, and the exact step uses the samples observed in full only (with all rows
    regressed on the same samples, least squares is the exact step whatever ``R``: Zellner
    1962, seemingly unrelated regressions with identical regressors). A mode (or row) whose
    state moment is singular keeps its ``C``.
    """
    y = mom.y
    seen = ~np.isnan(y)  # (N, K, m)
    if not np.all(R == np.eye(R.shape[1]) * R):  # a correlated R: the fully observed samples
        seen = np.broadcast_to(np.all(seen, axis=-1, keepdims=True), seen.shape)
    Exx = mom.P + mom.x[..., :, None] * mom.x[..., None, :]  # (N, K, L, n, n)
    Syx = np.einsum("nkj,nka,nkjb->jab", mom.weight, np.where(seen, y, 0.0), mom.x)
    new = C.copy()
    for a in range(C.shape[1]):
        Sxx = np.einsum("nkj,nk,nkjab->jab", mom.weight, seen[..., a].astype(float), Exx)
        for group in groups(C.shape[0], tied):
            xx = Sxx[group].sum(axis=0)
            if np.linalg.cond(xx) > 1e12:
                continue
            new[group, a] = np.linalg.solve(xx, Syx[group, a].sum(axis=0))
    return new
