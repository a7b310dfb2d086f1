"""The compiled kernel of the Gaussian filters: a bank of mode-matched Kalman filters.

:func:`filter_bank` runs, for every trial and every sample, ``L`` Kalman filters (one per
mode) with an interaction between them before each prediction: the IMM's mixing
(``MIX``: Blom & Bar-Shalom, 1988; Bar-Shalom, Li & Kirubarajan §11.6.6) or GPB1's
collapse of all of them into one Gaussian (``COLLAPSE``: Bar-Shalom, Li & Kirubarajan
§11.6.4). With one mode the interaction and the combination reduce to copies and it is the
Kalman filter (Shankar et al. eqs (6)-(10)). On request it writes the mode-matched
posteriors after each sample's update, the input of a smoother. :mod:`.imm` calls this
kernel for a whole record (``run``) or for one sample (``step``, the streaming API); the
Kalman filter has a kernel of its own (:mod:`.kalman_kernel`: trials that share their
covariance run its equations once) on the same equations of :mod:`.linalg`, so each
equation has one implementation.

Trials are processed in blocks of ``lanes`` laid across SIMD lanes (:mod:`.linalg`); the
results do not depend on the block size. Each trial may have a model of its own (its entries of
the transition and output tables, its mode transition matrix): one record filtered under many
candidate parameters fills the lanes as many trials do.
"""

from __future__ import annotations

import math

import numpy as np

from .linalg import (
    ACCEPTED,
    GATED,
    OK,
    PARTLY_GATED,
    borrow,
    collapse,
    combine,
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
    mix,
    observe,
    predict,
    scatter_modes,
    scatter_rows,
    write_lane,
    write_modes,
)

__all__ = ["LANES", "MIX", "COLLAPSE", "filter_bank", "lane_index", "gather_transition",
           "copy_rows", "report_sample"]

LANES = 16  # trials per block: four AVX2 registers of float64 per row of lanes

# the interaction of filter_bank's mode-matched filters at each sample after the first
MIX = 0  # the IMM's: mode j restarts from the mixture with weights mu_{i|j}
COLLAPSE = 1  # GPB1's: every mode restarts from the one Gaussian of all modes' mixture


@jit
def lane_index(index, i0, nb, k, j, out):
    """``out[b]``: entry ``[trial, k, j]`` of ``index (N or 1, K or 1, L)`` for trial
    ``i0 + b``; an axis of length 1 is shared by all trials (or samples)."""
    for b in range(nb):
        i = i0 + b if index.shape[0] > 1 else 0
        out[b] = index[i, k if index.shape[1] > 1 else 0, j]


@borrow
def gather_transition(F, G, Qd, trans, i0, nb, k, j, idx, Fl, Gl, Ql):
    """Each lane's exact transition of mode ``j`` into sample ``k``, ``trans[trial, k, j]``
    (:func:`lane_index`) of the table ``F, G, Qd``, into ``Fl (n, n, B)``, ``Gl (n, l, B)``,
    ``Ql (n, n, B)``; ``idx (B,)`` is scratch."""
    lane_index(trans, i0, nb, k, j, idx)
    gather_matrices(F, idx, nb, Fl)
    gather_matrices(G, idx, nb, Gl)
    gather_matrices(Qd, idx, nb, Ql)


@borrow
def _predict_modes(x, P, F, G, Qd, trans, i0, nb, k, ul, idx, Fl, Gl, Ql, AP, xs):
    """Every mode-matched Gaussian ``x[j]``, ``P[j]`` predicted into sample ``k`` through mode
    ``j``'s own transition (:func:`gather_transition`, :func:`.linalg.predict`), in place."""
    for j in range(x.shape[0]):
        gather_transition(F, G, Qd, trans, i0, nb, k, j, idx, Fl, Gl, Ql)
        predict(x[j], P[j], Fl, Gl, ul, Ql, nb, AP, xs)


