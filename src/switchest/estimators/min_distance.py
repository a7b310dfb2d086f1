"""Minimum-distance mode estimation and switching detection (Lee, Ping & Shim, 002).

The whole algorithm of Lee et al. §V, on the output sampled on a fine uniform grid:

1. **Estimation** (§III, on-line form of Remark 2). From the window start
   :math:`\\hat{t}_j` every mode :math:`i` integrates, from zero,
   :math:`\\dot{\\tilde{x}}_i = A_i \\tilde{x}_i + B_i u` (12) and
   :math:`\\dot{z}_i = -A_i^\\top z_i + C_i^\\top (y - C_i \\tilde{x}_i)` (13).
   At :math:`\\hat{t}_j + \\delta`:
   :math:`X_i^* = U_i(\\delta)^{-1} e^{A_i^\\top \\delta} z_i` (14), the
   least-squares initial state (7) of mode :math:`i`; :math:`J_i(X_i^*)` (17), the residual
   energy (6) of mode :math:`i` started from :math:`X_i^*`;
   :math:`\\hat{\\sigma} = \\arg\\min_i J_i` (5) and
   :math:`\\hat{x}(\\hat{t}_j) = X^*_{\\hat{\\sigma}}` (8).
2. **Detection** (§IV, Detection Algorithm). With :math:`s = \\hat{\\sigma}`: the open-loop
   predictor :math:`\\dot{\\tilde{x}} = A_s \\tilde{x} + B_s u` (18), the observer
   :math:`\\dot{\\hat{x}} = (A_s - L_s C_s) \\hat{x} + B_s u + L_s y` (19) and the residual
   energy :math:`\\dot{s} = |y - C_s \\tilde{x}|^2` (20), both started from :math:`X^*_s`
   at :math:`\\hat{t}_j` and brought up to :math:`\\hat{t}_j + \\delta` at once. Then
   on-line: if :math:`t - t_\\mathrm{up} \\ge \\Delta` and
   :math:`|\\tilde{x} - \\hat{x}| > v_{\\max} (\\mu e^{\\lambda \\Delta} + 1) \\hat{E}` the
   predictor is reset to the observer (21)-(22); a switch is declared at :math:`t` when
   :math:`t - t_\\mathrm{up} < \\Delta` and the same gap is exceeded (23), or when
   :math:`s(t) - s(t - \\Delta) > S_\\Delta` (24).
   The detection instant is :math:`\\hat{t}_{j+1}` and step 1 restarts there.

Under Lee et al.'s Assumptions 1-3 (checked by
:func:`switchest.analysis.lee_assumptions`) the mode after each window is exact
(Theorem 1) and every switch is detected within :math:`\\Delta` with no false alarm
(Theorem 2).

Implementation notes (where this departs from the letter of the paper)
----------------------------------------------------------------------
* **Continuous output from samples.** ``y`` is taken as piecewise linear between
  the grid points (first-order hold) and ``u`` as held (zero-order hold, the
  package's convention). Every ODE above, including the energies (16)/(20), is
  integrated *exactly* for that interpolant: one block-matrix exponential per
  mode and grid step (:func:`augmented_system`). ``v_max`` must therefore bound
  the noise plus the interpolation error of the noise-free output,
  :math:`\\le \\frac{h^2}{8} \\max |\\ddot{y}|`.
* **(15)-(17) and the catch-up of (18)-(20) without replaying stored data.** By
  linearity, the replay (15) from :math:`X_i^*` equals
  :math:`e^{A_i (t - \\hat{t}_j)} X_i^*` plus the forced solution (12); since (14) gives
  :math:`\\int \\phi_i^\\top (y - C_i \\tilde{x}_i) = U_i X_i^*`,
  :math:`J_i(X_i^*) = \\rho_i - X_i^{*\\top} U_i X_i^*`
  with :math:`\\rho_i = \\int |y - C_i \\tilde{x}_i|^2` accumulated on-line alongside
  (12)-(13) (the "routine computation" in the proof of Theorem 1). Likewise (18) and (19)
  at :math:`\\hat{t}_j + \\delta` are :math:`e^{A \\delta} X^*` resp.
  :math:`e^{(A - LC) \\delta} X^*` plus the mode's solutions from zero, which are also
  accumulated during the window. No window of data is stored.
* **The window of (24).** The proof of Lemma 1 bounds
  :math:`\\int_{\\max(\\bar{t}_j, t - \\Delta)}^t |y - C \\tilde{x}|^2`,
  :math:`\\bar{t}_j = \\hat{t}_j + \\delta`, which is (24) with :math:`s` started at 0 at
  :math:`\\bar{t}_j` (Remark 3: :math:`s = 0` before :math:`\\bar{t}_j`). The algorithm as
  printed starts :math:`s` at :math:`\\hat{t}_j` and runs (20) over
  :math:`[\\hat{t}_j, \\bar{t}_j]`; taken literally with Remark 3 that adds
  :math:`J_\\sigma(X^*) \\le v_{\\max}^2 \\delta` to the first windows, which Lemma 1 does
  not bound. Here :math:`s` starts at :math:`\\bar{t}_j`, as the proof requires;
  :math:`s(t - \\Delta)` is interpolated linearly between grid points.
* **Checks start after the window**: (21)-(24) are evaluated for
  :math:`t > \\hat{t}_j + \\delta` (lines 11-18 of the whole algorithm).
* **Outputs between a detection and the end of the next window** are undefined
  in the paper: ``x`` is NaN and ``mode`` is -1 there (and before the first
  window ends). ``x`` is the observer (19) elsewhere. There is no covariance:
  ``Estimate.P`` is None.
* **Missing samples** (NaN) are bridged by holding the last finite output; the
  theorems do not cover such gaps.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .._checks import check_finite, check_memory, float_array, positive_scalar
from ..analysis.min_distance_design import (
    LeeAssumptions,
    LeeConstants,
    lee_assumptions,
    lee_constants,
)
from ..discretize import mode_steps
from ..signals import SwitchingSignal
from ..system import SwitchedLinearSystem
from .base import Estimate, Estimator

__all__ = [
    "DetectionMatch",
    "MinDistanceState",
    "MinimumDistanceDetector",
    "WindowEstimate",
    "augmented_system",
    "exact_step",
    "match_detections",
    "window_estimate",
]

_GRID_RTOL = 1e-6


# ---------------------------------------------------------------------- kernels
def augmented_system(
    system: SwitchedLinearSystem, observer_gains: np.ndarray
) -> SwitchedLinearSystem:
    """The dual system whose exact discretization integrates one grid step of the algorithm.

    Per mode, with :math:`Z = [\\tilde{x}; z; \\hat{x}; u; y; \\dot{y}]` (sizes n, n, n, l,
    m, m; :math:`u` held, :math:`y` linear in time with slope :math:`\\dot{y}`), Lee et al.
    (12), (13) and (19) (equivalently (18)) read :math:`\\dot{Z} = M Z` with

    .. math::

        M = \\begin{bmatrix}
            A & 0 & 0 & B & 0 & 0 \\\\
            -C^\\top C & -A^\\top & 0 & 0 & C^\\top & 0 \\\\
            0 & 0 & A - LC & B & L & 0 \\\\
            0 & 0 & 0 & 0 & 0 & 0 \\\\
            0 & 0 & 0 & 0 & 0 & I \\\\
            0 & 0 & 0 & 0 & 0 & 0
        \\end{bmatrix}

    and the integrand of (16)/(20) is :math:`|H Z|^2`,
    :math:`H = [-C, 0, 0, 0, I, 0]`. The returned system has :math:`A = M^\\top` and
    :math:`Q = H^\\top H`: its exact step over :math:`h`
    (:func:`switchest.discretize.mode_steps`) gives :math:`F = e^{M^\\top h}` and
    :math:`Q_d = \\int_0^h e^{M^\\top s} H^\\top H e^{M s} \\, ds`, so that
    :math:`Z(h) = F^\\top Z(0)` and
    :math:`\\int_0^h |y - C \\tilde{x}|^2 = Z(0)^\\top Q_d Z(0)` — no quadrature.
    """
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    L, n, l, m = system.n_modes, system.n_states, system.n_inputs, system.n_outputs
    observer_gains = float_array(observer_gains, "observer_gains", ndim=3)
    if observer_gains.shape != (L, n, m):
        raise ValueError(
            f"observer_gains must have shape (L, n, m) = ({L}, {n}, {m}), "
            f"got {observer_gains.shape}"
        )
    check_finite(observer_gains, "observer_gains")
    d = 3 * n + l + 2 * m
    xt, z, xh = slice(0, n), slice(n, 2 * n), slice(2 * n, 3 * n)
    u, yy, yd = slice(3 * n, 3 * n + l), slice(3 * n + l, 3 * n + l + m), slice(3 * n + l + m, d)
    A, B, C = system.A, system.B, system.C
    Ct = np.swapaxes(C, 1, 2)
    M = np.zeros((L, d, d))
    M[:, xt, xt], M[:, xt, u] = A, B
    M[:, z, xt], M[:, z, z], M[:, z, yy] = -Ct @ C, -np.swapaxes(A, 1, 2), Ct
    M[:, xh, xh], M[:, xh, u], M[:, xh, yy] = A - observer_gains @ C, B, observer_gains
    M[:, yy, yd] = np.eye(m)
    H = np.zeros((L, m, d))
    H[:, :, xt], H[:, :, yy] = -C, np.eye(m)
    return SwitchedLinearSystem.continuous(np.swapaxes(M, 1, 2), Q=np.swapaxes(H, 1, 2) @ H)


def exact_step(core, u, y0, y1, h: float, F, G):
    """Advance ``core`` :math:`= [\\tilde{x}; z; \\hat{x}]` over one grid step, integrate
    :math:`|y - C \\tilde{x}|^2`.

    Parameters
    ----------
    core : ndarray, shape (..., 3n)
    u : ndarray, shape (..., l)
        Input held on the step.
    y0, y1 : ndarray, shape (..., m)
        Output at the two ends (linear in between).
    h : float
    F, G : ndarray, shape (..., d, d)
        :math:`F` and :math:`Q_d` of :func:`augmented_system` for step ``h`` (the mode of
        each row).

    Returns
    -------
    core : ndarray, shape (..., 3n)
    energy : ndarray, shape (...)
        :math:`\\int |y - C \\tilde{x}|^2` over the step, exactly (Lee et al. (16), (20)).
    """
    parts = (core, u, y0, (y1 - y0) / h)
    batch = np.broadcast_shapes(*(p.shape[:-1] for p in parts))
    ends = np.cumsum([0] + [p.shape[-1] for p in parts])
    Z = np.empty((*batch, ends[-1]))
    for p, a, b in zip(parts, ends[:-1], ends[1:]):
        Z[..., a:b] = p
    row = Z[..., None, :]
    out = (row @ F)[..., 0, :]  # (F' Z)' = Z' F
    energy = ((row @ G)[..., 0, :] * Z).sum(axis=-1)  # Z' Qd Z
    return out[..., : core.shape[-1]], energy


def window_estimate(z, rho, K, U):
    """Lee et al. (14), (17) and (5) at the end of an estimation window.

    Parameters
    ----------
    z : ndarray, shape (..., L, n)
        :math:`z_i(\\hat{t}_j + \\delta)` of (13).
    rho : ndarray, shape (..., L)
        :math:`\\int |y - C_i \\tilde{x}_i|^2` over the window, :math:`\\tilde{x}_i` of (12).
    K : ndarray, shape (L, n, n)
        :math:`U_i(\\delta)^{-1} e^{A_i^\\top \\delta}`.
    U : ndarray, shape (L, n, n)
        :math:`U_i(\\delta)`.

    Returns
    -------
    X : ndarray, shape (..., L, n)
        :math:`X_i^*` (14), the minimizer (7) of :math:`J_i`.
    J : ndarray, shape (..., L)
        :math:`J_i(X_i^*) = \\rho_i - X_i^{*\\top} U_i X_i^*`, equal to (17) (module
        docstring).
    mode : ndarray of int, shape (...)
        :math:`\\arg\\min_i J_i` (5).
    """
    X = np.einsum("lij,...lj->...li", K, z)
    J = rho - np.einsum("...li,lij,...lj->...l", X, U, X)
    return X, J, np.argmin(J, axis=-1)


# ---------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class MinDistanceState:
    """Per-trial state of the whole algorithm (batch axis first).

    Attributes
    ----------
    t : ndarray, shape (N,)
        Time since the first sample.
    h : ndarray, shape ()
        Grid step (NaN until the second sample).
    y_last : ndarray, shape (N, m)
        Last finite output sample.
    estimating : ndarray of bool, shape (N,)
        In an estimation window (step 1) rather than detecting (step 2).
    k_window : ndarray of int, shape (N,)
        Grid steps since the window start :math:`\\hat{t}_j`.
    window : ndarray, shape (N, L, 3n)
        :math:`[\\tilde{x}_i; z_i; \\hat{x}_i]` of (12), (13) and (19) from zero, every mode.
    rho : ndarray, shape (N, L)
        :math:`\\int |y - C_i \\tilde{x}_i|^2` over the window so far.
    mode : ndarray of int, shape (N,)
        :math:`\\hat{\\sigma}_j` (-1 before the first window ends).
    x_check, x_hat : ndarray, shape (N, n)
        Predictor (18) and observer (19).
    s_hist : ndarray, shape (N, c)
        :math:`s` of (20) at the last ``c`` grid points, newest last (0 before
        :math:`\\bar{t}_j`).
    k_up : ndarray of int, shape (N,)
        Grid steps since :math:`t_\\mathrm{up}`.
    window_energy : ndarray, shape (N,)
        :math:`s(t) - s(t - \\Delta)`, the left side of (24) (0 while estimating).
    detected : ndarray of bool, shape (N,)
        A switch was declared at this sample.
    """

    t: np.ndarray
    h: np.ndarray
    y_last: np.ndarray
    estimating: np.ndarray
    k_window: np.ndarray
    window: np.ndarray
    rho: np.ndarray
    mode: np.ndarray
    x_check: np.ndarray
    x_hat: np.ndarray
    s_hist: np.ndarray
    k_up: np.ndarray
    window_energy: np.ndarray
    detected: np.ndarray


@dataclass(frozen=True, eq=False)
class WindowEstimate:
    """Result of :meth:`MinimumDistanceDetector.estimate_window` (Lee et al. §III).

    Attributes
    ----------
    mode : ndarray of int, shape (...)
        :math:`\\hat{\\sigma}` (5).
    X : ndarray, shape (..., L, n)
        :math:`X_i^*` (7)/(14) of every mode; ``X[..., mode, :]`` is
        :math:`\\hat{x}(\\hat{t}_j)` (8).
    J : ndarray, shape (..., L)
        :math:`J_i(X_i^*)` (6)/(17).
    """

    mode: np.ndarray
    X: np.ndarray
    J: np.ndarray


# ---------------------------------------------------------------------- estimator
class MinimumDistanceDetector(Estimator):
    """Lee et al.'s switching-signal estimator: minimum-distance mode estimation and detection.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous-time; every mode observable.
    delta : float
        Estimation window :math:`\\delta` (Lee et al. (3)); must be a multiple of the grid
        step.
    Delta : float
        Detection delay :math:`\\Delta` (Lee et al. (4)).
    v_max : float
        Bound on :math:`|v(t)|` (eq. (2)), positive (it sets the thresholds of
        (21)-(24); with 0, round-off alone would trigger them). Include the
        interpolation error of the grid (module docstring).
    u_max : float
        Bound on :math:`|u(t)|` (keyword-only); the algorithm does not use it,
        :meth:`assumptions` does.
    observer_gains : array_like, shape (L, n, m), optional
        :math:`L_i` of (19) (keyword-only); default
        :func:`switchest.analysis.min_distance_design.default_observer_gains`.

    Notes
    -----
    The detector takes no prior ``x0, P0`` (the one exception to the constructor
    convention of :class:`~switchest.estimators.base.Estimator`): each window estimates
    the state from the output alone, eq. (14).

    ``run(y, u, t)`` takes the output on a uniform grid ``t`` and returns an
    :class:`Estimate` with ``x`` (observer (19)), ``mode`` (:math:`\\hat{\\sigma}`) and
    ``switch_time`` (the grid instant at which each switch is declared, NaN
    elsewhere); see the module docstring for what is reported inside windows.

    Examples
    --------
    >>> import numpy as np
    >>> from switchest.models import LEE_SCENARIO as S  # Lee et al.'s FSK oscillator, §V
    >>> from switchest.simulate import simulate
    >>> rng = np.random.default_rng(0)
    >>> t = 0.01 * np.arange(501)
    >>> u = S.input(t, 1, rng)
    >>> traj = simulate(S.system(), S.signal, t, np.array(S.x0), u, trials=1, rng=rng)
    >>> y = traj.x + S.noise(t, 1, rng, v_max=0.9 * S.v_max)  # bounded noise, |v| < v_max
    >>> det = MinimumDistanceDetector(S.system(), delta=S.delta, Delta=S.Delta, v_max=S.v_max,
    ...                               u_max=S.u_max, observer_gains=S.observer_gains)
    >>> est = det.run(y, u, t)
    >>> decided = est.mode[0] >= 0  # -1 until the first window is full
    >>> bool(np.mean(est.mode[0][decided] == traj.mode[0][decided]) > 0.9)
    True
    """

    def __init__(self, system, delta: float, Delta: float, v_max: float, *, u_max: float = 0.0,
                 observer_gains=None):
        if not isinstance(system, SwitchedLinearSystem):
            raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
        self.system = system
        self.v_max = positive_scalar(v_max, "v_max")
        self.u_max = positive_scalar(u_max, "u_max", allow_zero=True)
        self.constants: LeeConstants = lee_constants(system, delta, Delta, observer_gains)
        k = self.constants
        self.delta, self.Delta = k.delta, k.Delta
        self.observer_gains = k.observer_gains
        self.threshold = k.reset_threshold(self.v_max)  # (21), (23)
        self.S_Delta = k.S_Delta(self.v_max)  # (24)
        e_A = mode_steps(SwitchedLinearSystem.continuous(system.A), self.delta).F
        closed = SwitchedLinearSystem.continuous(system.A - self.observer_gains @ system.C)
        self._e_A = e_A  # e^{A_i delta}
        self._e_closed = mode_steps(closed, self.delta).F  # e^{(A_i - L_i C_i) delta}
        self._K = np.linalg.solve(k.U, np.swapaxes(e_A, 1, 2))  # U_i^{-1} e^{A_i' delta}, (14)
        self._augmented = augmented_system(system, self.observer_gains)

    def assumptions(
        self, x_min: float, *, signal=None, min_dwell: float | None = None
    ) -> LeeAssumptions:
        """Lee et al. Assumptions 1-3 for this detector's windows, bounds and gains.

        See :func:`switchest.analysis.min_distance_design.lee_assumptions`; ``x_min`` bounds
        :math:`|x(t)|` from below, ``signal`` / ``min_dwell`` check Assumption 3.
        """
        return lee_assumptions(self.system, u_max=self.u_max, v_max=self.v_max, x_min=x_min,
                               delta=self.delta, Delta=self.Delta,
                               observer_gains=self.observer_gains, signal=signal,
                               min_dwell=min_dwell)

    # ------------------------------------------------------------------ protocol
    def init(self, batch_shape=()) -> MinDistanceState:
        """Before the first sample: the first window opens there (:math:`\\hat{t}_0 = 0`)."""
        sys = self.system
        L, n, m = sys.n_modes, sys.n_states, sys.n_outputs
        return MinDistanceState(
            t=np.zeros(batch_shape),
            h=np.array(np.nan),
            y_last=np.full((*batch_shape, m), np.nan),
            estimating=np.ones(batch_shape, dtype=bool),
            k_window=np.zeros(batch_shape, dtype=np.int64),
            window=np.zeros((*batch_shape, L, 3 * n)),
            rho=np.zeros((*batch_shape, L)),
            mode=np.full(batch_shape, -1, dtype=np.int64),
            x_check=np.zeros((*batch_shape, n)),
            x_hat=np.zeros((*batch_shape, n)),
            s_hist=np.zeros((*batch_shape, 0)),
            k_up=np.zeros(batch_shape, dtype=np.int64),
            window_energy=np.zeros(batch_shape),
            detected=np.zeros(batch_shape, dtype=bool),
        )

    def step(self, state: MinDistanceState, y, u=None, *, dt=None) -> MinDistanceState:
        """Integrate over the grid step ``dt`` up to sample ``y (N, m)`` and run the checks.

        ``u (N, l)`` is the input held over the step. ``dt=None`` (the first sample)
        only records ``y``. Every later ``dt`` must equal the first one.
        """
        sys = self.system
        y = float_array(y, "y", masked="nan")
        if y.shape != state.y_last.shape:
            raise ValueError(f"y must have shape {state.y_last.shape}, got {y.shape}")
        missing = np.isnan(y).any(axis=-1, keepdims=True)
        y = np.where(missing, state.y_last, y)  # a missing sample holds the last output
        if np.isnan(y).any():
            raise ValueError("y must be finite at the first sample of every trial "
                             "(nothing to hold yet)")
        if dt is None:
            return replace(state, y_last=y, detected=np.zeros_like(state.detected))
        h = self._grid_step(state.h, dt)
        u = np.zeros((*y.shape[:-1], sys.n_inputs)) if u is None else float_array(u, "u")
        n = sys.n_states
        tr = mode_steps(self._augmented, h)
        F, G = tr.F, tr.Qd

        # (12), (13) and (19) from zero for every mode, and rho_i: the estimation window
        win, win_energy = exact_step(state.window, u[..., None, :], state.y_last[..., None, :],
                                     y[..., None, :], h, F, G)
        rho = state.rho + win_energy
        # (18), (19), (20) for the estimated mode: detection
        m_det = np.maximum(state.mode, 0)
        core = np.concatenate([state.x_check, np.zeros_like(state.x_check), state.x_hat], axis=-1)
        core, det_energy = exact_step(core, u, state.y_last, y, h, F[m_det], G[m_det])
        x_check, x_hat = core[..., :n], core[..., 2 * n :]
        s_prev = state.s_hist[..., -1] if state.s_hist.shape[-1] else np.zeros_like(det_energy)
        s_hist = self._shifted(state.s_hist, s_prev + det_energy, h)
        k_up = state.k_up + 1

        # end of a window: (14), (17), (5), (8), then (18)-(19) caught up to t_hat_j + delta
        k_window = state.k_window + 1
        done = state.estimating & (k_window == self._steps(h))
        if done.any():
            best, x_check_new, x_hat_new = self._complete(win, rho)
        else:
            best, x_check_new, x_hat_new = state.mode, x_check, x_hat

        # detection checks (21)-(24), only for trials that were already detecting
        detecting = ~state.estimating
        gap = np.linalg.norm(x_check - x_hat, axis=-1)
        old = k_up * h >= self.Delta * (1 - 1e-9)  # t - t_up >= Delta
        reset = detecting & old & (gap > self.threshold)  # (21) -> (22)
        x_check = np.where(reset[..., None], x_hat, x_check)
        k_up = np.where(reset, 0, k_up)
        energy = s_hist[..., -1] - self._lagged(s_hist, h)  # s(t) - s(t - Delta)
        # (23), (24)
        fired = detecting & ((~old & (gap > self.threshold)) | (energy > self.S_Delta))

        estimating = (state.estimating & ~done) | fired
        zero_win = fired | done
        return MinDistanceState(
            t=state.t + h,
            h=np.array(h),
            y_last=y,
            estimating=estimating,
            k_window=np.where(fired, 0, k_window),
            window=np.where(zero_win[..., None, None], 0.0, win),
            rho=np.where(zero_win[..., None], 0.0, rho),
            mode=np.where(done, best, np.where(fired, -1, state.mode)),
            x_check=np.where(done[..., None], x_check_new, x_check),
            x_hat=np.where(done[..., None], x_hat_new, x_hat),
            s_hist=np.where(detecting[..., None], s_hist, 0.0),  # s = 0 up to t_hat_j + delta
            k_up=np.where(done, k_window, k_up),  # t_up = t_hat_j
            window_energy=np.where(detecting, energy, 0.0),
            detected=fired,
        )

    def _complete(self, win: np.ndarray, rho: np.ndarray):
        """Lee et al. (14), (17), (5), (8), and (18)-(19) brought to :math:`\\hat{t}_j + \\delta`.

        By linearity, (18) from :math:`X^*` is :math:`e^{A \\delta} X^*` plus the window's
        forced solution (12), and (19) is :math:`e^{(A - LC) \\delta} X^*` plus the window's
        observer from zero (module docstring).
        """
        n = self.system.n_states
        X, _, best = window_estimate(win[..., n : 2 * n], rho, self._K, self.constants.U)
        pick = best[..., None, None]
        X_best = np.take_along_axis(X, pick, axis=-2)[..., 0, :]
        w_best = np.take_along_axis(win, pick, axis=-2)[..., 0, :]
        x_check = (self._e_A[best] @ X_best[..., None])[..., 0] + w_best[..., :n]
        x_hat = (self._e_closed[best] @ X_best[..., None])[..., 0] + w_best[..., 2 * n :]
        return best, x_check, x_hat

    def _output(self, state: MinDistanceState) -> dict[str, np.ndarray]:
        est = state.estimating
        return {
            "x": np.where(est[..., None], np.nan, state.x_hat),
            "mode": np.where(est, -1, state.mode),
            "switch_time": np.where(state.detected, state.t, np.nan),
        }

    def run(self, y, u=None, t=None) -> Estimate:
        """Run the whole algorithm on ``y (..., K, m)`` sampled on the uniform grid ``t (K,)``.

        ``u`` is held over each grid step (``u[k]`` on :math:`[t_k, t_{k+1})`).

        Returns
        -------
        Estimate
            ``x (..., K, n)``, ``mode (..., K)``, ``switch_time (..., K)``; ``P`` is None.
        """
        y2, u2, t, batch = self._prepare(y, u, t)
        steps = np.diff(t)
        off = np.flatnonzero(np.abs(steps - steps[0]) > _GRID_RTOL * steps[0]) if steps.size else ()
        if len(off):  # checked up front, so the message can name the sample
            k = int(off[0]) + 1
            raise ValueError(f"t must be a uniform grid: sample {k} is {steps[k - 1]:.6g} after "
                             f"the previous one, the first step is {steps[0]:.6g}")
        if steps.size:  # the history of s over the last Delta, one value per grid step and trial
            check_memory(8 * y2.shape[0] * (self.Delta / steps[0] + 2),
                         f"Delta / (grid step) = {self.Delta / steps[0]:.3g} values of s per trial "
                         f"for N = {y2.shape[0]} trials")
        est = self._loop(y2, u2, t)
        switch = np.where(np.isnan(est.switch_time), np.nan, t[None, :])  # the grid instants
        return self._unflatten(replace(est, switch_time=switch), batch)

    def estimate_window(self, y, u=None, t=None) -> WindowEstimate:
        """Lee et al. (5)-(8) on one window: ``y (..., K, m)`` on ``t`` spanning exactly ``delta``.

        The on-line integration (12)-(13) of :meth:`step`, then (14), (17) and (5).
        """
        y2, u2, t, batch = self._prepare(y, u, t)
        h = self._grid_step(np.array(np.nan), t[1] - t[0]) if t.size > 1 else np.nan
        if t.size < 2 or t.size - 1 != self._steps(h):
            raise ValueError(f"t must span exactly delta = {self.delta:g} "
                             f"(delta / step + 1 samples), got {t.size} samples over "
                             f"{t[-1] - t[0]:g}")
        state = self.init((y2.shape[0],))
        for k in range(t.size - 1):
            self._grid_step(np.array(h), t[k + 1] - t[k])
            tr = mode_steps(self._augmented, h)
            win, e = exact_step(state.window, u2[:, k, None, :], y2[:, k, None, :],
                                y2[:, k + 1, None, :], h, tr.F, tr.Qd)
            state = replace(state, window=win, rho=state.rho + e)
        n = self.system.n_states
        X, J, mode = window_estimate(state.window[..., n : 2 * n], state.rho, self._K,
                                     self.constants.U)
        return WindowEstimate(mode=mode.reshape(batch), X=X.reshape(*batch, *X.shape[1:]),
                              J=J.reshape(*batch, *J.shape[1:]))

    # ------------------------------------------------------------------ grid helpers
    def _grid_step(self, h_state: np.ndarray, dt) -> float:
        dt = positive_scalar(dt, "dt")
        if np.isnan(h_state):
            self._steps(dt)  # validates delta against the grid
            return dt
        h = float(h_state)
        if abs(dt - h) > _GRID_RTOL * h:
            raise ValueError(f"dt must stay equal to the first grid step {h:g} (uniform grid), "
                             f"got {dt:g}")
        return h

    def _steps(self, h: float) -> int:
        """Grid steps in one estimation window; ``delta`` must be a multiple of ``h``."""
        k = round(self.delta / h)
        if k < 1 or abs(k * h - self.delta) > _GRID_RTOL * self.delta:
            raise ValueError(
                f"delta must be a positive multiple of the grid step {h:g}, "
                f"got delta = {self.delta:g} (delta / step = {self.delta / h:.6g})"
            )
        return k

    def _lag(self, h: float) -> tuple[int, float]:
        """:math:`\\Delta = (c - \\theta) h`, integer :math:`c`, :math:`0 \\le \\theta < 1`."""
        c = int(np.ceil(self.Delta / h - 1e-9))
        return c, c - self.Delta / h

    def _shifted(self, hist: np.ndarray, newest: np.ndarray, h: float) -> np.ndarray:
        """Append the newest ``s (N,)``, keep the last ``c + 1`` values (allocated on first use)."""
        c, _ = self._lag(h)
        if hist.shape[-1] != c + 1:
            hist = np.zeros((*newest.shape, c + 1))
        return np.concatenate([hist[..., 1:], newest[..., None]], axis=-1)

    def _lagged(self, hist: np.ndarray, h: float) -> np.ndarray:
        """:math:`s(t - \\Delta)`, linear between the two grid points around it."""
        c, theta = self._lag(h)
        return (1 - theta) * hist[..., -1 - c] + theta * hist[..., -c]


# ---------------------------------------------------------------------- Theorem 2 bookkeeping
@dataclass(frozen=True, eq=False)
class DetectionMatch:
    """Detected against true switching instants (:func:`match_detections`).

    Attributes
    ----------
    delay : ndarray, shape (S_total,)
        :math:`t_\\mathrm{detected} - t_\\mathrm{switch}` of every true switch (NaN when
        missed), trials concatenated in order.
    on_time : int
        Switches detected with :math:`-\\mathrm{lead} \\le \\mathrm{delay} \\le \\Delta`.
    late : int
        Switches detected after :math:`\\Delta` (before the next switch).
    missed : int
        Switches with no detection before the next switch (or the end), at least
        :math:`\\Delta` before the end of the record.
    censored : int
        Undetected switches less than :math:`\\Delta` before the end: the record stops
        before their detection deadline.
    false : int
        Detections matched to no switch.
    n_switches : int
    """

    delay: np.ndarray
    on_time: int
    late: int
    missed: int
    censored: int
    false: int
    n_switches: int


def match_detections(switch_time, signals, *, Delta: float, t_end: float,
                     lead: float = 0.0) -> DetectionMatch:
    """Match declared switching instants to the true ones (Lee et al. Theorem 2 bookkeeping).

    The first detection in :math:`[t_s - \\mathrm{lead}, t_{s+1} - \\mathrm{lead})` is matched
    to true switch :math:`t_s` (:math:`t_{S+1} = \\infty`); every other detection is false.

    Parameters
    ----------
    switch_time : array_like, shape (N, K) or (K,)
        Declared instants, NaN elsewhere (``Estimate.switch_time``).
    signals : SwitchingSignal or sequence of N of them
        The true signals.
    Delta : float
        Allowed delay.
    t_end : float
        End of the record.
    lead : float
        How early a detection may come and still count (0 for the causal detector
        of Lee et al.; up to a sample period for filters that estimate the instant
        inside an interval).

    Returns
    -------
    DetectionMatch
    """
    st = float_array(switch_time, "switch_time", ndim=(1, 2))
    if np.any(np.isinf(st)):
        raise ValueError("switch_time must hold finite instants (NaN where nothing is declared)")
    st = st[None] if st.ndim == 1 else st
    sigs = [signals] if isinstance(signals, SwitchingSignal) else signals
    if not isinstance(sigs, Sequence) or not all(isinstance(s, SwitchingSignal) for s in sigs):
        raise TypeError(f"signals must be a SwitchingSignal or a sequence of them, got "
                        f"{type(signals).__name__}")
    if len(sigs) != st.shape[0]:
        raise ValueError(f"signals must hold one signal per trial ({st.shape[0]}), got {len(sigs)}")
    Delta = positive_scalar(Delta, "Delta")
    lead = positive_scalar(lead, "lead", allow_zero=True)
    t_end = float_array(t_end, "t_end", ndim=0)
    check_finite(t_end, "t_end")
    delays, switches, false = [], [], 0
    for row, sig in zip(st, sigs):
        switches.append(sig.times)
        found = np.sort(row[np.isfinite(row)])
        edges = np.concatenate([sig.times, [np.inf]]) - lead
        used = np.zeros(found.size, dtype=bool)
        for s, t_s in enumerate(sig.times):
            inside = np.flatnonzero((found >= edges[s]) & (found < edges[s + 1]))
            delays.append(found[inside[0]] - t_s if inside.size else np.nan)
            used[inside[:1]] = True
        false += int(np.count_nonzero(~used))
    delay = np.array(delays, dtype=float)
    ok = np.isfinite(delay)
    near_end = np.concatenate([np.zeros(0), *switches]) > t_end - Delta
    return DetectionMatch(
        delay=delay,
        on_time=int(np.count_nonzero(ok & (delay <= Delta))),
        late=int(np.count_nonzero(ok & (delay > Delta))),
        missed=int(np.count_nonzero(~ok & ~near_end)),
        censored=int(np.count_nonzero(~ok & near_end)),
        false=false,
        n_switches=int(delay.size),
    )
