"""The compiled second-order generalized pseudo-Bayesian filter, GPB2 (Bar-Shalom, Li &
Kirubarajan 2001, §11.6.5).

The state of a trial after sample ``k - 1`` is one Gaussian per mode, ``N(x_i, P_i)`` with
probability ``mu_i``. Into sample ``k`` run ``L^2`` Kalman filters, one per pair (mode ``i``
at ``k - 1``, mode ``j`` at ``k``): predicted from mode ``i``'s Gaussian and updated with
``C[j]``, ``R[j]``, with probability ``mu_ij ∝ Lambda_ij pi_ij mu_i``. The prediction goes
through the transition of the mode that governs the interval into ``k`` (the ``timing``,
docs/conventions.rst): mode ``i``'s, ``trans[k, i]`` of the table ``F, G, Qd``, in the
``"sample"`` timing (the same for every ``j``: computed once per ``i``), mode ``j``'s,
``trans[k, j]``, in the ``"interval"`` timing (Bar-Shalom, Li & Kirubarajan §11.6.5). Each
mode's pairs are then merged into one Gaussian, ``mu_j = sum_i mu_ij``,
``mu_{i|j} = mu_ij / mu_j``,
``x_j = sum_i mu_{i|j} x_ij``, ``P_j = sum_i mu_{i|j} (P_ij + (x_ij - x_j)(x_ij - x_j)')``,
and the output is the moments of the mixture over ``j`` (as the IMM's). Sample 0 has only
the prior: ``L`` filters, mode ``j``'s from its prior Gaussian with probability ``mu_j(0)``
(the first sample of :func:`.bank.filter_bank`).

``gpb2_run`` filters every trial over every sample, ``gpb2_step`` one sample (the streaming
API); both run :func:`gpb2_bank` on the equations of :mod:`.linalg` (prediction, innovation,
Joseph-form correction with its information-form fallback, merging, combination), over
blocks of trials laid across SIMD lanes. Convention of switchest: ``transition[i, j]`` =
P(mode j at k+1 | mode i at k), passed as its logarithm; probabilities are log-weights.

Gating is decided pair by pair, as :func:`.bank.filter_bank` decides it mode by mode: a pair
whose normalized innovation squared exceeds the gate, or whose likelihood is not finite, is not
updated and gets weight 0 (``PARTLY_GATED``); a sample no pair can use counts as missing (no
update, ``mu_ij ∝ pi_ij mu_i``, log-likelihood 0, ``GATED``).
"""

from __future__ import annotations

import math

import numpy as np

from ..._checks import positive_int
from .arrays import check_gate, checked
from .bank import LANES, copy_rows, gather_transition, report_sample
from .imm import IMMOutput, is_sample_timing
from .linalg import (
    ACCEPTED,
    GATED,
    OK,
    PARTLY_GATED,
    borrow,
    copy_gaussian,
    correct,
    gather_matrices,
    gather_modes,
    gather_rows,
    gather_samples,
    information_or_repair,
    inline,
    innovation,
    jit,
    joseph_lost,
    log_normalize,
    merge,
    observe,
    predict,
    scatter_modes,
    scatter_rows,
)

__all__ = ["gpb2_bank", "gpb2_run", "gpb2_step"]