@borrow
def _interact(x, P, prob, log_prob, transition, log_transition, interaction, nb, log_c, w, xm,
              Pm):
    """The bank's interaction, in place on the mode-matched ``x (L, n, B)``, ``P``, weighted by
    the mode probabilities ``prob`` of the previous sample and each lane's transition matrix
    ``transition (L, L, B)``: :func:`.linalg.mix` (``MIX``) or :func:`.linalg.collapse`
    (``COLLAPSE``); with one mode only ``log_c = log_prob``."""
    if x.shape[0] == 1:
        copy_rows(log_prob, log_c, nb)
    elif interaction == COLLAPSE:
        collapse(x, P, prob, log_prob, transition, log_transition, nb, log_c, w, xm, Pm)
    else:
        mix(x, P, prob, log_prob, transition, log_transition, nb, log_c, w, xm, Pm)


@jit
def gather_transitions(transition, log_transition, i0, nb, pi, log_pi):
    """Each lane's transition matrix and its logarithm, ``[trial]`` of ``transition (N or 1,
    L, L)`` and ``log_transition`` for trial ``i0 + b`` (an axis of length 1 is shared), into
    ``pi (L, L, B)``, ``log_pi``."""
    for b in range(nb):
        i = i0 + b if transition.shape[0] > 1 else 0
        for r in range(transition.shape[1]):
            for c in range(transition.shape[2]):
                pi[r, c, b] = transition[i, r, c]
                log_pi[r, c, b] = log_transition[i, r, c]


@jit
def copy_rows(src, dst, nb):
    """``dst[:, :nb] = src[:, :nb]`` as loops (numba compiles slice assignment slowly)."""
    for j in range(src.shape[0]):
        for b in range(nb):
            dst[j, b] = src[j, b]


@borrow
def report_sample(x, P, prob, log_prob, total, flag, n_obs, i0, nb, k, modes_wanted, xc, Pc,
                  best, x_out, P_out, prob_out, mode_out, loglik_out, flag_out, x_modes_out,
                  P_modes_out):
    """Write sample ``k`` of the block's trials: the combined output of the mode-matched
    Gaussians ``x (L, n, B)``, ``P`` with probabilities ``prob`` (Bar-Shalom, Li & Kirubarajan
    §11.6.6; ``xc``, ``Pc``, ``best`` scratch), the most probable mode, the log-likelihood
    ``total`` (0 where nothing was observed or the sample was gated), the flag, the mode
    probabilities and, if ``modes_wanted``, the mode-matched Gaussians themselves."""
    combine(x, P, prob, log_prob, nb, xc, Pc, best)
    for b in range(nb):
        i = i0 + b
        mode_out[i, k] = best[b]
        seen = flag[b] != GATED and n_obs[b] > 0
        loglik_out[i, k] = total[b] if seen else 0.0
        flag_out[i, k] = flag[b]
        for j in range(prob.shape[0]):
            prob_out[i, k, j] = prob[j, b]
        write_lane(xc, Pc, b, i, k, x_out, P_out)
        if modes_wanted:
            write_modes(x, P, b, i, k, x_modes_out, P_modes_out)


