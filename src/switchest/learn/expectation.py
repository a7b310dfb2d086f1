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

Unknown modes, exact (``exact=True``, short records): the posterior enumerated over every mode
sequence ``r`` (Ackerson & Fu 1970; Bar-Shalom, Li & Kirubarajan §11.6.3), in the convention
of the GPB2 path. Each sequence's Kalman filter and RTS smoother with lag-one moments run as
one trial of :class:`~switchest.estimators.ExactMixtureFilter`'s sequences and of
:func:`~switchest.estimators.smoothing.smooth_mode_matched` with one mode; the sequence's
posterior is ``p(r | Y) ∝ p(r_0) prod_k pi_{r_k r_{k+1}} prod_k p(y_k | y_0..k-1, r)``. A
moment given ``r_k = j`` (or, for an interval, ``r_{k+1} = j``) is the moment of the mixture
of the sequences through ``j`` there, weighted by ``p(r | Y)`` (Gaussian-mixture moments:
mean of the means, mean covariance plus the spread of the means; the cross-covariance of
``(x_{k+1}, x_k)`` as the off-diagonal block of their joint mixture). The expected
complete-data log-likelihood then is exact, and EM never decreases the likelihood (Dempster,
Laird & Rubin 1977, Theorem 1). Cost: ``L^K`` Kalman filters and smoothers per trial.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._linalg import log_normalize, mixture_moments
from ..discretize import Transition, sample_mode_steps
from ..estimators import ExactMixtureFilter, GPB2Filter, ModeKalmanFilter
from ..estimators.smoothing import smooth_filtered, smooth_mode_matched
from ..system import SwitchedLinearSystem
from .data import Record

__all__ = ["MAX_SEQUENCES", "Moments", "expectation", "log_likelihood"]

MAX_SEQUENCES = 2**16
"""Most mode sequences ``L^K`` the exact E-step enumerates (per trial)."""

_ROWS = 2**16  # (sequence, trial) rows per compiled run of the exact E-step


@dataclass(frozen=True, eq=False)
class Moments:
    """What an E-step hands to the M-steps, for ``N`` trials, ``K`` samples, ``L`` modes.

    Attributes
    ----------
    loglik : float
        Log-likelihood of the record under the parameters of the E-step (known modes:
        ``log p(y | r) + sum_k log pi_{r_k r_{k+1}}``; unknown: the GPB2 filter's ``sum log
        p(y_k | y_0..k-1)``, or with the exact E-step the exact ``log p(y)``, which
        :class:`~switchest.estimators.ExactMixtureFilter`'s ``loglik`` sums to).
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
                data: Record, *, exact: bool = False) -> Moments:
    """The E-step under ``system`` and ``transition``: exact for known modes; for unknown
    modes Kim's, or with ``exact`` the enumeration of every mode sequence."""
    if data.modes is not None:
        return _known(system, transition, x0, P0, data)
    if exact:
        return _enumerated(system, transition, x0, P0, data)
    return _unknown(system, transition, x0, P0, data)


def log_likelihood(system: SwitchedLinearSystem, transition, x0, P0, data: Record, *,
                   exact: bool = False) -> float:
    """The log-likelihood :attr:`Moments.loglik` reports, without the smoother."""
    if data.modes is not None:
        out = ModeKalmanFilter(system, x0, P0).run(data.y, data.u, data.t, modes=data.modes)
        return float(out.loglik.sum()) + _mode_term(transition, data.modes)
    if exact:
        flt = ExactMixtureFilter(system, transition, x0, P0, max_sequences=MAX_SEQUENCES)
        return float(sum(flt.run(data.y[c], data.u[c], data.t).loglik.sum()
                         for c in _chunks(data, system.n_modes)))
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
    fwd = flt.run_modes(data.y, data.u, data.t)  # the smoother's input (ModeMatchedRun)
    s = smooth_filtered(fwd.x_modes, fwd.P_modes, fwd.mode_prob, fwd.u, fwd.F, fwd.G,
                        fwd.Qd, fwd.trans, fwd.transition, lagged=True)
    table = Transition(fwd.F, fwd.G, fwd.Qd)
    return Moments(
        loglik=float(fwd.estimate.loglik.sum()), weight=s.mode_prob, x=s.x_modes, P=s.P_modes,
        step_weight=s.mode_prob[:, 1:],  # r_{k+1} drives the interval into k + 1
        x1=s.x_modes[:, 1:], P1=s.P_modes[:, 1:], x0=s.lag_x, P0=s.lag_P, cross=s.lag_cross,
        table=table, entry=fwd.trans[1:], pairs=s.pair_prob.sum(axis=(0, 1)))


