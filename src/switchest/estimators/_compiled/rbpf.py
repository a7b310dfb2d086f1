"""The compiled Rao-Blackwellized particle filter for jump-Markov linear systems.

Each particle carries a mode and the Kalman filter ``(x, P)`` conditional on its mode history
(Doucet, de Freitas, Murphy & Russell 2000, §3; Doucet, Gordon & Krishnamurthy 2001, §III).
The particles of one trial are laid across the SIMD lanes of :mod:`.linalg` (``x (n, Np)``,
``P (n, n, Np)``), so that the Kalman equations run there, once for all particles; the kernel
loops over trials and samples. ``rbpf_run`` filters whole records, ``rbpf_step`` one sample of
every trial (the streaming API); both call :func:`particle_filter`.

Randomness is counter-based (Salmon, Moraes, Dror & Shaw 2011, "Parallel random numbers: as
easy as 1, 2, 3"): uniform ``j`` of sample ``k`` of a trial is a pure function of the trial's
64-bit ``key``, ``k`` and ``j`` (:func:`uniform`), so a trial's result depends on its key alone
(not on the batch it ran in), and a streaming step needs nothing but the key and the sample
index to continue. At sample ``k``, uniforms ``0 .. Np-1`` draw the particles' modes and
``Np .. 2 Np - 1`` the resampling positions.

Convention of switchest: ``transition[i, j]`` = P(mode j at k+1 | mode i at k). ``trans[k, r]``
is mode ``r``'s transition over the interval into sample ``k`` in the table ``F, G, Qd``; mode
``r`` at sample ``k`` is updated with ``C[r]``, ``R[r]``; the input held over the interval into
sample ``k`` is ``u[:, k-1]``. Which mode's transition a particle takes into sample ``k`` is the
timing (docs/conventions.rst): with ``sample_timing`` its mode at ``k-1`` (the mode of a sample
governs the interval after it, ``x_k = F(r_{k-1}) x_{k-1} + G(r_{k-1}) u_{k-1} + w``: the
particle is predicted, then its mode at ``k`` drawn), else its mode at ``k`` (Bar-Shalom's
timing, ``x_k = F(r_k) x_{k-1} + G(r_k) u_{k-1} + w``: the mode drawn, then the particle
predicted with it).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..._checks import positive_int
from .arrays import checked
from .linalg import (
    ACCEPTED,
    GATED,
    OK,
    borrow,
    copy_gaussian,
    correct,
    gather_matrices,
    information_or_repair,
    inline,
    innovation,
    jit,
    joseph_lost,
    log_normalize,
    observe,
    predict,
)
from .warmup import register

__all__ = [
    "RESAMPLING",
    "RBPFOutput",
    "ancestors",
    "particle_filter",
    "rbpf_run",
    "rbpf_step",
    "resampling_positions",
    "trial_keys",
    "uniform",
]

RESAMPLING = {"systematic": 0, "stratified": 1, "multinomial": 2}
"""The resampling schemes by name, and the code the kernel takes for each."""
_SYSTEMATIC, _STRATIFIED = RESAMPLING["systematic"], RESAMPLING["stratified"]

# SplitMix64 (Steele, Lea & Flood 2014, "Fast splittable pseudorandom number generators",
# OOPSLA, §3): the golden-ratio increment and the two multipliers of its output mix
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_UNIT = 2.0**-53  # a 53-bit integer times this is a float64 in [0, 1)


@inline
def _mix64(z):
    """SplitMix64's output function (Steele, Lea & Flood 2014, §3): a bijection of the 64-bit
    integers whose every output bit depends on every input bit."""
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


@inline
def _stream(key, index):
    """Element ``index`` (0-based) of the SplitMix64 sequence started at ``key``:
    ``mix64(key + (index + 1) * golden)`` (Steele, Lea & Flood 2014, §3), modulo 2^64."""
    return _mix64(key + np.uint64(index + 1) * _GOLDEN)


@inline
def uniform(key, k, j):
    """Uniform ``j`` of sample ``k`` of the trial with ``key``, in ``[0, 1)``: the top 53 bits
    of ``stream(stream(key, k), j)``, the sample's own SplitMix64 sequence."""
    return (_stream(_stream(key, k), j) >> np.uint64(11)) * _UNIT


