"""Plain numpy smoothers and exact mixtures, one trial at a time: the oracles of the compiled
smoother (``engine/c/smoother.c``) and of ``ExactMixtureFilter``.

Written for clarity, not speed, from the textbook formulas, with LAPACK's Cholesky
(``scipy.linalg.cho_solve``) for the smoother gain and the covariance written as
``P + J (P_s - P_pred) J'``, where the kernel uses Joseph's form of a pseudo-measurement update
(the same quantity, computed another way). Conventions of switchest: ``transition[i, j]`` =
P(mode j at k+1 | mode i at k); mode ``j`` at sample ``k`` governs the measurement at ``k`` and,
by the ``timing`` (docs/conventions.rst), the interval after ``k`` (``"sample"``, the default:
``x_{k+1} = F(r_k) x_k + G(r_k) u_k + w_k``) or the interval into ``k`` (``"interval"``:
``x_k = F(r_k) x_{k-1} + G(r_k) u_{k-1} + w``); ``trans[k, j]`` indexes mode ``j``'s transition
over the interval into sample ``k`` in both; ``u[k]`` is held over the interval into sample
``k + 1``.
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy_oracle import imm_combine, imm_trial_step, log_sum_exp, predict, update
from scipy.linalg import cho_factor, cho_solve

from switchest import SwitchedLinearSystem
from switchest.discretize import mode_steps


def tables(system, t):
    """``F, G, Qd (M, ...)`` and ``trans (K, L)``: one exact transition per mode and distinct
    step of the sample times ``t``, indexed as ``IMMFilter.run`` indexes them."""
    L, K = system.n_modes, t.size
    steps, which = np.unique(np.diff(t), return_inverse=True)
    if steps.size == 0:
        steps = np.ones(1)
    table = [mode_steps(system, h) for h in steps]
    trans = np.zeros((K, L), dtype=np.int64)
    trans[1:] = np.arange(L) + L * which.reshape(-1, 1)
    return (np.concatenate([s.F for s in table]), np.concatenate([s.G for s in table]),
            np.concatenate([s.Qd for s in table]), trans)


def rts_gain(P, F, Qd, pinv=False):
    """``(P_pred, J)``: ``P_pred = F P F' + Qd`` and ``J = P F' P_pred^-1`` by Cholesky, or
    with ``pinv`` ``J = P F' pinv(P_pred)`` by the Moore-Penrose pseudo-inverse: the smoother
    of a singular predicted covariance (``Qd = 0`` with a singular ``F``)."""
    P_pred = F @ P @ F.T + Qd
    P_pred = 0.5 * (P_pred + P_pred.T)
    if pinv:
        return P_pred, P @ F.T @ np.linalg.pinv(P_pred)
    return P_pred, cho_solve(cho_factor(P_pred, lower=True), F @ P).T


def rts_step(x, P, x_next, P_next, F, G, u, Qd, pinv=False):
    """Rauch, Tung & Striebel (1965): ``x + J (x_next - x_pred)``,
    ``P + J (P_next - P_pred) J'`` (``pinv``: :func:`rts_gain`)."""
    P_pred, J = rts_gain(P, F, Qd, pinv)
    x_s = x + J @ (x_next - (F @ x + G @ u))
    P_s = P + J @ (P_next - P_pred) @ J.T
    return x_s, 0.5 * (P_s + P_s.T)


def rts_smooth(x, P, u, F, G, Qd, trans, pinv=False):
    """RTS smoother of one trial: filtered ``x (K, n)``, ``P (K, n, n)``, inputs ``u (K, l)``,
    ``trans (K,)`` the transition into each sample (``pinv``: :func:`rts_gain`)."""
    xs, Ps = x.copy(), P.copy()
    for k in range(x.shape[0] - 2, -1, -1):
        t = trans[k + 1]
        xs[k], Ps[k] = rts_step(x[k], P[k], xs[k + 1], Ps[k + 1], F[t], G[t], u[k], Qd[t],
                                pinv)
    return xs, Ps