def _chunks(data: Record, L: int) -> list[slice]:
    """Trials in blocks of at most :data:`_ROWS` (sequence, trial) rows (at least one trial)."""
    N, K = data.shape
    size = max(1, _ROWS // L**K)
    return [slice(a, min(a + size, N)) for a in range(0, N, size)]


def _enumerated(system, transition, x0, P0, data: Record) -> Moments:
    """The exact E-step of unknown modes, by enumeration (module docstring)."""
    parts = [_enumerated_block(system, transition, x0, P0, data.y[c], data.u[c], data.t)
             for c in _chunks(data, system.n_modes)]
    table, entry = sample_mode_steps(system, data.t)
    fields = {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}
    weight = fields.pop("weight")
    pair = fields.pop("pair")
    return Moments(loglik=float(fields.pop("loglik").sum()), weight=weight,
                   step_weight=weight[:, 1:],  # r_{k+1} drives the interval into k + 1
                   table=table, entry=entry[1:], pairs=pair.sum(axis=(0, 1)), **fields)


def _enumerated_block(system, transition, x0, P0, y, u, t) -> dict[str, np.ndarray]:
    """Moments of one block of ``N`` trials, summed over the ``S = L^K`` sequences."""
    flt = ExactMixtureFilter(system, transition, x0, P0, max_sequences=MAX_SEQUENCES)
    seq, _ = flt._sequences(y, u, t)  # every sequence's Kalman filter, one trial each
    S, N, K, n = seq.x.shape
    L = system.n_modes
    rts = smooth_mode_matched(  # the RTS smoother with lag-one moments of every sequence
        seq.x.reshape(S * N, K, 1, n), seq.P.reshape(S * N, K, 1, n, n), np.ones((S * N, K, 1)),
        seq.u, seq.F, seq.G, seq.Qd, seq.trans.reshape(S * N, K, 1), np.ones((1, 1)),
        lagged=True)
    log_w, loglik = log_normalize(seq.cum[..., -1], axis=0)  # p(r | Y) (S, N), log p(Y) (N,)
    w = np.exp(log_w).T  # (N, S)
    onehot = np.eye(L)[seq.modes]  # (S, K, L)
    weight = np.einsum("ns,skj->nkj", w, onehot)
    pair = np.einsum("ns,skj,ski->nkji", w, onehot[:, :-1], onehot[:, 1:])

    def given(w_k, weight_k, x, P):
        """Moments of the mixture over the sequences through each mode, ``x (N, K', S, d)``:
        weights ``w_k (N, K', S, L)`` normalized by ``weight_k (N, K', L)``; a mode no
        sequence of positive weight passes gets the mixture of all (its weight is zero)."""
        none = weight_k <= 0.0
        cond = np.where(none[:, :, None], w[:, None, :, None],
                        w_k / np.where(none, 1.0, weight_k)[:, :, None])
        return mixture_moments(cond, x, P)

    smoothed_x = np.moveaxis(rts.x.reshape(S, N, K, n), 0, 2)  # (N, K, S, n)
    smoothed_P = np.moveaxis(rts.P.reshape(S, N, K, n, n), 0, 2)
    through = w[:, None, :, None] * np.moveaxis(onehot, 0, 1)[None]  # (N, K, S, L)
    x, P = given(through, weight, smoothed_x, smoothed_P)
    # the pair (x_{k+1}, x_k) of each sequence, jointly Gaussian: mean (x_{k+1|K}, x_{k|K}),
    # covariance [[P_{k+1|K}, C_k], [C_k', P_{k|K}]], C_k = Cov(x_{k+1}, x_k | r, Y)
    lag_x = np.moveaxis(rts.lag_x[:, :, 0].reshape(S, N, K - 1, n), 0, 2)
    lag_P = np.moveaxis(rts.lag_P[:, :, 0].reshape(S, N, K - 1, n, n), 0, 2)
    cross = np.moveaxis(rts.lag_cross[:, :, 0].reshape(S, N, K - 1, n, n), 0, 2)
    joint_x = np.concatenate([smoothed_x[:, 1:], lag_x], axis=-1)
    joint_P = np.block([[smoothed_P[:, 1:], cross], [np.swapaxes(cross, -1, -2), lag_P]])
    jx, jP = given(through[:, 1:], weight[:, 1:], joint_x, joint_P)
    return {"loglik": loglik, "weight": weight, "pair": pair, "x": x, "P": P,
            "x1": jx[..., :n], "P1": jP[..., :n, :n], "x0": jx[..., n:], "P0": jP[..., n:, n:],
            "cross": jP[..., :n, n:]}
