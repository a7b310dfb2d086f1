"""Plain numpy versions of the compiled filters' equations, one trial and one sample at a time.

The oracle the compiled kernels of :mod:`switchest.engine` are checked against:
written for clarity, not speed, with LAPACK (``numpy.linalg``) where the kernels use explicit
loops (the innovation covariance equilibrated by its diagonal as theirs, so both factor the
same matrices), and the observed components selected by boolean indexing. The
semantics are those the kernels document (Shankar et al. eqs (6)-(10); Blom & Bar-Shalom 1988;
Bar-Shalom, Li & Kirubarajan §11.6.6), the IMM in both timings of docs/conventions.rst:
``"sample"`` (each mode-matched posterior predicted through its own transition, then mixed)
and ``"interval"`` (mixed, then mode ``j``'s mixture predicted through mode ``j``'s).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_triangular

LOG_2PI = np.log(2.0 * np.pi)
EPS = np.finfo(float).eps


def repair(P, indefinite_only=False):
    """``(P', changed)``: eigenvalues below ``n eps max|eig|`` (``indefinite_only``: below minus
    that) raised to it, as the kernels' ``linalg.repair``."""
    P = 0.5 * (P + P.T)
    w, V = np.linalg.eigh(P)
    level = P.shape[0] * EPS * np.abs(w).max()
    if not w[0] < (-level if indefinite_only else level):
        return P, False
    fixed = (V * np.maximum(w, level)) @ V.T
    return 0.5 * (fixed + fixed.T), True


def predict(x, P, F, G, u, Qd):
    """``x- = F x + G u``, ``P- = F P F' + Qd``, symmetrized."""
    P_pred = F @ P @ F.T + Qd
    return F @ x + G @ u, 0.5 * (P_pred + P_pred.T)


def innovation(x, P, y, C, R):
    """``(obs, e, S, nis, loglik)`` over the observed components; ``None`` if none observed."""
    obs = ~np.isnan(y)
    if not obs.any():
        return None
    Co, Ro = C[obs], R[np.ix_(obs, obs)]
    e = y[obs] - Co @ x
    S = Co @ P @ Co.T + Ro
    d = np.sqrt(np.diag(S))  # equilibrated, as the kernels: S = D L L' D
    if not np.all(d > 0):
        raise np.linalg.LinAlgError("Matrix is not positive definite")
    chol = np.linalg.cholesky(S / d[:, None] / d[None, :])
    with np.errstate(over="ignore", invalid="ignore"):
        z = solve_triangular(chol, e / d, lower=True)
        nis = z @ z
        log_det = 2.0 * (np.log(np.diag(chol)).sum() + np.log(d).sum())
        loglik = -0.5 * (nis + log_det + obs.sum() * LOG_2PI)
    return obs, e, S, nis, loglik


def correct(x, P, C, R, obs, e, S):
    """``K = P C' S^-1``, ``x + K e``, Joseph form ``(I - K C) P (I - K C)' + K R K'``; where
    that loses its digits (a posterior variance below ``eps`` times the prior's, a correlation
    beyond ``1 + sqrt(eps)``) the information form ``L (I + L' C' R^-1 C L)^-1 L'``
    (``P = L L'``), and where that fails too Joseph's repaired if indefinite."""
    Co, Ro = C[obs], R[np.ix_(obs, obs)]
    K = np.linalg.solve(S, Co @ P).T
    A = np.eye(x.size) - K @ Co
    P_new = A @ P @ A.T + K @ Ro @ K.T
    P_new = 0.5 * (P_new + P_new.T)
    post = np.diag(P_new)
    root = np.sqrt(np.abs(post))
    bound = (1.0 + np.sqrt(EPS)) * np.outer(root, root)
    if np.all(post >= EPS * np.diag(P)) and np.all(np.abs(P_new) <= bound):
        return x + K @ e, P_new
    try:
        L = np.linalg.cholesky(P)
        W = solve_triangular(np.linalg.cholesky(Ro), Co @ L, lower=True)
        Z = solve_triangular(np.linalg.cholesky(np.eye(x.size) + W.T @ W), L.T, lower=True)
        P_new = Z.T @ Z
        P_new = 0.5 * (P_new + P_new.T)
    except np.linalg.LinAlgError:
        P_new = repair(P_new, indefinite_only=True)[0]
    return x + K @ e, P_new