@jit
def trial_keys(root, count):
    """The keys of trials ``0 .. count-1`` derived from a ``root`` key (uint64): element ``i`` of
    the SplitMix64 sequence started at ``root`` (Steele, Lea & Flood 2014, §3)."""
    keys = np.empty(count, dtype=np.uint64)
    for i in range(count):
        keys[i] = _stream(root, i)
    return keys


@jit
def _pick(weights, u):
    """The index ``j`` drawn with probability ``weights[j] / sum(weights)`` by inversion of the
    cumulative sum: the first ``j`` whose running sum exceeds ``u * sum(weights)``, else the last
    positive weight (``u * sum`` rounded up to the sum). A zero weight is never drawn."""
    total = 0.0
    for j in range(weights.shape[0]):
        total += weights[j]
    target, acc, last = u * total, 0.0, 0
    for j in range(weights.shape[0]):
        if weights[j] > 0.0:
            last = j
            acc += weights[j]
            if acc > target:
                return j
    return last


@jit
def resampling_positions(key, k, scheme, nb, pos):
    """The ``nb`` sorted positions in ``[0, 1]`` of a resampling at sample ``k``, from uniforms
    ``nb .. 2 nb - 1`` (Douc, Cappé & Moulines 2005, "Comparison of resampling schemes for
    particle filtering", §2): systematic ``(p + U) / nb`` with one ``U``; stratified
    ``(p + U_p) / nb``; multinomial the ``U_p`` sorted."""
    if scheme == _SYSTEMATIC:
        shift = uniform(key, k, nb)
        for p in range(nb):
            pos[p] = (p + shift) / nb
    elif scheme == _STRATIFIED:
        for p in range(nb):
            pos[p] = (p + uniform(key, k, nb + p)) / nb
    else:
        for p in range(nb):
            pos[p] = uniform(key, k, nb + p)
        pos[:nb].sort()


@jit
def ancestors(w, pos, nb, out):
    """``out[p]``: the particle whose cumulative-weight interval holds position ``pos[p]``
    (sorted, in ``[0, 1]``), the first ``j`` with ``w_0 + .. + w_j > pos[p] sum(w)``, at most the
    last positive weight: the inversion every resampling scheme shares (Douc, Cappé & Moulines
    2005, §2), merged in one pass over the sorted positions."""
    total, last = 0.0, 0
    for j in range(nb):
        total += w[j]
        if w[j] > 0.0:
            last = j
    j, acc = 0, w[0]
    for p in range(nb):
        target = pos[p] * total
        while j < last and acc <= target:
            j += 1
            acc += w[j]
        out[p] = j


@jit
def _fill_lanes(vector, nb, out):
    """``out[a, b] = vector[a]`` in every lane: a trial's measurement or input for each of its
    particles."""
    for a in range(vector.shape[0]):
        for b in range(nb):
            out[a, b] = vector[a]


@jit
def _fill_index(value, nb, out):
    """``out[b] = value`` in every lane."""
    for b in range(nb):
        out[b] = value


@borrow
def _filter_lanes(x, P, yl, Cl, Rl, obs, n_obs, nb, loglik, use, work, report):
    """The Kalman measurement update of every lane, with its predictive log-likelihood.

    ``loglik = log N(y; C x, C P C' + R)`` over the observed components (0 with none), by
    :func:`.linalg.innovation` (Shankar et al. eq. (8)); the lanes whose likelihood is finite
    (``use``) are corrected in Joseph form (:func:`.linalg.correct`, Shankar et al. eqs
    (9)-(10)), in information form where that loses its digits, as the bank of filters does
    (:mod:`.bank`). ``work`` holds the scratch arrays. Returns the status of the innovation.
    """
    e, PCt, chol, scale, z, nis, inn, bad, gain, T, AP, prior, root, lost = work
    status = innovation(x, P, yl, Cl, Rl, obs, n_obs, nb, e, PCt, chol, scale, z, nis, loglik,
                        inn, bad, report)
    if status != OK:
        return status
    for b in range(nb):
        use[b] = math.isfinite(loglik[b])
    correct(x, P, Cl, Rl, use, nb, PCt, chol, scale, z, gain, T, AP, prior)
    if joseph_lost(P, prior, use, nb, root, lost):  # rare: lane by lane
        information_or_repair(P, prior, Cl, Rl, obs, n_obs, lost, nb, report)
    return OK


