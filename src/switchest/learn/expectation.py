"""Expectation steps: the smoothed moments the maximization steps read, and the log-likelihood.

Known modes (``record.modes`` given): the exact E-step of Shumway & Stoffer (1982, J. Time
Series Anal. 3, "An approach to time series smoothing and forecasting using the EM
algorithm", §2-3): the Kalman filter along the modes
(:class:`~switchest.estimators.ModeKalmanFilter`), the Rauch-Tung-Striebel smoother and the
lag-one cross-covariances :math:`P_{k+1,k|K} = P_{k+1|K} J_k^\\top` (de Jong & MacKinnon 1988),
all from :func:`~switchest.estimators.smoothing.smooth_mode_matched` with one mode per trial.
The mode :math:`r_k` at sample ``k`` drives the interval into ``k + 1`` and the measurement at
``k`` (the convention of ``ModeKalmanFilter`` and of ``switchest.simulate``: the signal is right
continuous, a switch at :math:`t_{k+1}` takes effect there). Known modes of a continuous-time
system whose switches fall inside the intervals: :mod:`~switchest.learn.between`.

Every E-step runs its filter with the filters' outlier gate: a sample it rejects is missing for
the smoother and the maximization steps (``Moments.y``, ``Moments.outlier``).

Unknown modes: the IMM and the two-filter smoother on the chain of consecutive mode pairs
:math:`s_{k+1} = (r_k, r_{k+1})`, or with switches inside the intervals of (mode before, mode
after, instant) (:mod:`~switchest.learn.chain`): approximate, the exact posterior being a mixture
of :math:`L^K` Gaussians. The pair chain's IMM (:class:`~switchest.estimators.IMMFilter` on the
pair system of :func:`_pair_chain`) gives the likelihood.

Unknown modes, exact (``exact=True``, short records): the posterior enumerated over every mode
sequence ``r`` (Ackerson & Fu 1970; Bar-Shalom, Li & Kirubarajan §11.6.3), in the package's
timing (:class:`~switchest.estimators.ExactMixtureFilter` with ``timing="sample"``). Each
sequence's Kalman filter and RTS smoother with lag-one moments run as one trial of
:class:`~switchest.estimators.ExactMixtureFilter`'s sequences and of
:func:`~switchest.estimators.smoothing.smooth_mode_matched` with one mode; the sequence's
posterior is
:math:`p(r \\mid Y) \\propto p(r_0) \\prod_k \\pi_{r_k r_{k+1}} \\prod_k p(y_k \\mid y_{0:k-1}, r)`.
A moment given :math:`r_k = j` (for the interval :math:`k \\to k+1` too: :math:`r_k` drives it) is
the moment of the mixture of the sequences through ``j`` there, weighted by :math:`p(r \\mid Y)`
(Gaussian-mixture moments: mean of the means, mean covariance plus the spread of the means; the
cross-covariance of :math:`(x_{k+1}, x_k)` as the off-diagonal block of their joint mixture).
The expected complete-data log-likelihood then is exact, and EM never decreases the likelihood
(Dempster, Laird & Rubin 1977, Theorem 1). Cost: :math:`L^K` Kalman filters and smoothers per
trial.
"""

from __future__ import annotations

import numpy as np

from .._linalg import log_normalize
from ..discretize import sample_mode_steps
from ..estimators import ExactMixtureFilter, IMMFilter, ModeKalmanFilter
from ..estimators.mode_chains import chain_transition, instant_chain, pair_chain
from ..estimators.smoothing import smooth_mode_matched
from ..estimators.step_tables import sample_table
from ..estimators.tables import imm_logliks, kalman_logliks
from ..system import SwitchedLinearSystem
from .between import between_log_likelihood, known_between
from .chain import chain_log_likelihood, chain_moments
from .data import Record
from .markov_step import mode_term
from .moments import Moments, mode_mixture

__all__ = ["MAX_SEQUENCES", "Moments", "expectation", "log_likelihood", "log_likelihoods"]