def accepts(inn, gate) -> bool:
    """Whether a measurement passes the gate (a finite likelihood and ``nis <= gate``)."""
    return bool(np.isfinite(inn[4]) and inn[3] <= gate)


def robust_innovation(x, P, y, C, R):
    """``(P, innovation)``: a ``P`` whose ``S`` fails its factorization is repaired and the
    innovation taken once more (``LinAlgError`` if ``P`` needs no repair or fails again)."""
    try:
        return P, innovation(x, P, y, C, R)
    except np.linalg.LinAlgError:
        P, changed = repair(P)
        if not changed:
            raise
        return P, innovation(x, P, y, C, R)


def update(x, P, y, C, R, gate):
    """Gated update: ``x, P, loglik, flag`` (flag 1: gated, treated as missing)."""
    P, inn = robust_innovation(x, P, y, C, R)
    if inn is None:
        return x, P, 0.0, 0
    if not accepts(inn, gate):
        return x, P, 0.0, 1
    obs, e, S, _, loglik = inn
    return (*correct(x, P, C, R, obs, e, S), loglik, 0)


def kalman_run(y, u, F, G, Qd, trans, C, R, mode, x0, P0, gate=np.inf):
    """Every trial and sample, as the compiled ``kalman_run``."""
    N, K, _ = y.shape
    n = x0.size
    xs, Ps = np.empty((N, K, n)), np.empty((N, K, n, n))
    lls, flags = np.empty((N, K)), np.empty((N, K), dtype=int)
    for i in range(N):
        x, P = x0, P0
        for k in range(K):
            if k:
                t = trans[i, k]
                x, P = predict(x, P, F[t], G[t], u[i, k - 1], Qd[t])
            md = mode[i, k]
            x, P, lls[i, k], flags[i, k] = update(x, P, y[i, k], C[md], R[md], gate)
            xs[i, k], Ps[i, k] = x, P
    return xs, Ps, lls, flags


def kalman_steady_run(y, u, F, G, trans, C, mode, gain, P_prior, P_post, whiten, x0,
                      gate=np.inf):
    """Fixed gains: ``x + K_i (y - C_i x)`` when all of ``y`` is observed and its normalized
    innovation squared ``|W_i e|^2`` is finite and within ``gate``; P from the tables."""
    N, K, _ = y.shape
    xs, Ps = np.empty((N, K, x0.size)), np.empty((N, K, x0.size, x0.size))
    flags = np.zeros((N, K), dtype=np.uint8)
    for i in range(N):
        x = x0
        for k in range(K):
            if k:
                t = trans[i, k]
                x = F[t] @ x + G[t] @ u[i, k - 1]
            md = mode[i, k]
            used = False
            if not np.isnan(y[i, k]).any():
                e = y[i, k] - C[md] @ x
                with np.errstate(over="ignore", invalid="ignore"):
                    nis = float(np.sum((whiten[md] @ e) ** 2))
                used = bool(np.isfinite(nis) and nis <= gate)
                flags[i, k] = 0 if used else 1
                if used:
                    x = x + gain[md] @ e
            xs[i, k], Ps[i, k] = x, (P_post if used else P_prior)[md]
    return xs, Ps, flags


def log_sum_exp(a):
    """``log sum exp(a)``; ``-inf`` when every entry is ``-inf``."""
    top = a.max()
    if top == -np.inf:
        return -np.inf
    return top + np.log(np.exp(a - top).sum())


def imm_mix(x, P, log_prob, log_transition):
    """Mixed means and covariances and ``log c`` (Bar-Shalom, Li & Kirubarajan §11.6.6)."""
    L = log_prob.size
    xm, Pm, log_c = np.zeros_like(x), np.zeros_like(P), np.empty(L)
    for j in range(L):
        joint = log_prob + log_transition[:, j]
        log_c[j] = log_sum_exp(joint)
        if log_c[j] == -np.inf:
            continue
        w = np.exp(joint - log_c[j])
        xm[j] = w @ x
        d = x - xm[j]
        Pm[j] = np.einsum("i,irc->rc", w, P) + (w[:, None] * d).T @ d
    return xm, Pm, log_c