@borrow
def _predict_lanes(x, P, mode, ul, F, G, Qd, trans_row, nb, idx, mats):
    """Kalman prediction of every lane ``p`` through the transition ``trans_row[mode[p]]`` of
    its mode (Shankar et al. eqs (6)-(7), :func:`.linalg.predict`)."""
    Fl, Gl, Ql, _, _, AP, xs = mats
    for p in range(nb):
        idx[p] = trans_row[mode[p]]
    gather_matrices(F, idx, nb, Fl)
    gather_matrices(G, idx, nb, Gl)
    gather_matrices(Qd, idx, nb, Ql)
    predict(x, P, Fl, Gl, ul, Ql, nb, AP, xs)


@borrow
def _prior_proposal(x, P, mode, yl, ul, obs, n_obs, F, G, Qd, trans_row, C, R, transition,
                    prob0, key, k, predicting, sample_timing, nb, idx, mats, ll, use, inc, work,
                    report):
    """Sample each particle's mode from its prior and update its filter; ``inc`` gets the
    incremental log-weights.

    ``r_k ~ pi(r_{k-1}, .)`` (``prob0`` at the first sample), Kalman prediction through
    ``r_{k-1}``'s transition before the draw (``sample_timing``) or through ``r_k``'s after
    it, ``inc = log N(y_k; C_{r_k} x-, C_{r_k} P- C_{r_k}' + R_{r_k})`` (``-inf`` where not
    finite) and the Joseph update (Doucet, Gordon & Krishnamurthy 2001, §III, with the prior as
    importance distribution; Doucet, de Freitas, Murphy & Russell 2000, §3). In either timing
    the weight is the likelihood of ``y_k`` given the particle's history up to ``r_k``, the
    target-to-proposal ratio when the proposal is the prior.
    """
    _, _, _, Cl, Rl, _, _ = mats
    if predicting and sample_timing:
        _predict_lanes(x, P, mode, ul, F, G, Qd, trans_row, nb, idx, mats)
    for p in range(nb):
        row = transition[mode[p]] if predicting else prob0
        mode[p] = _pick(row, uniform(key, k, p))
    if predicting and not sample_timing:
        _predict_lanes(x, P, mode, ul, F, G, Qd, trans_row, nb, idx, mats)
    gather_matrices(C, mode, nb, Cl)
    gather_matrices(R, mode, nb, Rl)
    status = _filter_lanes(x, P, yl, Cl, Rl, obs, n_obs, nb, ll[0], use[0], work, report)
    for p in range(nb):
        inc[p] = ll[0, p] if use[0, p] else -math.inf
    return status


