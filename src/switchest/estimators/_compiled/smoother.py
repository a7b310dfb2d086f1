"""The compiled backward pass of the fixed-interval smoother with mode probabilities.

Kim (1994, J. Econometrics 60, "Dynamic linear models with Markov-switching", §2.2), as applied
to collapsed (GPB2 / IMM) filters by Murphy (1998, "Switching Kalman filters", tech. report,
§3-4): from the filtered mode-matched posteriors ``x_j(k|k)``, ``P_j(k|k)`` and probabilities
``mu_j(k|k)``, for ``k = K-2 .. 0`` and every pair (mode ``j`` at ``k``, mode ``i`` at ``k+1``),

- the Rauch-Tung-Striebel step (Rauch, Tung & Striebel 1965) of ``x_j(k|k)`` towards
  ``x_i(k+1|K)``, ``P_i(k+1|K)`` through the transition of the interval ``k -> k+1`` of the
  mode that governs it, the *moving* mode ``m`` (table entry ``trans[k+1, m]``):
  ``x_ji = x_j + J (x_i(k+1|K) - x_pred)``, ``P_ji = P_j + J (P_i(k+1|K) - P_pred) J'``,
  ``x_pred = F_m x_j + G_m u_k``, ``P_pred = F_m P_j F_m' + Qd_m``, ``J = P_j F_m' P_pred^-1``,
  with

  - ``m = j`` in the ``"sample"`` timing (switchest's: the mode of sample ``k`` governs ``y_k``
    and the interval after it, ``x_{k+1} = F(s_k) x_k + G(s_k) u_k + w_k``; Costa, Fragoso &
    Marques 2005, "Discrete-Time Markov Jump Linear Systems", eq. (3.1)): ``x_pred``,
    ``P_pred``, its factorization and ``J`` do not depend on ``i`` and are computed once per
    ``j``, ``L`` of them per sample instead of ``L^2``;
  - ``m = i`` in the ``"interval"`` timing (Bar-Shalom, Li & Kirubarajan 2001, §11.6, and Kim's
    own model, 1994 §2, where the mode of sample ``k+1`` governs the step into it): once per
    pair;
- the pair's probability ``mu_ji(k|K) = mu_i(k+1|K) mu_j(k|k) pi_ji / c_i`` with
  ``c_i = sum_j' mu_j'(k|k) pi_j'i`` (Kim 1994 §2.2; log domain, a pair whose ``c_i`` is zero
  gets weight zero);
- the merge over ``i``: ``mu_j(k|K) = sum_i mu_ji``, ``x_j(k|K) = sum_i (mu_ji / mu_j) x_ji``,
  ``P_j(k|K) = sum_i (mu_ji / mu_j) (P_ji + (x_ji - x_j)(x_ji - x_j)')`` (Kim 1994 §2.2;
  Murphy 1998 §4), and the combined output, the moments of the mixture over ``j``
  (:func:`.linalg.combine`).

At ``k = K-1`` the smoothed posterior is the filtered one.

Why the moving mode. Kim's step approximates ``p(x_k | s_k = j, s_{k+1} = i, Y)`` by
conditioning mode ``j``'s filtered Gaussian on ``x_{k+1}`` and averaging over
``x_{k+1} ~ N(x_i(k+1|K), P_i(k+1|K))``: given ``x_{k+1}`` and the modes the later
measurements say nothing more of ``x_k`` (Kim 1994 §2.2), and the chain is independent of the
state, so ``p(x_k | x_{k+1}, s_k = j, s_{k+1} = i, Y_k) ∝ p(x_{k+1} | x_k, s_k = j,
s_{k+1} = i) p(x_k | s_k = j, Y_k)``. In the ``"sample"`` timing ``x_{k+1}`` depends on
``s_k``, not on ``s_{k+1}``: ``p(x_{k+1} | x_k, s_k = j) = N(F_j x_k + G_j u_k, Qd_j)``, so
the step conditions on ``x_{k+1}`` through ``F_j``; in the ``"interval"`` timing through
``F_i``. The pair probabilities (Kim's ``P(s_k = j | s_{k+1} = i, Y) ~ P(s_k = j | s_{k+1} = i,
y_0..k) = mu_j(k|k) pi_ji / c_i``) and the merges do not involve the state equation: they are
the same in both timings. With one mode the two timings are one smoother.

On request (``lagged``, ``"interval"`` timing or one mode) the pass also reports, for each
interval ``k -> k+1``, what the expectation step of maximum-likelihood fitting needs (Shumway &
Stoffer 1982, J. Time Series Anal. 3, eqs (9)-(12); Kim 1994 §2.2 for the mode pairs): the
pairwise probabilities ``mu_ji(k|K) = P(r_k = j, r_{k+1} = i | Y)`` above, and the moments of
``x_k`` given ``r_{k+1} = i`` (the mode that governs the interval in that timing) and the
record: the mixture over ``j`` (weights ``P(r_k = j | r_{k+1} = i, y_0..k)``, Kim's
approximation) of the pairs' ``x_ji``, ``P_ji``, and the lag-one cross-covariance
``Cov(x_{k+1}, x_k | r_{k+1} = i, Y) = P_i(k+1|K) Jbar_i'`` with ``Jbar_i`` the weighted mean
of the pairs' gains (de Jong & MacKinnon 1988, Econometric Theory 4,
``P_{k+1,k|K} = P_{k+1|K} J_k'``; with one mode it is exactly that formula). The weighted
covariance of the pairs' means is accumulated by West's incremental rule (West 1979, Comm. ACM
22) so that no second moment is differenced. In the ``"sample"`` timing with several modes the
interval's mode is ``r_k``, and the moments fitting would need are those given ``r_k``, of
``x_{k+1}`` as well as ``x_k``: they are not computed, and ``lagged`` is refused there.

Each pair's RTS step is taken in its direct form, in two halves: :func:`rts_gain`, once per
moving mode, predicts (``P_pred`` from the filters' :func:`.linalg.predict`), factors ``P_pred``
(its equilibrated Cholesky factor, :func:`.linalg.factor`) and solves for the rows of ``J``
(:func:`.linalg.solve_rows`); :func:`rts_pair`, once per pair, forms ``x_ji = x_j + J e`` and
``P_ji = P_j + J (P_i(k+1|K) - P_pred) J'`` (its upper triangle, mirrored): about half the
loops of the form below. The lanes that form cannot take, a ``P_pred`` that does not factor or
a ``P_ji`` that lost its digits (:func:`.linalg.joseph_lost` against ``P_j``), are redone in
the form below, so degenerate cases are handled as they always were: its conditional
(:func:`rts_joseph`) is again taken once per moving mode (in the ``"sample"`` timing for the
lanes any pair ``(j, .)`` needs), and finished per pair by :func:`rts_pair`. A pair of weight
zero in every lane of a block is not computed.

That form is a Kalman update of ``x_j(k|k)`` by the pseudo-measurement
``x_{k+1} = F_m x_k + G_m u_k + w``, ``w ~ N(0, Qd_m)``: conditioned on ``x_{k+1}`` the state
is Gaussian with mean ``x_j + J (x_{k+1} - x_pred)`` and covariance
``P_j - J P_pred J' = (I - J F_m) P_j (I - J F_m)' + J Qd_m J'`` (Joseph's form), the same for
every value of ``x_{k+1}``; averaging over ``x_{k+1} ~ N(x_i(k+1|K), P_i(k+1|K))`` adds
``J P_i(k+1|K) J'`` (Särkkä 2013, "Bayesian Filtering and Smoothing", the derivation of the RTS
smoother, Theorem 8.2). So :func:`rts_joseph` runs the filters' own update,
:func:`.linalg.innovation` and :func:`.linalg.correct` with ``C = F_m``, ``R = Qd_m``, and
:func:`rts_pair` adds ``J P_i(k+1|K) J'`` (its ``P_pred`` replaced by zero): the covariance is
a sum of two positive semidefinite terms, symmetric by construction; no second Kalman update,
no difference of covariances that could turn indefinite.

``P_pred`` is factored there by :func:`.linalg.innovation` as the innovation covariance of a
measurement of ``x_pred`` (``C = I``, ``R = 0``: ``S = P_pred``), never inverted. Where it is
singular to working precision (``Qd_m = 0`` with a singular ``F_m``: a state reset, a
deterministic component) that function's rule applies: its eigenvalues are raised to its
rounding level (:func:`.linalg.repair`, counted for the caller's warning) and it is factored
again. The gain ``J`` then annihilates the directions ``P_pred`` cannot reach (the columns of
``P_j F_m'`` vanish there) up to rounding, as a pseudo-inverse would, and Joseph's form keeps
the covariance positive semidefinite for that gain; a conditional covariance that loses its
digits (``Qd_m = 0`` with an invertible ``F_m``: ``x_k`` determined by ``x_{k+1}``) is taken in
information form or repaired (:func:`.linalg.joseph_lost`,
:func:`.linalg.information_or_repair`), as in the filters.

Trials are processed in blocks of ``lanes`` laid across SIMD lanes (:mod:`.linalg`); the
results do not depend on the block size.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..._checks import check_timing, positive_int
from .arrays import checked
from .bank import lane_index
from .linalg import (
    NOT_FINITE,
    OK,
    borrow,
    combine,
    copy_gaussian,
    copy_lanes,
    correct,
    factor,
    gather_matrices,
    gather_modes,
    gather_rows,
    gather_samples,
    information_or_repair,
    innovation,
    jit,
    joseph_lost,
    log_normalize,
    predict,
    scatter_modes,
    scatter_rows,
    solve_rows,
    symmetric_sum,
    write_lane,
)

__all__ = ["KimOutput", "kim_smooth", "screen_psd", "LANES"]

LANES = 64  # trials per block: the backward pass runs ~500 short loops over the lanes per pair,
# each with a fixed cost (alias checks, remainders); at 16 lanes (the filters' block) that cost
# doubled its time on the vehicle (n = 4, L = 3), at 64 and 128 it is amortized


class KimOutput(NamedTuple):
    """The smoothed posteriors of every trial and sample (:func:`kim_smooth`).

    Attributes
    ----------
    x, P : ndarray, shapes (N, K, n), (N, K, n, n)
        Combined smoothed estimate: the moments of the mixture of the mode-matched ones.
    mode_prob : ndarray, shape (N, K, L)
        Smoothed mode probabilities ``mu_j(k|K)``.
    mode : ndarray of int64, shape (N, K)
        Most probable smoothed mode (the first on a tie).
    x_modes, P_modes : ndarray, shapes (N, K, L, n), (N, K, L, n, n)
        Mode-matched smoothed posteriors ``x_j(k|K)``, ``P_j(k|K)``; a mode of smoothed
        probability zero keeps its filtered posterior.
    status : int
        ``linalg.OK`` or the failure code that stopped the kernel (outputs then incomplete).
    repaired : int
        How many covariances were repaired to their rounding level (:func:`.linalg.repair`).
    smallest_eigenvalue : float
        The smallest eigenvalue a repaired covariance had (``inf`` if none was).
    pair_prob : ndarray, shape (N, K-1, L, L), or None
        With ``lagged``: ``pair_prob[:, k, j, i] = mu_ji(k|K) = P(r_k = j, r_{k+1} = i | Y)``.
    lag_x, lag_P : ndarray, shapes (N, K-1, L, n), (N, K-1, L, n, n), or None
        With ``lagged``: mean and covariance of ``x_k`` given ``r_{k+1} = i`` and the record.
    lag_cross : ndarray, shape (N, K-1, L, n, n), or None
        With ``lagged``: ``Cov(x_{k+1}, x_k | r_{k+1} = i, Y)``, the lag-one cross-covariance.
    """

    x: np.ndarray
    P: np.ndarray
    mode_prob: np.ndarray
    mode: np.ndarray
    x_modes: np.ndarray
    P_modes: np.ndarray
    status: int
    repaired: int = 0
    smallest_eigenvalue: float = math.inf
    pair_prob: np.ndarray | None = None
    lag_x: np.ndarray | None = None
    lag_P: np.ndarray | None = None
    lag_cross: np.ndarray | None = None


def kim_smooth(x_modes, P_modes, log_prob, u, F, G, Qd, trans, log_transition, *,
               timing: str = "interval", lanes: int = LANES, lagged: bool = False,
               modes_out: bool = True) -> KimOutput:
    """Kim's fixed-interval smoother of ``N`` trials over ``K`` samples (module docstring).

    Parameters
    ----------
    x_modes, P_modes : array_like, shapes (N, K, L, n), (N, K, L, n, n)
        Filtered mode-matched posteriors after each sample's measurement update.
    log_prob : array_like, shape (N, K, L)
        Log filtered mode probabilities (``-inf`` for probability zero), normalized again
        here (log-sum-exp) against rounding.
    u : array_like, shape (N, K, l)
        Inputs; ``u[:, k]`` is held over the interval into sample ``k + 1``.
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        Table of exact transitions.
    trans : array_like of int, shape (N or 1, K, L)
        ``trans[., k + 1, j]``: the transition of mode ``j`` over the interval into sample
        ``k + 1`` (shared by all trials when the first axis has length 1; row 0 unused).
    log_transition : array_like, shape (L, L)
        ``log transition[i, j]`` = log P(mode j at k+1 | mode i at k), ``-inf`` if impossible.
    timing : {"sample", "interval"}
        Which mode's transition the pair (mode ``j`` at ``k``, mode ``i`` at ``k + 1``) takes
        its RTS step through: ``j``'s (``"sample"``) or ``i``'s (``"interval"``).
    lanes : int
        Trials per SIMD block (the results do not depend on it).
    lagged : bool
        Also report the pairwise mode probabilities and the lag-one moments of each interval
        (``pair_prob``, ``lag_x``, ``lag_P``, ``lag_cross``; module docstring); in the
        ``"interval"`` timing or with one mode only (a ``ValueError`` otherwise).
    modes_out : bool
        Whether to report the smoothed mode-matched posteriors (``x_modes``, ``P_modes``;
        None otherwise, and their writing is saved).
    """
    timing = check_timing(timing)
    sizes: dict[str, int] = {}
    x_modes, P_modes, log_prob, u, F, G, Qd, log_transition = checked(
        sizes, "x_modes:NKLn P_modes:NKLnn log_prob:NKL u:NKl F:Mnn G:Mnl Qd:Mnn "
        "log_transition:LL", x_modes, P_modes, log_prob, u, F, G, Qd, log_transition)
    (trans,) = checked(sizes, "trans:TKL<M", trans)
    N, K, L, n = x_modes.shape
    if sizes["T"] not in (1, N):
        raise ValueError(f"trans must have shape (N or 1, K, L) = ({N} or 1, {K}, {L}), "
                         f"got {trans.shape}")
    if lagged and timing == "sample" and L > 1:
        raise ValueError(
            "lagged moments are defined for timing='interval' (given the mode of sample k+1, "
            "which governs the interval k -> k+1 there) or one mode, got timing='sample' with "
            f"L = {L} modes")
    size = (N, K, L) if modes_out else (0, K, L)  # zero trials: the kernel writes none
    out = KimOutput(np.empty((N, K, n)), np.empty((N, K, n, n)), np.empty((N, K, L)),
                    np.empty((N, K), dtype=np.int64), np.empty((*size, n)),
                    np.empty((*size, n, n)), OK)
    report = np.empty(2)
    J = K - 1 if lagged else 0  # intervals reported (none unless asked)
    lag = (np.zeros((N, J, L, L)), np.zeros((N, J, L, n)), np.zeros((N, J, L, n, n)),
           np.zeros((N, J, L, n, n)))
    status = kim_backward(x_modes, P_modes, log_prob, u, F, G, Qd, trans, log_transition,
                          positive_int(lanes, "lanes"), timing == "sample", out.x, out.P,
                          out.mode_prob, out.mode, out.x_modes, out.P_modes, report,
                          bool(lagged), *lag)
    out = out._replace(status=int(status), repaired=int(report[0]),
                       smallest_eigenvalue=float(report[1]))
    if not modes_out:
        out = out._replace(x_modes=None, P_modes=None)
    return out._replace(pair_prob=lag[0], lag_x=lag[1], lag_P=lag[2],
                        lag_cross=lag[3]) if lagged else out


@jit
def kim_backward(x_f, P_f, log_prob_f, u, F, G, Qd, trans, log_transition, lanes,
                 sample_timing, x_out, P_out, prob_out, mode_out, x_s, P_s, report, lagged,
                 pair_out, lag_x, lag_P, lag_cross):
    """The backward recursion over every trial, in blocks of ``lanes`` trials.

    Arguments as :func:`kim_smooth` (checked there; ``sample_timing`` true for the
    ``"sample"`` timing); written: the combined ``x_out``, ``P_out``, ``prob_out``,
    ``mode_out`` and the mode-matched ``x_s``, ``P_s`` (shapes of :class:`KimOutput`),
    ``report`` ``[repairs, smallest eigenvalue]`` and, when ``lagged``, ``pair_out``,
    ``lag_x``, ``lag_P``, ``lag_cross`` (:class:`KimOutput`). Returns ``OK`` or the failure
    code of a predicted covariance that could not be factored even repaired.
    """
    N, K, L, n = x_f.shape
    n_in, B = u.shape[2], lanes
    xf, Pf = np.empty((L, n, B)), np.empty((L, n, n, B))  # filtered at k
    xn, Pn = np.empty((L, n, B)), np.empty((L, n, n, B))  # smoothed at k + 1
    xk, Pk = np.empty((L, n, B)), np.empty((L, n, n, B))  # smoothed at k
    lpf, lpn, lpk = np.empty((L, B)), np.empty((L, B)), np.empty((L, B))
    prob = np.empty((L, B))
    back = np.empty((L, L, B))  # back[i, j] = log P(r_k = j | r_{k+1} = i, y_0..k)
    x_pair, P_pair = np.empty((L, n, B)), np.empty((L, n, n, B))
    gain_pair = np.empty((L, n, n, B))  # each pair's J (read when lagged)
    redo = np.zeros((L, B), dtype=np.bool_)  # redo[i]: lanes of pair (j, i) for Joseph's form
    log_w, w = np.empty((L, B)), np.empty((L, B))
    total, best, idx = np.empty(B), np.empty(B, dtype=np.int64), np.empty(B, dtype=np.int64)
    xc, Pc, ul = np.empty((n, B)), np.empty((n, n, B)), np.empty((n_in, B))
    Fl, Gl, Ql = np.empty((L, n, n, B)), np.empty((L, n, n_in, B)), np.empty((L, n, n, B))
    # the direct form's prediction and gain of the moving mode (rts_gain)
    xp, Pp, gain = np.empty((n, B)), np.empty((n, n, B)), np.empty((n, n, B))
    failed, use = np.zeros(B, dtype=np.bool_), np.ones(B, dtype=np.bool_)
    scratch, joseph, pair = gain_scratch(n, B), joseph_scratch(n, B), pair_scratch(n, B)
    root, lost = scratch[5], joseph[16]
    # Joseph's form (_redo): the conditional's x_pred, covariance and gain, a pair's x, P, and
    # the lanes it is taken in
    conditional = (np.empty((n, B)), np.empty((n, n, B)), np.empty((n, n, B)), np.empty((n, B)),
                   np.empty((n, n, B)), np.zeros(B, dtype=np.bool_))
    acc_w, acc_x = np.empty((L, B)), np.empty((L, n, B))  # per mode i at k + 1: weight, mean,
    acc_M, acc_P, acc_J = (np.empty((L, n, n, B)), np.empty((L, n, n, B)),  # scatter of the
                           np.empty((L, n, n, B)))  # pairs' x_ji, mean P_ji and mean gain
    delta = np.empty(n)
    report[0], report[1] = 0.0, math.inf
    for i0 in range(0, N, B):
        nb = min(B, N - i0)
        gather_modes(x_f[:, K - 1], P_f[:, K - 1], i0, nb, xn, Pn)  # smoothed = filtered
        gather_rows(log_prob_f[:, K - 1], i0, nb, lpn)
        log_normalize(lpn, prob, total, nb)
        _write(xn, Pn, prob, lpn, i0, nb, K - 1, xc, Pc, best, x_out, P_out, prob_out,
               mode_out, x_s, P_s)
        for k in range(K - 2, -1, -1):
            gather_modes(x_f[:, k], P_f[:, k], i0, nb, xf, Pf)
            gather_rows(log_prob_f[:, k], i0, nb, lpf)
            log_normalize(lpf, prob, total, nb)
            gather_samples(u, i0, nb, k, ul)
            for i in range(L):  # log mu_j(k|k) pi_ji - log c_i, normalized over j
                for j in range(L):
                    for b in range(nb):
                        back[i, j, b] = lpf[j, b] + log_transition[j, i]
                log_normalize(back[i], prob, total, nb)
            if lagged:
                acc_w[:] = 0.0
                acc_x[:] = 0.0
                acc_M[:] = 0.0
                acc_P[:] = 0.0
                acc_J[:] = 0.0
            for m in range(L):  # each mode's transition into k + 1
                lane_index(trans, i0, nb, k + 1, m, idx)
                gather_matrices(F, idx, nb, Fl[m])
                gather_matrices(G, idx, nb, Gl[m])
                gather_matrices(Qd, idx, nb, Ql[m])
            for j in range(L):
                ready = False  # "sample": mode j's prediction and gain, shared by the pairs (j, .)
                for i in range(L):
                    for b in range(nb):  # log mu_ji(k|K) = log mu_i(k+1|K) + back[i, j]
                        log_w[i, b] = lpn[i, b] + back[i, j, b]
                    if _impossible(lpn[i], back[i, j], nb):  # weight 0 in every lane
                        _copy_pair(xf[j], Pf[j], nb, x_pair[i], P_pair[i], gain_pair[i])
                        _clear(redo[i], nb)
                        continue
                    if not ready:
                        m = j if sample_timing else i  # the mode that governs k -> k+1
                        status = rts_gain(xf[j], Pf[j], Fl[m], Gl[m], ul, Ql[m], nb, xp, Pp,
                                          gain, failed, scratch)
                        if status != OK:
                            return status
                        ready = sample_timing
                    rts_pair(xf[j], xp, Pf[j], Pp, gain, xn[i], Pn[i], nb, x_pair[i],
                             P_pair[i], pair)
                    joseph_lost(P_pair[i], Pf[j], use, nb, root, lost)
                    for b in range(nb):  # P_pred not factored, or P_ji lost its digits
                        redo[i, b] = failed[b] or lost[b]
                    if lagged:
                        copy_lanes(gain, nb, gain_pair[i])
                    if not sample_timing and _any(redo[i], nb):  # Joseph's form, through F_i
                        status = _redo(xf[j], Pf[j], Fl[i], Gl[i], ul, Ql[i], xn, Pn, redo, i,
                                       i + 1, nb, x_pair, P_pair, gain_pair, report,
                                       conditional, joseph, pair)
                        if status != OK:
                            return status
                if sample_timing:  # Joseph's form through F_j, once for every pair (j, .)
                    status = _redo(xf[j], Pf[j], Fl[j], Gl[j], ul, Ql[j], xn, Pn, redo, 0, L,
                                   nb, x_pair, P_pair, gain_pair, report, conditional, joseph,
                                   pair)
                    if status != OK:
                        return status
                if lagged:
                    for i in range(L):
                        _accumulate(x_pair[i], P_pair[i], gain_pair[i], back[i, j], nb,
                                    acc_w[i], acc_x[i], acc_M[i], acc_P[i], acc_J[i], delta)
                log_normalize(log_w, w, total, nb)  # total: log mu_j(k|K)
                combine(x_pair, P_pair, w, log_w, nb, xk[j], Pk[j], best)
                for b in range(nb):
                    lpk[j, b] = total[b]
                    if total[b] == -math.inf:  # mode j impossible: keep its filtered posterior
                        _copy_lane(xf[j], Pf[j], b, xk[j], Pk[j])
            log_normalize(lpk, prob, total, nb)
            _write(xk, Pk, prob, lpk, i0, nb, k, xc, Pc, best, x_out, P_out, prob_out,
                   mode_out, x_s, P_s)
            if lagged:
                _write_lagged(lpn, back, Pn, acc_x, acc_M, acc_P, acc_J, i0, nb, k, pair_out,
                              lag_x, lag_P, lag_cross)
            xn, xk = xk, xn
            Pn, Pk = Pk, Pn
            lpn, lpk = lpk, lpn
    return OK


@borrow
def _redo(xj, Pj, F, G, u, Qd, x_next, P_next, redo, first, last, nb, x_pair, P_pair,
          gain_pair, report, conditional, scratch, pair):
    """The pairs ``(j, i)``, ``first <= i < last``, in Joseph's form, in their lanes marked in
    ``redo[i]`` (module docstring): mode ``j``'s conditional through ``F``, ``G``, ``Qd``
    (:func:`rts_joseph`), once, for every lane one of them marks, then each pair's step
    (:func:`rts_pair`) into ``x_pair[i]``, ``P_pair[i]``, ``gain_pair[i]`` where marked.
    Nothing is done where no lane is marked. ``conditional`` holds ``x_pred``, the conditional
    covariance and gain, a pair's ``x``, ``P`` and the lanes ``use``d; ``scratch`` the work
    arrays of :func:`rts_joseph` (:func:`joseph_scratch`), ``pair`` those of :func:`rts_pair`.
    Returns ``OK`` or the failure code of :func:`rts_joseph`."""
    xp, P, J, x, Pr, use = conditional
    zero = scratch[19]
    for b in range(nb):
        use[b] = False
    for i in range(first, last):
        for b in range(nb):
            use[b] |= redo[i, b]
    if not _any(use, nb):
        return OK
    status = rts_joseph(xj, Pj, F, G, u, Qd, use, nb, xp, P, J, report, scratch)
    if status != OK:
        return status
    for i in range(first, last):
        if _any(redo[i], nb):
            rts_pair(xj, xp, P, zero, J, x_next[i], P_next[i], nb, x, Pr, pair)
            _take_lanes(x, Pr, J, redo[i], nb, x_pair[i], P_pair[i], gain_pair[i])
    return OK


@jit
def gain_scratch(n, B):
    """The work arrays of :func:`rts_gain` for ``n`` states and ``B`` lanes, in its order:
    ``F P, xs, chol, scale, work (2, B), root``."""
    return (np.empty((n, n, B)), np.empty((n, B)), np.zeros((n, n, B)), np.empty((n, B)),
            np.empty((2, B)), np.empty((n, B)))


@borrow
def rts_gain(xj, Pj, F, G, u, Qd, nb, xp, Pp, gain, failed, scratch):
    """The half of an RTS step in its direct form that does not depend on the smoothed
    posterior at ``k + 1``, per lane (Rauch, Tung & Striebel 1965; Särkkä 2013, Theorem 8.2):
    mode ``j``'s filtered ``xj``, ``Pj`` predicted through the transition ``F``, ``G``, ``Qd``
    (with input ``u``) into ``xp = x_pred``, ``Pp = P_pred`` (:func:`.linalg.predict`), and
    the gain ``J = P_j F' P_pred^-1`` into ``gain``.

    ``P_pred`` is factored as the filters factor an innovation covariance
    (:func:`.linalg.factor`) and each row of ``J``, ``P_pred^-1`` times a column of ``F P_j``,
    is two triangular solves (:func:`.linalg.solve_rows`). ``failed`` marks the lanes whose
    ``P_pred`` is not positive definite to working precision (their ``gain`` is not usable:
    :func:`rts_joseph` takes them). ``scratch`` holds the work arrays (:func:`gain_scratch`).
    Returns ``OK``, or ``NOT_FINITE`` if a lane's ``P_pred`` has a non-finite diagonal (it
    overflowed).
    """
    FP, xs, chol, scale, work, root = scratch
    n = xj.shape[0]
    copy_gaussian(xj, Pj, nb, xp, Pp)
    predict(xp, Pp, F, G, u, Qd, nb, FP, xs)  # x_pred, P_pred; FP = F P_j
    for r in range(n):  # P_pred's lower triangle, factored in place
        for c in range(r + 1):
            for b in range(nb):
                chol[r, c, b] = Pp[r, c, b]
    finite, _ = factor(chol, scale, nb, work[0], work[1])
    if not finite:
        return NOT_FINITE
    for b in range(nb):  # a failed pivot leaves NaN or 0 in the product of the pivots
        failed[b] = not work[0, b] > 0.0
    for r in range(n):  # row r of J: P_pred^-1 (column r of F P_j), P_pred symmetric
        for a in range(n):
            for b in range(nb):
                gain[r, a, b] = FP[a, r, b]
    solve_rows(chol, scale, gain, nb, root)
    return OK


@jit
def pair_scratch(n, B):
    """The work arrays of :func:`rts_pair` for ``n`` states and ``B`` lanes, in its order:
    ``e, D, T``."""
    return np.empty((n, B)), np.empty((n, n, B)), np.empty((n, n, B))


@borrow
def rts_pair(xj, xp, base, sub, gain, x_next, P_next, nb, x, P, scratch):
    """The half of an RTS step that takes the smoothed ``x_next``, ``P_next`` at ``k + 1``, per
    lane, into ``x``, ``P``: ``x = x_j + J (x_next - x_pred)`` and
    ``P = base + J (P_next - sub) J'`` with ``J = gain``, ``x_pred = xp``. In the direct form
    (:func:`rts_gain`) ``base = P_j``, ``sub = P_pred``; after :func:`rts_joseph`, ``base``
    its conditional covariance and ``sub`` zero. ``P`` is exactly symmetric
    (:func:`.linalg.symmetric_sum`); ``scratch`` holds the work arrays (:func:`pair_scratch`).
    """
    e, D, T = scratch
    n = xj.shape[0]
    for a in range(n):
        for b in range(nb):
            e[a, b] = x_next[a, b] - xp[a, b]
    for r in range(n):  # x = x_j + J (x_next - x_pred)
        for b in range(nb):
            x[r, b] = xj[r, b]
        for a in range(n):
            for b in range(nb):
                x[r, b] += gain[r, a, b] * e[a, b]
    for r in range(n):  # D = P_next - sub
        for c in range(n):
            for b in range(nb):
                D[r, c, b] = P_next[r, c, b] - sub[r, c, b]
    for r in range(n):  # T = J D
        for c in range(n):
            for b in range(nb):
                T[r, c, b] = 0.0
            for a in range(n):
                for b in range(nb):
                    T[r, c, b] += gain[r, a, b] * D[a, c, b]
    symmetric_sum(base, T, gain, nb, P)  # P = base + J D J'


@jit
def joseph_scratch(n, B):
    """The work arrays of :func:`rts_joseph` for ``n`` states and ``B`` lanes, in its order:
    ``P_pred, F P, xs`` (:func:`.linalg.predict`); ``e, P C', chol, scale, z, nis, loglik,
    work, bad`` (:func:`.linalg.innovation`); ``T, AP, prior`` (:func:`.linalg.correct`);
    ``root, lost`` (:func:`.linalg.joseph_lost`); ``x`` (the mean :func:`.linalg.correct`
    leaves unchanged); the lanes' identity and zero ``(n, n)``, ``obs`` ones ``(n, B)`` and
    ``n_obs = n`` (the pseudo-measurement, every component observed)."""
    eye = np.zeros((n, n, B))
    for r in range(n):
        eye[r, r, :] = 1.0
    return (np.empty((n, n, B)), np.empty((n, n, B)), np.empty((n, B)), np.empty((n, B)),
            np.empty((n, n, B)), np.empty((n, n, B)), np.empty((n, B)), np.empty((n, B)),
            np.empty(B), np.empty(B), np.empty((3, B)), np.zeros(B, dtype=np.bool_),
            np.empty((n, n, B)), np.empty((n, n, B)), np.empty((n, n, B)), np.empty((n, B)),
            np.zeros(B, dtype=np.bool_), np.empty((n, B)), eye, np.zeros((n, n, B)),
            np.ones((n, B)), np.full(B, float(n)))


@borrow
def rts_joseph(xj, Pj, F, G, u, Qd, use, nb, xp, P, gain, report, scratch):
    """The conditional of an RTS step in Joseph's form, in the lanes where ``use`` is true:
    mode ``j``'s filtered ``xj``, ``Pj`` at ``k`` given ``x_{k+1}`` through the transition
    ``F``, ``G``, ``Qd`` (with input ``u``), whatever its value (module docstring):
    ``xp = x_pred``, the covariance ``P = (I - J F) P_j (I - J F)' + J Qd J'`` and the gain
    ``J = P_j F' P_pred^-1`` into ``gain``, by the filters' update with the
    pseudo-measurement ``x_{k+1} = F x_k + G u + w``, ``w ~ N(0, Qd)``, set to its prediction
    (:func:`rts_pair` then adds ``J P_next J'``). A ``P_pred`` singular to working precision
    is repaired (:func:`.linalg.innovation`), a conditional covariance that lost its digits
    is taken in information form or repaired (:func:`.linalg.information_or_repair`), both
    counted in ``report``. ``scratch`` holds the work arrays (:func:`joseph_scratch`). Returns
    ``OK`` or the failure code of :func:`.linalg.innovation` on ``P_pred``.
    """
    (Pp, FP, xs, e, PCt, chol, scale, z, nis, loglik, work, bad, T, AP, prior, root, lost, x,
     eye, zero, obs, n_obs) = scratch
    n = xj.shape[0]
    copy_gaussian(xj, Pj, nb, xp, Pp)
    predict(xp, Pp, F, G, u, Qd, nb, FP, xs)  # x_pred, P_pred; FP = F P_j
    # S = P_pred factored (repaired where singular); the measurement x_pred: e = z = 0
    status = innovation(xp, Pp, xp, eye, zero, obs, n_obs, nb, e, PCt, chol, scale, z, nis,
                        loglik, work, bad, report)
    if status != OK:
        return status
    for r in range(n):  # the pseudo-measurement's P C' = P_j F' = (F P_j)'
        for a in range(n):
            for b in range(nb):
                PCt[r, a, b] = FP[a, r, b]
    copy_gaussian(xj, Pj, nb, x, P)
    # P = (I - J F) P_j (I - J F)' + J Qd J', gain = J = P_j F' P_pred^-1 (x: unchanged)
    correct(x, P, F, Qd, use, nb, PCt, chol, scale, z, gain, T, AP, prior)
    if joseph_lost(P, prior, use, nb, root, lost):
        information_or_repair(P, prior, F, Qd, obs, n_obs, lost, nb, report)
    return OK


@jit
def _clear(flag, nb):
    """``flag[b] = False`` for the lanes ``b < nb``."""
    for b in range(nb):
        flag[b] = False


@jit
def _any(flag, nb):
    """Whether ``flag[b]`` is true for a lane ``b < nb``."""
    for b in range(nb):
        if flag[b]:
            return True
    return False


@jit
def _impossible(log_next, log_back, nb):
    """Whether the pair's weight ``log mu_i(k+1|K) + back[i, j]`` is ``-inf`` in every lane."""
    for b in range(nb):
        if log_next[b] + log_back[b] > -math.inf:
            return False
    return True


@borrow
def _copy_pair(xj, Pj, nb, x, P, gain):
    """A pair of weight zero: ``x``, ``P`` get the filtered ``xj``, ``Pj`` (finite, so that a
    zero weight cancels them exactly) and ``gain`` zero."""
    copy_gaussian(xj, Pj, nb, x, P)
    for r in range(xj.shape[0]):
        for c in range(gain.shape[1]):
            for b in range(nb):
                gain[r, c, b] = 0.0


@jit
def _take_lanes(x_from, P_from, gain_from, take, nb, x, P, gain):
    """The lanes ``b`` with ``take[b]`` of ``x_from``, ``P_from``, ``gain_from`` into ``x``,
    ``P``, ``gain``."""
    n = x.shape[0]
    for b in range(nb):
        if take[b]:
            for r in range(n):
                x[r, b] = x_from[r, b]
                for c in range(n):
                    P[r, c, b] = P_from[r, c, b]
                    gain[r, c, b] = gain_from[r, c, b]


@jit
def _accumulate(x, P, gain, log_w, nb, acc_w, acc_x, acc_M, acc_P, acc_J, delta):
    """Add one pair ``(j, i)`` of weight ``exp(log_w)`` (``P(r_k = j | r_{k+1} = i, y_0..k)``)
    to mode ``i``'s running moments of ``x_k``: weight, mean and scatter of the means by West's
    (1979) weighted incremental rule, weighted sums of the covariances ``P`` and gains ``gain``."""
    n = x.shape[0]
    for b in range(nb):
        if log_w[b] == -math.inf:
            continue
        w = math.exp(log_w[b])
        acc_w[b] += w
        share = w / acc_w[b]
        for r in range(n):
            delta[r] = x[r, b] - acc_x[r, b]
            acc_x[r, b] += share * delta[r]
        for r in range(n):
            for c in range(n):
                acc_M[r, c, b] += w * delta[r] * (x[c, b] - acc_x[c, b])
                acc_P[r, c, b] += w * P[r, c, b]
                acc_J[r, c, b] += w * gain[r, c, b]


@jit
def _write_lagged(lpn, back, Pn, acc_x, acc_M, acc_P, acc_J, i0, nb, k, pair_out, lag_x, lag_P,
                  lag_cross):
    """Interval ``k -> k+1`` of the block's trials: ``mu_ji(k|K) = exp(lpn[i] + back[i, j])``,
    the moments of ``x_k`` given ``r_{k+1} = i`` and ``Cov(x_{k+1}, x_k | i) = P_i(k+1|K)
    Jbar_i'`` (module docstring). The weights over ``j`` sum to one (``back[i]`` is normalized;
    a mode ``i`` no pair reaches gets zeros)."""
    L, n = acc_x.shape[0], acc_x.shape[1]
    for b in range(nb):
        t = i0 + b
        for i in range(L):
            for j in range(L):
                pair_out[t, k, j, i] = math.exp(lpn[i, b] + back[i, j, b])
            for r in range(n):
                lag_x[t, k, i, r] = acc_x[i, r, b]
                for c in range(n):  # symmetric part of the scatter: rounding only
                    lag_P[t, k, i, r, c] = acc_P[i, r, c, b] + 0.5 * (acc_M[i, r, c, b]
                                                                       + acc_M[i, c, r, b])
                    s = 0.0
                    for a in range(n):
                        s += Pn[i, r, a, b] * acc_J[i, c, a, b]
                    lag_cross[t, k, i, r, c] = s


@jit
def _copy_lane(x, P, b, x_to, P_to):
    """Lane ``b`` of ``x (n, B)``, ``P (n, n, B)`` into ``x_to``, ``P_to``."""
    for r in range(x.shape[0]):
        x_to[r, b] = x[r, b]
        for c in range(x.shape[0]):
            P_to[r, c, b] = P[r, c, b]


@borrow
def _write(x, P, prob, log_prob, i0, nb, k, xc, Pc, best, x_out, P_out, prob_out, mode_out,
           x_s, P_s):
    """Sample ``k`` of the block's trials: the mode-matched ``x (L, n, B)``, ``P``, their
    probabilities and the combined moments (:func:`.linalg.combine`) into the outputs."""
    if x_s.shape[0] > 0:  # the mode-matched outputs, where asked for
        scatter_modes(x, P, i0, nb, x_s[:, k], P_s[:, k])
    scatter_rows(prob, i0, nb, prob_out[:, k])
    combine(x, P, prob, log_prob, nb, xc, Pc, best)
    for b in range(nb):
        mode_out[i0 + b, k] = best[b]
        write_lane(xc, Pc, b, i0 + b, k, x_out, P_out)


@jit
def screen_psd(A, relative_shift, sym, failed):
    """Symmetrize a stack ``A (M, n, n)`` and certify its matrices positive semidefinite to
    within a shift, as far as a Cholesky factorization can, without eigenvalues.

    ``scale = max |A|`` (at least the smallest normal float), ``sym = (A + A') / 2``, and
    ``failed[s]`` set where the Cholesky factorization of ``sym[s] + relative_shift scale I``
    (Golub & Van Loan, "Matrix Computations", 4th ed., Algorithm 4.2.2) meets a pivot that is
    not positive. Where it succeeds, the computed factor is the exact one of
    ``sym[s] + shift I + E`` with ``|E| <= gamma_{n+1} |R'| |R|`` (Higham, "Accuracy and
    Stability of Numerical Algorithms", 2nd ed., Theorem 10.3), so the smallest eigenvalue of
    ``sym[s]`` is at least ``-shift - n gamma_{n+1} (scale + shift)``. Returns
    ``(scale, max |A - A'|)``.
    """
    M, n = A.shape[0], A.shape[1]
    scale = 2.2250738585072014e-308  # numpy.finfo(float).tiny
    for s in range(M):
        for i in range(n):
            for j in range(n):
                scale = max(scale, abs(A[s, i, j]))
    shift = relative_shift * scale
    R = np.empty((n, n))
    asym = 0.0
    for s in range(M):
        for i in range(n):
            for j in range(n):
                asym = max(asym, abs(A[s, i, j] - A[s, j, i]))
                sym[s, i, j] = 0.5 * (A[s, i, j] + A[s, j, i])
        failed[s] = False
        for j in range(n):
            pivot = sym[s, j, j] + shift
            for p in range(j):
                pivot -= R[j, p] * R[j, p]
            if not pivot > 0.0:
                failed[s] = True
                break
            R[j, j] = math.sqrt(pivot)
            for i in range(j + 1, n):
                v = sym[s, i, j]
                for p in range(j):
                    v -= R[i, p] * R[j, p]
                R[i, j] = v / R[j, j]
    return scale, asym