def predict_modes(x, P, F, G, u, Qd, tr):
    """Mode ``j``'s Gaussian ``x[j]``, ``P[j]`` predicted through its transition ``tr[j]``."""
    pred = [predict(x[j], P[j], F[tr[j]], G[tr[j]], u, Qd[tr[j]]) for j in range(len(x))]
    return np.stack([p[0] for p in pred]), np.stack([p[1] for p in pred])


def imm_trial_step(x, P, log_prob, y, u, F, G, Qd, tr, C, R, log_transition, predict_first,
                   gate, timing="sample"):
    """One IMM cycle of one trial: ``x, P, log_prob, loglik, flag``; the log-likelihood is 0
    when nothing was observed or every mode gated the measurement. ``timing="sample"``:
    predict every posterior through its own transition, then mix; ``"interval"``: mix, then
    predict."""
    L = log_prob.size
    x, P = x.copy(), P.copy()
    if predict_first and timing == "sample":
        x, P = predict_modes(x, P, F, G, u, Qd, tr)
        x, P, log_c = imm_mix(x, P, log_prob, log_transition)
    elif predict_first and timing == "interval":
        x, P, log_c = imm_mix(x, P, log_prob, log_transition)
        x, P = predict_modes(x, P, F, G, u, Qd, tr)
    elif predict_first:
        raise ValueError(f"timing {timing!r}")
    else:
        log_c = log_prob.copy()
    inns = []
    for j in range(L):
        P[j], inn = robust_innovation(x[j], P[j], y, C[j], R[j])
        inns.append(inn)
    flag, seen = 0, inns[0] is not None
    if not seen:
        a = log_c
    else:
        use = np.array([accepts(inn, gate) for inn in inns])
        a = np.where(use, log_c + np.array([inn[4] for inn in inns]), -np.inf)
        if a.max() == -np.inf:
            flag, a, seen = 1, log_c, False
        else:
            flag = 0 if use.all() else 2
            for j in np.flatnonzero(use):
                obs, e, S = inns[j][:3]
                x[j], P[j] = correct(x[j], P[j], C[j], R[j], obs, e, S)
    total = log_sum_exp(a)
    return x, P, a - total, total if seen else 0.0, flag


def imm_combine(x, P, log_prob):
    """Combined mean and covariance of the mode-matched posteriors, ``mu``, argmax mode."""
    mu = np.exp(log_prob)
    xc = mu @ x
    d = x - xc
    Pc = np.einsum("j,jrc->rc", mu, P) + (mu[:, None] * d).T @ d
    return xc, Pc, mu, int(np.argmax(log_prob))


def imm_run(y, u, F, G, Qd, trans, C, R, log_transition, x0, P0, log_prob0, gate=np.inf,
            timing="sample"):
    """Every trial and sample, as the compiled ``imm_run``."""
    N, K, _ = y.shape
    L, n = log_prob0.size, x0.size
    out = {"x": np.empty((N, K, n)), "P": np.empty((N, K, n, n)),
           "mode_prob": np.empty((N, K, L)), "mode": np.empty((N, K), dtype=int),
           "loglik": np.empty((N, K)), "flag": np.empty((N, K), dtype=int)}
    for i in range(N):
        x, P, lp = np.tile(x0, (L, 1)), np.tile(P0, (L, 1, 1)), log_prob0
        for k in range(K):
            x, P, lp, out["loglik"][i, k], out["flag"][i, k] = imm_trial_step(
                x, P, lp, y[i, k], u[i, k - 1 if k else 0], F, G, Qd, trans[k], C, R,
                log_transition, k > 0, gate, timing)
            (out["x"][i, k], out["P"][i, k], out["mode_prob"][i, k],
             out["mode"][i, k]) = imm_combine(x, P, lp)
    return out