@borrow
def _optimal_proposal(x, P, mode, yl, ul, obs, n_obs, F, G, Qd, trans_row, C, R,
                      log_transition, log_prob0, key, k, predicting, sample_timing, nb, idx,
                      mats, xc, Pc, ll, use, terms, pick, inc, work, report):
    """Sample each particle's mode from the optimal importance distribution and keep that
    candidate's filter; ``inc`` gets the incremental log-weights.

    For every candidate mode ``r`` each particle's filter is predicted and updated with
    ``C_r``, ``R_r``, with predictive likelihood
    ``Lambda_r = N(y_k; C_r x-_r, C_r P-_r C_r' + R_r)``. The prediction goes through
    ``r_{k-1}``'s transition with ``sample_timing`` (once per particle, the same ``x-, P-`` for
    every candidate), else through the candidate ``r``'s own; then
    ``r_k ~ pi(r_{k-1}, r) Lambda_r / sum_r pi(r_{k-1}, r) Lambda_r`` and
    ``inc = log sum_r pi(r_{k-1}, r) Lambda_r``, the ratio of target to proposal (Doucet,
    Gordon & Krishnamurthy 2001, §III); ``prob0`` replaces ``pi(r_{k-1}, .)`` at the first
    sample. A candidate whose likelihood is not finite gets ``Lambda_r = 0``; a particle with
    no candidate left (``inc = -inf``) draws from ``pi(r_{k-1}, .)`` alone and keeps its
    predicted filter.
    """
    Fl, Gl, Ql, Cl, Rl, AP, xs = mats
    n_modes = C.shape[0]
    if predicting and sample_timing:
        _predict_lanes(x, P, mode, ul, F, G, Qd, trans_row, nb, idx, mats)
    for r in range(n_modes):
        copy_gaussian(x, P, nb, xc[r], Pc[r])
        if predicting and not sample_timing:
            _fill_index(trans_row[r], nb, idx)
            gather_matrices(F, idx, nb, Fl)
            gather_matrices(G, idx, nb, Gl)
            gather_matrices(Qd, idx, nb, Ql)
            predict(xc[r], Pc[r], Fl, Gl, ul, Ql, nb, AP, xs)
        _fill_index(r, nb, idx)
        gather_matrices(C, idx, nb, Cl)
        gather_matrices(R, idx, nb, Rl)
        status = _filter_lanes(xc[r], Pc[r], yl, Cl, Rl, obs, n_obs, nb, ll[r], use[r], work,
                               report)
        if status != OK:
            return status
    for p in range(nb):  # log pi(r_{k-1}, r) + log Lambda_r and their log-sum-exp
        prev = log_transition[mode[p]] if predicting else log_prob0
        top = -math.inf
        for r in range(n_modes):
            terms[r, p] = prev[r] + ll[r, p] if use[r, p] else -math.inf
            top = max(top, terms[r, p])
        acc = 0.0
        for r in range(n_modes):
            acc += math.exp(terms[r, p] - top) if top > -math.inf else 0.0
        inc[p] = top + math.log(acc) if top > -math.inf else -math.inf
    for p in range(nb):
        prev = log_transition[mode[p]] if predicting else log_prob0
        for r in range(n_modes):  # weights relative to the largest, or the prior's alone
            pick[r] = (math.exp(terms[r, p] - inc[p]) if inc[p] > -math.inf
                       else math.exp(prev[r]))
        chosen = _pick(pick, uniform(key, k, p))
        mode[p] = chosen
        for a in range(x.shape[0]):
            x[a, p] = xc[chosen, a, p]
            for c in range(x.shape[0]):
                P[a, c, p] = Pc[chosen, a, c, p]
    return OK


@jit
def _particle_moments(w, x, P, nb, xm, Pm):
    """Mean ``xm = sum_b w_b x_b`` and covariance ``Pm = sum_b w_b (P_b + (x_b - xm)(x_b -
    xm)')`` of the mixture of the lanes' Gaussians with weights ``w``: the RBPF's output
    (Doucet, Gordon & Krishnamurthy 2001, §III), a sum across lanes. Upper triangle computed,
    then mirrored."""
    n = x.shape[0]
    for r in range(n):
        xm[r] = 0.0
        for b in range(nb):
            xm[r] += w[b] * x[r, b]
    for r in range(n):
        for c in range(r, n):
            acc = 0.0
            for b in range(nb):
                acc += w[b] * (P[r, c, b] + (x[r, b] - xm[r]) * (x[c, b] - xm[c]))
            Pm[r, c] = acc
            Pm[c, r] = acc


@jit
def _resample(x, P, mode, anc, nb, x_to, P_to, mode_to):
    """``x_to[:, p] = x[:, anc[p]]`` and likewise ``P``, ``mode``: each particle replaced by its
    ancestor, mode and filter."""
    n = x.shape[0]
    for r in range(n):
        for p in range(nb):
            x_to[r, p] = x[r, anc[p]]
        for c in range(n):
            for p in range(nb):
                P_to[r, c, p] = P[r, c, anc[p]]
    for p in range(nb):
        mode_to[p] = mode[anc[p]]