MAX_SEQUENCES = 2**16
"""Most mode sequences :math:`L^K` the exact E-step enumerates (per trial)."""

_ROWS = 2**16  # (sequence, trial) rows per compiled run of the exact E-step
_LANES = 64  # (candidate, trial) rows per compiled run of log_likelihoods


def expectation(system: SwitchedLinearSystem, transition: np.ndarray, x0, P0,
                data: Record, *, exact: bool = False, gate: float | None = None,
                grid: int | None = None) -> Moments:
    """The E-step under ``system`` and ``transition``: exact for known modes switching at the
    samples; with ``grid`` (known modes of a continuous-time system switching inside the
    intervals) the switch-time filter's with the instants marginalized over a grid of that
    many (:func:`~switchest.learn.between.known_between`); for unknown modes the chain's
    (:func:`~switchest.learn.chain.chain_moments`, with ``grid`` on the chain of instants), or
    with ``exact`` the enumeration of every mode sequence. ``gate`` is the filters' outlier gate
    (:class:`~switchest.estimators.ModeKalmanFilter`): the samples it rejects are missing for
    the smoother and the maximization steps (``Moments.y``, ``Moments.outlier``)."""
    if data.modes is not None:
        if grid is not None:
            return known_between(system, transition, x0, P0, data, grid=grid, gate=gate)
        return _known(system, transition, x0, P0, data, gate)
    if exact:
        return _enumerated(system, transition, x0, P0, data, gate)
    chain = (pair_chain(system, transition, data.t) if grid is None else
             instant_chain(system, transition, data.t, grid))
    return chain_moments(chain, data, x0, P0, system.n_modes, gate)


def log_likelihood(system: SwitchedLinearSystem, transition, x0, P0, data: Record, *,
                   exact: bool = False, grid: int | None = None) -> float:
    """The log-likelihood :attr:`Moments.loglik` reports, without the smoother (and without a
    gate: give the record of the E-step's measurements, ``Moments.y``)."""
    if grid is not None:
        if data.modes is not None:
            return between_log_likelihood(system, transition, x0, P0, data, grid=grid)
        return chain_log_likelihood(instant_chain(system, transition, data.t, grid), data, x0,
                                    P0)
    if data.modes is not None:
        out = ModeKalmanFilter(system, x0, P0).run(data.y, data.u, data.t, modes=data.modes)
        return float(out.loglik.sum()) + mode_term(transition, data.modes)
    if exact:
        flt = ExactMixtureFilter(system, transition, x0, P0, max_sequences=MAX_SEQUENCES,
                                 timing="sample")
        return float(sum(flt.run(data.y[c], data.u[c], data.t).loglik.sum()
                         for c in _chunks(data, system.n_modes)))
    out = _pair_filter(system, transition, x0, P0).run(data.y, data.u, data.t)
    return float(out.loglik.sum())


