"""Expectation steps: the smoothed moments the maximization steps read, and the log-likelihood.

Known modes (``record.modes`` given): the exact E-step of Shumway & Stoffer (1982, J. Time
Series Anal. 3, "An approach to time series smoothing and forecasting using the EM
algorithm", §2-3): the Kalman filter along the modes
(:class:`~switchest.estimators.ModeKalmanFilter`), the Rauch-Tung-Striebel smoother and the
lag-one cross-covariances ``P_{k+1,k|K} = P_{k+1|K} J_k'`` (de Jong & MacKinnon 1988), all from
:func:`~switchest.estimators.smoothing.smooth_mode_matched` with one mode per trial. The mode
``r_k`` at sample ``k`` drives the interval into ``k + 1`` and the measurement at ``k`` (the
convention of ``ModeKalmanFilter`` and of ``switchest.simulate``: the signal is right
continuous, a switch at ``t_{k+1}`` takes effect there).

Unknown modes: the GPB2 filter (Bar-Shalom, Li & Kirubarajan §11.6.5) and Kim's smoother
(Kim 1994, §2.2) give the smoothed mode probabilities ``gamma_k(j)``, the pairwise
probabilities ``xi_k(j, i) = P(r_k = j, r_{k+1} = i | Y)`` and the mode-conditioned lag-one
moments. Here mode ``r_{k+1}`` drives the interval into ``k + 1`` (the convention of the IMM
and GPB filters the fitted model is meant for). The E-step is approximate: the exact posterior
is a mixture of ``L^K`` Gaussians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..discretize import Transition, sample_mode_steps
from ..estimators import GPB2Filter, ModeKalmanFilter
from ..estimators.smoothing import smooth_mode_matched
from ..system import SwitchedLinearSystem
from .data import Record

__all__ = ["Moments", "expectation", "log_likelihood"]


@dataclass(frozen=True, eq=False)
class Moments:
    """What an E-step hands to the M-steps, for ``N`` trials, ``K`` samples, ``L`` modes.

    Attributes
    ----------
    loglik : float
        Log-likelihood of the record under the parameters of the E-step (known modes:
        ``log p(y | r) + sum_k log pi_{r_k r_{k+1}}``; unknown: the filter's ``sum log p(y_k |
        y_0..k-1)``).
    weight : ndarray, shape (N, K, L)
        ``P(r_k = j | Y)`` (one-hot for known modes).
    x, P : ndarray, shapes (N, K, L, n), (N, K, L, n, n)
        Smoothed state moments given ``r_k = j`` (broadcast views for known modes).
    step_weight : ndarray, shape (N, K-1, L)
        Weight of mode ``j`` driving the interval ``k -> k+1``.
    x1, P1 : ndarray, shapes (N, K-1, L, n), (N, K-1, L, n, n)
        Moments of ``x_{k+1}`` given the driving mode ``j`` and ``Y``.
    x0, P0, cross : ndarray, shapes (N, K-1, L, n), (N, K-1, L, n, n), (N, K-1, L, n, n)
        Moments of ``x_k`` and ``Cov(x_{k+1}, x_k)`` given the driving mode and ``Y``.
    table : Transition
        Exact transitions of each mode and distinct step, batch ``(D L,)``.
    entry : ndarray of int64, shape (K-1, L)
        ``entry[k, j]``: the table row of mode ``j`` over the interval ``k -> k+1``.
    pairs : ndarray, shape (L, L)
        Expected transition counts ``sum_k P(r_k = j, r_{k+1} = i | Y)``.
    """

    loglik: float
    weight: np.ndarray
    x: np.ndarray
    P: np.ndarray
    step_weight: np.ndarray
    x1: np.ndarray
    P1: np.ndarray
    x0: np.ndarray
    P0: np.ndarray
    cross: np.ndarray
    table: Transition
    entry: np.ndarray
    pairs: np.ndarray


def expectation(system: SwitchedLinearSystem, transition: np.ndarray, x0, P0,
                data: Record) -> Moments:
    """The E-step under ``system`` and ``transition``: exact for known modes, Kim's otherwise."""
    if data.modes is not None:
        return _known(system, transition, x0, P0, data)
    return _unknown(system, transition, x0, P0, data)