@jit
def particle_filter(y, u, F, G, Qd, trans, C, R, transition, log_transition, prob0, log_prob0,
                    keys, k0, predict_first, sample_timing, optimal, scheme, threshold, x_init,
                    P_init, mode_init, logw_init, x_out, P_out, prob_out, mode_out, loglik_out,
                    flag_out, ess_out, x_last, P_last, mode_last, logw_last, report):
    """Filter ``N`` trials over ``K`` samples with ``Np`` particles each.

    Parameters
    ----------
    y : (N, K, m) float64
        Measurements; NaN components are missing.
    u : (N, K, l) float64
        Inputs; ``u[:, k-1]`` is held over the interval into sample ``k`` (``u[:, 0]`` into
        sample 0 when ``predict_first``).
    F, G, Qd : (M, n, n), (M, n, l), (M, n, n) float64
        Table of exact transitions.
    trans : (K, L) int64
        ``trans[k, r]``: the transition of mode ``r`` into sample ``k``.
    C, R : (L, m, n), (L, m, m) float64
        Output matrix and measurement-noise covariance of each mode.
    transition, log_transition : (L, L) float64
        ``transition[i, j]`` = P(mode j at k+1 | mode i at k), and its logarithm.
    prob0, log_prob0 : (L,) float64
        Mode probabilities at the first sample, and their logarithms.
    keys : (N,) uint64
        Each trial's random key (:func:`uniform`).
    k0 : int
        Index of the first sample of this call in its trials' records (for the uniforms).
    predict_first : bool
        Whether the first sample is predicted into (a streaming step after the first) or is
        the first of the record (modes drawn from ``prob0``, update only).
    sample_timing : bool
        Whether a particle predicts into sample ``k`` through its mode at ``k-1`` (the
        ``"sample"`` timing: predicted, then its new mode drawn) or through its mode at ``k``
        (the ``"interval"`` timing: mode drawn, then predicted with it).
    optimal : bool
        The optimal importance distribution (:func:`_optimal_proposal`) or the prior
        (:func:`_prior_proposal`).
    scheme : int
        Resampling scheme (:data:`RESAMPLING`).
    threshold : float
        Resample when ``ESS < threshold Np`` (always when ``threshold >= 1``).
    x_init, P_init, mode_init, logw_init : (N or 1, Np, n), (N or 1, Np, n, n), (N or 1, Np),
    (N or 1, Np)
        Particles before the first sample (shared by every trial when the first axis is 1):
        filters, modes and normalized log-weights.
    x_out, P_out, prob_out, mode_out, loglik_out, flag_out, ess_out
        Written, per trial and sample: ``x = sum_p w_p x_p``, its covariance
        ``sum_p w_p (P_p + (x_p - x)(x_p - x)')``, mode probabilities ``sum_{p: r_p = j} w_p``,
        the most probable mode (first on a tie), the log-likelihood of the measurement given
        the past (0 when nothing was observed or no particle could use it), the flag
        (``GATED`` when no particle's likelihood was finite: the sample was treated as
        missing) and the effective sample size ``1 / sum_p w_p^2`` before resampling.
    x_last, P_last, mode_last, logw_last : (N or 0, Np, ...)
        Written when their first axis is ``N``: the particles after the last sample.
    report : (2,) float64
        Written: the number of covariances repaired (:func:`.linalg.repair`) and the smallest
        eigenvalue one had (``inf`` if none).

    Returns
    -------
    status : int
        ``OK``, or the failure code of an innovation covariance that stopped the kernel.

    Notes
    -----
    After the proposal (which samples the modes and updates the filters), the weights are
    ``w_p ∝ w_{p,k-1} exp(inc_p)`` in the log domain and the log-likelihood is
    ``log sum_p w_{p,k-1} exp(inc_p)``, the unbiased particle estimate of ``p(y_k | y_{0:k-1})``
    (Doucet & Johansen 2011, "A tutorial on particle filtering and smoothing: fifteen years
    later", §4). A fully
    missing sample does not reweight. The outputs are taken, then the particles resampled when
    the effective sample size ``1 / sum_p w_p^2`` (Kong, Liu & Wong 1994) is below
    ``threshold Np``, each copying its ancestor's mode and filter, with weights ``1 / Np``.
    """
    N, K, m = y.shape
    Np, n = x_init.shape[1], x_init.shape[2]
    n_modes, n_in = C.shape[0], u.shape[2]
    x, P, mode = np.empty((n, Np)), np.empty((n, n, Np)), np.empty(Np, dtype=np.int64)
    x_to, P_to, mode_to = np.empty((n, Np)), np.empty((n, n, Np)), np.empty(Np, dtype=np.int64)
    logw, w, total = np.empty(Np), np.empty(Np), np.empty(1)
    logw2, w2 = logw.reshape((Np, 1)), w.reshape((Np, 1))  # views: weights as one lane of L
    yl, ul, obs, n_obs = np.empty((m, Np)), np.empty((n_in, Np)), np.empty((m, Np)), np.empty(Np)
    idx, anc, pos = np.empty(Np, dtype=np.int64), np.empty(Np, dtype=np.int64), np.empty(Np)
    mats = (np.empty((n, n, Np)), np.empty((n, n_in, Np)), np.empty((n, n, Np)),
            np.empty((m, n, Np)), np.empty((m, m, Np)), np.empty((n, n, Np)), np.empty((n, Np)))
    work = (np.empty((m, Np)), np.empty((n, m, Np)), np.empty((m, m, Np)), np.empty((m, Np)),
            np.empty((m, Np)), np.empty(Np), np.empty((3, Np)), np.zeros(Np, dtype=np.bool_),
            np.empty((n, m, Np)), np.empty((n, m, Np)), np.empty((n, n, Np)),
            np.empty((n, n, Np)), np.empty((n, Np)), np.empty(Np, dtype=np.bool_))
    n_cand = n_modes if optimal else 1  # filters updated per particle: candidates, or one
    ll, use = np.empty((n_cand, Np)), np.empty((n_cand, Np), dtype=np.bool_)
    n_copies = n_modes if optimal else 0  # the candidates' filters, kept until one is drawn
    xc, Pc = np.empty((n_copies, n, Np)), np.empty((n_copies, n, n, Np))
    terms, pick, inc = np.empty((n_cand, Np)), np.empty(n_modes), np.empty(Np)
    prob, xm, Pm = np.empty(n_modes), np.empty(n), np.empty((n, n))
    report[0], report[1] = 0.0, math.inf
    uniform_log_weight = -math.log(Np)
    for i in range(N):
        s = i if x_init.shape[0] > 1 else 0
        for p in range(Np):
            mode[p], logw[p] = mode_init[s, p], logw_init[s, p]
            for r in range(n):
                x[r, p] = x_init[s, p, r]
                for c in range(n):
                    P[r, c, p] = P_init[s, p, r, c]
        for k in range(K):
            predicting = k > 0 or predict_first
            _fill_lanes(y[i, k], Np, yl)
            observe(yl, Np, obs, n_obs)
            _fill_lanes(u[i, max(k - 1, 0)], Np, ul)
            if optimal:
                status = _optimal_proposal(x, P, mode, yl, ul, obs, n_obs, F, G, Qd, trans[k], C,
                                           R, log_transition, log_prob0, keys[i], k0 + k,
                                           predicting, sample_timing, Np, idx, mats, xc, Pc,
                                           ll, use, terms, pick, inc, work, report)
            else:
                status = _prior_proposal(x, P, mode, yl, ul, obs, n_obs, F, G, Qd, trans[k], C,
                                         R, transition, prob0, keys[i], k0 + k, predicting,
                                         sample_timing, Np, idx, mats, ll, use, inc, work,
                                         report)
            if status != OK:
                return status
            seen, alive = n_obs[0] > 0.0, False
            for p in range(Np):
                alive |= inc[p] > -math.inf
            usable = seen and alive  # else no reweighting: nothing observed, or nothing usable
            for p in range(Np):
                logw[p] += inc[p] if usable else 0.0
            log_normalize(logw2, w2, total, 1)  # w_p ∝ w_{p,k-1} exp(inc_p); total = loglik
            best, sq = 0, 0.0
            for j in range(n_modes):
                prob[j] = 0.0
            for p in range(Np):
                prob[mode[p]] += w[p]
                sq += w[p] * w[p]
            for j in range(n_modes):
                prob_out[i, k, j] = prob[j]
                if prob[j] > prob[best]:
                    best = j
            mode_out[i, k] = best
            _particle_moments(w, x, P, Np, xm, Pm)
            for r in range(n):
                x_out[i, k, r] = xm[r]
                for c in range(n):
                    P_out[i, k, r, c] = Pm[r, c]
            loglik_out[i, k] = total[0] if usable else 0.0
            flag_out[i, k] = GATED if seen and not alive else ACCEPTED
            ess = 1.0 / sq
            ess_out[i, k] = ess
            if threshold >= 1.0 or ess < threshold * Np:
                resampling_positions(keys[i], k0 + k, scheme, Np, pos)
                ancestors(w, pos, Np, anc)
                _resample(x, P, mode, anc, Np, x_to, P_to, mode_to)
                x, x_to, P, P_to, mode, mode_to = x_to, x, P_to, P, mode_to, mode
                for p in range(Np):
                    logw[p] = uniform_log_weight
        if x_last.shape[0] > 0:
            for p in range(Np):
                mode_last[i, p], logw_last[i, p] = mode[p], logw[p]
                for r in range(n):
                    x_last[i, p, r] = x[r, p]
                    for c in range(n):
                        P_last[i, p, r, c] = P[r, c, p]
    return OK


