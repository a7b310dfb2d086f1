"""The exact posterior of a jump-Markov linear system: a Gaussian per mode sequence.

The modes are a Markov chain that jumps at the samples,
:math:`\\Pr(r_k = j \\mid r_{k-1} = i)` = ``transition[i, j]``, :math:`\\Pr(r_0 = j)` =
``mode_prob0[j]``; mode :math:`r_k` of sample :math:`k` governs the
measurement at :math:`k` and, by the ``timing`` (:doc:`/conventions`), the interval after :math:`k`
(``"sample"``: :math:`x_{k+1} = F(r_k) x_k + G(r_k) u_k + w_k`,
:math:`w_k \\sim \\mathcal{N}(0, Q_d(r_k))`, :math:`y_k = C(r_k) x_k + v_k`,
:math:`v_k \\sim \\mathcal{N}(0, R(r_k))`;
Costa, Fragoso & Marques 2005, eq. (3.1)) or the interval into :math:`k` (``"interval"``,
Bar-Shalom, Li & Kirubarajan 2001, §11.6: :math:`x_k = F(r_k) x_{k-1} + G(r_k) u_{k-1} + w`,
:math:`y_k = C(r_k) x_k + v`; the default), :math:`F, G, Q_d` the exact discretization of a
mode over the interval.
So a sequence predicts into sample :math:`k` through :math:`r_{k-1}`'s transition in the
``"sample"`` timing and through :math:`r_k`'s in the ``"interval"`` timing, and updates with
:math:`C(r_k)`, :math:`R(r_k)` in both. Given a mode sequence :math:`r = (r_0, \\dots, r_{K-1})`
the system is linear Gaussian, so the posterior of the state is the mixture over the
:math:`L^K` sequences of the Kalman filter's (or RTS smoother's) Gaussian along each (Ackerson &
Fu 1970; Bar-Shalom, Li & Kirubarajan §11.6.3, the optimal dynamic multiple model estimator). It
is exponential in :math:`K`:
the yardstick the IMM, GPB and Kim smoother approximate, for short records only, refused
beyond ``max_sequences``.

The Kalman filters run in the filters' compiled kernel
(:func:`~switchest.engine.kalman.kalman_run`), every (sequence, trial) one trial of
it; the RTS smoother of each sequence is Kim's smoother with one mode
(:func:`~switchest.estimators.smoothing.smooth_mode_matched`), so each equation has one
implementation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import check_memory, positive_int
from .._linalg import log_normalize, mixture_moments
from ..discretize import mode_steps, sample_mode_steps
from ..engine import GATED, raise_for_status, warn_for_repairs
from ..engine.kalman import kalman_run, kalman_step
from .base import Estimate, Estimator, _with_mode_model_parameters
from .smoothing import smooth_mode_matched

__all__ = ["ExactMixtureState", "ExactMixtureFilter"]


@dataclass(frozen=True, eq=False)
class ExactMixtureState:
    """The exact posterior after a sample, for a batch of trials (``...``): one Gaussian per
    mode sequence up to that sample (a prefix), :math:`S` of them (:math:`L^{k+1}` after sample
    :math:`k`).

    Attributes
    ----------
    x, P : ndarray, shapes (..., S, n), (..., S, n, n)
        Each prefix's Kalman posterior.
    log_weight : ndarray, shape (..., S)
        Log posterior probability of each prefix (normalized; before the first sample the
        prior of :math:`r_0`).
    last_mode : ndarray of int, shape (S,)
        The mode of each prefix at the last sample (the prefixes are the same for every
        trial).
    loglik : ndarray, shape (...)
        Log-likelihood of the last measurement given the past (0 when nothing was observed
        or the measurement was an outlier).
    outlier : ndarray of bool, shape (...)
        True where every prefix's Kalman filter rejected the last measurement (its innovation
        overflowed): it was treated as missing.
    mode_prob : ndarray, shape (..., L)
        Posterior mode probabilities at the last sample.
    combined_x, combined_P : ndarray, shapes (..., n), (..., n, n)
        Mean and covariance of the mixture: what ``run`` reports.
    """

    x: np.ndarray
    P: np.ndarray
    log_weight: np.ndarray
    last_mode: np.ndarray
    loglik: np.ndarray
    outlier: np.ndarray
    mode_prob: np.ndarray
    combined_x: np.ndarray
    combined_P: np.ndarray


@_with_mode_model_parameters
class ExactMixtureFilter(Estimator):
    """Exact filter and smoother of a jump-Markov linear system, over every mode sequence.

    Parameters
    ----------
    {mode model parameters}
    max_sequences : int
        Most mode sequences (:math:`L^K` for :math:`K` samples) a run or a stream may hold
        (keyword-only); more are refused with a ``ValueError``.
    timing : {"sample", "interval"}, optional
        Which interval the mode of sample :math:`k` governs besides :math:`y_k` (keyword-only;
        module docstring): the one after it (``"sample"``) or the one into it
        (``"interval"``, Bar-Shalom's); ``None`` (the default): the system's ``timing``, and
        another is named in a :class:`~switchest.estimators.TimingWarning`. The filter is
        exact in either.

    Notes
    -----
    Filtering: the posterior at sample :math:`k` is the mixture of the prefixes' Kalman posteriors
    :math:`\\mathcal{N}(x_k(r_{0:k}), P_k(r_{0:k}))` weighted by

    .. math::

        p(r_{0:k} \\mid y_{0:k}) \\propto p(r_{0:k}) \\prod_{t \\le k} \\Lambda_t(r_{0:t}),

    :math:`\\Lambda_t` the likelihood of :math:`y_t` given the past along
    the prefix. ``run`` holds full sequences only and weights each by
    :math:`p(r_{0:K-1}) \\prod_{t \\le k} \\Lambda_t`: the Gaussian and the likelihoods up to
    :math:`k` depend on the prefix alone, and the prior summed over the suffixes
    :math:`r_{k+1:K-1}` is the prefix's :math:`p(r_{0:k})` (the rows of ``transition`` sum to 1),
    so the :math:`L^{K-1-k}` sequences sharing a prefix together carry exactly the prefix's
    weight: the mixture is the exact filter.
    Smoothing weights each sequence by the whole record, :math:`p(r) \\prod_{t<K} \\Lambda_t(r)`,
    and takes its RTS-smoothed moments (Rauch, Tung & Striebel 1965).

    Streaming (``step``) keeps the prefixes themselves, ``L`` times more after each sample
    (refused past ``max_sequences``).

    Examples
    --------
    >>> import numpy as np
    >>> from switchest import SwitchedLinearSystem, simulate
    >>> from switchest.signals import markov_at_samples
    >>> system = SwitchedLinearSystem.discrete(A=[[[0.5]], [[1.0]]], Q=[[[0.05]], [[0.3]]],
    ...                                        R=[[1.0]])  # x_{k+1} = a_j x_k + w_k
    >>> transition = np.array([[0.85, 0.15], [0.2, 0.8]])
    >>> t = np.arange(10.0)
    >>> traj = simulate(system, lambda rng: markov_at_samples(transition, t, rng=rng), t,
    ...                 np.zeros(1), trials=2, rng=3)
    >>> exact = ExactMixtureFilter(system, transition, np.zeros(1), np.eye(1))
    >>> est = exact.run(traj.y, t=t)  # 2^10 mode sequences, each its Kalman filter
    >>> est.x.shape, est.mode_prob.shape
    ((2, 10, 1), (2, 10, 2))
    """

    def __init__(self, system, transition, x0, P0, *, mode_prob0=None,
                 max_sequences: int = 2**16, timing: str | None = None):
        self._set_prior(system, x0, P0)
        self._set_mode_prior(transition, mode_prob0)
        self.max_sequences = positive_int(max_sequences, "max_sequences")
        self._set_timing(timing)

    # ------------------------------------------------------------------ streaming
    def init(self, batch_shape=()) -> ExactMixtureState:
        """The prior: one component per mode :math:`r_0 = j`, at ``(x0, P0)`` with weight
        ``mode_prob0[j]``."""
        L = self.system.n_modes
        self._refuse(L, f"L = {L} modes at the first sample")
        x, P = self._prior_copies((*batch_shape, L))
        combined_x, combined_P = self._prior_copies(batch_shape)
        return ExactMixtureState(
            x=x, P=P, log_weight=np.broadcast_to(self._log_p0, (*batch_shape, L)).copy(),
            last_mode=np.arange(L), loglik=np.zeros(batch_shape),
            outlier=np.zeros(batch_shape, dtype=bool),
            mode_prob=np.broadcast_to(self.mode_prob0, (*batch_shape, L)).copy(),
            combined_x=combined_x, combined_P=combined_P)

    def step(self, state: ExactMixtureState, y, u=None, *, dt=None) -> ExactMixtureState:
        """Extend every prefix by each mode and predict over ``dt`` (skipped when None: the
        first sample, whose prefixes are the prior's), then update with ``y (..., m)``.

        A prefix :math:`r_{0:k-1}` of weight :math:`w` becomes :math:`L` prefixes
        :math:`(r_{0:k-1}, j)` of weight :math:`w \\pi_{r_{k-1}, j} \\Lambda_k` (normalized), each
        predicted with the exact transition of mode :math:`r_{k-1}` (``"sample"`` timing) or
        :math:`j` (``"interval"``) and updated with :math:`C_j`, :math:`R_j` by the compiled Kalman
        kernel
        (:func:`~switchest.engine.kalman.kalman_step`).
        """
        sys = self.system
        batch = state.log_weight.shape[:-1]
        L, n, l, m = sys.n_modes, sys.n_states, sys.n_inputs, sys.n_outputs
        N, S = math.prod(batch), state.last_mode.size
        x, P = state.x.reshape(N, S, n), state.P.reshape(N, S, n, n)
        log_w, mode = state.log_weight.reshape(N, S), state.last_mode
        moving = mode  # the mode whose transition each prefix takes into this sample
        if dt is not None:  # every prefix r_0..k-1 extended by each mode r_k = j
            self._refuse(S * L, f"{S} prefixes times L = {L} modes")
            parent, mode = np.repeat(np.arange(S), L), np.tile(np.arange(L), S)
            x, P = x[:, parent], P[:, parent]
            log_w = log_w[:, parent] + self._log_transition[state.last_mode[parent], mode]
            moving = state.last_mode[parent] if self.timing == "sample" else mode
            S = mode.size
        y = np.asarray(y, dtype=float).reshape(N, m)
        u = np.zeros((N, l)) if u is None else np.broadcast_to(u, (*batch, l)).reshape(N, l)
        if dt is None:  # update only: the transition is not read
            F, G, Qd = np.zeros((S, n, n)), np.zeros((S, n, l)), np.zeros((S, n, n))
        else:
            steps = mode_steps(sys, dt)
            F, G, Qd = steps.F[moving], steps.G[moving], steps.Qd[moving]

        def per_trial(a):  # (N, ...) -> one row per (trial, prefix): (N S, ...)
            return np.repeat(a, S, axis=0)

        def per_prefix(a):  # (S, ...) -> (N S, ...)
            return np.broadcast_to(a, (N, *a.shape)).reshape(N * S, *a.shape[1:])

        out = kalman_step(x.reshape(N * S, n), P.reshape(N * S, n, n), per_trial(y), per_trial(u),
                          *(per_prefix(a) for a in (F, G, Qd, sys.C[mode], sys.R[mode])),
                          predict_first=dt is not None)
        raise_for_status(out.status)
        warn_for_repairs(out)
        loglik, outlier = _rejected(out.loglik.reshape(N, S), out.flag.reshape(N, S), axis=1)
        log_w, total = log_normalize(log_w + loglik, axis=-1)
        x, P = out.x.reshape(N, S, n), out.P.reshape(N, S, n, n)
        w = np.exp(log_w)
        mean, cov = mixture_moments(w[..., None], x, P)
        seen = ~np.all(np.isnan(y), axis=-1) & ~outlier
        return ExactMixtureState(
            x=x.reshape(*batch, S, n), P=P.reshape(*batch, S, n, n),
            log_weight=log_w.reshape(*batch, S), last_mode=mode,
            loglik=np.where(seen, total, 0.0).reshape(batch), outlier=outlier.reshape(batch),
            mode_prob=(w @ np.eye(L)[mode]).reshape(*batch, L),
            combined_x=mean[:, 0].reshape(*batch, n), combined_P=cov[:, 0].reshape(*batch, n, n))

    # ------------------------------------------------------------------ whole records
    def run(self, y, u=None, t=None, *, data_timing: str | None = None) -> Estimate:
        """The exact filter over ``y (..., K, m)``: the mixture's ``x``, ``P``, ``mode_prob``,
        the most probable ``mode``, ``loglik``, the log-likelihood of each measurement given
        the past, and ``outlier``, the measurements every sequence rejected (an overflowing
        innovation, treated as missing), after each sample (see the class Notes).
        ``data_timing``, the timing ``y`` was drawn in
        (:attr:`switchest.simulate.Trajectory.timing`), is named in a
        :class:`~switchest.estimators.TimingWarning` when it is not the filter's."""
        self._check_data_timing(data_timing)
        seq, batch = self._sequences(y, u, t)
        w, total = log_normalize(seq.cum, axis=0)  # (S, N, K): p(r_0..k | y_0..k) per sequence
        loglik = np.diff(total, axis=-1, prepend=0.0)
        return self._mixture(w, seq.x, seq.P, seq.modes, batch, loglik=loglik,
                             outlier=seq.outlier)

    def smooth(self, y, u=None, t=None, *, data_timing: str | None = None) -> Estimate:
        """The exact smoother over ``y (..., K, m)``: the mixture of every sequence's RTS
        posterior weighted by :math:`p(r \\mid y_{0:K-1})`, its ``x``, ``P``, ``mode_prob`` and the
        most probable ``mode`` at each sample; ``data_timing`` as in :meth:`run`."""
        self._check_data_timing(data_timing)
        seq, batch = self._sequences(y, u, t)
        S, N, K, n = seq.x.shape
        # each sequence is Kim's smoother with one mode, whose RTS step goes through the row's
        # own transition into k + 1 (seq.trans, built for self.timing): the same in both timings
        rts = smooth_mode_matched(
            seq.x.reshape(S * N, K, 1, n), seq.P.reshape(S * N, K, 1, n, n),
            np.ones((S * N, K, 1)), seq.u, seq.F, seq.G, seq.Qd,
            seq.trans.reshape(S * N, K, 1), np.ones((1, 1)), timing="interval")
        w, _ = log_normalize(seq.cum[..., -1:], axis=0)  # p(r | y_0..K-1)
        return self._mixture(np.broadcast_to(w, seq.cum.shape), rts.x.reshape(S, N, K, n),
                             rts.P.reshape(S, N, K, n, n), seq.modes, batch)

    def _sequences(self, y, u, t) -> tuple[_Sequences, tuple[int, ...]]:
        """Every mode sequence's Kalman filter on every trial (one compiled run)."""
        y, u, t, batch = self._prepare(y, u, t)
        sys = self.system
        (N, K, m), L, n, l = y.shape, sys.n_modes, sys.n_states, sys.n_inputs
        self._refuse(L**K, f"L^K = {L}^{K} (L = {L} modes, K = {K} samples)")
        S = L**K
        check_memory(  # per sequence, trial and sample: filtered and smoothed x, P, y, u, ...
            8 * S * N * K * (4 * n * n + 4 * n + m + l + 4),
            f"ExactMixtureFilter on y of shape {y.shape}: L^K = {S} sequences")
        modes = np.stack(np.unravel_index(np.arange(S), (L,) * K), axis=-1)  # (S, K)
        table, entry = sample_mode_steps(sys, t)
        F, G, Qd = table.F, table.G, table.Qd
        # sequence s predicts into sample k through r_{k-1} ("sample") or r_k ("interval");
        # row 0 is not read (the first sample is update-only)
        moving = np.roll(modes, 1, axis=1) if self.timing == "sample" else modes
        trans = entry[np.arange(K), moving]
        rows = (S * N, K)
        ys = np.broadcast_to(y, (S, N, K, m)).reshape(*rows, m)
        us = np.broadcast_to(u, (S, N, K, l)).reshape(*rows, l)
        trans_rows = np.broadcast_to(trans[:, None], (S, N, K)).reshape(rows)
        out = kalman_run(ys, us, F, G, Qd, trans_rows, sys.C, sys.R,
                         np.broadcast_to(modes[:, None], (S, N, K)).reshape(rows), self.x0,
                         self.P0)
        raise_for_status(out.status)
        warn_for_repairs(out)
        loglik, outlier = _rejected(out.loglik.reshape(S, N, K), out.flag.reshape(S, N, K),
                                    axis=0)
        log_prior = self._log_p0[modes[:, 0]] + self._log_transition[
            modes[:, :-1], modes[:, 1:]].sum(axis=1)
        cum = log_prior[:, None, None] + np.cumsum(loglik, axis=-1)
        return _Sequences(out.x.reshape(S, N, K, n), out.P.reshape(S, N, K, n, n), cum, modes,
                          outlier, us, F, G, Qd, trans_rows), batch

    def _mixture(self, log_w, x, P, modes, batch, loglik=None, outlier=None) -> Estimate:
        """The mixture over the sequences (axis 0) of ``x (S, N, K, n)``, ``P`` with normalized
        log-weights ``log_w (S, N, K)``, as an :class:`Estimate` with ``batch``."""
        w = np.exp(np.moveaxis(log_w, 0, -1))  # (N, K, S)
        mean, cov = mixture_moments(w[..., None], np.moveaxis(x, 0, -2), np.moveaxis(P, 0, -3))
        L = self.system.n_modes
        mode_prob = np.einsum("nks,skj->nkj", w, np.eye(L)[modes])
        est = Estimate(x=mean[..., 0, :], P=cov[..., 0, :, :], mode_prob=mode_prob,
                       mode=np.argmax(mode_prob, axis=-1), loglik=loglik, outlier=outlier)
        return self._unflatten(est, batch)

    def _refuse(self, count: int, what: str) -> None:
        """``ValueError`` when ``count`` mode sequences (``what`` says how many, and why)
        exceed ``max_sequences``."""
        if count > self.max_sequences:
            raise ValueError(f"ExactMixtureFilter: {what} = {count} mode sequences exceed "
                             f"max_sequences = {self.max_sequences}; shorten the record or raise "
                             "max_sequences")


@dataclass(frozen=True, eq=False)
class _Sequences:
    """Every sequence's filter on every trial: ``x (S, N, K, n)``, ``P``, the cumulative log
    weights ``cum (S, N, K)`` = log prior + sum of log-likelihoods up to each sample, the
    sequences ``modes (S, K)``, the samples every sequence rejected ``outlier (N, K)``, and the
    kernel's rows ``(S N, ...)``: inputs ``u``, the transition table ``F, G, Qd`` and each
    row's index into it ``trans``."""

    x: np.ndarray
    P: np.ndarray
    cum: np.ndarray
    modes: np.ndarray
    outlier: np.ndarray
    u: np.ndarray
    F: np.ndarray
    G: np.ndarray
    Qd: np.ndarray
    trans: np.ndarray


def _rejected(loglik, flag, axis):
    """The log-likelihoods of the sequences (along ``axis``) with a rejected measurement
    (``flag == GATED``: its innovation overflowed, the Kalman kernel left the state alone) set
    to ``-inf``: such a measurement is infinitely unlikely under that sequence. Where every
    sequence rejected it, it is an outlier treated as missing instead (likelihood 1 for all),
    as the IMM treats it. Returns the log-likelihoods and the outlier mask (``axis`` removed).
    """
    gated = flag == GATED
    outlier = np.all(gated, axis=axis)
    return np.where(gated & ~np.expand_dims(outlier, axis), -np.inf, loglik), outlier
