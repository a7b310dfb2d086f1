"""A plain numpy Rao-Blackwellized particle filter, one trial and one particle at a time.

The oracle the compiled kernel (:mod:`switchest.engine.rbpf`) is checked against:
the same algorithm (Doucet, Gordon & Krishnamurthy 2001, §III; Doucet, de Freitas, Murphy &
Russell 2000, §3) in either timing of the modes (docs/conventions.rst), written for clarity
with the Kalman equations of :mod:`numpy_oracle`, and driven by the same uniforms, which it
computes on its own (SplitMix64 in numpy's unsigned arithmetic, Steele, Lea & Flood 2014, §3)
so that the two can be compared exactly. Discrete draws invert cumulative sums with
``numpy.searchsorted``.
"""

from __future__ import annotations

import numpy as np
from numpy_oracle import correct, predict, robust_innovation

GOLDEN = np.uint64(0x9E3779B97F4A7C15)
MIX1, MIX2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
SCHEMES = ("systematic", "stratified", "multinomial")


def mix64(z):
    """SplitMix64's output function on uint64 arrays (wrapping arithmetic)."""
    z = (z ^ (z >> np.uint64(30))) * MIX1
    z = (z ^ (z >> np.uint64(27))) * MIX2
    return z ^ (z >> np.uint64(31))


def stream(key, index):
    """Elements ``index`` of the SplitMix64 sequence started at ``key``."""
    with np.errstate(over="ignore"):
        return mix64(np.uint64(key) + (np.asarray(index, dtype=np.uint64) + np.uint64(1)) * GOLDEN)


def trial_keys(root, count):
    return stream(root, np.arange(count))


def uniforms(key, k, count):
    """Uniforms ``0 .. count-1`` of sample ``k`` of the trial with ``key``."""
    bits = stream(stream(key, k), np.arange(count)) >> np.uint64(11)
    return bits.astype(np.float64) * 2.0**-53


def pick(weights, u):
    """First index whose cumulative weight exceeds ``u * total``, else the last positive one."""
    cum = np.cumsum(weights)
    j = int(np.searchsorted(cum, u * cum[-1], side="right"))
    return j if j < weights.size else int(np.flatnonzero(weights > 0)[-1])


def positions(key, k, scheme, Np):
    U = uniforms(key, k, 2 * Np)[Np:]
    if scheme == "systematic":
        return (np.arange(Np) + U[0]) / Np
    if scheme == "stratified":
        return (np.arange(Np) + U) / Np
    return np.sort(U)


def ancestors(w, pos):
    cum = np.cumsum(w)
    last = np.flatnonzero(w > 0)[-1]
    return np.minimum(np.searchsorted(cum, pos * cum[-1], side="right"), last)


def kalman_update(x, P, y, C, R):
    """``(x, P, loglik)``: the update and its predictive log-likelihood (0 with nothing
    observed); a non-finite likelihood leaves the filter alone and gives ``-inf``."""
    P, inn = robust_innovation(x, P, y, C, R)
    if inn is None:
        return x, P, 0.0
    obs, e, S, _, loglik = inn
    if not np.isfinite(loglik):
        return x, P, -np.inf
    return (*correct(x, P, C, R, obs, e, S), loglik)


def log_sum_exp(a):
    top = a.max()
    return -np.inf if top == -np.inf else top + np.log(np.exp(a - top).sum())