@jit
def _gate_pairs(prior, loglik, nis, gate, n_src, nb, use, a, flag):
    """The gating decision over every pair, before anything changes (as
    :func:`.bank.filter_bank` takes it over modes).

    ``use[j, i]``: pair ``(i, j)``'s likelihood is finite and its normalized innovation squared
    within ``gate``; ``a[j, i] = prior[j, i] + loglik[j, i]`` where used, ``-inf`` where not
    (``prior``: the log-weight ``log mu_i + log pi_ij`` before the measurement). If no pair
    has a finite ``a`` the sample counts as missing: no pair is used, ``a = prior``, flag
    ``GATED``; else the flag is ``PARTLY_GATED`` where a pair is not used. ``n_src`` sources per
    mode are in use (``L``, or 1 at the first sample).
    """
    n_modes = prior.shape[0]
    for b in range(nb):
        top = -math.inf
        for j in range(n_modes):
            for i in range(n_src):
                use[j, i, b] = math.isfinite(loglik[j, i, b]) and nis[j, i, b] <= gate
                a[j, i, b] = prior[j, i, b] + loglik[j, i, b] if use[j, i, b] else -math.inf
                top = max(top, a[j, i, b])
        flag[b] = ACCEPTED
        for j in range(n_modes):
            for i in range(n_src):
                if top == -math.inf:  # no pair can use it: the sample counts as missing
                    flag[b] = GATED
                    use[j, i, b] = False
                    a[j, i, b] = prior[j, i, b]
                elif not use[j, i, b]:
                    flag[b] = PARTLY_GATED


@borrow
def _merge_weights(a, prior, nb, log_mu, w):
    """Mode ``j``'s merging weights over its ``L`` pairs, per lane, and its log-weight.

    ``log_mu[b] = log sum_i exp(a[i, b])`` (``a``: the pairs' log-weights ``log mu_ij``, up to
    a common constant) and ``w[i, b] = mu_{i|j} = exp(a[i, b] - log_mu[b])``
    (Bar-Shalom, Li & Kirubarajan §11.6.5). A mode whose pairs all have weight 0 (every one
    gated) is merged with the weights the pairs had before the measurement, ``prior``, and
    one that had none either (unreachable) with equal weights: its probability is 0 and its
    Gaussian only needs to be finite.
    """
    n_src = a.shape[0]
    for b in range(nb):
        log_mu[b] = _log_sum_exp(a, b)
        ref = log_mu[b]
        if ref == -math.inf:
            ref = _log_sum_exp(prior, b)
            source = prior
        else:
            source = a
        for i in range(n_src):
            w[i, b] = math.exp(source[i, b] - ref) if ref > -math.inf else 1.0 / n_src


@inline
def _log_sum_exp(a, b):
    """``log sum_i exp(a[i, b])``, ``-inf`` when every term is ``-inf``."""
    top = -math.inf
    for i in range(a.shape[0]):
        top = max(top, a[i, b])
    if top == -math.inf:
        return -math.inf
    acc = 0.0
    for i in range(a.shape[0]):
        acc += math.exp(a[i, b] - top)
    return top + math.log(acc)