class RBPFOutput(NamedTuple):
    """What the RBPF reports after each sample, for every trial (:func:`rbpf_run`; from
    :func:`rbpf_step`, the one sample as ``K = 1``).

    Attributes
    ----------
    x, P : ndarray, shapes (N, K, n), (N, K, n, n)
        Weighted mean of the particles' filters and the covariance of their mixture.
    mode_prob : ndarray, shape (N, K, L)
        Sum of the weights of the particles in each mode.
    mode : ndarray of int64, shape (N, K)
        Most probable mode (the first on a tie).
    loglik : ndarray, shape (N, K)
        Log of the particle estimate of ``p(y_k | y_{0:k-1})``.
    flag : ndarray of uint8, shape (N, K)
        ``ACCEPTED`` (0) or ``GATED`` (1: no particle's likelihood was finite, the sample was
        treated as missing).
    ess : ndarray, shape (N, K)
        Effective sample size ``1 / sum_p w_p^2`` before resampling.
    status : int
        ``linalg.OK`` or the failure code that stopped the kernel (outputs then incomplete).
    repaired : int
        How many covariances were repaired to their rounding level (:func:`.linalg.repair`).
    smallest_eigenvalue : float
        The smallest eigenvalue a repaired covariance had (``inf`` if none was).
    """

    x: np.ndarray
    P: np.ndarray
    mode_prob: np.ndarray
    mode: np.ndarray
    loglik: np.ndarray
    flag: np.ndarray
    ess: np.ndarray
    status: int
    repaired: int = 0
    smallest_eigenvalue: float = math.inf


