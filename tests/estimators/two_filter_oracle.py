"""A numpy oracle of the two-filter smoother's backward pass (engine/c/two_filter.c): the
implementation ``switchest.estimators.two_filter`` had before the pass became an engine kernel,
a loop over the samples in numpy, each step batched over the trials and the mode pairs.

The equations, numbered as the kernel's steps, are the module docstring of
:mod:`switchest.estimators.two_filter` (Helmick, Blair & Hoffman 1995): 1. the measurement
``N(y_{k+1}; C_l x', R_l) beta_l(k+1)(x')`` (``_measure``), 2. the dynamics, the Gaussian
integral through ``F_l``, ``G_l u_k``, ``Qd_l`` (``_dynamics``), 3. the log-linear pooling over
the next mode, weighed by each message's evidence under a reference Gaussian, whose pairs also
give the smoothed probabilities of the next mode (``_pool``), and the posterior of a Gaussian
and a message (``_posterior``). Here every system ``I + P Omega``,
``I + Omega Qd`` is solved by ``numpy.linalg.solve`` (LAPACK's LU with partial pivoting) and
its determinant taken by ``slogdet``; the measurement by a Cholesky factor of ``R`` over the
observed components: a different route from the kernel's (se_innovation's equilibrated
factor, se_lu), to the same numbers within rounding.
"""

from __future__ import annotations

import math

import numpy as np

from switchest._linalg import log_normalize, symmetrize

__all__ = ["two_filter_smooth"]

_LOG_2PI = math.log(2.0 * math.pi)


def two_filter_smooth(x_modes, P_modes, mode_prob, y, u, F, G, Qd, trans, transition, C, R, *,
                      outlier=None, timing: str = "interval"):
    """Smoothed mode-matched posteriors and mode probabilities (module docstring).

    Parameters
    ----------
    x_modes, P_modes : ndarray, shapes (N, K, L, n), (N, K, L, n, n)
        The forward filter's mode-matched posteriors after each sample's update.
    mode_prob : ndarray, shape (N, K, L)
        Its mode probabilities after each sample's update.
    y : ndarray, shape (N, K, m)
        The measurements (NaN: missing).
    u : ndarray, shape (N, K, l)
        Inputs, ``u[:, k]`` held over the interval into sample ``k + 1``.
    F, G, Qd : ndarray, shapes (M, n, n), (M, n, l), (M, n, n)
        Table of exact transitions; ``trans (N or 1, K, L)`` indexes mode ``j``'s into sample
        ``k`` (row 0 unused).
    transition : ndarray, shape (L, L)
        ``transition[i, j]`` = P(mode j at k+1 | mode i at k).
    C, R : ndarray, shapes (L, m, n), (L, m, m)
        Each mode's output matrix and measurement noise covariance.
    outlier : ndarray of bool, shape (N, K), optional
        Samples the forward filter rejected (treated as missing).
    timing : {"sample", "interval"}
        Which mode governs the interval ``k -> k+1``: that of sample ``k`` or of ``k+1``.

    Returns
    -------
    x_s, P_s : ndarray, shapes (N, K, L, n), (N, K, L, n, n)
        Smoothed mode-matched posteriors.
    prob_s : ndarray, shape (N, K, L)
        Smoothed mode probabilities.
    """
    N, K, L, n = x_modes.shape
    with np.errstate(divide="ignore"):
        log_pi = np.log(transition)
        log_mu = np.log(mode_prob)
    observed = ~np.isnan(y)
    if outlier is not None:
        observed &= ~np.asarray(outlier, dtype=bool)[..., None]
    trans = np.broadcast_to(trans, (N, K, L))
    x_s, P_s, log_s = x_modes.copy(), P_modes.copy(), log_mu.copy()
    pair = log_mu.copy()  # the mode probabilities of sample k + 1 from the pairs (k, k + 1)
    Omega, omega, c = np.zeros((N, L, n, n)), np.zeros((N, L, n)), np.zeros((N, L))
    for k in range(K - 2, -1, -1):
        entry = trans[:, k + 1]  # (N, L): mode l's transition into k+1
        g = np.einsum("nlij,nj->nli", G[entry], u[:, k])
        alpha = _measure(Omega, omega, c, y[:, k + 1], observed[:, k + 1], C, R)
        if timing == "interval":
            delta = _dynamics(*alpha, F[entry], g, Qd[entry])
            Omega, omega, c, pair[:, k + 1] = _pool(x_modes[:, k], P_modes[:, k], delta,
                                                    log_pi, log_mu[:, k])
        else:
            Fi = F[entry]
            x_pred = np.einsum("nlij,nlj->nli", Fi, x_modes[:, k]) + g
            P_pred = symmetrize(Fi @ P_modes[:, k] @ np.swapaxes(Fi, -1, -2) + Qd[entry])
            *pooled, pair[:, k + 1] = _pool(x_pred, P_pred, alpha, log_pi, log_mu[:, k])
            Omega, omega, c = _dynamics(*pooled, Fi, g, Qd[entry])
        log_z, x_s[:, k], P_s[:, k] = _posterior(x_modes[:, k], P_modes[:, k], Omega, omega, c)
        log_s[:, k] = log_mu[:, k] + log_z
    log_s[:, 1:-1] = pair[:, 1:-1]  # the last sample keeps the filtered probabilities
    prob_s = np.exp(log_normalize(log_s)[0])
    if not (np.all(np.isfinite(x_s)) and np.all(np.isfinite(P_s)) and np.all(np.isfinite(prob_s))):
        raise np.linalg.LinAlgError(
            "the two-filter smoother lost its digits: the filtered covariances reach "
            f"{np.abs(P_modes).max():.3g} (a mode that grows without process noise), beyond "
            "what its information messages can be combined with in double precision")
    return x_s, P_s, prob_s


