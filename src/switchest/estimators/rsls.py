"""Subsystem observers for random switching among unobservable modes (Wang et al., seed 003).

Wang et al. §3: mode :math:`i` observes only the sub-state :math:`z^i = F_i x`. Its
sub-observer runs closed loop while :math:`\\alpha_k = i`:

.. math::

    d\\hat z^i = A_{22}^i \\hat z^i \\, dt + L_i (dy - C_2^i \\hat z^i \\, dt)
    \\qquad \\text{eq. (7)}

and open loop otherwise, restarted at every switching instant from the combined
estimate: :math:`\\hat z^j_{k+1} = F_j e^{A_k T} \\hat x_k` (eq. (14)), with
:math:`\\hat x = \\Phi \\hat z`, :math:`\\Phi = (F^\\top F)^{-1} F^\\top` (§3.2).

The output is Ito's :math:`dy = C x \\, dt + \\Xi \\, dw` (eq. (1), Remark 1): the observer is
fed the integrated output ``y`` on a fine time grid (``simulate(...,
output="integrated")``, ``Trajectory.y_fine``) and uses its increments, never a
derivative. Over a fine step :math:`h` the closed-loop block is updated in innovation
form:

.. math::

    \\begin{aligned}
    \\hat z &\\leftarrow e^{A_{22} h} \\hat z + K_h (\\Delta y - C_2 \\Psi_h \\hat z), \\\\
    \\Psi_h &= \\int_0^h e^{A_{22} s} \\, ds, \\qquad
    K_h = \\frac{1}{h} \\int_0^h e^{A_c s} \\, ds \\, L
    \\end{aligned}

so that the noise-free error obeys :math:`e \\leftarrow (e^{A_{22} h} - K_h C_2 \\Psi_h) e`
exactly, whatever the state (the error never picks up a term proportional to a growing
:math:`x`), and that map agrees with :math:`e^{A_c h}` to second order in :math:`h` (the
:math:`h^2` terms coincide), as does the injected noise covariance with Proposition
1's integral. Every exponential and integral comes from
:func:`switchest.discretize.mode_steps`.

The filter state is :math:`s = [\\hat z; x_{\\mathrm{ol}}]`: the stacked sub-state estimates
and the open-loop prediction :math:`x_{\\mathrm{ol}}(t) = e^{A_k (t - kT)} \\hat x_k` that drives
the open blocks inside the interval. Alongside it the estimator propagates :math:`\\Sigma`, the
exact covariance of the error of :math:`s` given the mode path (for a Gaussian
initial error :math:`\\mathcal{N}(0, \\mathrm{P0})`); :math:`P = \\Phi \\Sigma_{zz} \\Phi^\\top` is
reported.

:meth:`RSLSObserver.sample_errors` gives the observer's error at the samples of a simulated
trajectory, :func:`fine_step_error_system` the exact sampled error system of its fine steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_bool, float_array, positive_int, positive_scalar
from .._linalg import symmetrize
from ..analysis.subsystem_observers import substate_gains, subsystem_structure
from ..discretize import mode_steps
from ..system import SwitchedLinearSystem
from .base import Estimate, Estimator

__all__ = ["RSLSObserver", "RSLSState", "fine_step_error_system"]

_GRID_RTOL = 1e-9


@dataclass(frozen=True, eq=False)
class RSLSState:
    """Observer state after the last fine sample.

    Attributes
    ----------
    s : ndarray, shape (N, n_s + n)
        :math:`[\\hat z; x_{\\mathrm{ol}}]`.
    Sigma : ndarray, shape (N, n_s + n, n_s + n)
        Covariance of the error of ``s`` given the modes.
    y_prev : ndarray, shape (N, m)
        The integrated output at the previous fine sample (NaN before the first).
    tau : ndarray, shape (N,)
        Time elapsed since the last switching instant.
    """

    s: np.ndarray
    Sigma: np.ndarray
    y_prev: np.ndarray
    tau: np.ndarray


@dataclass(frozen=True, eq=False)
class _FineStep:
    """Per-mode matrices of one fine step: :math:`s^+ = \\mathrm{A0}\\, s + B \\nu`,
    :math:`\\nu = \\Delta y - C s`."""

    A0: np.ndarray  # (L, d, d)
    B: np.ndarray  # (L, d, m)
    C: np.ndarray  # (L, m, d)


class RSLSObserver(Estimator):
    """The MS-convergent observer of Wang et al. §3 for randomly switched systems.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous time, no input, no process noise; ``R`` the output-noise
        intensity :math:`\\Xi \\Xi^\\top`.
    gains : array_like, shape (L, n, m)
        Sub-observer gains in state coordinates (columns in each mode's
        observable subspace), e.g. from :func:`switchest.analysis.subsystem_observers.place_gains`.
    T : float
        Switching interval: modes change only at :math:`t[0] + kT` (Assumption 1).
    x0, P0 : array_like
        Initial estimate :math:`\\hat x(t[0])` ``(n,)`` and the covariance of its error ``(n, n)``.
    shared : bool
        Modes with equal observable subspaces share one sub-observer (default;
        see :func:`switchest.analysis.subsystem_observers.subsystem_structure`).

    Notes
    -----
    ``run(y, t=t_fine, modes=mode_fine)`` takes the integrated output at fine
    instants ``t`` that include every switching instant :math:`t[0] + kT`, and the
    (measured, Assumption 1(d)) mode at each instant; the estimate is returned at
    every fine instant. NaN in ``y`` marks a lost sample: the steps on either
    side of it make no correction from that channel.

    Examples
    --------
    >>> import numpy as np
    >>> from switchest.models import wang_scalar_pair
    >>> from switchest.signals import iid_at_samples
    >>> from switchest.simulate import simulate
    >>> system = wang_scalar_pair(2.0, 4.0, 0.01)  # Wang et al. Example 1: no mode observable
    >>> T = 0.03
    >>> t = T * np.arange(101)
    >>> traj = simulate(system, lambda r: iid_at_samples([0.5, 0.5], t, rng=r), t,
    ...                 np.array([1.0, 1.0]), trials=2, rng=0, fine_dt=T / 10,
    ...                 output="integrated")  # the integrated output on a fine grid
    >>> gains = np.array([[[40.0], [0.0]], [[0.0], [40.0]]])  # one sub-observer per mode
    >>> obs = RSLSObserver(system, gains, T, [0.0, 0.0], np.zeros((2, 2)))
    >>> est = obs.run(traj.y_fine, t=traj.t_fine, modes=traj.mode_fine)
    >>> at = np.searchsorted(traj.t_fine, t)  # the switching instants kT
    >>> error = np.linalg.norm(est.x[:, at[-1]] - traj.x[:, -1], axis=-1)
    >>> bool(np.all(error < 1e-3 * np.linalg.norm(traj.x[:, -1], axis=-1)))  # x grows as e^(4t)
    True
    """

    def __init__(self, system, gains, T: float, x0, P0, *, shared: bool = True):
        self._set_prior(system, x0, P0)
        self.structure = subsystem_structure(system, shared=check_bool(shared, "shared"))
        self.T = positive_scalar(T, "T")
        self._L = substate_gains(self.structure, gains)
        st, L, n_s = self.structure, system.n_modes, self.structure.n_substates
        # Block-lifted sub-observer models (R^{n_s}; identity dynamics outside the active block):
        # open loop (A22, B = I) gives e^{A22 h} and Psi_h, closed loop (A_c, B = L) gives K_h h.
        A22, Ac, Lb = (
            np.zeros((L, n_s, n_s)),
            np.zeros((L, n_s, n_s)),
            np.zeros((L, n_s, system.n_outputs)),
        )
        self._C2 = np.zeros((L, system.n_outputs, n_s))
        self._rows = np.ones((L, n_s))  # 1 on the rows of the blocks that run open loop
        for i in range(L):
            if st.block[i] >= 0:
                r = st.rows(st.block[i])
                A22[i, r, r] = st.A22[i]
                Ac[i, r, r] = st.A22[i] - self._L[i] @ st.C2[i]
                Lb[i, r] = self._L[i]
                self._C2[i, :, r] = st.C2[i]
                self._rows[i, r] = 0.0
        self._open = SwitchedLinearSystem.continuous(
            A22, B=np.broadcast_to(np.eye(n_s), (L, n_s, n_s))
        )
        self._closed = SwitchedLinearSystem.continuous(Ac, B=Lb)
        n = system.n_states
        d = n_s + n
        self._reset = np.zeros((d, d))  # at t = (k+1)T: x_ol <- Phi z_hat (eq. (14))
        self._reset[:n_s, :n_s] = np.eye(n_s)
        self._reset[n_s:, :n_s] = st.Phi
        self._lift = np.concatenate([st.F, np.eye(n)], axis=0)  # s = [F; I] x
        self._steps: dict[float, _FineStep] = {}

    # ------------------------------------------------------------------ protocol
    def init(self, batch_shape=()) -> RSLSState:
        """The prior :math:`s = [F \\mathrm{x0}; \\mathrm{x0}]`,
        :math:`\\Sigma = [F; I] \\mathrm{P0} [F; I]^\\top`, one per ``batch_shape``."""
        d = self._lift.shape[0]
        m = self.system.n_outputs
        return RSLSState(
            s=np.broadcast_to(self._lift @ self.x0, (*batch_shape, d)).copy(),
            Sigma=np.broadcast_to(self._lift @ self.P0 @ self._lift.T, (*batch_shape, d, d)).copy(),
            y_prev=np.full((*batch_shape, m), np.nan),
            tau=np.zeros(batch_shape),
        )

    def step(self, state: RSLSState, y, u=None, *, dt=None, mode) -> RSLSState:
        """Advance over the fine step ``dt`` ending at the integrated output ``y (N, m)``.

        ``mode (N,)`` is the mode active during the step. With ``dt=None`` (first
        sample) only ``y`` is recorded.
        """
        y = float_array(y, "y", masked="nan")
        if dt is None:
            return RSLSState(state.s, state.Sigma, y.copy(), state.tau)
        h = positive_scalar(dt, "dt")
        tau = state.tau + h
        if np.any(tau > self.T * (1 + _GRID_RTOL) + 1e-12):
            raise ValueError(
                f"the fine grid must contain every switching instant t[0] + kT (T = {self.T:g}); "
                f"a step of {h:g} crosses one"
            )
        mode = np.asarray(mode)
        fs = self._fine(h)
        A0, B, C = fs.A0[mode], fs.B[mode], fs.C[mode]
        innovation = (y - state.y_prev) - np.einsum(
            "nmd,nd->nm", C, state.s
        )  # Delta y - C2 Psi_h z_hat
        observed = np.isfinite(innovation)
        innovation = np.where(observed, innovation, 0.0)
        s = np.einsum("nij,nj->ni", A0, state.s) + np.einsum("nim,nm->ni", B, innovation)
        Bo = B * observed[:, None, :]  # a lost channel corrects nothing and injects no noise
        E = A0 - Bo @ C  # error map of the step
        noise = Bo @ (self.system.R[mode] * h) @ np.swapaxes(Bo, -1, -2)  # E[dw dw'] = R h
        Sigma = symmetrize(E @ state.Sigma @ np.swapaxes(E, -1, -2) + noise)
        end = tau >= self.T * (1 - _GRID_RTOL) - 1e-12
        if np.any(end):
            s = np.where(end[:, None], s @ self._reset.T, s)
            Sigma = np.where(end[:, None, None], self._reset @ Sigma @ self._reset.T, Sigma)
            tau = np.where(end, 0.0, tau)
        return RSLSState(s, Sigma, y.copy(), tau)

    def _output(self, state: RSLSState) -> dict[str, np.ndarray]:
        st = self.structure
        n_s = st.n_substates
        Szz = state.Sigma[:, :n_s, :n_s]
        return {"x": state.s[:, :n_s] @ st.Phi.T, "P": symmetrize(st.Phi @ Szz @ st.Phi.T)}

    def run(self, y, u=None, t=None, *, modes) -> Estimate:
        """Observe the integrated output ``y (..., K, m)`` at fine instants ``t (K,)``.

        Parameters
        ----------
        y : array_like, shape (..., K, m)
            Integrated output :math:`y(t_j)` (e.g. ``Trajectory.y_fine``).
        u : None
            The model has no input (Wang et al. eq. (1)).
        t : array_like, shape (K,)
            Fine instants, containing every switching instant :math:`t[0] + kT`.
        modes : array_like of int, shape (K,) or (..., K)
            Mode at each instant (``Trajectory.mode_fine``), constant on each
            :math:`[t[0] + kT, t[0] + (k+1)T)`.
        """
        if u is not None:
            raise ValueError("u must be None: Wang et al.'s model (1) has no input")
        y2, u2, t, batch = self._prepare(y, None, t)
        K = t.size
        modes = self._modes(modes, batch, K)
        # step j covers [t_{j-1}, t_j) and uses the mode at t_{j-1}
        used = np.concatenate([modes[:, :1], modes[:, :-1]], axis=1)
        interval = np.floor((t - t[0]) / self.T * (1 + _GRID_RTOL) + _GRID_RTOL).astype(np.int64)
        interval = np.concatenate([interval[:1], interval[:-1]])
        first = np.searchsorted(interval, interval, side="left")
        if np.any(used != used[:, first]):
            raise ValueError(
                f"modes must be constant on each switching interval [t[0] + kT, t[0] + (k+1)T), "
                f"T = {self.T:g} (Wang et al. Assumption 1(a))"
            )
        return self._unflatten(self._loop(y2, u2, t, {"mode": used}), batch)

    def sample_errors(self, traj) -> np.ndarray:
        """The estimation error :math:`\\hat x_k - x_k` at the samples of a simulated trajectory.

        Runs the observer on ``traj``'s integrated output on its fine grid and subtracts the
        true state at the samples: with samples at the switching instants :math:`kT` this is the
        error of Wang et al. Theorem 1 (eq. (15)), whose moments
        :mod:`switchest.analysis.error_moments` gives exactly.

        Parameters
        ----------
        traj : Trajectory
            From ``simulate(..., fine_dt=..., output="integrated")``: the fine grid contains
            every sample.

        Returns
        -------
        ndarray, shape (N, K, n)
        """
        if traj.y_fine is None:
            raise ValueError("traj must carry the integrated output on a fine grid: "
                             "simulate(..., fine_dt=..., output='integrated')")
        est = self.run(traj.y_fine, t=traj.t_fine, modes=traj.mode_fine)
        return est.x[:, np.searchsorted(traj.t_fine, traj.t)] - traj.x

    # ------------------------------------------------------------------ fine-step matrices
    def _fine(self, h: float) -> _FineStep:
        key = float(np.format_float_positional(h, precision=13, unique=False, fractional=False))
        if key in self._steps:
            return self._steps[key]
        st, sys = self.structure, self.system
        n_s, n, L = st.n_substates, sys.n_states, sys.n_modes
        d = n_s + n
        expA = mode_steps(sys, h).F  # e^{A_i h}
        op = mode_steps(self._open, h)  # block b: e^{A22 h}, Psi_h
        K = mode_steps(self._closed, h).G / h  # block b: K_h = (1/h) int_0^h e^{A_c s} ds L
        active = 1.0 - self._rows  # 1 on the closed-loop block's rows
        A0 = np.zeros((L, d, d))
        A0[:, :n_s, :n_s] = op.F * active[:, :, None] * active[:, None, :]
        A0[:, :n_s, n_s:] = (st.F @ expA) * self._rows[:, :, None]  # z_hat^j = F_j x_ol, eq. (14)
        A0[:, n_s:, n_s:] = expA
        B = np.zeros((L, d, sys.n_outputs))
        B[:, :n_s] = K
        C = np.zeros((L, sys.n_outputs, d))
        C[:, :, :n_s] = self._C2 @ op.G  # C2 Psi_h
        self._steps[key] = _FineStep(A0, B, C)
        return self._steps[key]


def fine_step_error_system(system, gains, T: float, substeps: int) -> tuple[np.ndarray, np.ndarray]:
    """The sampled error system of the observer as it runs, ``substeps`` fine steps per interval.

    Wang et al. Theorem 1 (eq. (15)),
    :math:`e_{k+1} = \\Lambda(\\alpha_k) e_k + \\Gamma(\\alpha_k) d_k`,
    is the error of the continuous-time sub-observers
    (:func:`~switchest.analysis.subsystem_observers.error_dynamics`). :class:`RSLSObserver`
    runs them on fine steps :math:`h = T / \\mathrm{substeps}`, whose error map agrees with
    :math:`e^{A_c h}` to second order in :math:`h` only. This is the sampled error system of that
    discretization, in state coordinates: column :math:`j` of ``Lam[i]`` is the error after one
    interval in mode :math:`i` from the unit initial error :math:`e_j`, noise free, and ``W[i]``
    the covariance of the error the interval's output noise injects (the propagated covariance
    from :math:`\\mathrm{P0} = 0`). The
    steady state of eq. (21) of the observer as it runs is then
    :func:`~switchest.analysis.error_moments.moment_fixed_point` of ``(Lam, W)``.

    Parameters
    ----------
    system : SwitchedLinearSystem
        As for :class:`RSLSObserver`, with one sub-state per state (:math:`n_s = n`), so that the
        state error at :math:`kT` determines the sub-state error the next interval starts from.
    gains : array_like, shape (L, n, m)
        Sub-observer gains in state coordinates.
    T : float
        Switching interval.
    substeps : int
        Fine steps per interval.

    Returns
    -------
    Lam, W : ndarray, shape (L, n, n)
    """
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    substeps = positive_int(substeps, "substeps")
    n, L, m = system.n_states, system.n_modes, system.n_outputs
    observers = [RSLSObserver(system, gains, T, e, np.zeros((n, n))) for e in np.eye(n)]
    if observers[0].structure.n_substates != n:
        raise ValueError(f"fine_step_error_system needs one sub-state per state (n_s = n), got "
                         f"n_s = {observers[0].structure.n_substates}, n = {n}")
    t = np.linspace(0.0, T, substeps + 1)
    quiet = np.zeros((L, substeps + 1, m))  # x = 0 and no noise: the estimate is the error
    modes = np.repeat(np.arange(L)[:, None], substeps + 1, axis=1)  # run i stays in mode i
    runs = [obs.run(quiet, t=t, modes=modes) for obs in observers]
    Lam = np.stack([r.x[:, -1] for r in runs], axis=-1)
    return Lam, runs[0].P[:, -1]  # the covariance does not depend on the estimate