def rbpf_run(y, u, F, G, Qd, trans, C, R, transition, x0, P0, prob0, keys, *, particles: int,
             sample_timing: bool, optimal: bool, scheme: int, threshold: float) -> RBPFOutput:
    """RBPF of ``N`` trials over ``K`` samples (:func:`particle_filter`), every particle
    starting from the prior ``(x0, P0)`` at sample 0 with its mode drawn from ``prob0``.

    Parameters
    ----------
    y, u : array_like, shapes (N, K, m), (N, K, l)
        Measurements (NaN: missing) and inputs (``u[:, k-1]`` held into sample ``k``).
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        Table of exact transitions.
    trans : array_like of int, shape (K, L)
        ``trans[k, r]``: the transition of mode ``r`` into sample ``k`` (row 0 unused).
    C, R : array_like, shapes (L, m, n), (L, m, m)
    transition : array_like, shape (L, L)
        ``transition[i, j]`` = P(mode j at k+1 | mode i at k).
    x0, P0, prob0 : array_like, shapes (n,), (n, n), (L,)
        Prior of every particle's filter and mode probabilities at sample 0.
    keys : array_like of uint64, shape (N,)
        Each trial's random key.
    particles, sample_timing, optimal, scheme, threshold
        As :func:`particle_filter`.
    """
    sizes: dict[str, int] = {}
    y, u, F, G, Qd, trans, C, R, transition, x0, P0, prob0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn trans:KL<M C:Lmn R:Lmm transition:LL x0:n "
        "P0:nn prob0:L", y, u, F, G, Qd, trans, C, R, transition, x0, P0, prob0)
    Np = positive_int(particles, "particles")
    N, n = sizes["N"], sizes["n"]
    state = (np.tile(x0, (1, Np, 1)), np.tile(P0, (1, Np, 1, 1)),
             np.zeros((1, Np), dtype=np.int64), np.full((1, Np), -math.log(Np)))
    last = (np.empty((0, Np, n)), np.empty((0, Np, n, n)), np.empty((0, Np), dtype=np.int64),
            np.empty((0, Np)))
    return _kernel(y, u, F, G, Qd, trans, C, R, transition, prob0, _keys(keys, N), 0, False,
                   sample_timing, optimal, scheme, threshold, state, last)[0]