@jit
def gpb2_bank(y, u, F, G, Qd, trans, C, R, log_transition, x_init, P_init, log_prob_init,
              sample_timing, predict_first, gate, lanes, x_out, P_out, prob_out, mode_out,
              loglik_out, flag_out, x_modes_out, P_modes_out, x_last, P_last, log_prob_last,
              report):
    """GPB2 over ``N`` trials and ``K`` samples (Bar-Shalom, Li & Kirubarajan §11.6.5).

    Parameters
    ----------
    y, u, F, G, Qd, trans
        As in :func:`.bank.filter_bank`: measurements ``(N, K, m)`` (NaN components missing),
        inputs ``(N, K, l)`` (``u[:, k-1]`` held over the interval into sample ``k``), the
        table of exact transitions and ``trans (N or 1, K, L)``, the transition of mode ``j``
        into sample ``k``.
    C, R : (L, m, n), (L, m, m) float64
        Output matrix and measurement-noise covariance of each mode.
    log_transition : (L, L) float64
        ``log transition[i, j]``, ``-inf`` for an impossible switch.
    x_init, P_init, log_prob_init : (N, L, n), (N, L, n, n), (N, L) float64
        The merged Gaussian and log-probability of each mode before the first sample.
    sample_timing : bool
        Which transition the pair (``i`` at ``k - 1``, ``j`` at ``k``) is predicted through:
        mode ``i``'s, ``trans[k, i]`` (True: the ``"sample"`` timing; one prediction per
        ``i``, copied to its ``L`` pairs), or mode ``j``'s, ``trans[k, j]`` (False: the
        ``"interval"`` timing, Bar-Shalom, Li & Kirubarajan §11.6.5).
    predict_first : bool
        Whether the first sample is predicted into through the ``L^2`` pairs (a streaming step)
        or only updated, ``L`` filters (the start of a record).
    gate : float
        Largest normalized innovation squared a pair accepts.
    lanes : int
        Trials per block (the results do not depend on it).
    x_out, P_out, prob_out, mode_out, loglik_out, flag_out
        Written as by :func:`.bank.filter_bank`: combined estimate, mode probabilities
        ``mu_j``, most probable mode, log-likelihood ``log sum_ij exp(a_ij)`` (0 when nothing
        was observed or the sample was gated) and flag.
    x_modes_out, P_modes_out
        Written when their first axis has length ``N`` (zero-size arrays otherwise): the merged
        Gaussians ``x_j``, ``P_j`` after each sample, ``(N, K, L, n)``, ``(N, K, L, n, n)``.
    x_last, P_last, log_prob_last
        Written: the merged state after the last sample, shaped as ``x_init`` etc.
    report : (2,) float64
        Written: covariances repaired and the smallest eigenvalue one had (``inf`` if none).

    Returns
    -------
    status : int
        ``OK`` or the failure code of the innovation covariance that stopped the kernel.
    """
    N, K, m = y.shape
    n_modes, n = x_init.shape[1], x_init.shape[2]
    n_in = u.shape[2]
    B = lanes
    x, P = np.empty((n_modes, n, B)), np.empty((n_modes, n, n, B))
    log_prob, prob = np.empty((n_modes, B)), np.empty((n_modes, B))
    xp, Pp = np.empty((n_modes, n_modes, n, B)), np.empty((n_modes, n_modes, n, n, B))
    Fl, Gl, Ql = np.empty((n, n, B)), np.empty((n, n_in, B)), np.empty((n, n, B))
    Cl, Rl = np.empty((n_modes, m, n, B)), np.empty((n_modes, m, m, B))
    idx = np.empty(B, dtype=np.int64)
    yl, ul, obs, n_obs = np.empty((m, B)), np.empty((n_in, B)), np.empty((m, B)), np.empty(B)
    shape = (n_modes, n_modes, m, B)
    e, z, scale = np.empty(shape), np.empty(shape), np.empty(shape)
    PCt = np.empty((n_modes, n_modes, n, m, B))
    chol = np.empty((n_modes, n_modes, m, m, B))
    nis, loglik = np.empty((n_modes, n_modes, B)), np.empty((n_modes, n_modes, B))
    prior_w, a = np.empty((n_modes, n_modes, B)), np.empty((n_modes, n_modes, B))
    use = np.empty((n_modes, n_modes, B), dtype=np.bool_)
    w, log_mu, work = np.empty((n_modes, B)), np.empty((n_modes, B)), np.empty((3, B))
    gain, T = np.empty((n, m, B)), np.empty((n, m, B))
    AP, xs = np.empty((n, n, B)), np.empty((n, B))
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
        for j in range(n_modes):
            for b in range(nb):
                idx[b] = j
            gather_matrices(C, idx, nb, Cl[j])
            gather_matrices(R, idx, nb, Rl[j])
        for k in range(K):
            gather_samples(y, i0, nb, k, yl)
            observe(yl, nb, obs, n_obs)
            paired = k > 0 or predict_first
            n_src = n_modes if paired else 1  # sources per mode: the modes at k-1, or the prior
            if paired:
                gather_samples(u, i0, nb, max(k - 1, 0), ul)
                if sample_timing:  # x_i(k|k-1) through mode i's transition, once per i
                    for i in range(n_modes):
                        gather_transition(F, G, Qd, trans, i0, nb, k, i, idx, Fl, Gl, Ql)
                        predict(x[i], P[i], Fl, Gl, ul, Ql, nb, AP, xs)
                for j in range(n_modes):
                    if not sample_timing:  # every pair into j through mode j's transition
                        gather_transition(F, G, Qd, trans, i0, nb, k, j, idx, Fl, Gl, Ql)
                    for i in range(n_modes):  # pair (i at k-1, j at k): log mu_i + log pi_ij
                        copy_gaussian(x[i], P[i], nb, xp[j, i], Pp[j, i])
                        if not sample_timing:
                            predict(xp[j, i], Pp[j, i], Fl, Gl, ul, Ql, nb, AP, xs)
                        for b in range(nb):
                            prior_w[j, i, b] = log_prob[i, b] + log_transition[i, j]
            else:
                for j in range(n_modes):  # the prior of mode j: log mu_j(0)
                    copy_gaussian(x[j], P[j], nb, xp[j, 0], Pp[j, 0])
                    for b in range(nb):
                        prior_w[j, 0, b] = log_prob[j, b]
            for j in range(n_modes):
                for i in range(n_src):
                    status = innovation(xp[j, i], Pp[j, i], yl, Cl[j], Rl[j], obs, n_obs, nb,
                                        e[j, i], PCt[j, i], chol[j, i], scale[j, i], z[j, i],
                                        nis[j, i], loglik[j, i], work, bad, report)
                    if status != OK:
                        return status
            _gate_pairs(prior_w, loglik, nis, gate, n_src, nb, use, a, flag)
            for j in range(n_modes):
                for i in range(n_src):  # a_ij = log mu_i + log pi_ij + log Lambda_ij
                    correct(xp[j, i], Pp[j, i], Cl[j], Rl[j], use[j, i], nb, PCt[j, i],
                            chol[j, i], scale[j, i], z[j, i], gain, T, AP, prior)
                    if joseph_lost(Pp[j, i], prior, use[j, i], nb, root, lost):  # rare
                        information_or_repair(Pp[j, i], prior, Cl[j], Rl[j], obs, n_obs, lost,
                                              nb, report)
            for j in range(n_modes):  # mu_j = sum_i mu_ij, x_j, P_j: the moments over i
                if paired:
                    _merge_weights(a[j], prior_w[j], nb, log_mu[j], w)
                    merge(w, xp[j], Pp[j], nb, x[j], P[j])
                else:
                    for b in range(nb):
                        log_mu[j, b] = a[j, 0, b]
                    copy_gaussian(xp[j, 0], Pp[j, 0], nb, x[j], P[j])
            log_normalize(log_mu, prob, total, nb)
            copy_rows(log_mu, log_prob, nb)
            report_sample(x, P, prob, log_prob, total, flag, n_obs, i0, nb, k, modes_wanted, xc,
                          Pc, best, x_out, P_out, prob_out, mode_out, loglik_out, flag_out,
                          x_modes_out, P_modes_out)
        scatter_rows(log_prob, i0, nb, log_prob_last)
        scatter_modes(x, P, i0, nb, x_last, P_last)
    return OK