def log_likelihood(system: SwitchedLinearSystem, transition, x0, P0, data: Record) -> float:
    """The log-likelihood :attr:`Moments.loglik` reports, without the smoother."""
    if data.modes is not None:
        out = ModeKalmanFilter(system, x0, P0).run(data.y, data.u, data.t, modes=data.modes)
        return float(out.loglik.sum()) + _mode_term(transition, data.modes)
    out = GPB2Filter(system, transition, x0, P0).run(data.y, data.u, data.t)
    return float(out.loglik.sum())


def _mode_term(transition, modes) -> float:
    """``sum_k log pi_{r_k r_{k+1}}`` of the known mode sequences (``-inf`` if impossible)."""
    with np.errstate(divide="ignore"):
        return float(np.log(transition)[modes[:, :-1], modes[:, 1:]].sum())


def _known(system, transition, x0, P0, data: Record) -> Moments:
    y, u, t, modes = data.y, data.u, data.t, data.modes
    (N, K), L = data.shape, system.n_modes
    out = ModeKalmanFilter(system, x0, P0).run(y, u, t, modes=modes)
    table, entry = sample_mode_steps(system, t)
    trans = np.zeros((N, K), dtype=np.int64)
    trans[:, 1:] = entry[np.arange(1, K), modes[:, :-1]]  # r_k drives the interval into k + 1
    s = smooth_mode_matched(out.x[:, :, None], out.P[:, :, None], np.ones((N, K, 1)), u,
                            table.F, table.G, table.Qd, trans[:, :, None], np.ones((1, 1)),
                            lagged=True)
    onehot = np.eye(L)[modes]  # (N, K, L)

    def modes_axis(a, k_axis_len):
        return np.broadcast_to(a, (N, k_axis_len, L, *a.shape[3:]))

    pairs = np.zeros((L, L))
    np.add.at(pairs, (modes[:, :-1], modes[:, 1:]), 1.0)
    return Moments(
        loglik=float(out.loglik.sum()) + _mode_term(transition, modes),
        weight=onehot, x=modes_axis(s.x[:, :, None], K), P=modes_axis(s.P[:, :, None], K),
        step_weight=onehot[:, :-1],
        x1=modes_axis(s.x[:, 1:, None], K - 1), P1=modes_axis(s.P[:, 1:, None], K - 1),
        x0=modes_axis(s.lag_x, K - 1), P0=modes_axis(s.lag_P, K - 1),
        cross=modes_axis(s.lag_cross, K - 1), table=table, entry=entry[1:], pairs=pairs)


def _unknown(system, transition, x0, P0, data: Record) -> Moments:
    flt = GPB2Filter(system, transition, x0, P0)
    fwd = flt._run_modes(data.y, data.u, data.t)  # the smoother's input (ModeMatchedRun)
    s = smooth_mode_matched(fwd.x_modes, fwd.P_modes, fwd.mode_prob, fwd.u, fwd.F, fwd.G,
                            fwd.Qd, fwd.trans, fwd.transition, lagged=True)
    table = Transition(fwd.F, fwd.G, fwd.Qd)
    return Moments(
        loglik=float(fwd.estimate.loglik.sum()), weight=s.mode_prob, x=s.x_modes, P=s.P_modes,
        step_weight=s.mode_prob[:, 1:],  # r_{k+1} drives the interval into k + 1
        x1=s.x_modes[:, 1:], P1=s.P_modes[:, 1:], x0=s.lag_x, P0=s.lag_P, cross=s.lag_cross,
        table=table, entry=fwd.trans[1:], pairs=s.pair_prob.sum(axis=(0, 1)))
