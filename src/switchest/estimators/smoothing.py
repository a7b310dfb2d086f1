"""Fixed-interval smoothing of a filter's mode-matched posteriors, with mode probabilities.

:func:`smooth_mode_matched` runs the backward recursion of Kim (1994, J. Econometrics 60,
"Dynamic linear models with Markov-switching", §2.2) on what a collapsing filter (IMM, GPB1,
GPB2) reports after each sample: its mode-matched posteriors and mode probabilities. Murphy
(1998, "Switching Kalman filters", tech. report, §3-4) shows how it applies to such filters.
For every pair (mode :math:`j` at sample :math:`k`, mode :math:`i` at :math:`k+1`) mode
:math:`j`'s filtered posterior takes a Rauch-Tung-Striebel step towards mode :math:`i`'s
smoothed posterior,

.. math::

    \\begin{aligned}
    x_{ji} &= x_j(k|k) + J \\left(x_i(k+1|K) - F_m x_j(k|k) - G_m u_k\\right), \\\\
    P_{ji} &= P_j(k|k) + J \\left(P_i(k+1|K) - P_\\mathrm{pred}\\right) J^\\top, \\qquad
        P_\\mathrm{pred} = F_m P_j(k|k) F_m^\\top + Q_{d,m}, \\\\
    J &= P_j(k|k) F_m^\\top P_\\mathrm{pred}^{-1},
    \\end{aligned}

through the transition of the mode :math:`m` that governs the interval :math:`k \\to k+1`, by
the ``timing`` (:doc:`/conventions`):

- ``"sample"`` (switchest's convention for data: the mode of sample :math:`k` governs
  :math:`y_k` and the interval after it, :math:`x_{k+1} = F(s_k) x_k + G(s_k) u_k + w_k`;
  Costa, Fragoso & Marques 2005, eq. (3.1)): :math:`m = j`, table entry ``trans[k+1, j]``.
  :math:`x_{k+1}` depends on :math:`s_k`, not on :math:`s_{k+1}`, so the step conditions on
  :math:`x_{k+1}` through :math:`F_j`; the prediction and the gain are the same for every
  :math:`i`, computed once per :math:`j`;
- ``"interval"`` (the default; Bar-Shalom, Li & Kirubarajan 2001, §11.6; Kim's own model: the
  mode of sample :math:`k+1` governs the interval into it): :math:`m = i`, table entry
  ``trans[k+1, i]``.

In both the pairs are weighted by

.. math::

    \\mu_{ji}(k|K) = \\frac{\\mu_i(k+1|K) \\, \\mu_j(k|k) \\, \\pi_{ji}}
        {\\sum_{j'} \\mu_{j'}(k|k) \\, \\pi_{j'i}}

(Kim's approximation
:math:`\\Pr(s_k = j \\mid s_{k+1} = i, Y) \\approx \\Pr(s_k = j \\mid s_{k+1} = i, y_{0..k})`)
and merged over :math:`i` by moment matching (Kim 1994 §2.2; Murphy 1998 §4). With one mode
both timings are the RTS smoother (Rauch, Tung & Striebel 1965). The equations, their
derivation in each timing and how a singular predicted covariance is handled are in
:mod:`switchest.engine.smoother`; the backward loop runs there, compiled.

Convention (all of switchest): ``transition[i, j]`` =
:math:`\\Pr(\\text{mode } j \\text{ at } k+1 \\mid \\text{mode } i \\text{ at } k)`;
``trans[k+1, j]`` indexes mode :math:`j`'s exact transition over the interval into sample
:math:`k+1` (in both timings), with the input ``u[k]`` held over it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import (
    _SYM_RTOL,
    check_bool,
    check_finite,
    check_row_stochastic,
    check_symmetric_psd,
    check_timing,
    float_array,
    int_array,
)
from ..engine import raise_for_status, warn_for_repairs
from ..engine.smoother import kim_smooth, screen_psd

__all__ = ["SmoothedModes", "smooth_filtered", "smooth_mode_matched"]

_PSD_RTOL = 1e-12  # check_symmetric_psd's tolerance: smallest eigenvalue >= -1e-12 max |P|
_SCREENED = 32  # states up to which a Cholesky factorization screens covariances (_covariances)


@dataclass(frozen=True, eq=False)
class SmoothedModes:
    """Smoothed posteriors, with the batch shape the filtered ones were given.

    Attributes
    ----------
    x, P : ndarray, shapes (..., K, n), (..., K, n, n)
        Combined smoothed estimate: the moments of the mixture of the mode-matched
        posteriors (Bar-Shalom, Li & Kirubarajan §11.6.6).
    mode_prob : ndarray, shape (..., K, L)
        Smoothed mode probabilities
        :math:`\\Pr(\\text{mode } j \\text{ at } k \\mid y_0 .. y_{K-1})` (as the collapsed
        filter approximates them).
    mode : ndarray of int, shape (..., K)
        Most probable smoothed mode (the first on a tie).
    x_modes, P_modes : ndarray, shapes (..., K, L, n), (..., K, L, n, n)
        Mode-matched smoothed posteriors; a mode of smoothed probability zero keeps its
        filtered posterior (None from :func:`smooth_filtered` without ``modes_out``).
    pair_prob : ndarray, shape (..., K-1, L, L), or None
        With ``lagged=True``: ``pair_prob[..., k, j, i]``
        :math:`= \\Pr(r_k = j, r_{k+1} = i \\mid Y)`, Kim's :math:`\\mu_{ji}(k|K)`.
    lag_x, lag_P : ndarray, shapes (..., K-1, L, n), (..., K-1, L, n, n), or None
        With ``lagged=True``: mean and covariance of :math:`x_k` given :math:`r_{k+1} = i` and
        the
        record.
    lag_cross : ndarray, shape (..., K-1, L, n, n), or None
        With ``lagged=True``: the lag-one cross-covariance
        :math:`\\operatorname{Cov}(x_{k+1}, x_k \\mid r_{k+1} = i, Y)`; with one mode
        :math:`P_{k+1|K} J_k^\\top` (de Jong & MacKinnon 1988).
    """

    x: np.ndarray
    P: np.ndarray
    mode_prob: np.ndarray
    mode: np.ndarray
    x_modes: np.ndarray | None
    P_modes: np.ndarray | None
    pair_prob: np.ndarray | None = None
    lag_x: np.ndarray | None = None
    lag_P: np.ndarray | None = None
    lag_cross: np.ndarray | None = None


def smooth_mode_matched(x_modes, P_modes, mode_prob, u, F, G, Qd, trans, transition, *,
                        timing: str, lagged: bool = False) -> SmoothedModes:
    """Kim's fixed-interval smoother of filtered mode-matched posteriors (Kim 1994, §2.2).

    Parameters
    ----------
    x_modes : array_like, shape (..., K, L, n)
        Filtered mode-matched means after each sample's measurement update.
    P_modes : array_like, shape (..., K, L, n, n)
        Their covariances (symmetric positive semidefinite).
    mode_prob : array_like, shape (..., K, L)
        Filtered mode probabilities after each sample (each row sums to 1).
    u : array_like or None
        Inputs, ``u[..., k, :]`` held over the interval into sample ``k + 1``: ``(l,)``,
        ``(K, l)`` or ``(..., K, l)``; None for zero input.
    F, G, Qd : array_like, shapes (M, n, n), (M, n, l), (M, n, n)
        Table of exact transitions (e.g. :func:`switchest.discretize.mode_steps` of each
        distinct sampling step, concatenated).
    trans : array_like of int, shape (K, L) or (..., K, L)
        ``trans[..., k + 1, j]``: the table entry of mode ``j`` over the interval into sample
        ``k + 1`` (row 0 unused); ``(K, L)`` or leading axes of length 1 share it across trials.
    transition : array_like, shape (L, L)
        ``transition[i, j]`` =
        :math:`\\Pr(\\text{mode } j \\text{ at } k+1 \\mid \\text{mode } i \\text{ at } k)`,
        rows summing to 1.
    timing : {"sample", "interval"}
        Which mode governs the interval :math:`k \\to k+1` (module docstring), so which mode's
        transition the pair (mode :math:`j` at :math:`k`, mode :math:`i` at :math:`k + 1`)
        takes its RTS step through: :math:`j`'s (``"sample"``) or :math:`i`'s
        (``"interval"``); required (keyword-only), as the arrays do not say it. The filtered
        posteriors should come from a filter of the same timing (its ``timing`` attribute).
    lagged : bool
        Also return, for each interval :math:`k \\to k+1`, the pairwise mode probabilities and the
        lag-one moments an expectation-maximization step needs (``pair_prob``, ``lag_x``,
        ``lag_P``, ``lag_cross``; :mod:`switchest.engine.smoother`). They are
        conditioned on the mode of sample :math:`k+1`, which governs the interval in the
        ``"interval"`` timing: with ``timing="sample"`` they are refused unless :math:`L = 1`
        (where the timings agree).

    Returns
    -------
    SmoothedModes

    Raises
    ------
    ValueError, TypeError
        For arguments of the wrong shape or values (each named), a ``timing`` other than
        ``"sample"`` or ``"interval"``, or ``lagged`` with ``timing="sample"`` and several
        modes.
    numpy.linalg.LinAlgError
        When a predicted covariance :math:`F P F^\\top + Q_d` is not finite (it overflowed) or
        cannot be factored even after its repair. A covariance repaired to its rounding level (a
        singular :math:`F P F^\\top + Q_d`) issues a ``RuntimeWarning``.
    """
    timing = check_timing(timing)
    lagged = check_bool(lagged, "lagged")
    x_modes = _finite(x_modes, "x_modes")
    if x_modes.ndim < 3:
        raise ValueError(f"x_modes must have shape (..., K, L, n), got {x_modes.shape}")
    *batch, K, L, n = x_modes.shape
    batch = tuple(batch)
    P_modes = _finite(P_modes, "P_modes")
    if P_modes.shape != (*batch, K, L, n, n):
        raise ValueError(f"P_modes must have shape (..., K, L, n, n) = {(*batch, K, L, n, n)} "
                         f"as x_modes, got {P_modes.shape}")
    if K == 0 or L == 0 or n == 0 or 0 in batch:
        raise ValueError(f"x_modes must hold at least one trial, sample, mode and state, got "
                         f"shape {x_modes.shape}")
    P_modes = _covariances(P_modes, "P_modes")
    mode_prob = _probabilities(mode_prob, (*batch, K, L))
    transition = check_row_stochastic(transition, "transition", n=L)
    F, G, Qd = _table(F, G, Qd, n)
    u = _inputs(u, batch, K, G.shape[2])
    trans = _transitions(trans, batch, K, L, F.shape[0])
    N = math.prod(batch)
    out = smooth_filtered(x_modes.reshape(N, K, L, n), P_modes.reshape(N, K, L, n, n),
                          mode_prob.reshape(N, K, L), u, F, G, Qd, trans, transition,
                          timing=timing, lagged=lagged)
    return SmoothedModes(*(None if a is None else a.reshape(*batch, *a.shape[1:])
                           for a in (getattr(out, f) for f in SmoothedModes.__dataclass_fields__)))


def smooth_filtered(x_modes, P_modes, mode_prob, u, F, G, Qd, trans, transition, *,
                    timing: str, lagged: bool = False,
                    modes_out: bool = True) -> SmoothedModes:
    """:func:`smooth_mode_matched` of arrays a filter of switchest produced and checked, with
    one batch axis: ``(N, K, L, n)``, ``(N, K, L, n, n)``, ``(N, K, L)``, ``u (N, K, l)``,
    ``trans (N or 1, K, L)`` (or ``(K, L)``); no array is validated again (the smoother of
    :meth:`~switchest.estimators.mode_bank.ModeBankFilter.smooth` calls it on its own forward
    pass); ``timing`` is (by :func:`~switchest.engine.smoother.kim_smooth`).
    Raises and warns as :func:`smooth_mode_matched`; without ``modes_out`` the smoothed
    mode-matched posteriors are not written (``x_modes``, ``P_modes`` None)."""
    with np.errstate(divide="ignore"):
        log_prob, log_transition = np.log(mode_prob), np.log(transition)
    trans = trans[None] if trans.ndim == 2 else trans
    out = kim_smooth(x_modes, P_modes, log_prob, u, F, G, Qd, trans, log_transition,
                     timing=timing, lagged=lagged, modes_out=modes_out)
    try:
        raise_for_status(out.status)
    except np.linalg.LinAlgError as err:
        raise np.linalg.LinAlgError(
            f"a predicted covariance F P F' + Qd of the smoother could not be factored ({err})"
        ) from None
    warn_for_repairs(out)
    fields = (out.x, out.P, out.mode_prob, out.mode, out.x_modes, out.P_modes)
    if lagged:
        fields += (out.pair_prob, out.lag_x, out.lag_P, out.lag_cross)
    return SmoothedModes(*fields)


def _finite(value, name: str) -> np.ndarray:
    arr = float_array(value, name)
    check_finite(arr, name)
    return arr


def _covariances(P: np.ndarray, name: str) -> np.ndarray:
    """:func:`switchest._checks.check_symmetric_psd` of a finite stack ``P (..., n, n)``: the
    same verdict, message and symmetrized result, with eigenvalues only where needed.

    The matrices whose factorization with half the tolerance added to their diagonal succeeds
    (:func:`~switchest.engine.smoother.screen_psd`) have their smallest
    eigenvalue above :math:`-(1/2 + n (n + 1) u / 10^{-12}) \\, 10^{-12} \\max |P|`, within the
    tolerance for :math:`n \\le 32` (:math:`u` the unit roundoff): only the others have their
    eigenvalues computed.
    """
    n = P.shape[-1]
    if n > _SCREENED:
        return check_symmetric_psd(P, name)
    flat = np.ascontiguousarray(P).reshape(-1, n, n)
    sym, failed = np.empty_like(flat), np.empty(flat.shape[0], dtype=np.bool_)
    scale, asym = screen_psd(flat, 0.5 * _PSD_RTOL, sym, failed)
    if asym > _SYM_RTOL * scale:
        raise ValueError(f"{name} must be symmetric positive semidefinite, got asymmetry "
                         f"{asym:.3g}")
    if failed.any():
        lowest = float(np.linalg.eigvalsh(sym[failed]).min())
        if lowest < -_PSD_RTOL * scale:
            raise ValueError(f"{name} must be symmetric positive semidefinite, got eigenvalue "
                             f"{lowest:.3g}")
    return sym.reshape(P.shape)


def _probabilities(value, shape) -> np.ndarray:
    """``mode_prob`` of exactly ``shape``: finite, non-negative, each row summing to 1."""
    p = _finite(value, "mode_prob")
    if p.shape != shape:
        raise ValueError(f"mode_prob must have shape (..., K, L) = {shape} as x_modes, "
                         f"got {p.shape}")
    if np.any(p < 0):
        raise ValueError(f"mode_prob must be non-negative, got minimum {p.min():.3g}")
    worst = float(np.max(np.abs(p.sum(axis=-1) - 1.0)))
    if worst > 1e-9:
        raise ValueError(f"mode_prob must sum to 1 over the modes (last axis), got a row off by "
                         f"{worst:.3g}")
    return p


def _table(F, G, Qd, n) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The transition table: ``F (M, n, n)``, ``G (M, n, l)``, ``Qd (M, n, n)`` symmetric PSD."""
    F, G, Qd = _finite(F, "F"), _finite(G, "G"), _finite(Qd, "Qd")
    if F.ndim != 3 or F.shape[1:] != (n, n) or F.shape[0] == 0:
        raise ValueError(f"F must have shape (M, n, n) with n = {n}, got {F.shape}")
    M = F.shape[0]
    if G.ndim != 3 or G.shape[:2] != (M, n):
        raise ValueError(f"G must have shape (M, n, l) = ({M}, {n}, l) as F, got {G.shape}")
    if Qd.shape != F.shape:
        raise ValueError(f"Qd must have shape (M, n, n) = {F.shape} as F, got {Qd.shape}")
    return F, G, check_symmetric_psd(Qd, "Qd")