def kim_smooth_trial(x_modes, P_modes, mode_prob, u, F, G, Qd, trans, transition, *,
                     timing="sample", pinv=False):
    """Kim (1994) §2.2 on one trial's filtered mode-matched posteriors ``(K, L, ...)``:
    ``(x, P, mode_prob, mode, x_modes, P_modes)`` smoothed. The pair (mode ``j`` at ``k``,
    mode ``i`` at ``k+1``) takes its RTS step through mode ``j``'s transition into ``k+1``
    (``"sample"`` timing) or mode ``i``'s (``"interval"``); ``pinv``: :func:`rts_gain`."""
    K, L, _ = x_modes.shape
    with np.errstate(divide="ignore"):
        log_pi, log_f = np.log(transition), np.log(mode_prob)
    xs, Ps, lps = x_modes.copy(), P_modes.copy(), log_f.copy()
    lps[K - 1] -= log_sum_exp(lps[K - 1])
    for k in range(K - 2, -1, -1):
        log_c = np.array([log_sum_exp(log_f[k] + log_pi[:, i]) for i in range(L)])
        for j in range(L):
            moving = [j if timing == "sample" else i for i in range(L)]
            pairs = [rts_step(x_modes[k, j], P_modes[k, j], xs[k + 1, i], Ps[k + 1, i],
                              F[trans[k + 1, m]], G[trans[k + 1, m]], u[k], Qd[trans[k + 1, m]],
                              pinv)
                     for i, m in enumerate(moving)]
            log_w = np.array([lps[k + 1, i] + log_f[k, j] + log_pi[j, i] - log_c[i]
                              if log_c[i] > -np.inf and log_pi[j, i] > -np.inf else -np.inf
                              for i in range(L)])
            lps[k, j] = log_sum_exp(log_w)
            if lps[k, j] == -np.inf:  # impossible mode: its filtered posterior is kept
                continue
            w = np.exp(log_w - lps[k, j])
            xs[k, j] = sum(w[i] * pairs[i][0] for i in range(L))
            Ps[k, j] = sum(w[i] * (pairs[i][1] + np.outer(pairs[i][0] - xs[k, j],
                                                           pairs[i][0] - xs[k, j]))
                           for i in range(L))
        lps[k] -= log_sum_exp(lps[k])
    out = [imm_combine(xs[k], Ps[k], lps[k]) for k in range(K)]
    return (np.stack([o[0] for o in out]), np.stack([o[1] for o in out]), np.exp(lps),
            np.array([o[3] for o in out]), xs, Ps)


def kim_smooth(x_modes, P_modes, mode_prob, u, F, G, Qd, trans, transition, *,
               timing="sample", pinv=False):
    """:func:`kim_smooth_trial` over trials ``(N, ...)``; ``trans (N or 1, K, L)``."""
    runs = [kim_smooth_trial(x_modes[i], P_modes[i], mode_prob[i], u[i], F, G, Qd,
                             trans[i if trans.shape[0] > 1 else 0], transition, timing=timing,
                             pinv=pinv)
            for i in range(x_modes.shape[0])]
    return [np.stack(a) for a in zip(*runs)]


