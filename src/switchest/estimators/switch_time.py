"""Kalman filtering with known modes at the samples and unknown switching times.

Shankar et al. §III-§IV: the mode at each sample is known, but when the mode
changes between :math:`t_{k-1}` and :math:`t_k` the instant of the switch is not. It is
estimated by maximizing the likelihood of the new measurement over a grid of
:math:`g` candidate instants (eq. (23)), and the filter then predicts with the
transition of the estimated instant (eqs (4)-(5), (6)-(10)).

Both ``run`` (a whole record) and ``step`` (streaming) call the compiled kernel of
:mod:`switchest.engine.switch_time`, which holds the one implementation of
the filter; :func:`switch_time_loglik` and :func:`marginalize_switch_time` are the
numpy forms of its likelihood and merge, for other filters.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .._checks import (
    check_bool,
    check_cores,
    check_finite,
    check_memory,
    float_array,
    int_array,
    positive_scalar,
)
from .._linalg import log_normalize, mixture_moments
from ..discretize import (
    OFFSET_BITS,
    distinct_steps,
    interval,
    mode_steps,
    offset_table,
    offset_table_nbytes,
    pairwise_grid,
    pairwise_grid_nbytes,
    switch_grid,
)
from ..engine import GATED, raise_for_status, warn_for_repairs
from ..engine.switch_time import coarse_outputs, switch_time_run
from .base import Estimate, Estimator
from .kalman import kf_update

__all__ = [
    "SwitchTimeState",
    "SwitchTimeKalmanFilter",
    "switch_time_loglik",
    "marginalize_switch_time",
]

_TABLE_BUDGET = 2**28  # bytes of offset tables per kernel call (refine=True, irregular times)
_CACHED_BYTES = 2**25  # the kernel's tables are kept for the next call up to this size


@dataclass(frozen=True, eq=False)
class SwitchTimeState:
    """Posterior ``x (N, n)``, ``P (N, n, n)``, ``loglik (N,)``, the estimated switch
    offset inside the last interval, ``switch_offset (N,)`` (NaN without a switch), and
    ``outlier (N,)``, True where the measurement was rejected."""

    x: np.ndarray
    P: np.ndarray
    loglik: np.ndarray
    switch_offset: np.ndarray
    outlier: np.ndarray


def switch_time_loglik(x_pred, P_pred, y, C, R, *, likelihood: str = "innovation"):
    """Log of the switching-time likelihood :math:`J_k(\\tau)` of Shankar et al. §IV.

    ``likelihood="innovation"`` gives
    :math:`\\log \\mathcal{N}(y; C x^-(\\tau), C P^-(\\tau) C^\\top + R)`, the
    likelihood of the measurement given the past, whose maximizer is the
    maximum-likelihood switching time. ``likelihood="printed"`` gives the paper's
    literal
    :math:`J_k(\\tau) = p(y_{k+1} \\mid x_{k+1} = x^-(\\tau)) = \\mathcal{N}(y; C x^-(\\tau), R)`,
    which ignores the prediction covariance (and so how much each hypothesis is
    trusted). Both are evaluated by the Kalman core; shapes broadcast. NaN entries
    of ``y`` are missing components.
    """
    _check_likelihood(likelihood)
    arrays = {k: float_array(v, k) for k, v in zip(("x_pred", "P_pred", "y", "C", "R"),
                                                   (x_pred, P_pred, y, C, R))}
    check_cores(arrays, {"x_pred": "n", "P_pred": "nn", "y": "m", "C": "mn", "R": "mm"})
    for name in ("x_pred", "P_pred", "C", "R"):
        check_finite(arrays[name], name)
    return _switch_time_loglik(*arrays.values(), likelihood=likelihood)


def _switch_time_loglik(x_pred, P_pred, y, C, R, *, likelihood: str):
    """:func:`switch_time_loglik` on validated arrays (the filter's per-step kernel)."""
    P = P_pred if likelihood == "innovation" else np.zeros_like(P_pred)  # "printed": R alone
    return kf_update(x_pred, P, y, C, R)[2]


def _check_likelihood(likelihood) -> None:
    if not isinstance(likelihood, str) or likelihood not in ("innovation", "printed"):
        raise ValueError(f"likelihood must be 'innovation' or 'printed', got {likelihood!r}")


def marginalize_switch_time(loglik, x_up, P_up, tau):
    """Collapse the hypotheses of a switching-time grid into one Gaussian (beyond Shankar et al.).

    Instead of keeping the maximizer of eq. (23), the switching instant is
    integrated out with a uniform prior on the grid ``tau (g,)``: the posterior
    weights are :math:`w_i = p(y \\mid \\tau_i) / \\sum_k p(y \\mid \\tau_k)` from the innovation
    log-likelihoods ``loglik (..., g)``, the updated estimates ``x_up (..., g, n)``,
    ``P_up (..., g, n, n)`` are merged by moment matching, and the likelihood of
    the measurement is the grid mean :math:`(1/g) \\sum_i p(y \\mid \\tau_i)`.

    Returns
    -------
    x, P, loglik, tau_mean
        Merged mean ``(..., n)`` and covariance,
        :math:`\\log\\bigl((1/g) \\sum_i p(y \\mid \\tau_i)\\bigr)` and the posterior mean switching
        instant :math:`\\sum_i w_i \\tau_i`, each ``(...)``.
    """
    log_w, log_sum = log_normalize(loglik)
    w = np.exp(log_w)
    x, P = mixture_moments(w[..., :, None], x_up, P_up)
    return x[..., 0, :], P[..., 0, :, :], log_sum - np.log(tau.size), w @ tau


class SwitchTimeKalmanFilter(Estimator):
    """Kalman filter with gridded maximum-likelihood switching times (Shankar et al.).

    Parameters
    ----------
    system : SwitchedLinearSystem
        A continuous-time system.
    x0, P0 : array_like
        Prior mean and covariance at the first sample.
    grid : int
        Number :math:`g` of candidate switching instants per interval,
        :math:`\\tau_i = i T / g - T / (2 g)` (eq. (23)).
    refine : bool
        Beyond the paper: polish the grid maximum by Brent's method (golden section
        and parabolic interpolation, Brent 1973 ch. 5) on the exact likelihood over
        the grid cell around it, :math:`[\\tau - T/(2g), \\tau + T/(2g)]`, started from the
        grid instant, with one addition: a search heading for an edge of the cell
        probes that edge (see ``refine`` in ``engine/c/switch_time.c``);
        the search stops once the maximizer is bracketed to within
        about :math:`2 \\cdot 10^{-4}\\, T` (tolerance :math:`10^{-4}\\, T`,
        :data:`~switchest.engine.switch_time.REFINE_TOLERANCE`) or after
        ``refine_iterations`` probes. The grid instant is kept unless a probe beats
        it. Each probe is quantized to :math:`T / 2^{18}` (3.8e-6 T) and its likelihood is
        exact there: its transition is composed from three flows of a table
        (:func:`switchest.discretize.offset_table`), without a matrix exponential.
    likelihood : {"innovation", "printed"}
        Which :math:`J_k` to maximize, see :func:`switch_time_loglik`.
    refine_iterations : int
        The most probes of the search when ``refine=True`` (a cap: on the boost converter
        of Shankar et al. a search stops at its tolerance after 7-12 probes, about 4 where
        the maximum lies at an edge of the cell).
    switch_time : {"max", "marginal"}
        ``"max"``: the grid maximizer of eq. (23) (the paper). Its covariance is
        conditional on the chosen instant, as if it were the true one: on the boost
        converter (Table I's setting, :math:`g = 5`) the normalized estimation error squared
        (NEES) has median 3e4 where a consistent filter's is 1.4 (its mean 2), and the
        :math:`\\pm 2\\,\\mathrm{std}` band of :math:`i_L` is 0.03 A wide against errors of about
        9 A.
        ``"marginal"`` (beyond the paper): every grid instant is predicted and updated,
        and the hypotheses are merged with their posterior weights
        (:func:`marginalize_switch_time`), so the covariance counts the instant's
        uncertainty (there: mean NEES 2.2 at :math:`g = 16`, and a smaller RMSE); the reported
        switching instant is the posterior mean. Needs ``likelihood="innovation"`` and
        ``refine=False``.
    inflation : float
        :math:`\\epsilon \\ge 0` added as :math:`\\epsilon I` to every predicted covariance,
        :math:`P_{k|k-1} = F P F^\\top + Q_d + \\epsilon I`: the inflation of Shankar et al.'s
        Algorithm 1 (§IV, which adds it so that the bound of Assumption 2 exists), here for the grid
        filter of Table I too (default 0: none). It is defined on the grid's whole-interval
        transitions; ``refine=True`` composes its probes from partial flows and does not
        take it.
    gate : float, optional
        Largest normalized innovation squared accepted. A measurement beyond it,
        or one whose innovation overflows (whatever the gate), is rejected: treated
        as missing and flagged in ``Estimate.outlier``. Where every grid instant
        rejects it, the measurement says nothing of the switching instant: the
        hypotheses are weighed equally (``"marginal"``) or the middle grid instant
        is taken (``"max"``, as for a missing measurement).

    Notes
    -----
    At most one switch per interval is assumed (dwell time :math:`> T`, Shankar §II).

    Examples
    --------
    >>> from switchest.models.shankar import BoostTable1
    >>> boost = BoostTable1()  # Shankar et al.'s boost converter, Table I's setting
    >>> traj = boost.simulate(0.01, 3, rng=0)  # 3 trials x 10 ms
    >>> f = SwitchTimeKalmanFilter(boost.system(), *boost.prior, grid=5, switch_time="marginal")
    >>> est = f.run(traj.y, boost.input, traj.t, modes=traj.mode)
    >>> est.x.shape
    (3, 21, 2)
    >>> import numpy as np
    >>> instant = est.switch_time[:, 1:]  # the estimated instant in each interval with a switch
    >>> switched = ~np.isnan(instant)
    >>> bool(np.all(((instant > traj.t[:-1]) & (instant < traj.t[1:]))[switched]))
    True
    """

    def __init__(self, system, x0, P0, *, grid: int = 5, refine: bool = False,
                 likelihood: str = "innovation", refine_iterations: int = 20,
                 switch_time: str = "max", inflation: float = 0.0,
                 gate: float | None = None):
        self._set_prior(system, x0, P0)
        if not system.is_continuous:
            raise ValueError("SwitchTimeKalmanFilter needs a continuous-time system (switches "
                             "inside intervals)")
        switch_grid(1.0, grid)  # validates g
        check_memory(pairwise_grid_nbytes(system, grid),
                     f"grid = {grid} switching instants per interval (the transitions of every "
                     f"mode pair at every instant, L = {system.n_modes} modes)")
        refine = check_bool(refine, "refine")
        _check_likelihood(likelihood)
        iters = int_array(refine_iterations, "refine_iterations", ndim=0)
        if iters < 1:
            raise ValueError(f"refine_iterations must be >= 1, got {int(iters)}")
        if not isinstance(switch_time, str) or switch_time not in ("max", "marginal"):
            raise ValueError(f"switch_time must be 'max' or 'marginal', got {switch_time!r}")
        if switch_time == "marginal" and (refine or likelihood != "innovation"):
            raise ValueError("switch_time='marginal' weighs the grid by the innovation "
                             "likelihood: it needs likelihood='innovation' and refine=False")
        inflation = positive_scalar(inflation, "inflation", allow_zero=True)
        if refine and inflation:
            raise ValueError("inflation applies to the grid's whole-interval transitions: it "
                             "needs refine=False")
        if refine:
            check_memory(offset_table_nbytes(system),
                         f"refine=True (an offset table of L = {system.n_modes} modes)")
        self.switch_time = switch_time
        self.grid = int(grid)
        self.refine = refine
        self.likelihood = likelihood
        self.refine_iterations = int(iters)
        self.inflation = inflation
        self.gate = None if gate is None else positive_scalar(gate, "gate")

    def init(self, batch_shape=()) -> SwitchTimeState:
        """The prior, replicated over ``batch_shape``."""
        x, P = self._prior_copies(batch_shape)
        return SwitchTimeState(x=x, P=P, loglik=np.zeros(batch_shape),
                               switch_offset=np.full(batch_shape, np.nan),
                               outlier=np.zeros(batch_shape, dtype=bool))

    def step(self, state: SwitchTimeState, y, u=None, *, dt=None, mode,
             prev_mode=None) -> SwitchTimeState:
        """Predict over ``dt`` from ``prev_mode`` to ``mode``, estimating the switch time
        when they differ, then update with ``y (..., m)``.

        One sample of the compiled kernel that ``run`` loops over
        (:func:`~switchest.engine.switch_time.switch_time_run`); ``dt=None``
        (a first sample) updates only. ``mode`` and ``prev_mode`` (default ``mode``: no
        switch) broadcast over the batch.
        """
        sys = self.system
        batch = state.x.shape[:-1]
        N, n = int(np.prod(batch, dtype=np.int64)), sys.n_states
        y = np.asarray(y, dtype=float).reshape(N, sys.n_outputs)
        u = np.zeros(sys.n_inputs) if u is None else np.asarray(u, dtype=float)
        u = np.broadcast_to(u, (*batch, sys.n_inputs)).reshape(N, sys.n_inputs)
        mode = np.broadcast_to(np.asarray(mode), batch).reshape(N)
        prev = mode if prev_mode is None else np.asarray(prev_mode)
        prev = np.broadcast_to(prev, batch).reshape(N)
        steps = np.empty(0) if dt is None else np.array([positive_scalar(dt, "dt")])
        out = self._kernel(y[:, None], u[:, None], np.zeros(1, dtype=np.int64), mode[:, None],
                           prev[:, None], steps, state.x.reshape(N, n),
                           state.P.reshape(N, n, n), predict_first=dt is not None)
        return SwitchTimeState(out.x[:, 0].reshape(*batch, n), out.P[:, 0].reshape(*batch, n, n),
                               out.loglik[:, 0].reshape(batch), out.offset[:, 0].reshape(batch),
                               (out.flag[:, 0] == GATED).reshape(batch))

    def run(self, y, u=None, t=None, *, modes) -> Estimate:
        """Filter ``y (..., K, m)`` given the true ``modes`` at the samples, ``(K,)`` or
        ``(..., K)``.

        The returned ``switch_time`` holds the estimated absolute switching instant
        in :math:`(t_{k-1}, t_k)` at sample :math:`k`, NaN where the mode did not change. The whole
        record runs in the compiled kernel, with the transition tables of each distinct sampling
        step (with ``refine=True`` and many distinct steps, in stretches of samples whose offset
        tables fit 256 MiB).
        """
        y2, u2, t, batch = self._prepare(y, u, t)
        K = t.size
        modes = self._modes(modes, batch, K)
        n, N = self.system.n_states, y2.shape[0]
        check_memory(  # grid x trials hypotheses, the bound of the numpy filter, kept as the limit
            8 * N * self.grid * (6 * n * n + 4 * n + self.system.n_inputs * n),
            f"grid = {self.grid} switching-time hypotheses for each of N = {N} trials",
        )
        prev = np.concatenate([modes[:, :1], modes[:, :-1]], axis=1)
        held = np.concatenate([u2[:, :1], u2[:, :-1]], axis=1)  # u[:, k-1] over interval k
        per_step = offset_table_nbytes(self.system) if self.refine else 0
        distinct = distinct_steps(t)[0].size
        span = K if per_step * distinct <= _TABLE_BUDGET else max(1, _TABLE_BUDGET // per_step)
        x, P = np.tile(self.x0, (N, 1)), np.tile(self.P0, (N, 1, 1))
        parts = []
        for k0 in range(0, K, span):
            k1 = min(K, k0 + span)
            steps, which = distinct_steps(t[max(k0 - 1, 0):k1])  # the intervals into k0..k1-1
            which = np.concatenate([[0], which]) if k0 == 0 else which
            out = self._kernel(y2[:, k0:k1], held[:, k0:k1], which, modes[:, k0:k1],
                               prev[:, k0:k1], steps, x, P, predict_first=k0 > 0)
            x, P = out.x[:, -1], out.P[:, -1]
            parts.append(out)

        def joined(field):
            arrays = [getattr(out, field) for out in parts]
            return arrays[0] if len(arrays) == 1 else np.concatenate(arrays, axis=1)

        start = np.concatenate([[np.nan], t[:-1]])
        est = Estimate(x=joined("x"), P=joined("P"), loglik=joined("loglik"),
                       switch_time=joined("offset") + start, outlier=joined("flag") == GATED)
        return self._unflatten(est, batch)

    def _kernel(self, y, u, which, mode, prev, steps, x, P, *, predict_first):
        """The compiled filter over ``y (N, K, m)`` from ``x (N, n)``, ``P (N, n, n)`` with the
        transition tables of the sampling ``steps (D,)`` (:func:`_tables`); raises for a failure
        and warns of repaired covariances."""
        key = (self.system, tuple(steps.tolist()), self.grid, self.refine, self.inflation)
        size = steps.size * offset_table_nbytes(self.system) if self.refine else 0
        F, G, Qd, grid_tau, levels, outputs = (_cached_tables if size <= _CACHED_BYTES
                                               else _tables)(*key)
        out = switch_time_run(y, u, which, mode, prev, self.system.C, self.system.R, F, G, Qd,
                              steps, grid_tau, x, P, levels=levels, predict_first=predict_first,
                              marginal=self.switch_time == "marginal",
                              printed=self.likelihood == "printed",
                              gate=np.inf if self.gate is None else self.gate,
                              iterations=self.refine_iterations if self.refine else 0,
                              outputs=outputs)
        raise_for_status(out.status)
        warn_for_repairs(out)
        return out

    def _estimate(self, x, P, y, u, prev, mode, dt):
        """The switching instants the filter estimates for one sample of the trials ``x (N, n)``,
        ``P (N, n, n)`` (a step of the kernel), with their exact transitions (for inspection).

        Returns ``tau (N,)`` and ``(F, G, Qd)`` of :func:`switchest.discretize.interval` at
        ``tau``; every trial must switch (``prev != mode``).
        """
        N = x.shape[0]
        state = SwitchTimeState(x, P, np.zeros(N), np.full(N, np.nan), np.zeros(N, dtype=bool))
        tau = self.step(state, y, u, dt=dt, mode=mode, prev_mode=prev).switch_offset
        tr = interval(self.system, dt, np.stack([prev, mode], axis=1), tau[:, None])
        return tau, (tr.F, tr.G, tr.Qd)


def _tables(system, steps: tuple, g: int, refine: bool, inflation: float = 0.0):
    """The kernel's transition table for the distinct sampling ``steps`` (the layout of
    :mod:`switchest.engine.switch_time`): per step and mode the transition without
    a switch (:func:`~switchest.discretize.mode_steps`), per step, mode pair and grid instant the
    switched one (:func:`~switchest.discretize.pairwise_grid`, eq. (23)) and, with ``refine``,
    the offset tables (:func:`~switchest.discretize.offset_table`); the grid ``(D, g)`` and the
    refinement levels ``(N1, N0 + 1)``. ``inflation`` (without ``refine``: every entry is then a
    whole interval) is added as :math:`\\epsilon I` to each :math:`Q_d`, so the kernel's prediction
    :math:`F P F^\\top + Q_d` is Algorithm 1's :math:`F P F^\\top + Q_d + \\epsilon I`
    (Shankar et al. §IV)."""
    n, l = system.n_states, system.n_inputs
    parts = [mode_steps(system, h) for h in steps] + [pairwise_grid(system, h, g) for h in steps]
    levels = (0, 0)
    if refine:
        tables = [offset_table(system, h) for h in steps]
        parts += [tab.coarse for tab in tables] + [tab.switch for tab in tables]
        levels = (2**OFFSET_BITS, 2**OFFSET_BITS + 1)
    F = np.concatenate([np.empty((0, n, n))] + [p.F.reshape(-1, n, n) for p in parts])
    G = np.concatenate([np.empty((0, n, l))] + [p.G.reshape(-1, n, l) for p in parts])
    Qd = np.concatenate([np.empty((0, n, n))] + [p.Qd.reshape(-1, n, n) for p in parts])
    if inflation:
        Qd = Qd + inflation * np.eye(n)
    grid_tau = np.array([switch_grid(h, g) for h in steps]).reshape(len(steps), g)
    outputs = coarse_outputs(system.C, F, G, Qd, len(steps), g, levels[0])
    return F, G, Qd, grid_tau, levels, outputs


_cached_tables = lru_cache(maxsize=8)(_tables)  # the kernel only reads them