def _inputs(u, batch, K, l) -> np.ndarray:
    """``u`` as ``(N, K, l)``: zeros for None; ``(l,)``, ``(K, l)`` broadcast over trials."""
    N = math.prod(batch)
    if u is None:
        return np.zeros((N, K, l))
    u = _finite(u, "u")
    if u.shape not in ((l,), (K, l), (*batch, K, l)):
        raise ValueError(f"u must have shape (l,) = ({l},), (K, l) = ({K}, {l}) or "
                         f"{(*batch, K, l)}, got {u.shape}")
    return np.broadcast_to(u, (*batch, K, l)).reshape(N, K, l)


def _transitions(trans, batch, K, L, M) -> np.ndarray:
    """``trans`` as ``(1, K, L)`` (shared) or ``(N, K, L)``, each entry in ``0..M-1``."""
    trans = int_array(trans, "trans")
    lead = trans.shape[:-2]
    if (trans.ndim < 2 or trans.shape[-2:] != (K, L) or len(lead) > len(batch)
            or any(a not in (1, b) for a, b in zip(lead[::-1], batch[::-1]))):
        raise ValueError(f"trans must have shape (K, L) = ({K}, {L}) or {(*batch, K, L)} "
                         f"(leading axes of length 1 are shared), got {trans.shape}")
    if trans.min() < 0 or trans.max() >= M:
        raise ValueError(f"trans must index the table's 0..{M - 1} entries, "
                         f"got {trans.min()}..{trans.max()}")
    if all(a == 1 for a in lead):
        return trans.reshape(1, K, L)
    return np.broadcast_to(trans, (*batch, K, L)).reshape(-1, K, L)
