"""Filters on a bank of mode-matched Kalman filters: the IMM, GPB1 and GPB2.

They share their configuration (``system, transition, x0, P0, *, mode_prob0, gate, timing``),
their state (:class:`IMMState`: one Gaussian and one log-probability per mode, and the combined
estimate), their streaming ``step``, their ``run`` and a fixed-interval smoother, and differ
only in the compiled kernel that takes one sample: the IMM's interaction (Blom & Bar-Shalom,
1988), GPB1's collapse (Bar-Shalom, Li & Kirubarajan §11.6.4) or GPB2's pairs of modes
(§11.6.5). :class:`ModeBankFilter` holds what they share; a filter names its kernels.

``smooth`` runs a backward pass on the filter's mode-matched posteriors: by default the
two-filter smoother (:mod:`switchest.estimators.two_filter`), with ``method="kim"`` Kim's
(1994) recursion (:func:`switchest.estimators.smoothing.smooth_mode_matched`).

Convention (all of switchest): ``transition[i, j]`` =
:math:`\\Pr(\\text{mode } j \\text{ at } k+1 \\mid \\text{mode } i \\text{ at } k)`. The mode
:math:`s_k` of sample :math:`k` governs the measurement there and, by the ``timing``
(:doc:`/conventions`), the interval after :math:`k` (``"sample"``) or the one into it
(``"interval"``, Bar-Shalom's); by default the system's (:attr:`SwitchedLinearSystem.timing`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .._checks import (
    check_memory,
    positive_scalar,
)
from ..discretize import mode_steps, sample_mode_steps
from ..engine import GATED, raise_for_status, warn_for_repairs
from ..engine.imm import Bank, BankTable, IMMOutput
from .base import Estimate, Estimator, _with_mode_model_parameters
from .smoothing import smooth_filtered
from .two_filter import two_filter_smooth

__all__ = ["IMMState", "Members", "ModeBankFilter", "ModeMatchedRun",
           "SmootherDivergenceWarning"]

_DIVERGED = 1e4  # smoothed spread beyond this many times the filtered one: the smoother diverged
_CACHED_TABLES = 8  # step lengths (or records' sample times) whose checked tables a filter keeps
_CACHED_SAMPLES = 4096  # longest record whose table is kept
_FLOAT64 = np.dtype(np.float64)
_STEP_TYPES = (float, int, np.float64)  # step lengths whose tables are kept (bool is not one)
_UNCACHED = object()  # the key of a step length of another type: its table is made anew


class SmootherDivergenceWarning(RuntimeWarning):
    """Kim's smoother moved an estimate far outside its filtered uncertainty: its approximation
    is unstable on this system (:meth:`ModeBankFilter.smooth`)."""


@dataclass(frozen=True, eq=False)
class IMMState:
    """The state of the IMM after a sample, for ``N`` trials.

    Attributes
    ----------
    x, P : ndarray, shapes (N, L, n), (N, L, n, n)
        Mode-matched posteriors.
    log_prob : ndarray, shape (N, L)
        Log mode probabilities.
    loglik : ndarray, shape (N,)
        Log-likelihood of the last measurement given the past (0 when nothing was observed
        or every mode rejected it).
    outlier : ndarray of bool, shape (N,)
        True where every mode rejected the last measurement.
    combined_x, combined_P : ndarray, shapes (N, n), (N, n, n)
        The combined estimate, the moments of the mixture of the mode-matched posteriors
        (Bar-Shalom, Li & Kirubarajan §11.6.6, the output of the IMM): what ``run`` reports.
    """

    x: np.ndarray
    P: np.ndarray
    log_prob: np.ndarray
    loglik: np.ndarray
    outlier: np.ndarray
    combined_x: np.ndarray
    combined_P: np.ndarray



class Members(NamedTuple):
    """What the bank's filters are matched to: ``M`` members, each measured through one mode.
    Without a chain (:mod:`~switchest.estimators.mode_chains`) the members are the modes.

    Attributes
    ----------
    C, R : ndarray, shapes (M, m, n), (M, m, m)
        Each member's measurement.
    transition : ndarray, shape (M, M)
        ``transition[i, j]``: the probability of member ``j`` at the next sample given member
        ``i`` now.
    prob0 : ndarray, shape (M,)
        The members' prior probabilities at the first sample.
    mode : ndarray of int64, shape (M,)
        The mode each member is in at its sample (measures it).
    timing : {"sample", "interval"}
        The timing the bank's kernels run in.
    """

    C: np.ndarray
    R: np.ndarray
    transition: np.ndarray
    prob0: np.ndarray
    mode: np.ndarray
    timing: str


class ModeMatchedRun(NamedTuple):
    """A filtered record with the per-mode Gaussians after each sample's update and the model
    that produced them: the input of a smoother over the modes.

    Attributes
    ----------
    estimate : Estimate
        The filter's output with the batch axes flattened to one, ``(N, K, ...)``.
    x_modes, P_modes : ndarray, shapes (N, K, M, n), (N, K, M, n, n)
        Member-matched posteriors after each sample's update (GPB2: the merged Gaussians;
        the members are the ``L`` modes but on a chain, :class:`Members`).
    mode_prob : ndarray, shape (N, K, M)
        Member probabilities after each sample's update.
    u : ndarray, shape (N, K, l)
        The inputs, ``u[:, k]`` held over the interval into sample ``k + 1``.
    F, G, Qd : ndarray, shapes (M, n, n), (M, n, l), (M, n, n)
        The table of exact transitions.
    trans : ndarray of int64, shape (K, M)
        ``trans[k, j]``: member :math:`j`'s transition into sample :math:`k` (row 0 unused).
    transition : ndarray, shape (M, M)
        ``transition[i, j]`` =
        :math:`\\Pr(\\text{member } j \\text{ at } k+1 \\mid \\text{member } i \\text{ at } k)`.
    batch : tuple of int
        The batch shape of ``y``, ``N`` its product (to restore it in a result).
    y : ndarray, shape (N, K, m)
        The measurements (NaN: missing).
    t : ndarray, shape (K,)
        The sample times.
    """

    estimate: Estimate
    x_modes: np.ndarray
    P_modes: np.ndarray
    mode_prob: np.ndarray
    u: np.ndarray
    F: np.ndarray
    G: np.ndarray
    Qd: np.ndarray
    trans: np.ndarray
    transition: np.ndarray
    batch: tuple[int, ...]
    y: np.ndarray
    t: np.ndarray


@_with_mode_model_parameters
class ModeBankFilter(Estimator):
    """Configuration, state, loop and smoother of the filters on a bank of mode-matched
    Kalman filters (IMM, GPB1, GPB2); a subclass names its compiled kernels.

    Parameters
    ----------
    {mode model parameters}
    gate : float, optional
        Largest normalized innovation squared :math:`e^\\top S^{-1} e` a filter accepts
        (keyword-only); e.g. ``scipy.stats.chi2.ppf(0.9999, m)``. ``None`` rejects only
        measurements whose innovation overflows. A sample every filter rejects is treated as missing
        and flagged in ``Estimate.outlier``.
    timing : {"sample", "interval"}, optional
        Which interval the mode :math:`s_k` of sample :math:`k` governs besides :math:`y_k`
        (keyword-only; :doc:`/conventions`); ``None`` (the default): the system's ``timing``,
        and another is named in a :class:`~switchest.estimators.TimingWarning`. ``"sample"``
        (:func:`switchest.simulate` with switches at the samples; Costa, Fragoso & Marques
        2005, eq. (3.1)): the one after it,
        :math:`x_{k+1} = F(s_k) x_k + G(s_k) u_k + w_k`, :math:`w_k \\sim \\mathcal{N}(0,
        Q_d(s_k))`, :math:`y_k = C(s_k) x_k + v_k`, :math:`v_k \\sim \\mathcal{N}(0, R(s_k))`.
        ``"interval"`` (Bar-Shalom, Li & Kirubarajan 2001, §11.6; FilterPy's ``IMMEstimator``): the
        one into it, :math:`x_k = F(s_k) x_{k-1} + G(s_k) u_{k-1} + w`, :math:`y_k = C(s_k) x_k +
        v`. :math:`F, G, Q_d` are the exact discretization of a mode over the interval. With one
        mode the two are the same filter.

    Notes
    -----
    In the ``"sample"`` timing :math:`x_k` does not depend on :math:`s_k` given :math:`s_{k-1}`
    and :math:`x_{k-1}`, so the prior of mode :math:`j` at sample :math:`k` is the mixture

    .. math::

        p(x_k \\mid s_k = j, Y_{k-1}) = \\sum_i \\Pr(s_{k-1} = i \\mid s_k = j, Y_{k-1}) \\,
        p(x_k \\mid s_{k-1} = i, Y_{k-1})

    with :math:`\\Pr(s_{k-1} = i \\mid s_k = j, Y_{k-1}) = \\pi_{ij} \\mu_i(k-1) / c_j`,
    :math:`c_j = \\sum_i \\pi_{ij} \\mu_i(k-1)`, and :math:`p(x_k \\mid s_{k-1} = i, Y_{k-1})`
    mode :math:`i`'s Kalman prediction through its own transition. The filters therefore predict
    first and interact after: the IMM moment-matches that mixture (the approximation of Blom &
    Bar-Shalom, 1988, applied after the prediction instead of before it); GPB1 collapses the
    :math:`L` predictions with weights :math:`\\mu_i(k-1)`; GPB2 predicts pair :math:`(i, j)`
    through mode :math:`i`'s transition. In the ``"interval"`` timing they interact first and
    predict mode :math:`j`'s restarted prior through mode :math:`j`'s transition (Bar-Shalom, Li &
    Kirubarajan §11.6.4-6). The updates (mode :math:`j` with :math:`C_j`, :math:`R_j`), the
    weighting of the hypotheses by their likelihoods and the output are the same in both.

    These filters approximate Bar-Shalom's timing better: in the ``"sample"`` timing the IMM
    and GPB1 merge predictions through different dynamics before the measurement that would
    tell them apart. With modes that differ only in :math:`A`, :math:`B`, :math:`Q` the two timings
    are one model with the chain shifted by a sample, and on the Markov jump system of the
    bake-off (switches at the samples, 64 trials) the IMM's state RMSE was 0.180 in
    Bar-Shalom's timing against 0.202, its smoother's 0.163 against 0.311: such a model is
    best given ``timing="interval"`` on the system itself (``system.replace(timing=
    "interval")``, or the model file's ``timing``). When the modes also differ in :math:`C` or
    :math:`R` and switch at the samples, the data's timing is the one to filter in
    (:doc:`/conventions`).
    """

    _interaction: str  # the bank's interaction (:class:`switchest.engine.imm.Bank`)

    def __init__(self, system, transition, x0, P0, *, mode_prob0=None, gate: float | None = None,
                 timing: str | None = None):
        if not hasattr(type(self), "_interaction"):
            raise TypeError("ModeBankFilter is the base of IMMFilter, GPB1Filter and GPB2Filter, "
                            "which name its interaction: construct one of those")
        self._set_prior(system, x0, P0)
        self.gate = None if gate is None else positive_scalar(gate, "gate")
        self._set_mode_prior(transition, mode_prob0)
        self._set_timing(timing)
        self._gate = math.inf if self.gate is None else self.gate
        # the tables that do not change, checked and converted once for every run and step
        members = self._members = self._bank_members()
        with np.errstate(divide="ignore"):  # log 0 = -inf: an impossible member or move
            log_transition = np.log(members.transition)
            self._log_prob0 = np.log(members.prob0)
        self._bank = Bank(members.C, members.R, log_transition, self.x0, self.P0,
                          self._log_prob0, gate=self._gate, interaction=self._interaction,
                          timing=members.timing)
        self._tables: dict = {}  # dt -> the bank's table of one sample (of the cached steps)
        self._dims = members.mode.size, system.n_states, system.n_outputs, system.n_inputs
        # each member's mode as a 0/1 matrix (M, L), None when the members are the modes
        M, L = members.mode.size, system.n_modes
        same = M == L and np.array_equal(members.mode, np.arange(L))
        self._member_modes = None if same else np.eye(L)[members.mode]
        self._records: dict = {}  # t's bytes -> (F, G, Qd, trans, the bank's table)

    def _bank_members(self) -> Members:
        """The members of the bank: the system's modes, in the filter's timing."""
        sys = self.system
        return Members(sys.C, sys.R, self.transition, self.mode_prob0, np.arange(sys.n_modes),
                       self.timing)

    # ------------------------------------------------------------------ the kernels
    def _kernel_run(self, y, u, table: BankTable, modes_out: bool) -> IMMOutput:
        """The compiled filter over a prepared record and its table, in ``self.timing``."""
        return self._bank.run(y, u, table, modes_out=modes_out)

    def _step_table(self, dt) -> BankTable:
        """The bank's table of one sample predicted over ``dt`` (None: update only, the table
        not read; else :meth:`_step_rows`), checked once per step length."""
        key = dt if dt is None or type(dt) in _STEP_TYPES else _UNCACHED
        table = self._tables.get(key)
        if table is None:
            M, n, _, l = self._dims
            if dt is None:  # update only: the transition table is not read
                F, G, Qd = np.zeros((1, n, n)), np.zeros((1, n, l)), np.zeros((1, n, n))
                rows = np.zeros(M, dtype=np.int64)
            else:
                F, G, Qd, rows = self._step_rows(positive_scalar(dt, "dt"))
            table = self._bank.table(F, G, Qd, rows)
            if key is not _UNCACHED:
                if len(self._tables) >= _CACHED_TABLES:
                    self._tables.clear()
                self._tables[key] = table
        return table

    def _step_rows(self, dt: float):
        """``F, G, Qd`` of one sample predicted over ``dt`` and each member's row of them:
        every mode's own transition (:func:`switchest.discretize.mode_steps`)."""
        steps = mode_steps(self.system, dt)
        return steps.F, steps.G, steps.Qd, np.arange(self.system.n_modes)

    # ------------------------------------------------------------------ the protocol
    def init(self, batch_shape=()) -> IMMState:
        """Every member starts from the prior ``(x0, P0)`` with its prior probability
        (``mode_prob0`` for the modes)."""
        M = self._dims[0]
        x, P = self._prior_copies((*batch_shape, M))
        combined_x, combined_P = self._prior_copies(batch_shape)
        return IMMState(x=x, P=P,
                        log_prob=np.broadcast_to(self._log_prob0, (*batch_shape, M)).copy(),
                        loglik=np.zeros(batch_shape), outlier=np.zeros(batch_shape, dtype=bool),
                        combined_x=combined_x, combined_P=combined_P)

    def step(self, state: IMMState, y, u=None, *, dt=None) -> IMMState:
        """Predict over ``dt`` (skipped when ``None``: the first sample) and update with
        ``y (..., m)``; one sample of the compiled kernel ``run`` loops over, in the filter's
        ``timing`` (with ``dt`` at the first sample, each mode predicts from the prior through
        its own transition in either timing: the prior is the same Gaussian for every mode).

        ``state`` is an :class:`~switchest.estimators.imm.IMMState`: the mode-matched
        Gaussians (GPB2: merged), log mode probabilities and the combined estimate.
        """
        batch = state.log_prob.shape[:-1]
        L, n, m, l = self._dims
        N = math.prod(batch)
        if type(y) is not np.ndarray or y.dtype is not _FLOAT64:
            y = np.asarray(y, dtype=float)
        y = np.ascontiguousarray(y.reshape(N, m))  # (a copy of a strided one)
        one = len(batch) == 1  # the state's arrays keep their shapes: no reshape to make
        if u is None:
            u = np.zeros((N, l))
        else:
            if type(u) is not np.ndarray or u.dtype is not _FLOAT64:
                u = np.asarray(u, dtype=float)
            if u.shape != (*batch, l) or not u.flags.c_contiguous:
                held = np.empty((*batch, l))
                held[...] = u  # u broadcast over the batch
                u = held
            if not one:
                u = u.reshape(N, l)
        out, (x, P, log_prob) = self._bank.step(
            state.x if one else state.x.reshape(N, L, n),
            state.P if one else state.P.reshape(N, L, n, n),
            state.log_prob if one else state.log_prob.reshape(N, L), y, u,
            self._step_table(dt), predict_first=dt is not None)
        raise_for_status(out.status)
        warn_for_repairs(out)
        if one:
            return IMMState(x=x, P=P, log_prob=log_prob, loglik=out.loglik[:, 0],
                            outlier=out.flag[:, 0] == GATED, combined_x=out.x[:, 0],
                            combined_P=out.P[:, 0])
        return IMMState(
            x=x.reshape(*batch, L, n), P=P.reshape(*batch, L, n, n),
            log_prob=log_prob.reshape(*batch, L), loglik=out.loglik.reshape(batch),
            outlier=(out.flag == GATED).reshape(batch),
            combined_x=out.x.reshape(*batch, n), combined_P=out.P.reshape(*batch, n, n),
        )

    def run(self, y, u=None, t=None, *, data_timing: str | None = None) -> Estimate:
        """Filter ``y (..., K, m)``; returns the combined ``x``, ``P``, ``mode_prob``, the most
        probable ``mode``, ``loglik`` and the ``outlier`` flags at each sample.

        The whole record runs in the compiled kernel, with one exact transition per mode and
        distinct sampling step. ``data_timing`` (keyword-only), the timing ``y`` was drawn in
        (:attr:`switchest.simulate.Trajectory.timing`), is named in a
        :class:`~switchest.estimators.TimingWarning` when it is not the filter's.
        """
        self._check_data_timing(data_timing)
        y2, u2, t, batch = self._prepare(y, u, t)
        table = self._record_table(t)[-1]
        return self._unflatten(self._estimate(self._kernel_run(y2, u2, table, False), t), batch)

    def run_modes(self, y, u=None, t=None) -> ModeMatchedRun:
        """:meth:`run`, also returning the mode-matched Gaussians after each sample's update,
        the prepared inputs and the transition table (:class:`ModeMatchedRun`, batch axes
        flattened): what a smoother over the modes needs."""
        y2, u2, t, batch = self._prepare(y, u, t)
        N, K, _ = y2.shape
        M, n = self._dims[:2]
        check_memory(8 * N * K * M * (n * n + n),
                     f"{type(self).__name__} member-matched posteriors of y of shape {y2.shape} "
                     f"(N K M (n^2 + n) floats, n = {n}, M = {M} members)")
        F, G, Qd, trans, table = self._record_table(t)
        out = self._kernel_run(y2, u2, table, True)
        return ModeMatchedRun(self._estimate(out, t), out.x_modes, out.P_modes, out.mode_prob,
                              np.ascontiguousarray(u2), F.copy(), G.copy(), Qd.copy(),
                              trans.copy(), self._members.transition, tuple(batch), y2, t)

    def _table(self, t):
        """``F, G, Qd`` of each mode and distinct sampling step, and ``trans (K, M)``, the entry
        of member (mode) ``j`` into sample ``k``
        (:func:`switchest.discretize.sample_mode_steps`)."""
        table, trans = sample_mode_steps(self.system, t)
        return table.F, table.G, table.Qd, trans

    def _record_table(self, t):
        """:meth:`_table` of the checked sample times ``t`` and the bank's table of it, kept
        for the last few ``t`` (of at most :data:`_CACHED_SAMPLES` samples): a run on the
        same times reuses them (they are only read; :meth:`run_modes` hands out copies)."""
        key = t.tobytes() if t.size <= _CACHED_SAMPLES else None
        entry = self._records.get(key) if key is not None else None
        if entry is None:
            F, G, Qd, trans = self._table(t)
            entry = F, G, Qd, trans, self._bank.table(F, G, Qd, trans)
            if key is not None:
                if len(self._records) >= _CACHED_TABLES:
                    self._records.clear()
                self._records[key] = entry
        return entry

    def smooth(self, y, u=None, t=None, *, method: str = "two-filter",
               data_timing: str | None = None) -> Estimate:
        """Fixed-interval smoothing of ``y (..., K, m)``: the combined smoothed ``x``, ``P``,
        the smoothed ``mode_prob`` and the most probable ``mode`` at each sample, given the
        whole record.

        The filter runs forward (:meth:`run`, keeping its mode-matched posteriors), then a
        backward pass in the filter's ``timing``:

        - ``method="two-filter"`` (the default): backward information messages, the
          likelihood of the later measurements given each mode and state, combined with the
          filtered mode-matched posteriors by Bayes' rule
          (:mod:`switchest.estimators.two_filter`; Helmick, Blair & Hoffman 1995). No
          smoothed mode-matched covariance exceeds the filtered one, so it cannot diverge
          where the filter does not; its mode probabilities lie 0.002-0.007 (mean absolute
          error) from the exact smoothed ones after GPB2, 0.005-0.015 after the IMM (whose
          filtered ones are 0.008-0.019 from the exact filtered ones), on small problems where
          Kim's are 0.03-0.09 off.
        - ``method="kim"``: Kim's recursion (Kim 1994, §2.2; for collapsing filters Murphy
          1998, §3-4), the pairs (mode :math:`j` at :math:`k`, mode :math:`i` at :math:`k + 1`)
          weighed by :math:`\\mu_{ji}(k|K) = \\mu_i(k+1|K) \\mu_j(k|k) \\pi_{ji} / (\\sum_{j'}
          \\mu_{j'}(k|k) \\pi_{j'i})` and mode :math:`j`'s filtered posterior moved by a
          Rauch-Tung-Striebel step (:func:`~switchest.estimators.smoothing.smooth_mode_matched`). It
          warns (:class:`SmootherDivergenceWarning`) where its step diverges.

        The last sample's smoothed estimate is the filtered one. Like the filter it
        approximates, the smoother is not exact;
        :class:`~switchest.estimators.ExactMixtureFilter` is, for short records.
        ``data_timing`` as in :meth:`run`.
        """
        if method not in ("two-filter", "kim"):
            raise ValueError(f"method must be 'two-filter' or 'kim', got {method!r}")
        self._check_data_timing(data_timing)
        fwd = self.run_modes(y, u, t)
        members = self._members
        if method == "kim":
            s = smooth_filtered(fwd.x_modes, fwd.P_modes, fwd.mode_prob, fwd.u, fwd.F, fwd.G,
                                fwd.Qd, fwd.trans, fwd.transition, modes_out=False,
                                timing=members.timing)
            _warn_if_diverged(fwd.estimate, s)
        else:
            s = two_filter_smooth(
                fwd.x_modes, fwd.P_modes, fwd.mode_prob, fwd.y, fwd.u, fwd.F, fwd.G, fwd.Qd,
                fwd.trans, fwd.transition, members.C, members.R, outlier=fwd.estimate.outlier,
                timing=members.timing, modes_out=False)
        prob, mode = self._mode_probabilities(s.mode_prob, s.mode)
        return self._unflatten(Estimate(x=s.x, P=s.P, mode_prob=prob, mode=mode,
                                        switch_time=self._switch_time(s.mode_prob, fwd.t)),
                               fwd.batch)

    def _mode_probabilities(self, prob, mode):
        """The modes' probabilities and the most probable mode of the members' ``prob
        (..., M)`` and most probable member ``mode``: the sums over the members in each mode."""
        if self._member_modes is None:
            return prob, mode
        prob = prob @ self._member_modes
        return prob, np.argmax(prob, axis=-1)

    def _switch_time(self, member_prob, t) -> np.ndarray | None:
        """The estimated switching instant in each interval from the members' probabilities
        ``(N, K, M)`` at the sample times ``t``: none when the members are modes switching at the
        samples."""
        return None

    def _estimate(self, out: IMMOutput, t) -> Estimate:
        """The :class:`Estimate` of a kernel's output over the sample times ``t``, after raising
        for its status and warning about repaired covariances."""
        raise_for_status(out.status)
        warn_for_repairs(out)
        prob, mode = self._mode_probabilities(out.mode_prob, out.mode)
        return Estimate(x=out.x, P=out.P, mode_prob=prob, mode=mode,
                        switch_time=self._switch_time(out.mode_prob, t), loglik=out.loglik,
                        outlier=out.flag == GATED)


def _warn_if_diverged(filtered: Estimate, smoothed) -> None:
    """Warn when a smoothed covariance's trace, or the squared distance of a smoothed mean from
    the filtered one, exceeds :data:`_DIVERGED` times the filtered covariance's trace.

    An exact smoother never increases the uncertainty of the filter it smooths; Kim's
    approximation can, and on a system with a strongly contracting direction that some mode
    leaves unobserved (the boost converter: :math:`e^{A T}` shrinks the inductor current by 0.14
    per sample while the switch is closed) its backward step, :math:`J \\sim F^{-1}` in that
    direction, multiplies the mismatch between the merged pairs at every sample: the estimates
    grow geometrically towards the start of the record.
    """
    spread = np.trace(filtered.P, axis1=-2, axis2=-1)
    with np.errstate(over="ignore"):  # a diverged estimate squares to inf: said below
        grown = np.trace(smoothed.P, axis1=-2, axis2=-1) / spread
        moved = np.sum((smoothed.x - filtered.x) ** 2, axis=-1) / spread
    worst = np.nanmax(np.maximum(grown, moved), initial=0.0)
    if not worst <= _DIVERGED:
        k = int(np.unravel_index(np.nanargmax(np.maximum(grown, moved)), grown.shape)[-1])
        warnings.warn(
            f"Kim's smoother diverged: at sample {k} the smoothed estimate lies {worst:.3g} "
            "times the filtered covariance's trace away from (or its covariance beyond) the "
            "filtered one; its approximation is unstable on this system (a mode that leaves a "
            "strongly contracting direction unobserved). Use the filtered estimate, or "
            "ExactMixtureFilter.smooth on short records.", SmootherDivergenceWarning,
            stacklevel=3)