def gpb2_run(y, u, F, G, Qd, trans, C, R, log_transition, x0, P0, log_prob0, *,
             gate=math.inf, lanes: int = LANES, timing: str = "interval",
             modes_out: bool = False) -> IMMOutput:
    """GPB2 filter of ``N`` trials over ``K`` samples (Bar-Shalom, Li & Kirubarajan §11.6.5).

    Arguments as :func:`.imm.imm_run` (``trans (K, L)``: the transition of mode ``j`` into
    sample ``k``, row 0 unused; ``x0, P0``: the prior of every mode at the first sample;
    ``timing``: the pair (``i``, ``j``) predicts through mode ``i``'s transition in the
    ``"sample"`` timing, through mode ``j``'s in the ``"interval"`` timing).
    Returns the combined estimate, ``mu_j``, the most probable mode, the log-likelihood and the
    flags as an :class:`.imm.IMMOutput`, with the merged Gaussians ``x_j``, ``P_j`` after each
    sample if ``modes_out``.
    """
    sizes: dict[str, int] = {}
    y, u, F, G, Qd, C, trans, R, log_transition, x0, P0, log_prob0 = checked(
        sizes, "y:NKm u:NKl F:Mnn G:Mnl Qd:Mnn C:Lmn trans:KL<M R:Lmm log_transition:LL x0:n "
        "P0:nn log_prob0:L", y, u, F, G, Qd, C, trans, R, log_transition, x0, P0, log_prob0)
    N, L = sizes["N"], sizes["L"]
    output, _ = _gpb2(y, u, F, G, Qd, trans[None], C, R, log_transition,
                      np.tile(x0, (N, L, 1)), np.tile(P0, (N, L, 1, 1)),
                      np.tile(log_prob0, (N, 1)), is_sample_timing(timing), False,
                      check_gate(gate), positive_int(lanes, "lanes"), bool(modes_out))
    return output


