"""The engine's backward pass of the fixed-interval smoother with mode probabilities.

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
  (``se_combine``).

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

Each pair's RTS step is taken in its direct form, in two halves: ``rts_gain``, once per
moving mode, predicts (``P_pred`` from the filters' ``se_predict``), factors ``P_pred``
(its equilibrated Cholesky factor, ``se_factor``) and solves for the rows of ``J``
(``se_solve_rows``); ``rts_pair``, once per pair, forms ``x_ji = x_j + J e`` and
``P_ji = P_j + J (P_i(k+1|K) - P_pred) J'`` (its upper triangle, mirrored): about half the
loops of the form below. The lanes that form cannot take, a ``P_pred`` that does not factor or
a ``P_ji`` that lost its digits (``se_joseph_lost`` against ``P_j``), are redone in
the form below, so degenerate cases are handled as they always were: its conditional
(``rts_joseph``) is again taken once per moving mode (in the ``"sample"`` timing for the
lanes any pair ``(j, .)`` needs), and finished per pair by ``rts_pair``. A pair of weight
zero in every lane of a block is not computed.

That form is a Kalman update of ``x_j(k|k)`` by the pseudo-measurement
``x_{k+1} = F_m x_k + G_m u_k + w``, ``w ~ N(0, Qd_m)``: conditioned on ``x_{k+1}`` the state
is Gaussian with mean ``x_j + J (x_{k+1} - x_pred)`` and covariance
``P_j - J P_pred J' = (I - J F_m) P_j (I - J F_m)' + J Qd_m J'`` (Joseph's form), the same for
every value of ``x_{k+1}``; averaging over ``x_{k+1} ~ N(x_i(k+1|K), P_i(k+1|K))`` adds
``J P_i(k+1|K) J'`` (Särkkä 2013, "Bayesian Filtering and Smoothing", the derivation of the RTS
smoother, Theorem 8.2). So ``rts_joseph`` runs the filters' own update,
``se_innovation`` and ``se_correct`` with ``C = F_m``, ``R = Qd_m``, and
``rts_pair`` adds ``J P_i(k+1|K) J'`` (its ``P_pred`` replaced by zero): the covariance is
a sum of two positive semidefinite terms, symmetric by construction; no second Kalman update,
no difference of covariances that could turn indefinite.

``P_pred`` is factored there by ``se_innovation`` as the innovation covariance of a
measurement of ``x_pred`` (``C = I``, ``R = 0``: ``S = P_pred``), never inverted. Where it is
singular to working precision (``Qd_m = 0`` with a singular ``F_m``: a state reset, a
deterministic component) that function's rule applies: its eigenvalues are raised to its
rounding level (``se_repair``, counted for the caller's warning) and it is factored
again. The gain ``J`` then annihilates the directions ``P_pred`` cannot reach (the columns of
``P_j F_m'`` vanish there) up to rounding, as a pseudo-inverse would, and Joseph's form keeps
the covariance positive semidefinite for that gain; a conditional covariance that loses its
digits (``Qd_m = 0`` with an invertible ``F_m``: ``x_k`` determined by ``x_{k+1}``) is taken in
information form or repaired (``se_joseph_lost``,
``se_information_or_repair``), as in the filters.

Trials are processed in blocks of ``lanes`` laid across SIMD lanes (``engine/c/linalg.h``); the
results do not depend on the block size.

The kernel (``se_kim_backward``) and its helpers (``rts_gain``, ``rts_pair``, ``rts_joseph``,
...) are C functions of ``engine/c/smoother.c``, the shared equations (``se_*``) those of
``engine/c/linalg.c``; this module checks the arrays, allocates the outputs and calls the
kernel through its binding (``engine/_backward.pyx``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .._checks import check_timing, positive_int
from ._arrays import checked
from ._backward import kim_backward
from ._backward import screen_psd as _screen_psd
from ._parallel import MixtureOutput, run_split

__all__ = ["KimOutput", "kim_smooth", "screen_psd", "LANES"]

OK = 0  # se_common.h SE_OK

LANES = 64  # trials per block: the backward pass runs ~500 short loops over the lanes per pair,
# each with a fixed cost (alias checks, remainders); at 16 lanes (the filters' block) that cost
# doubled its time on the vehicle (n = 4, L = 3), at 64 and 128 it is amortized


@dataclass
class KimOutput(MixtureOutput):
    """Kim's smoothed posteriors of every trial and sample (:func:`kim_smooth`): ``x``, ``P``
    of the mixture of the mode-matched ones, the smoothed mode probabilities ``mu_j(k|K)`` and
    the most probable smoothed mode (:class:`MixtureOutput`), and

    Attributes
    ----------
    x_modes, P_modes : ndarray, shapes (N, K, L, n), (N, K, L, n, n)
        Mode-matched smoothed posteriors ``x_j(k|K)``, ``P_j(k|K)``; a mode of smoothed
        probability zero keeps its filtered posterior.
    status, repaired, smallest_eigenvalue
        The kernel's report (:class:`~switchest.engine.Reported`).
    pair_prob : ndarray, shape (N, K-1, L, L), or None
        With ``lagged``: ``pair_prob[:, k, j, i] = mu_ji(k|K) = P(r_k = j, r_{k+1} = i | Y)``.
    lag_x, lag_P : ndarray, shapes (N, K-1, L, n), (N, K-1, L, n, n), or None
        With ``lagged``: mean and covariance of ``x_k`` given ``r_{k+1} = i`` and the record.
    lag_cross : ndarray, shape (N, K-1, L, n, n), or None
        With ``lagged``: ``Cov(x_{k+1}, x_k | r_{k+1} = i, Y)``, the lag-one cross-covariance.
    """

    x_modes: np.ndarray
    P_modes: np.ndarray
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
                    np.empty((*size, n, n)), status=OK)
    J = K - 1 if lagged else 0  # intervals reported (none unless asked)
    lag = (np.zeros((N, J, L, L)), np.zeros((N, J, L, n)), np.zeros((N, J, L, n, n)),
           np.zeros((N, J, L, n, n)))
    lanes = positive_int(lanes, "lanes")
    mine, shared = True, False  # per-trial arrays, sliced to each thread's trials; the rest
    # (trans of first axis 1 serves every trial; without modes_out the zero-trial x_modes)
    outcome = run_split(_backward, [
        (x_modes, mine), (P_modes, mine), (log_prob, mine), (u, mine), (F, shared),
        (G, shared), (Qd, shared), (trans, len(trans) > 1), (log_transition, shared),
        (lanes, shared), (timing == "sample", shared), (out.x, mine), (out.P, mine),
        (out.mode_prob, mine), (out.mode, mine), (out.x_modes, modes_out),
        (out.P_modes, modes_out), (bool(lagged), shared), *((a, mine) for a in lag)],
        trials=N, samples=K, block=lanes)
    out = replace(out, **outcome._asdict())
    if not modes_out:
        out = replace(out, x_modes=None, P_modes=None)
    return replace(out, pair_prob=lag[0], lag_x=lag[1], lag_P=lag[2],
                   lag_cross=lag[3]) if lagged else out


def _backward(x_f, P_f, log_prob_f, u, F, G, Qd, trans, log_transition, lanes, sample_timing,
              x_out, P_out, prob_out, mode_out, x_s, P_s, lagged, pair_out, lag_x, lag_P,
              lag_cross, report):
    """:func:`._backward.kim_backward` with its report
    last, as :func:`._parallel.run_split` calls a kernel."""
    return kim_backward(x_f, P_f, log_prob_f, u, F, G, Qd, trans, log_transition, lanes,
                        sample_timing, x_out, P_out, prob_out, mode_out, x_s, P_s, report,
                        lagged, pair_out, lag_x, lag_P, lag_cross)


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

    ``A`` is read as C-contiguous float64 (converted if it is not); ``sym`` (float64, the shape
    of ``A``) and ``failed`` (bool, ``(M,)``) are written in place and must be C-contiguous.
    """
    if type(A) is not np.ndarray or A.dtype != np.float64 or not A.flags.c_contiguous:
        A = np.ascontiguousarray(A, dtype=np.float64)
    return _screen_psd(A, float(relative_shift), sym, failed)
