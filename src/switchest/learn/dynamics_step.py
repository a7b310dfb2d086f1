"""Maximization steps of the mode dynamics ``A``, ``B`` (discrete time) and the output map ``C``.

Conditional maximization (Meng & Rubin 1993, Biometrika 80, ECM) of the expected complete-data
log-likelihood, before the noise steps that then use the new matrices: a weighted least-squares
regression of ``x_{k+1}`` on ``z_k = (x_k, u_k)`` per mode (or pooled where the model shares the
matrices), ``[A B] = (sum w E[x_{k+1} z_k']) (sum w E[z_k z_k'])^-1`` (Shumway & Stoffer 1982,
eq. (13); Ghahramani & Hinton 1996, "Parameter estimation for linear dynamical systems", eq.
(12)), and ``C = (sum w y_k E[x_k]') (sum w E[x_k x_k'])^-1`` over the samples observed in full
(Ghahramani & Hinton 1996, eq. (14); a partly observed sample is left out of this regression).
The generalized least-squares solution equals the ordinary one because every row shares the
regressors, so neither depends on ``Q`` or ``R``. ``B`` is fitted only where the inputs are not
all zero (otherwise it is not identifiable and kept).
"""

from __future__ import annotations

import numpy as np

from .expectation import Moments
from .noise_step import shared

__all__ = ["fit_AB", "fit_C"]


def _groups(*stacks) -> list[list[int]]:
    L = stacks[0].shape[0]
    return [list(range(L))] if all(shared(s) for s in stacks) else [[j] for j in range(L)]


def fit_AB(A: np.ndarray, B: np.ndarray, u: np.ndarray, mom: Moments, *, with_B: bool
           ) -> tuple[np.ndarray, np.ndarray]:
    """New ``A (L, n, n)`` and ``B (L, n, l)``; ``B`` kept unless ``with_B``. A mode whose
    regressor moment is singular (too few intervals) keeps its matrices."""
    n, l = A.shape[1], B.shape[2]
    w = mom.step_weight
    uk = u[:, :-1]
    Sxx = np.einsum("nkj,nkjab->jab", w, mom.P0 + mom.x0[..., :, None] * mom.x0[..., None, :])
    Sxu = np.einsum("nkj,nkja,nkb->jab", w, mom.x0, uk)
    Suu = np.einsum("nkj,nka,nkb->jab", w, uk, uk)
    S1x = np.einsum("nkj,nkjab->jab", w, mom.cross + mom.x1[..., :, None] * mom.x0[..., None, :])
    S1u = np.einsum("nkj,nkja,nkb->jab", w, mom.x1, uk)
    newA, newB = A.copy(), B.copy()
    for group in _groups(A, B) if with_B else _groups(A):
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


def fit_C(C: np.ndarray, y: np.ndarray, mom: Moments) -> np.ndarray:
    """New ``C (L, m, n)`` from the samples observed in full; a mode whose state moment is
    singular keeps its ``C``."""
    full = ~np.any(np.isnan(y), axis=-1)  # (N, K)
    w = mom.weight * full[..., None]
    yz = np.where(full[..., None], y, 0.0)
    Syx = np.einsum("nkj,nka,nkjb->jab", w, yz, mom.x)
    Sxx = np.einsum("nkj,nkjab->jab", w, mom.P + mom.x[..., :, None] * mom.x[..., None, :])
    new = C.copy()
    for group in _groups(C):
        xx = Sxx[group].sum(axis=0)
        if np.linalg.cond(xx) > 1e12:
            continue
        new[group] = np.linalg.solve(xx, Syx[group].sum(axis=0).T).T
    return new