def gpb2_step(x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition, *,
              predict_first: bool, gate=math.inf,
              timing: str = "interval") -> tuple[IMMOutput, tuple[np.ndarray, ...]]:
    """One sample of every trial: the ``L^2`` pairs predicted (in the ``timing`` of
    :func:`gpb2_run`) and updated, then merged (when ``predict_first``; else the ``L`` modes
    updated), as :func:`.imm.imm_step`.

    ``x (N, L, n)``, ``P (N, L, n, n)``, ``log_prob (N, L)`` are the merged Gaussians and log
    mode probabilities at the previous sample, ``y (N, m)``, ``u (N, l)``, ``trans (L,)`` the
    transition of each mode into this sample. Returns the :class:`.imm.IMMOutput` of this
    sample (a sample axis of length 1) and the state ``(x, P, log_prob)`` after it.
    """
    sizes: dict[str, int] = {}
    x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition = checked(
        sizes, "x:NLn P:NLnn log_prob:NL y:Nm u:Nl F:Mnn G:Mnl Qd:Mnn trans:L<M C:Lmn R:Lmm "
        "log_transition:LL", x, P, log_prob, y, u, F, G, Qd, trans, C, R, log_transition)
    return _gpb2(y[:, None], u[:, None], F, G, Qd, trans[None, None], C, R, log_transition,
                 x, P, log_prob, is_sample_timing(timing), bool(predict_first),
                 check_gate(gate), LANES, False)


def _gpb2(y, u, F, G, Qd, trans, C, R, log_transition, x_init, P_init, log_prob_init,
          sample_timing, predict_first, gate, lanes, modes_out):
    """:func:`gpb2_bank` on checked arrays: the :class:`.imm.IMMOutput` and the merged state
    ``(x, P, log_prob)`` after the last sample."""
    N, K, _ = y.shape
    L, n = x_init.shape[1], x_init.shape[2]
    x, P = np.empty((N, K, n)), np.empty((N, K, n, n))
    prob, mode = np.empty((N, K, L)), np.empty((N, K), dtype=np.int64)
    loglik, flag = np.empty((N, K)), np.empty((N, K), dtype=np.uint8)
    size = (N, K, L) if modes_out else (0, 0, 0)  # zero-size: not written
    x_modes, P_modes = np.empty((*size, n)), np.empty((*size, n, n))
    last = np.empty_like(x_init), np.empty_like(P_init), np.empty_like(log_prob_init)
    report = np.empty(2)
    status = gpb2_bank(y, u, F, G, Qd, trans, C, R, log_transition, x_init, P_init,
                       log_prob_init, sample_timing, predict_first, gate, lanes, x, P, prob,
                       mode, loglik, flag, x_modes, P_modes, *last, report)
    modes = (x_modes, P_modes) if modes_out else (None, None)
    return (IMMOutput(x, P, prob, mode, loglik, flag, int(status), int(report[0]),
                      float(report[1]), *modes), last)
