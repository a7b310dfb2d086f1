"""The mode-based Kalman filter: a Kalman filter that follows a given mode sequence.

Zhang & Natarajan, Algorithm 1: at each sample the filter uses the matrices of
the mode it *believes* is active — the true one, or a mismatched one. For a
continuous-time system sampled at :math:`t_k`, the interval :math:`[t_{k-1}, t_k)` is
discretized exactly (:mod:`switchest.discretize`); given the true switching
offsets inside the intervals it is the clairvoyant filter of Shankar et al.
(known switching times), the best any method here can do.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import solve_triangular

from .._checks import (
    check_bool,
    check_finite,
    check_memory,
    float_array,
    int_array,
    positive_scalar,
)
from ..analysis.steady_state_kalman import steady_state_gain
from ..discretize import distinct_steps, mode_steps, segment_transitions
from ..dyadic import dyadic_table, interval_transitions
from ..engine import GATED, raise_for_status, warn_for_repairs
from ..engine.kalman import KalmanRun, kalman_steady_run, kalman_steady_step, kalman_step
from .base import Estimate, Estimator, TimingWarning

__all__ = ["KalmanState", "ModeKalmanFilter"]


@dataclass(frozen=True, eq=False)
class KalmanState:
    """Posterior after the last processed sample: ``x (N, n)``, ``P (N, n, n)``, ``loglik (N,)``
    and ``outlier (N,)``, True where the measurement was rejected."""

    x: np.ndarray
    P: np.ndarray
    loglik: np.ndarray
    outlier: np.ndarray


class ModeKalmanFilter(Estimator):
    """Kalman filter along a believed mode sequence (Zhang & Natarajan, Algorithm 1).

    Parameters
    ----------
    system : SwitchedLinearSystem
    x0, P0 : array_like
        Prior mean ``(n,)`` and covariance ``(n, n)`` of the state at the first sample.
    steady_state : bool
        Use each mode's steady-state gain :math:`K_i` (Zhang & Natarajan eq. (6): the
        Riccati solution of mode :math:`i` alone) instead of the time-varying gain; the
        reported ``P`` is then that mode's steady-state a-posteriori covariance.
        Requires periodic sampling.
    gate : float, optional
        Largest normalized innovation squared :math:`e^\\top S^{-1} e` accepted. A measurement
        beyond it, or one whose innovation overflows (whatever the gate), is
        rejected: treated as missing and flagged in ``Estimate.outlier`` (its
        ``loglik`` is 0, as for a missing sample).

    Notes
    -----
    Prediction over :math:`[t_{k-1}, t_k)` uses the mode believed at :math:`t_{k-1}` (a
    switch at the sample instants, as in discrete-time models), unless ``run`` is
    given the segments of each interval (``segments=trajectory.segments()``), in
    which case the exact switching offsets are used. The update at :math:`t_k` uses
    :math:`C` and :math:`R` of the mode believed at :math:`t_k`. Along given modes this is the
    ``"sample"`` timing only (:doc:`/conventions`): a system of the ``"interval"`` timing,
    whose mode of sample :math:`k` governs the interval into it, is named in a
    :class:`~switchest.estimators.TimingWarning`.

    Examples
    --------
    >>> from switchest.models.shankar import BoostTable1
    >>> boost = BoostTable1()  # Shankar et al.'s boost converter, Table I's setting
    >>> traj = boost.simulate(0.01, 3, rng=0)  # 3 trials x 10 ms
    >>> kf = ModeKalmanFilter(boost.system(), *boost.prior)
    >>> est = kf.run(traj.y, boost.input, traj.t, modes=traj.mode)  # the modes at the samples
    >>> est.x.shape, est.P.shape
    ((3, 21, 2), (3, 21, 2, 2))
    >>> clairvoyant = kf.run(traj.y, boost.input, traj.t, modes=traj.mode,
    ...                      segments=traj.segments())  # and the switching instants between them
    >>> import numpy as np
    >>> def rmse(e):
    ...     return np.sqrt(np.mean((e.x - traj.x) ** 2))
    >>> bool(rmse(clairvoyant) < rmse(est))
    True
    """

    def __init__(self, system, x0, P0, *, steady_state: bool = False, gate: float | None = None):
        self._set_prior(system, x0, P0)
        if system.timing != "sample":
            warnings.warn("ModeKalmanFilter predicts each interval in the mode of the sample "
                          "that starts it (the 'sample' timing), its system is in the "
                          f"{system.timing!r} one (docs/conventions.rst): along its modes the "
                          "estimates are of a model other than the system's", TimingWarning,
                          stacklevel=2)
        self.steady_state = check_bool(steady_state, "steady_state")
        self.gate = None if gate is None else positive_scalar(gate, "gate")
        self._gate = math.inf if self.gate is None else self.gate
        self._kalman = KalmanRun(system.C, system.R, self.x0, self.P0, gate=self._gate)
        self._steps: dict = {}  # t's bytes -> its table of steps (_step_table)

    def init(self, batch_shape=()) -> KalmanState:
        """The prior, replicated over ``batch_shape``."""
        x, P = self._prior_copies(batch_shape)
        return KalmanState(x=x, P=P, loglik=np.zeros(batch_shape),
                           outlier=np.zeros(batch_shape, dtype=bool))

    def step(self, state: KalmanState, y, u=None, *, dt=None, mode, prev_mode=None,
             segment_modes=None, segment_offsets=None, period=None) -> KalmanState:
        """Predict over ``dt`` (skipped when ``None``) and update with ``y (N, m)``.

        ``mode (N,)`` is the believed mode at this sample; ``prev_mode (N,)`` the one
        during the interval (default ``mode``); ``segment_modes (N, S+1)`` and
        ``segment_offsets (N, S)`` give exact switches inside the interval instead.
        ``period`` is the sampling period whose steady-state gains apply
        (``steady_state=True``); it defaults to ``dt`` (to ``system.dt`` for a
        discrete system) and must be given at a first sample of a continuous system.
        One sample of the compiled kernel that ``run`` loops over
        (:func:`~switchest.engine.kalman.kalman_step`).
        """
        sys = self.system
        mode = np.asarray(mode)
        N, n = mode.shape[0], sys.n_states
        y = np.asarray(y, dtype=float).reshape(N, sys.n_outputs)
        u = np.zeros((N, sys.n_inputs)) if u is None else np.broadcast_to(u, (N, sys.n_inputs))
        if dt is None:  # update only: the transition is not read
            F, G, Qd = np.zeros((N, n, n)), np.zeros((N, n, sys.n_inputs)), np.zeros((N, n, n))
        elif segment_modes is not None:
            tr = segment_transitions(sys, dt, segment_modes, segment_offsets)
            F, G, Qd = tr.F, tr.G, tr.Qd
        else:
            m = mode if prev_mode is None else np.asarray(prev_mode)
            steps = mode_steps(sys, dt)
            F, G, Qd = steps.F[m], steps.G[m], steps.Qd[m]
        if self.steady_state:
            K, P_prior, P_post, whiten = self._steady(period if dt is None else dt)
            out = kalman_steady_step(state.x, y, u, F, G, sys.C[mode], K[mode], P_prior[mode],
                                     P_post[mode], whiten[mode], predict_first=dt is not None,
                                     gate=self._gate)
        else:
            out = kalman_step(state.x, state.P, y, u, F, G, Qd, sys.C[mode], sys.R[mode],
                              predict_first=dt is not None, gate=self._gate)
            raise_for_status(out.status)
            warn_for_repairs(out)
        return KalmanState(out.x, out.P, out.loglik, out.flag == GATED)

    def _steady(self, period):
        """Per-mode steady-state gain and covariances for the sampling ``period``."""
        if period is None:
            if self.system.dt is None:
                raise ValueError("steady_state=True needs the sampling period at the first sample: "
                                 "give step() period=T, or run() at least two samples")
            period = self.system.dt
        return _steady_gains(self.system, positive_scalar(period, "period"))

    def run(self, y, u=None, t=None, *, modes, segments=None) -> Estimate:
        """Filter measurements ``y (..., K, m)`` along the believed ``modes``.

        Parameters
        ----------
        y : array_like, shape (..., K, m)
            Measurements; NaN marks a missing one (so does a masked entry of a numpy
            masked array).
        u : array_like, optional
            Inputs held on :math:`[t_k, t_{k+1})`: ``(l,)``, ``(K, l)`` or ``(..., K, l)``.
        t : array_like, shape (K,)
            Sample times (optional for discrete systems).
        modes : array_like of int, shape (K,) or (..., K)
            Believed mode at each sample (true or mismatched).
        segments : tuple of arrays, optional
            ``(modes (..., K-1, S+1), offsets (..., K-1, S))`` — the exact segments of
            each interval, e.g. ``trajectory.segments()``: the clairvoyant filter.
            Offsets are finite, non-decreasing and within :math:`[0, t_k - t_{k-1}]`.
        """
        y2, u2, t, batch = self._prepare(y, u, t)
        K = t.size
        modes = self._modes(modes, batch, K)
        if self.steady_state and K > 1 and np.ptp(np.diff(t)) > 1e-9 * np.diff(t).max():
            raise ValueError("steady_state=True requires periodic sample times t")
        seg = None if segments is None else self._segments(segments, batch, t)
        F, G, Qd, trans = self._transitions(t, modes, seg)
        sys = self.system
        if self.steady_state:
            gain, P_prior, P_post, whiten = self._steady(t[1] - t[0] if K > 1 else None)
            out = kalman_steady_run(y2, u2, F, G, trans, sys.C, modes, gain, P_prior, P_post,
                                    whiten, self.x0, gate=self._gate)
        else:
            out = self._kalman(y2, u2, F, G, Qd, trans, modes)
            raise_for_status(out.status)
            warn_for_repairs(out)
        est = Estimate(x=out.x, P=out.P, loglik=out.loglik, outlier=out.flag == GATED)
        return self._unflatten(est, batch)

    def _transitions(self, t, modes, seg):
        """The table of distinct exact transitions and the index of each trial's into each
        sample (the layout of :func:`~switchest.engine.kalman.kalman_run`).

        Without segments an interval is predicted in the mode believed at its start: one
        entry per (distinct step, mode). With segments (``(modes (N, K-1, S+1), offsets)``)
        each interval with a switch gets the exact transition of its segments (Shankar et al.
        eqs (3)-(5)), composed from the step's dyadic table
        (:func:`switchest.dyadic.interval_transitions`: no matrix exponential per interval).
        """
        sys = self.system
        L, (N, K) = sys.n_modes, modes.shape
        steps, which, F0, G0, Qd0 = self._step_table(t)
        F, G, Qd = [F0], [G0], [Qd0]
        trans = np.zeros((N, K), dtype=np.int64)
        first = modes[:, :-1] if seg is None else seg[0][..., 0]
        trans[:, 1:] = L * which + first
        if seg is not None:
            seg_m, seg_o = seg
            rows, cols = np.nonzero(np.any(seg_m[..., 1:] != seg_m[..., :1], axis=-1))
            check_memory(8 * rows.size * sys.n_states * (2 * sys.n_states + sys.n_inputs),
                         f"the exact transitions of {rows.size} intervals with a switch")
            for d in np.unique(which[cols]):  # intervals with a switch, by their length
                at = which[cols] == d
                r, c = rows[at], cols[at]
                # a switch at the end of an interval up to the rounding the step stands for
                # (distinct_steps) is at the end of the step
                offsets = np.minimum(seg_o[r, c], steps[d])
                tr = interval_transitions(dyadic_table(sys, steps[d]), seg_m[r, c], offsets)
                trans[r, c + 1] = sum(len(a) for a in F) + np.arange(r.size)
                F.append(tr.F)
                G.append(tr.G)
                Qd.append(tr.Qd)
        if len(F) == 1:  # the table of the steps itself (only read)
            return F0, G0, Qd0, trans
        return np.concatenate(F), np.concatenate(G), np.concatenate(Qd), trans

    def _step_table(self, t):
        """The distinct steps of the sample times ``t``, the step of each interval (``which``)
        and the table of every mode over each step (entry :math:`d L + j`: mode :math:`j` over step
        :math:`d`), kept for the last few ``t`` of at most 4096 samples (only read)."""
        key = t.tobytes() if t.size <= 4096 else None
        entry = self._steps.get(key) if key is not None else None
        if entry is None:
            sys = self.system
            length = np.diff(t)
            if length.size == 0:  # one sample: update only, the table is not read
                steps, which = np.ones(1), length.astype(np.intp)
            elif np.all(length == length[0]):  # periodic sampling: one step, nothing to sort
                steps, which = length[:1], np.zeros(length.size, dtype=np.intp)
            else:
                steps, which = distinct_steps(t)
            table = [mode_steps(sys, h) for h in steps]
            entry = (steps, which, *(np.concatenate([getattr(s, a) for s in table])
                                     for a in ("F", "G", "Qd")))
            if key is not None:
                if len(self._steps) >= 8:
                    self._steps.clear()
                self._steps[key] = entry
        return entry

    def _segments(self, segments, batch, t) -> tuple[np.ndarray, np.ndarray]:
        """Validate ``(modes, offsets)``: modes in range, offsets finite in their interval."""
        if not (isinstance(segments, tuple) and len(segments) == 2):
            raise TypeError("segments must be a tuple "
                            "(modes (..., K-1, S+1), offsets (..., K-1, S))")
        K = t.size
        seg_m = int_array(segments[0], "segments[0] (modes)")
        seg_o = float_array(segments[1], "segments[1] (offsets)")
        N = int(np.prod(batch, dtype=np.int64))
        if (seg_m.ndim == 0 or seg_m.shape[-1] == 0 or seg_m.shape[:-1] != (*batch, K - 1)
                or seg_o.shape != (*batch, K - 1, seg_m.shape[-1] - 1)):
            raise ValueError(
                f"segments must have shapes {(*batch, K - 1, 'S+1')} and {(*batch, K - 1, 'S')}, "
                f"got {seg_m.shape} and {seg_o.shape}"
            )
        L = self.system.n_modes
        if np.any((seg_m < 0) | (seg_m >= L)):
            raise ValueError(f"segments[0] (modes) must be in 0..{L - 1}, "
                             f"got {seg_m.min()}..{seg_m.max()}")
        check_finite(seg_o, "segments[1] (offsets)")
        length = np.diff(t)[:, None]  # interval k-1 -> k; offsets are measured from its start
        if np.any(seg_o < 0) or np.any(seg_o > length):
            raise ValueError("segments[1] (offsets) must lie within [0, t[k] - t[k-1]] of their "
                             f"interval, got {seg_o.min():g}..{seg_o.max():g}")
        if np.any(np.diff(seg_o, axis=-1) < 0):
            raise ValueError("segments[1] (offsets) must be non-decreasing within each interval")
        return seg_m.reshape(N, K - 1, -1), seg_o.reshape(N, K - 1, -1)


@lru_cache(maxsize=64)
def _steady_gains(system, period: float) -> tuple[np.ndarray, ...]:
    """Stacked per-mode :math:`K_i`, a-priori and a-posteriori steady-state covariances of mode
    :math:`i` alone at ``period`` (Zhang & Natarajan eq. (6)), and the whitening
    :math:`W_i = L_i^{-1}` of the steady innovation covariance
    :math:`S_i = C_i P_i C_i^\\top + R_i = L_i L_i^\\top` (for the gate's
    :math:`e^\\top S_i^{-1} e = \\lVert W_i e \\rVert^2`); a function of its arguments only, so a
    filter keeps no state between runs."""
    steps = mode_steps(system, period)
    out = [steady_state_gain(steps.F[i], system.C[i], steps.Qd[i], system.R[i])
           for i in range(system.n_modes)]
    K, P_prior, P_post = (np.stack(a) for a in zip(*out))
    S = system.C @ P_prior @ np.swapaxes(system.C, -1, -2) + system.R
    eye = np.eye(system.n_outputs)
    whiten = np.stack([solve_triangular(np.linalg.cholesky(S_i), eye, lower=True) for S_i in S])
    return K, P_prior, P_post, whiten