def _measure(Omega, omega, c, y, observed, C, R):
    """``N(y; C_l x, R_l) beta_l(x)`` for every mode ``l`` (step 1), the observed components
    of ``y`` only: a missing one gets a zero row of ``C`` and a unit, uncoupled variance."""
    N, L, n = omega.shape
    m = y.shape[-1]
    both = observed[:, :, None] & observed[:, None, :]  # (N, m, m)
    eye = np.eye(m, dtype=bool)
    R_obs = np.where(both[:, None], R[None], np.where(eye, 1.0, 0.0))  # (N, L, m, m)
    C_obs = np.where(observed[:, None, :, None], C[None], 0.0)  # (N, L, m, n)
    y_obs = np.where(observed, y, 0.0)[:, None, :, None]  # (N, 1, m, 1)
    chol = np.linalg.cholesky(R_obs)
    W = np.linalg.solve(chol, C_obs)  # R^-1/2 C
    z = np.linalg.solve(chol, np.broadcast_to(y_obs, (N, L, m, 1)))[..., 0]  # R^-1/2 y
    Wt = np.swapaxes(W, -1, -2)
    missing = m - observed.sum(axis=-1)
    log_det = 2.0 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(axis=-1)
    c_new = (c - 0.5 * (z * z).sum(axis=-1) - 0.5 * log_det
             - 0.5 * _LOG_2PI * (m - missing)[:, None])
    return Omega + Wt @ W, omega + np.einsum("nlij,nlj->nli", Wt, z), c_new


def _dynamics(Omega, omega, c, F, g, Qd):
    """``∫ N(x'; F x + g, Qd) beta(x') dx'`` as a message on ``x`` (step 2)."""
    n = omega.shape[-1]
    M = np.eye(n) + Omega @ Qd  # eigenvalues >= 1
    Omega_t = symmetrize(_solve(M, Omega))
    omega_t = _solve(M, omega[..., None])[..., 0]
    log_det = np.linalg.slogdet(M)[1]
    quad = np.einsum("...i,...ij,...j->...", omega, Qd, omega_t)
    Ft = np.swapaxes(F, -1, -2)
    Og = np.einsum("...ij,...j->...i", Omega_t, g)
    c_new = (c - 0.5 * log_det - 0.5 * np.einsum("...i,...i->...", g, Og)
             + np.einsum("...i,...i->...", omega_t, g) + 0.5 * quad)
    return (symmetrize(Ft @ Omega_t @ F), np.einsum("...ij,...j->...i", Ft, omega_t - Og), c_new)


def _pool(x_ref, P_ref, messages, log_pi, log_mu):
    """The messages of the next modes ``l`` collapsed into one per mode ``i`` (step 3), weighed
    and scaled under the reference Gaussians ``N(x_ref[:, i], P_ref[:, i])``; last, the log
    smoothed probabilities of the next mode from the pairs,
    ``log sum_i mu_i pi_il Z_il`` (``log_mu (N, L)`` = log mu_i), up to a constant."""
    Omega, omega, c = messages  # (N, L_l, ...)
    log_z = _posterior(x_ref[:, :, None], P_ref[:, :, None], Omega[:, None], omega[:, None],
                       c[:, None])[0]  # (N, L_i, L_l)
    log_w, total = log_normalize(log_pi[None] + log_z)  # total (N, L_i)
    w = np.where(np.isfinite(total)[..., None], np.exp(log_w), 0.0)  # impossible: no message
    Omega_p = symmetrize(np.einsum("nil,nlab->niab", w, Omega))
    omega_p = np.einsum("nil,nla->nia", w, omega)
    base = _posterior(x_ref, P_ref, Omega_p, omega_p, np.zeros(total.shape))[0]
    pair = np.logaddexp.reduce(log_mu[:, :, None] + log_pi[None] + log_z, axis=1)
    return Omega_p, omega_p, total - base, pair


def _posterior(x, P, Omega, omega, c):
    """``(log Z, x_s, P_s)`` of the Gaussian ``N(x, P)`` times the message (module
    docstring), broadcast over the leading axes."""
    n = x.shape[-1]
    M = np.eye(n) + P @ Omega  # eigenvalues >= 1
    P_s = symmetrize(_solve(M, np.broadcast_to(P, M.shape)))
    r = omega - np.einsum("...ij,...j->...i", Omega, x)
    Pr = np.einsum("...ij,...j->...i", P_s, r)
    x_s = x + Pr
    log_z = (c - 0.5 * np.einsum("...i,...ij,...j->...", x, Omega, x)
             + np.einsum("...i,...i->...", omega, x) + 0.5 * np.einsum("...i,...i->...", r, Pr)
             - 0.5 * np.linalg.slogdet(M)[1])
    return log_z, x_s, P_s


def _solve(M, B):
    """``M^-1 B`` for a stack of ``I + (PSD)(PSD)`` matrices (eigenvalues >= 1, so regular);
    one whose factorization meets an exact zero pivot, its entries beyond double precision's
    range of the identity, by the pseudo-inverse."""
    try:
        return np.linalg.solve(M, B)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(M) @ B
