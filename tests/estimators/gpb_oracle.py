"""Plain numpy GPB1 and GPB2 (Bar-Shalom, Li & Kirubarajan 2001, §11.6.4-§11.6.5), one trial
and one sample at a time: the oracle of the compiled filters.

Both are built on the IMM oracle's update (numpy_oracle.imm_trial_step without its interaction,
``predict_first=False``): a bank of Kalman filters with prior log-weights, gated filter by filter,
a sample no filter can use counting as missing. What differs is what the bank is given:

- GPB1: ``L`` filters with prior weights ``log c_j = log sum_i pi_ij mu_i``, each starting from
  one Gaussian: in the ``"interval"`` timing the moments of the previous sample's mixture
  predicted through mode ``j``'s transition; in the ``"sample"`` timing the moments of the
  mixture of the previous posteriors each predicted through its own mode's transition.
- GPB2: ``L^2`` filters, pair ``(i, j)`` predicted from mode ``i``'s Gaussian with mode ``j``'s
  transition (``"interval"``) or mode ``i``'s (``"sample"``) and updated with ``C[j]``,
  ``R[j]``, prior weight ``log mu_i + log pi_ij``; then merged over ``i`` per ``j``.

At the first sample both are that bank of ``L`` filters from the prior.
"""

from __future__ import annotations

import numpy as np
from numpy_oracle import imm_combine, imm_trial_step, log_sum_exp, predict, predict_modes


def gpb1_trial_step(x, P, log_prob, y, u, F, G, Qd, tr, C, R, log_transition, predict_first,
                    gate, timing="sample"):
    """One GPB1 cycle of one trial: ``x, P, log_prob, loglik, flag`` (as imm_trial_step)."""
    if predict_first:
        L = log_prob.size
        log_c = np.array([log_sum_exp(log_prob + log_transition[:, j]) for j in range(L)])
        if timing == "sample":  # each posterior through its own mode, then the collapse
            x0, P0 = imm_combine(*predict_modes(x, P, F, G, u, Qd, tr), log_prob)[:2]
            x, P = np.tile(x0, (L, 1)), np.tile(P0, (L, 1, 1))
        elif timing == "interval":  # the collapse, then mode j's prediction
            x0, P0 = imm_combine(x, P, log_prob)[:2]
            x, P = predict_modes(np.tile(x0, (L, 1)), np.tile(P0, (L, 1, 1)), F, G, u, Qd, tr)
        else:
            raise ValueError(f"timing {timing!r}")
        log_prob = log_c
    return imm_trial_step(x, P, log_prob, y, u, F, G, Qd, tr, C, R, log_transition, False, gate)


def merge(w, x, P):
    """Moments of the mixture ``sum_i w_i N(x_i, P_i)``."""
    xm = w @ x
    d = x - xm
    return xm, np.einsum("i,irc->rc", w, P) + (w[:, None] * d).T @ d


def gpb2_trial_step(x, P, log_prob, y, u, F, G, Qd, tr, C, R, log_transition, predict_first,
                    gate, timing="sample"):
    """One GPB2 cycle of one trial: ``x, P, log_prob`` (the merged Gaussians and log mode
    probabilities), ``loglik, flag``.

    Pair ``p = j L + i``. A mode whose pairs all got weight 0 (gated) is merged with the weights
    they had before the measurement, one without those either (unreachable) with equal ones.
    """
    if not predict_first:  # the first sample: L filters from the prior
        return imm_trial_step(x, P, log_prob, y, u, F, G, Qd, tr, C, R, log_transition, False,
                              gate)
    L = log_prob.size
    if timing not in ("sample", "interval"):
        raise ValueError(f"timing {timing!r}")
    pred = []
    for j in range(L):
        for i in range(L):  # pair (i, j) through mode i's transition ("sample") or mode j's
            e = tr[i] if timing == "sample" else tr[j]
            pred.append(predict(x[i], P[i], F[e], G[e], u, Qd[e]))
    prior = np.array([log_prob[i] + log_transition[i, j] for j in range(L) for i in range(L)])
    xp, Pp, log_w, loglik, flag = imm_trial_step(
        np.stack([p[0] for p in pred]), np.stack([p[1] for p in pred]), prior, y, u, F, G, Qd,
        tr, np.repeat(C, L, axis=0), np.repeat(R, L, axis=0), log_transition, False, gate)
    x_new, P_new, log_mu = np.empty_like(x), np.empty_like(P), np.empty(L)
    for j in range(L):
        block = slice(j * L, (j + 1) * L)
        log_mu[j] = log_sum_exp(log_w[block])  # mu_j = sum_i mu_ij
        if log_mu[j] > -np.inf:
            w = np.exp(log_w[block] - log_mu[j])  # mu_{i|j} = mu_ij / mu_j
        elif log_sum_exp(prior[block]) > -np.inf:
            w = np.exp(prior[block] - log_sum_exp(prior[block]))
        else:
            w = np.full(L, 1.0 / L)
        x_new[j], P_new[j] = merge(w, xp[block], Pp[block])
    return x_new, P_new, log_mu, loglik, flag


def bank_run(trial_step, y, u, F, G, Qd, trans, C, R, log_transition, x0, P0, log_prob0,
             gate=np.inf, timing="sample"):
    """Every trial and sample of ``trial_step`` (gpb1_trial_step, gpb2_trial_step or the IMM's
    imm_trial_step) in ``timing``: the compiled kernels' outputs, with the mode-matched (GPB2:
    merged) Gaussians after each sample as ``x_modes``, ``P_modes``."""
    N, K, _ = y.shape
    L, n = log_prob0.size, x0.size
    out = {"x": np.empty((N, K, n)), "P": np.empty((N, K, n, n)),
           "mode_prob": np.empty((N, K, L)), "mode": np.empty((N, K), dtype=int),
           "loglik": np.empty((N, K)), "flag": np.empty((N, K), dtype=int),
           "x_modes": np.empty((N, K, L, n)), "P_modes": np.empty((N, K, L, n, n))}
    for i in range(N):
        x, P, lp = np.tile(x0, (L, 1)), np.tile(P0, (L, 1, 1)), log_prob0
        for k in range(K):
            x, P, lp, out["loglik"][i, k], out["flag"][i, k] = trial_step(
                x, P, lp, y[i, k], u[i, k - 1 if k else 0], F, G, Qd, trans[k], C, R,
                log_transition, k > 0, gate, timing)
            out["x_modes"][i, k], out["P_modes"][i, k] = x, P
            (out["x"][i, k], out["P"][i, k], out["mode_prob"][i, k],
             out["mode"][i, k]) = imm_combine(x, P, lp)
    return out