def imm_modes(y, u, F, G, Qd, trans, C, R, transition, x0, P0, mode_prob0, *,
              timing="sample"):
    """numpy IMM (``numpy_oracle.imm_trial_step``, in the ``timing``) on ``y (N, K, m)``: the
    filtered mode-matched ``x (N, K, L, n)``, ``P``, mode probabilities ``(N, K, L)`` and the
    combined ``x (N, K, n)``."""
    N, K, _ = y.shape
    L, n = transition.shape[0], x0.size
    log_pi = np.log(transition)
    xm, Pm = np.empty((N, K, L, n)), np.empty((N, K, L, n, n))
    prob, xc = np.empty((N, K, L)), np.empty((N, K, n))
    for i in range(N):
        x, P, lp = np.tile(x0, (L, 1)), np.tile(P0, (L, 1, 1)), np.log(mode_prob0)
        for k in range(K):
            x, P, lp, _, _ = imm_trial_step(x, P, lp, y[i, k], u[i, k - 1 if k else 0], F, G, Qd,
                                            trans[k], C, R, log_pi, k > 0, np.inf, timing)
            xm[i, k], Pm[i, k], prob[i, k] = x, P, np.exp(lp)
            xc[i, k] = imm_combine(x, P, lp)[0]
    return xm, Pm, prob, xc


def moving_transitions(trans, modes, timing="sample"):
    """``(K,)``: the table entry of the transition into each sample along ``modes (K,)``,
    ``trans[k, modes[k-1]]`` (``"sample"`` timing) or ``trans[k, modes[k]]`` (``"interval"``);
    entry 0 (no transition into the first sample) is ``trans[0, modes[0]]``, never read."""
    moving = np.r_[modes[:1], modes[:-1]] if timing == "sample" else modes
    return trans[np.arange(len(modes)), moving]


def kalman_sequence(y, u, F, G, Qd, trans, C, R, modes, x0, P0, *, timing="sample"):
    """numpy Kalman filter of one trial along ``modes (K,)``, mode ``modes[k]`` governing the
    measurement at sample ``k`` and, by the ``timing``, the interval after it or into it:
    ``x (K, n)``, ``P``, ``loglik (K,)``."""
    K, n = y.shape[0], x0.size
    xs, Ps, ll = np.empty((K, n)), np.empty((K, n, n)), np.empty(K)
    x, P = x0, P0
    into = moving_transitions(trans, modes, timing)
    for k in range(K):
        r = modes[k]
        if k:
            t = into[k]
            x, P = predict(x, P, F[t], G[t], u[k - 1], Qd[t])
        x, P, ll[k], _ = update(x, P, y[k], C[r], R[r], np.inf)
        xs[k], Ps[k] = x, P
    return xs, Ps, ll


def mixture(log_w, x, P):
    """Moments of ``sum_s w_s N(x_s, P_s)`` with ``w = exp(log_w)`` normalized."""
    w = np.exp(log_w - log_sum_exp(log_w))
    mean = w @ x
    d = x - mean
    return mean, np.einsum("s,sab->ab", w, P) + (w[:, None] * d).T @ d, w