def rbpf_step(x, P, mode, log_weight, y, u, F, G, Qd, trans, C, R, transition, prob0, keys, k,
              *, predict_first: bool, sample_timing: bool, optimal: bool, scheme: int,
              threshold: float) -> tuple[RBPFOutput, tuple[np.ndarray, ...]]:
    """One sample ``k`` of every trial: predict (when ``predict_first``; before or after the
    draw of the modes, by ``sample_timing``), sample the modes and update each particle's
    filter, reweight, resample if due.

    ``x (N, Np, n)``, ``P (N, Np, n, n)``, ``mode (N, Np)``, ``log_weight (N, Np)`` are the
    particles after the previous sample, ``y (N, m)``, ``u (N, l)``, ``trans (L,)`` the
    transition of each mode into this sample, ``k`` its index in the record (the uniforms of
    :func:`uniform`); the rest as in :func:`rbpf_run`. Inputs are not modified.

    Returns
    -------
    output : RBPFOutput
        What the RBPF reports for this sample, each array with a sample axis of length 1.
    state : tuple of ndarray
        ``x``, ``P``, ``mode``, ``log_weight`` after this sample: the particles to continue
        from.
    """
    sizes: dict[str, int] = {}
    x, P, log_weight, y, u, F, G, Qd, trans, C, R, transition, prob0 = checked(
        sizes, "x:NPn P:NPnn log_weight:NP y:Nm u:Nl F:Mnn G:Mnl Qd:Mnn trans:L<M C:Lmn R:Lmm "
        "transition:LL prob0:L", x, P, log_weight, y, u, F, G, Qd, trans, C, R, transition,
        prob0)
    mode = checked(sizes, "mode:NP<L", mode)[0]
    N, Np, n = sizes["N"], sizes["P"], sizes["n"]
    last = (np.empty((N, Np, n)), np.empty((N, Np, n, n)), np.empty((N, Np), dtype=np.int64),
            np.empty((N, Np)))
    return _kernel(y[:, None], u[:, None], F, G, Qd, trans[None], C, R, transition, prob0,
                   _keys(keys, N), int(k), bool(predict_first), sample_timing, optimal, scheme,
                   threshold, (x, P, mode, log_weight), last)


def _keys(keys, N: int) -> np.ndarray:
    """``keys`` as a C-contiguous uint64 array of shape ``(N,)``."""
    keys = np.ascontiguousarray(keys, dtype=np.uint64)
    if keys.shape != (N,):
        raise ValueError(f"keys must have shape (N,) = ({N},), got {keys.shape}")
    return keys


def _kernel(y, u, F, G, Qd, trans, C, R, transition, prob0, keys, k0, predict_first,
            sample_timing, optimal, scheme, threshold, state,
            last) -> tuple[RBPFOutput, tuple[np.ndarray, ...]]:
    """:func:`particle_filter` with its outputs allocated; returns them and ``last``."""
    N, K, _ = y.shape
    n, L = state[0].shape[2], C.shape[0]
    x, P = np.empty((N, K, n)), np.empty((N, K, n, n))
    prob, mode = np.empty((N, K, L)), np.empty((N, K), dtype=np.int64)
    loglik, flag, ess = np.empty((N, K)), np.empty((N, K), dtype=np.uint8), np.empty((N, K))
    report = np.empty(2)
    with np.errstate(divide="ignore"):  # log 0 = -inf: an impossible switch or first mode
        log_transition, log_prob0 = np.log(transition), np.log(prob0)
    status = particle_filter(y, u, F, G, Qd, trans, C, R, transition, log_transition, prob0,
                             log_prob0, keys, k0, predict_first, bool(sample_timing),
                             bool(optimal), int(scheme), float(threshold), *state, x, P, prob,
                             mode, loglik, flag, ess, *last, report)
    return (RBPFOutput(x, P, prob, mode, loglik, flag, ess, int(status), int(report[0]),
                       float(report[1])), last)


@register
def _warm_up() -> None:
    """Both proposals on tiny arrays of the dtypes and layouts :class:`RBPFilter` passes (the
    timing is a value of the same type: one signature serves both)."""
    eye = np.eye(1)[None]
    for optimal in (False, True):
        rbpf_run(np.zeros((1, 2, 1)), np.zeros((1, 2, 1)), eye, eye, eye,
                 np.zeros((2, 1), dtype=np.int64), eye, eye, np.eye(1), np.zeros(1), np.eye(1),
                 np.ones(1), np.zeros(1, dtype=np.uint64), particles=2, sample_timing=True,
                 optimal=optimal, scheme=0, threshold=0.5)