@jit
def filter_bank(y, u, F, G, Qd, trans, C, R, out_index, transition, log_transition, x_init,
                P_init, log_prob_init, interaction, sample_timing, predict_first, gate, lanes,
                x_out, P_out, prob_out, mode_out, loglik_out, flag_out, x_modes_out, P_modes_out,
                x_last, P_last, log_prob_last, report):
    """Filter ``N`` trials over ``K`` samples with ``L`` interacting mode-matched filters.

    Parameters
    ----------
    y : (N, K, m) float64
        Measurements; NaN components are missing.
    u : (N, K, l) float64
        Inputs; ``u[:, k-1]`` is held over the interval into sample ``k``, ``u[:, 0]`` over
        the interval into sample 0 when ``predict_first``.
    F, G, Qd : (M, n, n), (M, n, l), (M, n, n) float64
        Table of exact transitions.
    trans : (N or 1, K, L) int64
        Transition of mode ``j`` into sample ``k`` of each trial (shared if the first axis
        has length 1).
    C, R : (M', m, n), (M', m, m) float64
        Table of output matrices and measurement-noise covariances.
    out_index : (N or 1, K or 1, L) int64
        Which ``C``, ``R`` mode ``j`` uses at sample ``k`` of each trial.
    transition, log_transition : (N or 1, L, L) float64
        Mode transition matrix of each trial (shared if the first axis has length 1) and its
        logarithm (``transition[trial, i, j]`` = P(j next | i now)).
    x_init, P_init, log_prob_init : (N, L, n), (N, L, n, n), (N, L) float64
        Mode-matched state of every trial before the first sample.
    interaction : int
        ``MIX``: the IMM's interaction (:func:`.linalg.mix`); ``COLLAPSE``: GPB1's
        (:func:`.linalg.collapse`). The predicted mode probabilities are
        ``c_j = sum_i pi_ij mu_i`` either way.
    sample_timing : bool
        The order of interaction and prediction into each sample ``k``. False (the
        ``"interval"`` timing, Bar-Shalom, Li & Kirubarajan §11.6.6): interact, then predict
        each mode's restarted prior through its own transition ``trans[k, j]``. True (the
        ``"sample"`` timing): predict each mode-matched posterior ``i`` of sample ``k - 1``
        through its own transition ``trans[k, i]``, then interact the predictions with the same
        weights (``mu_{i|j} = pi_ij mu_i / c_j`` for the IMM, ``mu_i`` for GPB1).
    predict_first : bool
        Whether the first sample is mixed and predicted into (a streaming step) or only
        updated (the start of a record).
    gate : float
        Largest normalized innovation squared a mode accepts.
    lanes : int
        Trials per block.
    x_out, P_out, prob_out, mode_out, loglik_out, flag_out
        Written: combined estimate ``(N, K, n)``, ``(N, K, n, n)``, mode probabilities
        ``(N, K, L)``, most probable mode, log-likelihood (0 when nothing was observed or the
        sample was gated) and flag ``(N, K)``.
    x_modes_out, P_modes_out
        Written when their first axis has length ``N`` (pass zero-size arrays otherwise): the
        mode-matched posteriors after each sample's update, ``(N, K, L, n)``,
        ``(N, K, L, n, n)``.
    x_last, P_last, log_prob_last
        Written: the mode-matched state after the last sample, shaped as ``x_init`` etc.
    report : (2,) float64
        Written: the number of covariances repaired (:func:`.linalg.repair`) and the smallest
        eigenvalue one had before its repair (``inf`` if none), for the caller's warning.

    Returns
    -------
    status : int
        ``OK``, or the failure code of the mode-matched innovation covariance that stopped the
        kernel (outputs then incomplete).

    Notes
    -----
    Gating (mode by mode): a mode whose normalized innovation squared exceeds ``gate``, or
    whose likelihood is not finite (an outlier such as 1e300 overflows it), does not use the
    measurement: its estimate is not updated and its likelihood is taken as 0 (a truncated
    likelihood), flag ``PARTLY_GATED``. If no mode can use it the sample is treated as
    missing: no mode is updated, the mode probabilities stay the predicted ``c``, the
    log-likelihood is 0, flag ``GATED``.

    Ill-conditioned covariances, lane by lane: where Joseph's form loses its digits the
    posterior is taken in information form (:func:`.linalg.joseph_lost`,
    :func:`.linalg.information_form`); a posterior neither form resolves is repaired if
    indefinite, and a lane whose innovation covariance fails its factorization has its prior
    ``P`` repaired and is factored once more (:func:`.linalg.repair`); ``report`` counts the
    repairs. Only a lane whose ``P`` needs no repair and still fails stops the kernel.
    """
    N, K, m = y.shape
    n_modes, n = x_init.shape[1], x_init.shape[2]
    n_in = u.shape[2]
    B = lanes
    x, P = np.empty((n_modes, n, B)), np.empty((n_modes, n, n, B))
    log_prob, prob = np.empty((n_modes, B)), np.empty((n_modes, B))
    Fl, Gl, Ql = np.empty((n, n, B)), np.empty((n, n_in, B)), np.empty((n, n, B))
    Cl, Rl = np.empty((n_modes, m, n, B)), np.empty((n_modes, m, m, B))
    idx = np.empty(B, dtype=np.int64)
    yl, ul, obs, n_obs = np.empty((m, B)), np.empty((n_in, B)), np.empty((m, B)), np.empty(B)
    e, z, scale = np.empty((n_modes, m, B)), np.empty((n_modes, m, B)), np.empty((n_modes, m, B))
    PCt, chol = np.empty((n_modes, n, m, B)), np.empty((n_modes, m, m, B))
    nis, loglik, work = np.empty((n_modes, B)), np.empty((n_modes, B)), np.empty((3, B))
    gain, T = np.empty((n, m, B)), np.empty((n, m, B))
    AP, xs = np.empty((n, n, B)), np.empty((n, B))
    log_c, w = np.empty((n_modes, B)), np.empty((n_modes, n_modes, B))
    pi, log_pi = np.empty((n_modes, n_modes, B)), np.empty((n_modes, n_modes, B))
    xm, Pm = np.empty((n_modes, n, B)), np.empty((n_modes, n, n, B))
    a, use = np.empty((n_modes, B)), np.empty((n_modes, B), dtype=np.bool_)
    total, flag, best = np.empty(B), np.empty(B, dtype=np.uint8), np.empty(B, dtype=np.int64)
    xc, Pc = np.empty((n, B)), np.empty((n, n, B))
    bad, lost = np.zeros(B, dtype=np.bool_), np.empty(B, dtype=np.bool_)
    prior, root = np.empty((n, n, B)), np.empty((n, B))
    modes_wanted = x_modes_out.shape[0] == N
    report[0], report[1] = 0.0, math.inf
    for i0 in range(0, N, B):
        nb = min(B, N - i0)
        gather_rows(log_prob_init, i0, nb, log_prob)
        gather_modes(x_init, P_init, i0, nb, x, P)
        gather_transitions(transition, log_transition, i0, nb, pi, log_pi)
        for j in range(n_modes):
            for b in range(nb):
                prob[j, b] = math.exp(log_prob[j, b])
        for k in range(K):
            gather_samples(y, i0, nb, k, yl)
            observe(yl, nb, obs, n_obs)
            if k > 0 or predict_first:
                gather_samples(u, i0, nb, max(k - 1, 0), ul)
                if not sample_timing:  # "interval": interact, then predict
                    _interact(x, P, prob, log_prob, pi, log_pi, interaction, nb, log_c, w, xm,
                              Pm)
                _predict_modes(x, P, F, G, Qd, trans, i0, nb, k, ul, idx, Fl, Gl, Ql, AP, xs)
                if sample_timing:  # "sample": predict, then interact
                    _interact(x, P, prob, log_prob, pi, log_pi, interaction, nb, log_c, w, xm,
                              Pm)
            else:
                copy_rows(log_prob, log_c, nb)
            if k == 0 or out_index.shape[1] > 1:
                for j in range(n_modes):
                    lane_index(out_index, i0, nb, k, j, idx)
                    gather_matrices(C, idx, nb, Cl[j])
                    gather_matrices(R, idx, nb, Rl[j])
            for j in range(n_modes):
                status = innovation(x[j], P[j], yl, Cl[j], Rl[j], obs, n_obs, nb, e[j], PCt[j],
                                    chol[j], scale[j], z[j], nis[j], loglik[j], work, bad, report)
                if status != OK:
                    return status
            for b in range(nb):  # the gating decision, before anything changes
                top = -math.inf
                for j in range(n_modes):
                    use[j, b] = math.isfinite(loglik[j, b]) and nis[j, b] <= gate
                    a[j, b] = log_c[j, b] + loglik[j, b] if use[j, b] else -math.inf
                    top = max(top, a[j, b])
                flag[b] = ACCEPTED
                for j in range(n_modes):
                    if top == -math.inf:  # no mode can use it: the sample counts as missing
                        flag[b] = GATED
                        use[j, b] = False
                        a[j, b] = log_c[j, b]
                    elif not use[j, b]:
                        flag[b] = PARTLY_GATED
            for j in range(n_modes):
                correct(x[j], P[j], Cl[j], Rl[j], use[j], nb, PCt[j], chol[j], scale[j], z[j],
                        gain, T, AP, prior)
                if joseph_lost(P[j], prior, use[j], nb, root, lost):  # rare: lane by lane
                    information_or_repair(P[j], prior, Cl[j], Rl[j], obs, n_obs, lost, nb, report)
            log_normalize(a, prob, total, nb)  # log mu_j = log c_j + log Lambda_j, normalized
            copy_rows(a, log_prob, nb)
            report_sample(x, P, prob, log_prob, total, flag, n_obs, i0, nb, k, modes_wanted, xc,
                          Pc, best, x_out, P_out, prob_out, mode_out, loglik_out, flag_out,
                          x_modes_out, P_modes_out)
        scatter_rows(log_prob, i0, nb, log_prob_last)
        scatter_modes(x, P, i0, nb, x_last, P_last)
    return OK