def log_likelihoods(candidates, x0, P0, data: Record, *, exact: bool = False,
                    grid: int | None = None) -> np.ndarray:
    """:func:`log_likelihood` of each ``(system, transition)`` of ``candidates`` (all with the
    sizes of one model), NaN where its filter fails (a transition or covariance beyond the
    floating-point range).

    The candidates' filters run together in one compiled call, each (candidate, trial) a trial
    under its own model: the Kalman filters along known modes
    (:func:`~switchest.estimators.tables.kalman_logliks`), or with unknown modes the pair-chain
    IMMs (:func:`~switchest.estimators.tables.imm_logliks`; :math:`L^2` mode-matched
    filters per sample). The trials then fill the SIMD lanes, where one record alone leaves all
    but one empty (about ten times the cost per trial-step for the IMM). The values are those
    of :func:`log_likelihood`, computed by the same kernels; the exact E-step's enumeration
    and the switch-time filter of switches inside the intervals (``grid``) run one candidate
    at a time (each candidate's filter its own tables).
    """
    candidates = list(candidates)
    if (exact and data.modes is None) or grid is not None:
        return np.array([_or_nan(log_likelihood, s, pi, x0, P0, data, exact=exact, grid=grid)
                         for s, pi in candidates])
    size = max(1, _LANES // data.shape[0])
    return np.concatenate([_together(candidates[a:a + size], x0, P0, data)
                           for a in range(0, len(candidates), size)] or [np.zeros(0)])


def _or_nan(function, *args, **kwargs) -> float:
    """``function(*args, **kwargs)``, or NaN where a transition or covariance overflows."""
    try:
        return function(*args, **kwargs)
    except (ValueError, np.linalg.LinAlgError):
        return np.nan


def _together(candidates, x0, P0, data: Record) -> np.ndarray:
    """The log-likelihood of each candidate, all in one compiled call (each candidate's tables
    appended to one table); NaN for a candidate whose transitions overflow, and one candidate
    at a time if that call fails. With unknown modes each candidate's pair chain runs on its
    own ``L`` modes' tables: pair ``(a, b)`` moves through mode ``a``'s entries and measures
    through mode ``b``'s ``C``, ``R`` (:func:`_pair_chain`, without discretizing each mode
    ``L`` times)."""
    N, K = data.shape
    values = np.full(len(candidates), np.nan)
    tables, entries, where, offset = [], [], [], 0
    for q, (system, _) in enumerate(candidates):
        try:
            table, entry = sample_mode_steps(system, data.t)
        except ValueError:  # a transition beyond the floating-point range
            continue
        tables.append(table)
        entries.append(entry + offset)
        where.append(q)
        offset += table.F.shape[0]
    if not where:
        return values
    S, L = len(where), candidates[0][0].n_modes
    F, G, Qd = (np.concatenate([getattr(t, name) for t in tables]) for name in ("F", "G", "Qd"))
    C, R = (np.concatenate([getattr(candidates[q][0], name) for q in where])
            for name in ("C", "R"))
    y, u = np.tile(data.y, (S, 1, 1)), np.tile(data.u, (S, 1, 1))
    if data.modes is not None:  # each interval in the mode at its start (ModeKalmanFilter's)
        before = np.concatenate([data.modes[:, :1], data.modes[:, :-1]], axis=1)  # (N, K)
        trans = np.concatenate([entry[np.arange(K), before] for entry in entries])
        mode = np.concatenate([data.modes + s * L for s in range(S)])
        loglik = kalman_logliks(y, u, F, G, Qd, trans, C, R, mode, x0, P0)
        extra = np.array([mode_term(candidates[q][1], data.modes) for q in where])
    else:
        a, b = np.divmod(np.arange(L * L), L)
        chains = [_pair_markov(candidates[q][1]) for q in where]
        with np.errstate(divide="ignore"):
            log_chain = np.log([chain for chain, _ in chains])
            log_prior = np.log(chains[0][1])
        trans = np.concatenate([np.broadcast_to(entry[:, a], (N, K, L * L)) for entry in entries])
        loglik = imm_logliks(y, u, F, G, Qd, trans, C, R,
                             np.repeat(np.arange(S)[:, None] * L + b, N, axis=0),
                             np.repeat(log_chain, N, axis=0), x0, P0, log_prior,
                             timing="interval")
        extra = 0.0
    if loglik is not None:
        values[where] = loglik.reshape(S, N * K).sum(axis=1) + extra
    else:
        values[where] = [_or_nan(log_likelihood, *candidates[q], x0, P0, data) for q in where]
    return values


def _masked(y: np.ndarray, outlier: np.ndarray) -> np.ndarray:
    """``y`` with the gated samples missing."""
    return np.where(outlier[..., None], np.nan, y)


def _known(system, transition, x0, P0, data: Record, gate) -> Moments:
    u, t, modes = data.u, data.t, data.modes
    (N, K), L = data.shape, system.n_modes
    out = ModeKalmanFilter(system, x0, P0, gate=gate).run(data.y, u, t, modes=modes)
    table, entry = sample_table(system, t)
    trans = np.zeros((N, K), dtype=np.int64)
    trans[:, 1:] = entry[np.arange(1, K), modes[:, :-1]]  # r_k drives the interval into k + 1
    s = smooth_mode_matched(out.x[:, :, None], out.P[:, :, None], np.ones((N, K, 1)), u,
                            table.F, table.G, table.Qd, trans[:, :, None], np.ones((1, 1)),
                            lagged=True, timing="interval")  # one mode: the timings agree
    onehot = np.eye(L)[modes]  # (N, K, L)

    def modes_axis(a, k_axis_len):
        return np.broadcast_to(a, (N, k_axis_len, L, *a.shape[3:]))

    pairs = np.zeros((L, L))
    np.add.at(pairs, (modes[:, :-1], modes[:, 1:]), 1.0)
    return Moments(
        loglik=float(out.loglik.sum()) + mode_term(transition, modes),
        weight=onehot, x=modes_axis(s.x[:, :, None], K), P=modes_axis(s.P[:, :, None], K),
        step_weight=onehot[:, :-1],
        x1=modes_axis(s.x[:, 1:, None], K - 1), P1=modes_axis(s.P[:, 1:, None], K - 1),
        x0=modes_axis(s.lag_x, K - 1), P0=modes_axis(s.lag_P, K - 1),
        cross=modes_axis(s.lag_cross, K - 1), table=table, entry=entry[1:], pairs=pairs,
        y=_masked(data.y, out.outlier), outlier=out.outlier)


def _pair_filter(system: SwitchedLinearSystem, transition, x0, P0, gate=None) -> IMMFilter:
    """The IMM on the chain of consecutive mode pairs (:func:`_pair_chain`)."""
    pairs, chain, prior = _pair_chain(system, transition)
    return IMMFilter(pairs, chain, x0, P0, mode_prob0=prior, timing="interval", gate=gate)


def _pair_chain(system: SwitchedLinearSystem, transition
                ) -> tuple[SwitchedLinearSystem, np.ndarray, np.ndarray]:
    """The chain of consecutive mode pairs :math:`s_k = (r_{k-1}, r_k)`, pair ``(a, b)`` at
    index :math:`a L + b` (module docstring): its system, whose mode ``(a, b)`` moves through
    mode ``a``'s ``A``, ``B``, ``Q`` and measures through mode ``b``'s ``C``, ``R``, its
    transition matrix and its prior at sample 0, which is only measured: the pair there is
    :math:`(r_0, r_0)` with :math:`r_0` uniform. The pair system is in the ``"interval"``
    timing, the one in which it rewrites the ``"sample"``-timed model exactly."""
    L = system.n_modes
    a, b = np.divmod(np.arange(L * L), L)
    parts = {"A": system.A[a], "B": system.B[a], "C": system.C[b], "Q": system.Q[a],
             "R": system.R[b]}
    return system.replace(**parts, timing="interval"), *_pair_markov(transition)


def _pair_markov(transition: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pair chain's transition matrix, :math:`P((b, c) \\mid (a, b')) = [b = b']\\, \\pi_{bc}`,
    and its prior at sample 0, :math:`(r_0, r_0)` with :math:`r_0` uniform
    (:func:`_pair_chain`; :func:`~switchest.estimators.mode_chains.chain_transition`)."""
    L = transition.shape[0]
    a, b = np.divmod(np.arange(L * L), L)
    return chain_transition(a, b, transition[a, b], L)


def _chunks(data: Record, L: int) -> list[slice]:
    """Trials in blocks of at most :data:`_ROWS` (sequence, trial) rows (at least one trial)."""
    N, K = data.shape
    size = max(1, _ROWS // L**K)
    return [slice(a, min(a + size, N)) for a in range(0, N, size)]


def _enumerated(system, transition, x0, P0, data: Record, gate) -> Moments:
    """The exact E-step of unknown modes, by enumeration (module docstring), of the samples
    the pair chain's IMM does not gate (:func:`_unknown`'s filter, whose gate sees the same
    predictions up to its merging)."""
    outlier = _pair_filter(system, transition, x0, P0, gate).run(
        data.y, data.u, data.t).outlier
    y = _masked(data.y, outlier)
    parts = [_enumerated_block(system, transition, x0, P0, y[c], data.u[c], data.t)
             for c in _chunks(data, system.n_modes)]
    table, entry = sample_table(system, data.t)
    fields = {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}
    weight = fields.pop("weight")
    pair = fields.pop("pair")
    return Moments(loglik=float(fields.pop("loglik").sum()), weight=weight,
                   step_weight=weight[:, :-1],  # r_k drives the interval into k + 1
                   table=table, entry=entry[1:], pairs=pair.sum(axis=(0, 1)), y=y,
                   outlier=outlier, **fields)


def _enumerated_block(system, transition, x0, P0, y, u, t) -> dict[str, np.ndarray]:
    """Moments of one block of ``N`` trials, summed over the :math:`S = L^K` sequences."""
    flt = ExactMixtureFilter(system, transition, x0, P0, max_sequences=MAX_SEQUENCES,
                             timing="sample")
    seq, _ = flt._sequences(y, u, t)  # every sequence's Kalman filter, one trial each
    S, N, K, n = seq.x.shape
    L = system.n_modes
    rts = smooth_mode_matched(  # the RTS smoother with lag-one moments of every sequence
        seq.x.reshape(S * N, K, 1, n), seq.P.reshape(S * N, K, 1, n, n), np.ones((S * N, K, 1)),
        seq.u, seq.F, seq.G, seq.Qd, seq.trans.reshape(S * N, K, 1), np.ones((1, 1)),
        lagged=True, timing="interval")  # one mode per sequence: the timings agree
    log_w, loglik = log_normalize(seq.cum[..., -1], axis=0)  # p(r | Y) (S, N), log p(Y) (N,)
    w = np.exp(log_w).T  # (N, S)
    onehot = np.eye(L)[seq.modes]  # (S, K, L)
    weight = np.einsum("ns,skj->nkj", w, onehot)
    pair = np.einsum("ns,skj,ski->nkji", w, onehot[:, :-1], onehot[:, 1:])

    smoothed_x = np.moveaxis(rts.x.reshape(S, N, K, n), 0, 2)  # (N, K, S, n)
    smoothed_P = np.moveaxis(rts.P.reshape(S, N, K, n, n), 0, 2)
    through = np.moveaxis(onehot, 0, 1)[None]  # (1, K, S, L): the sequences through each mode
    x, P = mode_mixture(w[:, None], weight, through, smoothed_x, smoothed_P)
    # the pair (x_{k+1}, x_k) of each sequence, jointly Gaussian: mean (x_{k+1|K}, x_{k|K}),
    # covariance [[P_{k+1|K}, C_k], [C_k', P_{k|K}]], C_k = Cov(x_{k+1}, x_k | r, Y)
    lag_x = np.moveaxis(rts.lag_x[:, :, 0].reshape(S, N, K - 1, n), 0, 2)
    lag_P = np.moveaxis(rts.lag_P[:, :, 0].reshape(S, N, K - 1, n, n), 0, 2)
    cross = np.moveaxis(rts.lag_cross[:, :, 0].reshape(S, N, K - 1, n, n), 0, 2)
    joint_x = np.concatenate([smoothed_x[:, 1:], lag_x], axis=-1)
    joint_P = np.block([[smoothed_P[:, 1:], cross], [np.swapaxes(cross, -1, -2), lag_P]])
    # the interval k -> k+1 is driven by r_k: the sequences through each mode at k
    jx, jP = mode_mixture(w[:, None], weight[:, :-1], through[:, :-1], joint_x, joint_P)
    return {"loglik": loglik, "weight": weight, "pair": pair, "x": x, "P": P,
            "x1": jx[..., :n], "P1": jP[..., :n, :n], "x0": jx[..., n:], "P0": jP[..., n:, n:],
            "cross": jP[..., :n, n:]}