def exact_mixture(y, u, F, G, Qd, trans, C, R, transition, x0, P0, mode_prob0, *,
                  timing="sample"):
    """Brute force over every mode sequence (``itertools.product``) of every trial: a Kalman
    filter per sequence (in the ``timing``), Bayes over the sequences. Returns
    ``(filtered, smoothed)`` dicts with ``x (N, K, n)``, ``P``, ``mode_prob (N, K, L)`` and,
    filtered, ``loglik (N, K)`` and the exact mode-conditioned moments ``x_modes
    (N, K, L, n)``, ``P_modes`` (of the sequences with mode ``j`` at ``k``; the mean of an
    impossible mode is zero, its covariance the identity)."""
    N, K, _ = y.shape
    L, n = transition.shape[0], x0.size
    seqs = np.array(list(itertools.product(range(L), repeat=K)))
    with np.errstate(divide="ignore"):
        log_prior = np.log(mode_prob0[seqs[:, 0]]) + np.log(
            transition[seqs[:, :-1], seqs[:, 1:]]).sum(axis=1)
    filt = {"x": np.empty((N, K, n)), "P": np.empty((N, K, n, n)),
            "mode_prob": np.empty((N, K, L)), "loglik": np.empty((N, K)),
            "x_modes": np.zeros((N, K, L, n)), "P_modes": np.tile(np.eye(n), (N, K, L, 1, 1))}
    smooth = {"x": np.empty((N, K, n)), "P": np.empty((N, K, n, n)),
              "mode_prob": np.empty((N, K, L))}
    for i in range(N):
        runs = [kalman_sequence(y[i], u[i], F, G, Qd, trans, C, R, r, x0, P0, timing=timing)
                for r in seqs]
        xs = np.stack([a[0] for a in runs])
        Ps = np.stack([a[1] for a in runs])
        cum = log_prior[:, None] + np.cumsum(np.stack([a[2] for a in runs]), axis=1)
        rts = [rts_smooth(a[0], a[1], u[i], F, G, Qd, moving_transitions(trans, r, timing))
               for a, r in zip(runs, seqs)]
        xr, Pr = np.stack([a[0] for a in rts]), np.stack([a[1] for a in rts])
        previous = 0.0
        for k in range(K):
            filt["x"][i, k], filt["P"][i, k], w = mixture(cum[:, k], xs[:, k], Ps[:, k])
            filt["mode_prob"][i, k] = [w[seqs[:, k] == j].sum() for j in range(L)]
            for j in range(L):
                given = seqs[:, k] == j
                if np.any(cum[given, k] > -np.inf):
                    filt["x_modes"][i, k, j], filt["P_modes"][i, k, j], _ = mixture(
                        cum[given, k], xs[given, k], Ps[given, k])
            total = log_sum_exp(cum[:, k])
            filt["loglik"][i, k], previous = total - previous, total
            smooth["x"][i, k], smooth["P"][i, k], w = mixture(cum[:, -1], xr[:, k], Pr[:, k])
            smooth["mode_prob"][i, k] = [w[seqs[:, k] == j].sum() for j in range(L)]
    return filt, smooth


def random_system(rng, n=3, m=2, l=1, L=2, domain="continuous"):
    """A random stable switched system: modes with different dynamics, outputs and noises."""
    A = rng.standard_normal((L, n, n))
    W = rng.standard_normal((L, n, n))
    V = rng.standard_normal((L, m, m))
    Q = 0.1 * W @ np.swapaxes(W, 1, 2) + 0.05 * np.eye(n)
    R = 0.1 * V @ np.swapaxes(V, 1, 2) + 0.1 * np.eye(m)
    B, C = rng.standard_normal((L, n, l)), rng.standard_normal((L, m, n))
    if domain == "continuous":
        A = 0.5 * A - (np.abs(np.linalg.eigvals(0.5 * A).real).max() + 0.2) * np.eye(n)
        return SwitchedLinearSystem.continuous(A, B, C, Q=Q, R=R)
    A *= 0.9 / np.abs(np.linalg.eigvals(A)).max(axis=1)[:, None, None]
    return SwitchedLinearSystem.discrete(A, B, C, Q=Q, R=R, dt=1.0)


def simulate_jump_markov(rng, system, transition, x0, P0, mode_prob0, N, K):
    """``y (N, K, m)`` of a discrete-time jump-Markov linear system without input, mode ``r_k``
    governing the step into sample ``k`` and the measurement there (the "interval" timing):
    ``x_k = A_{r_k} x_{k-1} + w``, ``y_k = C_{r_k} x_k + v``."""
    L, n, m = system.n_modes, system.n_states, system.n_outputs
    x = rng.multivariate_normal(x0, P0, N)
    r = rng.choice(L, N, p=mode_prob0)
    y = np.empty((N, K, m))
    for k in range(K):
        if k:
            r = np.array([rng.choice(L, p=transition[i]) for i in r])
            w = np.stack([rng.multivariate_normal(np.zeros(n), system.Q[i]) for i in r])
            x = np.einsum("nab,nb->na", system.A[r], x) + w
        v = np.stack([rng.multivariate_normal(np.zeros(m), system.R[i]) for i in r])
        y[:, k] = np.einsum("nab,nb->na", system.C[r], x) + v
    return y
