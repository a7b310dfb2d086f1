"""The compiled IMM extended-Viterbi filter with gridded switching times (numba).

Shankar, Yang & Hespanha, Algorithm 1, on the IMM-EV1 of Ho & Chen (2006): one Kalman filter
per destination mode ``i``. At each sample every predecessor ``j`` and, when ``j != i``, every
switching instant ``tau_k`` of the grid of eq. (23) is a hypothesis, predicted with the exact
transition of that switch (eqs (4)-(5)), ``epsilon I`` added to its predicted covariance
(§IV), and scored by its likelihood ``J`` of the measurement. ``imm_ev1_run`` filters every
trial over every sample; ``imm_ev1_step`` processes one sample (the streaming API). Both call
:func:`viterbi_bank`, which uses the Kalman equations of :mod:`.linalg`; trials are laid
across SIMD lanes in blocks as in :mod:`.bank`, and so are the hypotheses: a lane holds one
hypothesis of one trial, so that each equation runs once per sample over all of them.

Each sample takes two passes (:func:`viterbi_bank`, Notes): the likelihoods of all ``L^2 g``
hypotheses, without forming their predictions; then, once each destination has chosen its
predecessor and instant, the prediction and update of the chosen hypotheses only.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..._checks import positive_int, positive_scalar
from .arrays import check_gate, checked, indices
from .bank import LANES
from .linalg import (
    OK,
    _moments,
    borrow,
    correct,
    gather_matrices,
    gather_modes,
    gather_rows,
    gather_samples,
    information_or_repair,
    innovation,
    jit,
    joseph_lost,
    log_normalize,
    observe,
    predict,
    residual,
    scatter_modes,
    scatter_rows,
    write_lane,
)

__all__ = ["IMMEV1Output", "imm_ev1_run", "imm_ev1_step", "viterbi_bank"]


@jit
def _spread(v, nb, width):
    """``v[a, q nb + b] = v[a, b]`` for every lane below ``width``: each trial's row, in lanes
    ``0 .. nb - 1``, repeated for every hypothesis."""
    for a in range(v.shape[0]):
        for q in range(1, width // nb):
            for b in range(nb):
                v[a, q * nb + b] = v[a, b]


@jit
def _gather_states(x, P, source, nb, width, xs, Ps):
    """``xs[:, l] = x[source[l], :, l % nb]``, ``Ps[:, :, l] = P[source[l], :, :, l % nb]``:
    in each lane, the filter of mode ``source[l]`` of its trial."""
    n = xs.shape[0]
    for r in range(n):
        for q in range(width // nb):
            for b in range(nb):
                xs[r, q * nb + b] = x[source[q * nb + b], r, b]
        for c in range(n):
            for q in range(width // nb):
                for b in range(nb):
                    Ps[r, c, q * nb + b] = P[source[q * nb + b], r, c, b]


@jit
def _inflate(P, epsilon, width):
    """``P <- P + epsilon I``: the inflation of every predicted covariance (Shankar et al.
    §IV, so that the inverse of ``P_k|k-1`` stays bounded, Assumption 2)."""
    for r in range(P.shape[0]):
        for b in range(width):
            P[r, r, b] += epsilon


@borrow
def _hypothesis(x, P, source, F, G, Qd, entry, u, epsilon, y, C, R, obs, n_obs, nb, width, pred,
                inn, report):
    """Predict in each lane the filter ``source[l]`` of its trial with transition ``entry[l]``
    and form its innovation.

    ``x- = F x + G u``, ``P- = F P F' + Qd + epsilon I`` (Shankar et al. eqs (6)-(7), §IV) into
    ``pred[0]``, ``pred[1]`` (``pred``: ``xs, Ps, Fl, Gl, Ql, FP, xv``), then
    :func:`.linalg.innovation` of ``y`` against ``(x-, P-)`` (eq. (8)) into ``inn``
    (``e, PCt, chol, scale, z, nis, loglik, work, bad``): a lane whose innovation covariance
    fails its factorization has ``P-`` repaired, as in :func:`.bank.filter_bank`. Returns its
    status.
    """
    xs, Ps, Fl, Gl, Ql, FP, xv = pred
    _gather_states(x, P, source, nb, width, xs, Ps)
    gather_matrices(F, entry, width, Fl)
    gather_matrices(G, entry, width, Gl)
    gather_matrices(Qd, entry, width, Ql)
    predict(xs, Ps, Fl, Gl, u, Ql, width, FP, xv)
    _inflate(Ps, epsilon, width)
    return innovation(xs, Ps, y, C, R, obs, n_obs, width, *inn, report)


@borrow
def _likelihoods(x, P, nb, width, y, u, obs, n_obs, F, G, Qd, H, Gy, S0, C, R, source, entry,
                 epsilon, gate, printed, zero, yh, pred, inn, report, J, use):
    """``J`` of every hypothesis, one per lane (``width`` lanes); ``use`` where it accepts the
    measurement.

    Lane ``l`` holds the switch from ``source[l]`` to a destination ``i`` at an instant
    ``tau``, transition ``entry[l]``, with ``C``, ``R`` those of ``i`` and ``H = C_i F``,
    ``Gy = C_i G``, ``S0 = C_i (Qd + epsilon I) C_i' + R_i`` of the transition. ``J`` is the
    likelihood of the measurement given the predecessor's posterior ``(x_j, P_j)`` and the
    switch: ``log N(y; C_i x-, C_i P- C_i' + R_i)``, or with ``printed`` the paper's literal
    ``J_k(tau) = N(y; C_i x-, R_i)`` (§IV), each ``-inf`` where the hypothesis rejects ``y``
    (its normalized innovation squared is not finite or exceeds ``gate``).

    It is evaluated without forming the prediction: the innovation of the prediction is
    ``(y - C_i G u) - H x_j``, with covariance ``H P_j H' + S0`` (eqs (6)-(8) seen through
    ``C_i``), which is :func:`.linalg.innovation` of ``(x_j, P_j)`` with output matrix ``H``
    and noise ``S0``: O(m n^2) per hypothesis instead of O(n^3). If a factorization fails
    there, the hypotheses are predicted in full instead (:func:`_hypothesis`, which repairs
    ``P-``). Returns a status.
    """
    xw, Pw = pred[0], pred[1]
    nis, loglik = inn[5], inn[6]
    _gather_states(x, P, source, nb, width, xw, Pw)
    residual(u, y, Gy, width, yh)  # y less the response to the input, (C G) u
    full = innovation(xw, Pw, yh, H, S0, obs, n_obs, width, *inn) != OK
    if full:  # the predictions themselves, repaired where needed
        status = _hypothesis(x, P, source, F, G, Qd, entry, u, epsilon, y, C, R, obs, n_obs, nb,
                             width, pred, inn, report)
        if status != OK:
            return status
    for b in range(width):
        use[b] = math.isfinite(loglik[b]) and nis[b] <= gate
        J[b] = loglik[b] if use[b] else -math.inf
    if not printed:
        return OK
    if full:
        status = innovation(xw, zero, y, C, R, obs, n_obs, width, *inn)
    else:
        status = innovation(xw, zero, yh, H, R, obs, n_obs, width, *inn)
    if status != OK:
        return status
    for b in range(width):  # N(y; C x-, R): -inf where its quadratic form overflows
        J[b] = loglik[b] if use[b] and nis[b] < math.inf else -math.inf
    return OK


@jit
def _by_pair(J_lanes, use_lanes, hypotheses, nb, J, use):
    """``J[j, i, k, b]`` and ``use[j, i, k, b]`` from lane ``q nb + b`` of the hypothesis
    ``hypotheses[q] = (j, i, k)``."""
    for q in range(hypotheses.shape[0]):
        j, i, k = hypotheses[q, 0], hypotheses[q, 1], hypotheses[q, 2]
        for b in range(nb):
            J[j, i, k, b] = J_lanes[q * nb + b]
            use[j, i, k, b] = use_lanes[q * nb + b]


@jit
def _choose(J, use, log_w, log_transition, tau, marginal, by_path, nb, outlier, log_b, best_k,
            w, tau_pair, chosen, a, offset):
    """Each destination's predecessor and switching instant (Algorithm 1, Ho & Chen).

    A lane where every hypothesis rejects the measurement is an outlier: there ``J = 0`` and no
    hypothesis is updated (a missing sample). Per pair ``(j, i)``: with ``"max"`` the grid
    maximizer of eq. (23), ``b_ji = J(tau_k*)`` (the first on a tie); with ``marginal``, the
    instant integrated out under a uniform prior on the grid, ``b_ji = (1/g) sum_k J_k``
    (in the log domain), weights ``w_k = J_k / sum J`` and mean instant ``sum w_k tau_k``
    (a pair whose every hypothesis rejected ``y`` gets zero weights and instant, so its merged
    posterior is zero: it has weight zero). Path weights
    ``log a_j + log b_ji (+ log pi_ji)``; destination ``i`` keeps ``j^ = argmax_j`` of the
    path weight (``by_path``, the extended Viterbi rule) or of ``b_ji`` (the printed line
    "j^ = max_j b_ij"), and gets ``log a_i = path weight of j^`` (unnormalized, into ``a``)
    and ``offset`` = the instant, NaN when ``j^ == i``.
    """
    n_modes, g = J.shape[0], J.shape[2]
    log_g = math.log(g)
    for b in range(nb):
        outlier[b] = True
        for j in range(n_modes):
            for i in range(n_modes):
                for k in range(g if j != i else 1):
                    outlier[b] &= J[j, i, k, b] == -math.inf
        for j in range(n_modes):
            for i in range(n_modes):
                if outlier[b]:  # every hypothesis keeps its prediction, J = 0
                    for k in range(g if j != i else 1):
                        J[j, i, k, b] = 0.0
                        use[j, i, k, b] = False
                if j == i:  # one hypothesis stands for the g equal ones
                    log_b[j, i, b] = J[j, i, 0, b]
                    best_k[j, i, b] = 0
                    for k in range(g):
                        w[j, i, k, b] = 1.0 if k == 0 and J[j, i, 0, b] > -math.inf else 0.0
                    continue
                top, kt = J[j, i, 0, b], 0
                for k in range(1, g):
                    if J[j, i, k, b] > top:
                        top, kt = J[j, i, k, b], k
                best_k[j, i, b] = kt
                if not marginal:
                    log_b[j, i, b] = top
                    tau_pair[j, i, b] = tau[kt]
                    continue
                if top == -math.inf:
                    for k in range(g):
                        w[j, i, k, b] = 0.0
                    log_b[j, i, b], tau_pair[j, i, b] = -math.inf, 0.0
                    continue
                acc = 0.0
                for k in range(g):
                    acc += math.exp(J[j, i, k, b] - top)
                log_acc = math.log(acc)
                tau_pair[j, i, b] = 0.0
                for k in range(g):
                    w[j, i, k, b] = math.exp((J[j, i, k, b] - top) - log_acc)
                    tau_pair[j, i, b] += w[j, i, k, b] * tau[k]
                log_b[j, i, b] = (top + log_acc) - log_g
        for i in range(n_modes):
            chosen[i, b] = 0
            best = -math.inf
            for j in range(n_modes):
                path = (log_w[j, b] + log_b[j, i, b]) + log_transition[j, i]
                score = path if by_path else log_b[j, i, b]
                if j == 0 or score > best:
                    chosen[i, b], best, a[i, b] = j, score, path
            j = chosen[i, b]
            offset[i, b] = math.nan if j == i else tau_pair[j, i, b]


@jit
def _from_lanes(xs, Ps, first, nb, xo, Po):
    """``xo[:, b] = xs[:, first + b]``, ``Po[:, :, b] = Ps[:, :, first + b]`` for the ``nb``
    trials of one hypothesis."""
    n = xo.shape[0]
    for r in range(n):
        for b in range(nb):
            xo[r, b] = xs[r, first + b]
        for c in range(n):
            for b in range(nb):
                Po[r, c, b] = Ps[r, c, first + b]


@borrow
def _predict_chosen(x, P, d, chosen, best_k, use, w, F, G, Qd, u, epsilon, y, C, R, obs, n_obs,
                    marginal, nb, source, entry, use_lanes, w_lanes, pred, inn, fix, report,
                    xg, Pg, x_new, P_new):
    """Each destination's posterior from its chosen predecessor (Algorithm 1: "compute
    x^i_k+1, P^i_k+1 from x^j_k, P^j_k and t^ij_k").

    ``"max"``: the hypothesis of the chosen instant, predicted and updated (eqs (4)-(10));
    ``marginal``: every grid hypothesis of the chosen pair, merged by moment matching with the
    weights ``w`` of :func:`_choose` (:func:`.linalg._moments`). A hypothesis that rejected the
    measurement keeps its prediction. Lane ``(i per + q) nb + b`` holds destination ``i``,
    hypothesis ``q`` (of ``per = g`` or 1), trial ``b``; ``C``, ``R`` are laid out so.
    Into ``x_new (L, n, B)``, ``P_new (L, n, n, B)``; returns a status.
    """
    n_modes, g = x.shape[0], w.shape[2]
    per = g if marginal else 1
    width = n_modes * per * nb
    for i in range(n_modes):
        for q in range(per):
            for b in range(nb):
                lane, j = (i * per + q) * nb + b, chosen[i, b]
                k = 0 if j == i else (q if marginal else best_k[j, i, b])
                source[lane] = j
                entry[lane] = ((d * n_modes + j) * n_modes + i) * g + k
                use_lanes[lane] = use[j, i, k, b]
    status = _hypothesis(x, P, source, F, G, Qd, entry, u, epsilon, y, C, R, obs, n_obs, nb,
                         width, pred, inn, report)
    if status != OK:
        return status
    xs, Ps = pred[0], pred[1]
    gain, T, AP, prior, root, lost = fix
    correct(xs, Ps, C, R, use_lanes, width, *inn[1:5], gain, T, AP, prior)
    if joseph_lost(Ps, prior, use_lanes, width, root, lost):  # rare: lane by lane
        information_or_repair(Ps, prior, C, R, obs, n_obs, lost, width, report)
    for i in range(n_modes):
        if not marginal:
            _from_lanes(xs, Ps, i * nb, nb, x_new[i], P_new[i])
            continue
        for q in range(g):
            for b in range(nb):
                w_lanes[q, b] = w[chosen[i, b], i, q, b]
            _from_lanes(xs, Ps, (i * g + q) * nb, nb, xg[q], Pg[q])
        _moments(w_lanes, xg, Pg, nb, x_new[i], P_new[i])
    return OK


@borrow
def _update_only(x, P, log_w, y, Cl, Rl, obs, n_obs, gate, nb, use, a, outlier, inn, fix,
                 report):
    """A sample without prediction (the first of a record): every mode's filter updated with
    its prior (Shankar et al. eqs (8)-(10)), ``log a_j += log N(y; C_j x_j, S_j)``, ``-inf``
    where mode ``j`` rejects ``y``; where every mode rejects it, nothing is updated and the
    weights are kept (an outlier). Unnormalized weights into ``a``; returns a status."""
    n_modes = x.shape[0]
    nis, loglik = inn[5], inn[6]
    gain, T, AP, prior, root, lost = fix
    for j in range(n_modes):
        status = innovation(x[j], P[j], y, Cl[j], Rl[j], obs, n_obs, nb, *inn, report)
        if status != OK:
            return status
        for b in range(nb):
            use[j, b] = math.isfinite(loglik[b]) and nis[b] <= gate
            a[j, b] = log_w[j, b] + loglik[b] if use[j, b] else -math.inf
        correct(x[j], P[j], Cl[j], Rl[j], use[j], nb, *inn[1:5], gain, T, AP, prior)
        if joseph_lost(P[j], prior, use[j], nb, root, lost):  # rare: lane by lane
            information_or_repair(P[j], prior, Cl[j], Rl[j], obs, n_obs, lost, nb, report)
    for b in range(nb):
        outlier[b] = True
        for j in range(n_modes):
            outlier[b] &= not use[j, b]
        if outlier[b]:  # the sample counts as missing; no mode was updated
            for j in range(n_modes):
                a[j, b] = log_w[j, b]
    return OK


@jit
def viterbi_bank(y, u, table, F, G, Qd, H, Gy, S0, tau, C, R, log_transition, epsilon, x_init,
                 P_init, log_w_init, chosen_init, offset_init, predict_first, gate, printed,
                 marginal, by_path, lanes, x_out, P_out, prob_out, mode_out, offset_out,
                 outlier_out, x_last, P_last, log_w_last, chosen_last, offset_last, report):
    """Filter ``N`` trials over ``K`` samples with the IMM-EV1 of Shankar et al., Algorithm 1.

    Parameters
    ----------
    y, u : (N, K, m), (N, K, l) float64
        Measurements and inputs, as in :func:`.bank.filter_bank`.
    table : (K,) int64
        The interval length ``d`` into each sample (entry 0 unused unless ``predict_first``).
    F, G, Qd : (M, n, n), (M, n, l), (M, n, n) float64
        Transitions of the hypotheses, ``M = D L L g``: entry ``((d L + j) L + i) g + k`` is
        the switch from ``j`` to ``i`` at ``tau[d, k]`` over interval length ``d`` (for
        ``j == i`` no switch, read at ``k = 0``).
    H, Gy, S0 : (M, m, n), (M, m, l), (M, m, m) float64
        ``C_i F``, ``C_i G`` and ``C_i (Qd + epsilon I) C_i' + R_i`` of each entry.
    tau : (D, g) float64
        The grid of switching instants (offsets in the interval) of each interval length.
    C, R : (L, m, n), (L, m, m) float64
    log_transition : (L, L) float64
        ``log pi_ji`` added to the path weights (zeros for none).
    epsilon : float
        The inflation of every predicted covariance (§IV).
    x_init, P_init, log_w_init, chosen_init, offset_init
        State before the first sample: ``(N, L, n)``, ``(N, L, n, n)``, normalized log
        weights ``(N, L)``, predecessors ``(N, L)`` int64, switch offsets ``(N, L)``.
    predict_first : bool
        Whether the first sample is predicted into (a streaming step) or only updated.
    gate : float
        Largest normalized innovation squared a hypothesis accepts.
    printed, marginal, by_path : bool
        ``likelihood="printed"``, ``switch_time="marginal"``, ``predecessor="path"``.
    lanes : int
        Trials per block.
    x_out, P_out, prob_out, mode_out, offset_out, outlier_out
        Written: the MAP destination's ``x (N, K, n)``, ``P (N, K, n, n)``, normalized weights
        ``(N, K, L)``, the MAP destination (the first on a tie), its switch offset (NaN
        without a switch) and whether every hypothesis rejected the sample ``(N, K)``.
    x_last, P_last, log_w_last, chosen_last, offset_last
        Written: the state after the last sample, shaped as the ``_init`` arrays.
    report : (2,) float64
        Written: covariances repaired and the smallest eigenvalue one had (as the bank's).

    Returns
    -------
    status : int
        ``OK``, or the failure code of the innovation covariance (of a hypothesis, or of a
        destination's update) that stopped the kernel (outputs then incomplete).

    Notes
    -----
    Each sample predicted into takes two passes over lanes that hold one hypothesis of one
    trial each. :func:`_likelihoods` scores the ``L + L (L - 1) g`` distinct hypotheses (the
    no-switch transition is the same at every instant) from the predecessors' posteriors
    without forming their predictions (an ``m x n`` output matrix instead of an ``n x n``
    transition); :func:`_choose` picks each destination's predecessor and instant; then only
    the chosen hypotheses are predicted and updated (:func:`_predict_chosen`: ``L``, or
    ``L g`` for ``"marginal"``, per trial). The results are those of updating every hypothesis
    and selecting afterwards, as Algorithm 1 states. Gating and ill-conditioned covariances
    are handled lane by lane as in :func:`.bank.filter_bank`.
    """
    N, K, m = y.shape
    n_modes, n = x_init.shape[1], x_init.shape[2]
    n_in, g = u.shape[2], tau.shape[1]
    B = lanes
    per = g if marginal else 1  # hypotheses predicted per destination
    hypotheses = np.empty((n_modes + n_modes * (n_modes - 1) * g, 3), dtype=np.int64)
    q = 0
    for j in range(n_modes):
        for i in range(n_modes):
            for k in range(g if j != i else 1):
                hypotheses[q, 0], hypotheses[q, 1], hypotheses[q, 2] = j, i, k
                q += 1
    n_hyp = hypotheses.shape[0]
    W = max(n_hyp, n_modes * per) * B  # lanes of the widest pass
    x, P = np.empty((n_modes, n, B)), np.empty((n_modes, n, n, B))
    x_new, P_new = np.empty((n_modes, n, B)), np.empty((n_modes, n, n, B))
    log_w, prob, total = np.empty((n_modes, B)), np.empty((n_modes, B)), np.empty(B)
    chosen, offset = np.empty((n_modes, B), dtype=np.int64), np.empty((n_modes, B))
    a, outlier = np.empty((n_modes, B)), np.empty(B, dtype=np.bool_)
    J, use = np.empty((n_modes, n_modes, g, B)), np.empty((n_modes, n_modes, g, B), np.bool_)
    log_b, w = np.empty((n_modes, n_modes, B)), np.empty((n_modes, n_modes, g, B))
    best_k = np.empty((n_modes, n_modes, B), dtype=np.int64)
    tau_pair = np.empty((n_modes, n_modes, B))
    w_lanes, xg, Pg = np.empty((g, B)), np.empty((g, n, B)), np.empty((g, n, n, B))
    Cl, Rl = np.empty((n_modes, m, n, B)), np.empty((n_modes, m, m, B))
    update_use = np.empty((n_modes, B), dtype=np.bool_)
    yw, uw, yh = np.empty((m, W)), np.empty((n_in, W)), np.empty((m, W))
    obs, n_obs = np.empty((m, W)), np.empty(W)
    source, entry = np.empty(W, dtype=np.int64), np.empty(W, dtype=np.int64)
    source2, entry2 = np.empty(W, dtype=np.int64), np.empty(W, dtype=np.int64)
    J_lanes, use_lanes = np.empty(W), np.empty(W, dtype=np.bool_)
    C1, R1 = np.empty((m, n, W)), np.empty((m, m, W))  # the likelihood pass's lanes
    C2, R2 = np.empty((m, n, W)), np.empty((m, m, W))  # the update pass's lanes
    H1, Gy1, S1 = np.empty((m, n, W)), np.empty((m, n_in, W)), np.empty((m, m, W))
    zero = np.zeros((n, n, W))
    # the workspaces: pred of _hypothesis (xs, Ps, Fl, Gl, Ql, FP, xv), inn of
    # linalg.innovation (e, PCt, chol, scale, z, nis, loglik, work, bad) and fix, the rest of
    # linalg.correct's and joseph_lost's (gain, T, AP, prior, root, lost)
    pred = (np.empty((n, W)), np.empty((n, n, W)), np.empty((n, n, W)), np.empty((n, n_in, W)),
            np.empty((n, n, W)), np.empty((n, n, W)), np.empty((n, W)))
    inn = (np.empty((m, W)), np.empty((n, m, W)), np.empty((m, m, W)), np.empty((m, W)),
           np.empty((m, W)), np.empty(W), np.empty(W), np.empty((3, W)),
           np.zeros(W, dtype=np.bool_))
    fix = (np.empty((n, m, W)), np.empty((n, m, W)), np.empty((n, n, W)), np.empty((n, n, W)),
           np.empty((n, W)), np.empty(W, dtype=np.bool_))
    report[0], report[1] = 0.0, math.inf
    for i in range(n_modes):  # every trial's C_i, R_i, for the update without prediction
        for b in range(B):
            entry[b] = i
        gather_matrices(C, entry, B, Cl[i])
        gather_matrices(R, entry, B, Rl[i])
    for i0 in range(0, N, B):
        nb = min(B, N - i0)
        width1, width2 = n_hyp * nb, n_modes * per * nb
        for q in range(n_hyp):  # the lanes' predecessors and destinations' C, R
            for b in range(nb):
                source[q * nb + b] = hypotheses[q, 0]
                entry[q * nb + b] = hypotheses[q, 1]
        gather_matrices(C, entry, width1, C1)
        gather_matrices(R, entry, width1, R1)
        for lane in range(width2):
            entry[lane] = lane // (per * nb)
        gather_matrices(C, entry, width2, C2)
        gather_matrices(R, entry, width2, R2)
        d_last = -1
        gather_rows(log_w_init, i0, nb, log_w)
        gather_rows(chosen_init, i0, nb, chosen)
        gather_rows(offset_init, i0, nb, offset)
        gather_modes(x_init, P_init, i0, nb, x, P)
        for k in range(K):
            predicted = k > 0 or predict_first
            width = max(width1, width2) if predicted else nb
            gather_samples(y, i0, nb, k, yw)
            _spread(yw, nb, width)
            observe(yw, width, obs, n_obs)
            if predicted:
                d = table[k]
                gather_samples(u, i0, nb, max(k - 1, 0), uw)
                _spread(uw, nb, width)
                if d != d_last:  # the hypotheses' transitions as the likelihood pass reads them
                    for q in range(n_hyp):
                        j, i, kk = hypotheses[q, 0], hypotheses[q, 1], hypotheses[q, 2]
                        for b in range(nb):
                            entry[q * nb + b] = ((d * n_modes + j) * n_modes + i) * g + kk
                    gather_matrices(H, entry, width1, H1)
                    gather_matrices(Gy, entry, width1, Gy1)
                    gather_matrices(S0, entry, width1, S1)
                    d_last = d
                status = _likelihoods(x, P, nb, width1, yw, uw, obs, n_obs, F, G, Qd, H1, Gy1, S1,
                                      C1, R1, source, entry, epsilon, gate, printed, zero, yh,
                                      pred, inn, report, J_lanes, use_lanes)
                if status != OK:
                    return status
                _by_pair(J_lanes, use_lanes, hypotheses, nb, J, use)
                _choose(J, use, log_w, log_transition, tau[d], marginal, by_path, nb, outlier,
                        log_b, best_k, w, tau_pair, chosen, a, offset)
                status = _predict_chosen(x, P, d, chosen, best_k, use, w, F, G, Qd, uw, epsilon,
                                         yw, C2, R2, obs, n_obs, marginal, nb, source2, entry2,
                                         use_lanes, w_lanes, pred, inn, fix, report, xg, Pg,
                                         x_new, P_new)
                if status != OK:
                    return status
                x, x_new, P, P_new = x_new, x, P_new, P
            else:
                status = _update_only(x, P, log_w, yw, Cl, Rl, obs, n_obs, gate, nb,
                                      update_use, a, outlier, inn, fix, report)
                if status != OK:
                    return status
            log_normalize(a, prob, total, nb)  # a^i = b_ji a^j (pi_ji), normalized
            for j in range(n_modes):
                for b in range(nb):
                    log_w[j, b] = a[j, b]
            for b in range(nb):
                i, best = i0 + b, 0
                for j in range(1, n_modes):
                    if log_w[j, b] > log_w[best, b]:
                        best = j
                mode_out[i, k] = best
                offset_out[i, k] = offset[best, b]
                outlier_out[i, k] = outlier[b]
                for j in range(n_modes):
                    prob_out[i, k, j] = prob[j, b]
                write_lane(x[best], P[best], b, i, k, x_out, P_out)
        scatter_rows(log_w, i0, nb, log_w_last)
        scatter_rows(chosen, i0, nb, chosen_last)
        scatter_rows(offset, i0, nb, offset_last)
        scatter_modes(x, P, i0, nb, x_last, P_last)
    return OK


class IMMEV1Output(NamedTuple):
    """What the IMM-EV1 reports after each sample, for every trial (:func:`imm_ev1_run`; from
    :func:`imm_ev1_step`, the one sample as ``K = 1``).

    Attributes
    ----------
    x, P : ndarray, shapes (N, K, n), (N, K, n, n)
        Posterior of the destination of largest weight (the MAP path).
    mode_prob : ndarray, shape (N, K, L)
        Normalized path weights of the destinations.
    mode : ndarray of int64, shape (N, K)
        The MAP destination (the first on a tie).
    switch_offset : ndarray, shape (N, K)
        Its switching instant as an offset into the interval, NaN where it did not switch.
    outlier : ndarray of bool, shape (N, K)
        True where every hypothesis rejected the measurement (treated as missing).
    status, repaired, smallest_eigenvalue
        As in :class:`.imm.IMMOutput`.
    """

    x: np.ndarray
    P: np.ndarray
    mode_prob: np.ndarray
    mode: np.ndarray
    switch_offset: np.ndarray
    outlier: np.ndarray
    status: int
    repaired: int = 0
    smallest_eigenvalue: float = math.inf


def imm_ev1_run(y, u, F, G, Qd, table, tau, C, R, log_transition, x0, P0, log_weight0, *,
                epsilon, gate=math.inf, printed=False, marginal=False, by_path=True,
                lanes: int = LANES) -> IMMEV1Output:
    """IMM-EV1 filter of ``N`` trials over ``K`` samples (Shankar et al., Algorithm 1).

    Parameters
    ----------
    y, u : array_like, shapes (N, K, m), (N, K, l)
        Measurements and inputs, as in :func:`.imm.imm_run`.
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        Transitions of the hypotheses, ``M = D L L g`` (entry ``((d L + j) L + i) g + k``:
        from ``j`` to ``i`` at ``tau[d, k]``), e.g. :func:`switchest.discretize.pairwise_grid`
        of each of ``D`` interval lengths, reshaped and concatenated.
    table : array_like of int, shape (K,)
        The interval length ``d`` into each sample (entry 0 unused).
    tau : array_like, shape (D, g)
        The switching-time grid of each interval length (eq. (23)).
    C, R : array_like, shapes (L, m, n), (L, m, m)
    log_transition : array_like, shape (L, L)
        ``log pi_ji`` added to the path weights; zeros for none.
    x0, P0 : array_like, shapes (n,), (n, n)
        Prior of every destination's filter at the first sample.
    log_weight0 : array_like, shape (L,)
        Normalized log prior weights.
    epsilon : float
        ``epsilon I`` added to every predicted covariance (§IV).
    gate : float
        Largest normalized innovation squared a hypothesis accepts (``inf``: no gate).
    printed, marginal, by_path : bool
        The filter's ``likelihood="printed"``, ``switch_time="marginal"`` and
        ``predecessor="path"``.
    lanes : int
        Trials per SIMD block (the results do not depend on it).
    """
    sizes: dict[str, int] = {}
    y, u, x0, P0, log_weight0 = checked(sizes, "y:NKm u:NKl x0:n P0:nn log_weight0:L",
                                        y, u, x0, P0, log_weight0)
    N, L = sizes["N"], sizes["L"]
    state = (np.tile(x0, (N, L, 1)), np.tile(P0, (N, L, 1, 1)), np.tile(log_weight0, (N, 1)),
             np.tile(np.arange(L), (N, 1)), np.full((N, L), np.nan))
    tables = _tables(F, G, Qd, tau, C, R, log_transition, epsilon, sizes)
    table = indices(table, "table", "K", sizes, "D")
    out, _ = _viterbi(y, u, tables, table, state, False, check_gate(gate), printed, marginal,
                      by_path, positive_int(lanes, "lanes"))
    return out


def imm_ev1_step(x, P, log_weight, predecessor, switch_offset, y, u, F, G, Qd, tau, C, R,
                 log_transition, *, predict_first: bool, epsilon, gate=math.inf, printed=False,
                 marginal=False, by_path=True) -> tuple[IMMEV1Output, tuple[np.ndarray, ...]]:
    """One sample of every trial: the hypotheses of one interval and the update (when
    ``predict_first``), else the update of every destination's filter alone.

    ``x (N, L, n)``, ``P (N, L, n, n)``, ``log_weight (N, L)``, ``predecessor (N, L)``,
    ``switch_offset (N, L)`` are the state at the previous sample, ``y (N, m)``, ``u (N, l)``
    this sample's measurement and the input held over the interval, ``F``, ``G``, ``Qd``
    ``(L L g, ...)`` and ``tau (g,)`` the hypotheses of this interval (read only when
    ``predict_first``); the rest as in :func:`imm_ev1_run`, whose compiled kernel runs this
    one sample. Inputs are not modified.

    Returns
    -------
    output : IMMEV1Output
        What the IMM-EV1 reports for this sample, each array with a sample axis of length 1.
    state : tuple of ndarray
        ``x``, ``P``, ``log_weight``, ``predecessor``, ``switch_offset`` after this sample,
        shaped as given: the state to continue from.
    """
    sizes: dict[str, int] = {}
    x, P, log_weight, predecessor, switch_offset, y, u, tau = checked(
        sizes, "x:NLn P:NLnn log_weight:NL predecessor:NL<L switch_offset:NL y:Nm u:Nl tau:g",
        x, P, log_weight, predecessor, switch_offset, y, u, tau)
    tables = _tables(F, G, Qd, tau[None], C, R, log_transition, epsilon, sizes)
    state = (x.copy(), P.copy(), log_weight.copy(), predecessor.copy(), switch_offset.copy())
    return _viterbi(y[:, None], u[:, None], tables, np.zeros(1, dtype=np.int64), state,
                    bool(predict_first), check_gate(gate), printed, marginal, by_path, LANES)


def _tables(F, G, Qd, tau, C, R, log_transition, epsilon, sizes):
    """The validated hypothesis tables and what the likelihood pass reads of them:
    ``H = C_i F``, ``Gy = C_i G`` and ``S0 = C_i (Qd + epsilon I) C_i' + R_i`` per entry
    (:func:`_likelihoods`), with ``i`` the destination of each entry."""
    F, G, Qd, tau, C, R, log_transition = checked(
        sizes, "F:Mnn G:Mnl Qd:Mnn tau:Dg C:Lmn R:Lmm log_transition:LL",
        F, G, Qd, tau, C, R, log_transition)
    epsilon = positive_scalar(epsilon, "epsilon", allow_zero=True)
    D, L, g, n = sizes["D"], sizes["L"], sizes["g"], sizes["n"]
    if sizes["M"] != D * L * L * g:
        raise ValueError(f"F, G, Qd must hold D L L g = {D} x {L} x {L} x {g} = {D * L * L * g} "
                         f"transitions (interval lengths x modes x modes x grid), "
                         f"got {sizes['M']}")
    dest = np.broadcast_to(np.arange(L)[None, None, :, None], (D, L, L, g)).ravel()
    Ci, Ri = C[dest], R[dest]
    Ct = np.swapaxes(Ci, -1, -2)
    S0 = Ci @ (Qd + epsilon * np.eye(n)) @ Ct + Ri
    S0 = 0.5 * (S0 + np.swapaxes(S0, -1, -2))
    return (F, G, Qd, np.ascontiguousarray(Ci @ F), np.ascontiguousarray(Ci @ G),
            np.ascontiguousarray(S0), tau, C, R, log_transition, epsilon)


def _viterbi(y, u, tables, table, state, predict_first, gate, printed, marginal, by_path,
             lanes):
    """:func:`viterbi_bank` from ``state`` (``x, P, log_weight, predecessor, offset`` per
    trial and destination); returns the :class:`IMMEV1Output` and the state after the last
    sample."""
    N, K, _ = y.shape
    L, n = state[0].shape[1], state[0].shape[2]
    x, P = np.empty((N, K, n)), np.empty((N, K, n, n))
    prob, mode = np.empty((N, K, L)), np.empty((N, K), dtype=np.int64)
    offset, outlier = np.empty((N, K)), np.empty((N, K), dtype=np.bool_)
    last = tuple(np.empty_like(a) for a in state)
    report = np.empty(2)
    status = viterbi_bank(y, u, table, *tables, *state, predict_first, gate, bool(printed),
                          bool(marginal), bool(by_path), lanes, x, P, prob, mode, offset,
                          outlier, *last, report)
    return (IMMEV1Output(x, P, prob, mode, offset, outlier, int(status), int(report[0]),
                         float(report[1])), last)