def rbpf_trial(y, u, F, G, Qd, trans, C, R, transition, prob0, key, Np, proposal, scheme,
               threshold, x0, P0, timing):
    """One trial ``y (K, m)``, ``u (K, l)``: dict of per-sample outputs as the kernel's.

    ``timing="sample"``: a particle is predicted into sample ``k`` through its mode at ``k-1``
    (once, before its mode at ``k`` is drawn or its candidates are tried); ``"interval"``:
    through its (candidate) mode at ``k``."""
    K, L, n = y.shape[0], C.shape[0], x0.size
    with np.errstate(divide="ignore"):
        log_T, log_p0 = np.log(transition), np.log(prob0)
    xs, Ps = [x0.copy() for _ in range(Np)], [P0.copy() for _ in range(Np)]
    mode, logw = np.zeros(Np, dtype=int), np.full(Np, -np.log(Np))
    out = {"x": np.empty((K, n)), "P": np.empty((K, n, n)), "mode_prob": np.empty((K, L)),
           "mode": np.empty(K, dtype=int), "loglik": np.empty(K), "flag": np.empty(K, dtype=int),
           "ess": np.empty(K)}
    for k in range(K):
        U = uniforms(key, k, Np)
        inc = np.empty(Np)
        step = [None] * Np  # per particle: per candidate (x, P, loglik) predicted and updated
        for p in range(Np):
            step[p] = {}
            x_prev, P_prev = xs[p], Ps[p]
            if k and timing == "sample":  # through the mode at k-1, before the draw
                t = trans[k, mode[p]]
                x_prev, P_prev = predict(x_prev, P_prev, F[t], G[t], u[k - 1], Qd[t])
            cands = range(L)
            if proposal == "prior":
                mode[p] = pick(transition[mode[p]] if k else prob0, U[p])
                cands = [mode[p]]
            for r in cands:
                x, P = x_prev, P_prev
                if k and timing == "interval":  # through the (candidate) mode at k
                    t = trans[k, r]
                    x, P = predict(x, P, F[t], G[t], u[k - 1], Qd[t])
                step[p][r] = kalman_update(x, P, y[k], C[r], R[r])
        for p in range(Np):
            if proposal == "prior":
                inc[p] = step[p][mode[p]][2]
            else:
                prev = log_T[mode[p]] if k else log_p0
                inc[p] = log_sum_exp(prev + np.array([step[p][r][2] for r in range(L)]))
        for p in range(Np):
            if proposal == "optimal":
                prev = log_T[mode[p]] if k else log_p0
                terms = prev + np.array([step[p][r][2] for r in range(L)])
                weights = np.exp(terms - inc[p]) if inc[p] > -np.inf else np.exp(prev)
                mode[p] = pick(weights, U[p])
            xs[p], Ps[p] = step[p][mode[p]][:2]
        seen = not np.isnan(y[k]).all()
        alive = bool(np.any(inc > -np.inf))
        a = logw + inc if seen and alive else logw
        total = log_sum_exp(a)
        logw = a - total
        w = np.exp(logw)
        X, PP = np.array(xs), np.array(Ps)
        out["x"][k] = w @ X
        d = X - out["x"][k]
        out["P"][k] = np.einsum("p,prc->rc", w, PP) + (w[:, None] * d).T @ d
        out["mode_prob"][k] = np.bincount(mode, weights=w, minlength=L)
        out["mode"][k] = int(np.argmax(out["mode_prob"][k]))
        out["loglik"][k] = total if seen and alive else 0.0
        out["flag"][k] = int(seen and not alive)
        out["ess"][k] = 1.0 / np.sum(w**2)
        if threshold >= 1.0 or out["ess"][k] < threshold * Np:
            anc = ancestors(w, positions(key, k, scheme, Np))
            xs, Ps, mode = [xs[a] for a in anc], [Ps[a] for a in anc], mode[anc]
            logw = np.full(Np, -np.log(Np))
    return out


def rbpf_run(y, u, F, G, Qd, trans, C, R, transition, prob0, keys, Np, proposal, scheme,
             threshold, x0, P0, timing):
    """Every trial of ``y (N, K, m)``, as the compiled ``rbpf_run``: dict of ``(N, K, ...)``."""
    trials = [rbpf_trial(y[i], u[i], F, G, Qd, trans, C, R, transition, prob0, keys[i], Np,
                         proposal, scheme, threshold, x0, P0, timing)
              for i in range(y.shape[0])]
    return {f: np.stack([tr[f] for tr in trials]) for f in trials[0]}
