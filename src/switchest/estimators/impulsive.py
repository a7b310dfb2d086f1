"""Impulsive (continuous-discrete) observers under aperiodic sampling (Etienne et al., seed 004).

Etienne, Motchon, Duviella & Guelton, eqs (2)-(3): between two samples the
observer is a copy of the mode it believes active,
:math:`d\\hat x/dt = A_{\\hat\\sigma} \\hat x + B_{\\hat\\sigma} u`; at each (aperiodic) sample
:math:`t_k` it jumps:

.. math::

    \\hat x(t_k^+) = \\hat x(t_k)
    + G_{\\hat\\sigma(t_k)} \\bigl(y(t_k) - C_{\\hat\\sigma(t_k)} \\hat x(t_k)\\bigr)

The estimated switching signal :math:`\\hat\\sigma` is either the true one (synchronous,
eq. (3)) or a delayed replica whose switches lag the true ones by at most
:math:`\\delta` (Assumption 5). Between samples the observer is propagated exactly
through :mod:`switchest.discretize`, switches of :math:`\\hat\\sigma` inside a sample
interval included.

:func:`simulate_observer_control` simulates the observer-based feedback
:math:`u = K_{\\hat\\sigma} \\hat x` of §3.2 exactly, as the extended system (21)-(23);
its matrices come from :func:`switchest.analysis.impulsive_lmis.closed_loop_matrices` (with
the sign of the jump block (22b) corrected, see there), which stays importable from here.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from numbers import Real

import numpy as np

from .._checks import as_rng, check_cores, check_finite, float_array, gain_stack
from .._linalg import joseph_update, matvec
from ..discretize import mode_steps, segment_transitions
from ..signals import SwitchingSignal, sample_segments, schedule
from ..system import SwitchedLinearSystem
from .base import Estimate, Estimator

__all__ = [
    "ImpulsiveObserver",
    "ImpulsiveState",
    "ObserverControlTrajectory",
    "closed_loop_matrices",  # noqa: F822 - see __getattr__
    "delayed_replica",
    "impulsive_update",
    "simulate_observer_control",
]

ModeEstimate = str | float | Callable[[SwitchingSignal], SwitchingSignal]


# ---------------------------------------------------------------------- pure equations
def impulsive_update(x, P, y, C, G, R):
    """The jump of the impulsive observer at a sample (Etienne et al. equation (2), third line).

    :math:`x^+ = x + G (y - C x)` with the fixed gain ``G`` of the estimated mode, and
    the error covariance in Joseph form :math:`P^+ = (I - G C) P (I - G C)^\\top + G R G^\\top`
    (valid for any gain, optimal or not). A NaN entry of ``y`` is a missing
    component: its column of ``G`` is dropped, so an all-NaN ``y`` leaves ``x``
    and ``P`` unchanged.

    Parameters
    ----------
    x : ndarray, shape (..., n)
    P : ndarray, shape (..., n, n)
    y : ndarray, shape (..., m)
    C : ndarray, shape (..., m, n)
    G : ndarray, shape (..., n, m)
    R : ndarray, shape (..., m, m)

    Returns
    -------
    x, P
        The corrected estimate and error covariance.
    """
    arrays = {k: float_array(v, k) for k, v in zip("xPyCGR", (x, P, y, C, G, R))}
    check_cores(arrays, {"x": "n", "P": "nn", "y": "m", "C": "mn", "G": "nm", "R": "mm"})
    for name in "xPCGR":
        check_finite(arrays[name], name)
    return _jump(*arrays.values())


def _jump(x, P, y, C, G, R):
    """:func:`impulsive_update` on validated arrays (the observer's per-sample kernel)."""
    observed = ~np.isnan(y)
    G = G * observed[..., None, :]  # a missing component's gain column is dropped
    innovation = np.where(observed, y - matvec(C, x), 0.0)
    return x + matvec(G, innovation), joseph_update(P, G, C, R)


def delayed_replica(signal: SwitchingSignal, delay) -> SwitchingSignal:
    """The estimated switching signal that detects every switch late (Etienne et al. Assumption 5).

    :math:`\\hat\\sigma` switches to the same modes as :math:`\\sigma`, at
    :math:`s_k + \\mathrm{delay}_k`; before its first switch it holds :math:`\\sigma`'s initial
    mode.

    Parameters
    ----------
    signal : SwitchingSignal
        The true switching signal :math:`\\sigma`.
    delay : float or array_like, shape (S,)
        Non-negative detection delay of each switch (one value for all). The
        delayed switches must stay strictly increasing.

    Returns
    -------
    SwitchingSignal
    """
    if not isinstance(signal, SwitchingSignal):
        raise TypeError(f"signal must be a SwitchingSignal, got {type(signal).__name__}")
    d = float_array(delay, "delay", ndim=(0, 1))
    check_finite(d, "delay")
    if d.ndim == 1 and d.shape != signal.times.shape:
        raise ValueError(
            f"delay must be a scalar or have one entry per switch ({signal.n_switches},), "
            f"got {d.shape}"
        )
    if np.any(d < 0):
        raise ValueError(f"delay must be non-negative (a delayed replica), got {float(d.min()):g}")
    times = signal.times + d
    if np.any(np.diff(times) <= 0):
        raise ValueError(
            "delay reorders the switches: the delayed switch times must stay strictly increasing"
        )
    return SwitchingSignal(times, signal.modes)


# ---------------------------------------------------------------------- the observer
@dataclass(frozen=True, eq=False)
class ImpulsiveState:
    """After the last sample's jump: ``x (N, n)``, error covariance ``P (N, n, n)``,
    estimated mode ``mode (N,)`` at that sample."""

    x: np.ndarray
    P: np.ndarray
    mode: np.ndarray


class ImpulsiveObserver(Estimator):
    """Impulsive observer with synchronous or delayed mode knowledge (Etienne et al. eqs (2)-(3)).

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous-time system (the observer is continuous-discrete).
    gains : array_like, shape (L, n, m)
        Observer gains :math:`G_i`, e.g. ``impulsive_observer_synthesis(...).G``.
    x0 : array_like, shape (n,), optional
        Initial estimate (default zero).
    P0 : array_like, shape (n, n), optional
        Covariance of the initial error :math:`e(0) = x(0) - \\mathrm{x0}` (default identity).
    mode_estimate : {"synchronous"} or float or callable, optional
        (Keyword-only.) How the observer's switching signal :math:`\\hat\\sigma` follows the true
        one given to :meth:`run`: ``"synchronous"`` (:math:`\\hat\\sigma = \\sigma`, eq. (3)); a
        delay :math:`d \\ge 0` (every switch detected :math:`d` late, the extreme case of
        Assumption 5 with :math:`\\delta = d`); or a function :math:`\\sigma \\mapsto \\hat\\sigma`
        (e.g. random delays through :func:`delayed_replica`, or any mode estimator).

    Notes
    -----
    The reported ``P`` is the covariance of the error :math:`e = x - \\hat x` propagated
    through the error dynamics (4) of the observer's own modes:
    :math:`P^- = F P F^\\top + Q_d` over each interval (exact transition of :math:`\\hat\\sigma`'s
    segments, process noise :math:`Q`), then :func:`impulsive_update` at the sample.
    It is the exact error covariance when :math:`\\hat\\sigma = \\sigma`; with a wrong
    mode the error also depends on :math:`x` (eqs (21)-(22)) and ``P`` ignores that.
    The input is held constant over each interval (zero-order hold, as in
    :func:`switchest.simulate.simulate`).

    Examples
    --------
    >>> import numpy as np
    >>> from switchest import signals
    >>> from switchest.models import etienne_academic
    >>> from switchest.simulate import simulate
    >>> system = etienne_academic()  # Etienne et al. §4
    >>> t = signals.aperiodic(0.3, 0.4, 8.0, rng=5)  # samples 0.3-0.4 s apart
    >>> sigma = signals.schedule([2.2, 5.5], [1, 0, 1])
    >>> traj = simulate(system, sigma, t, np.array([1.0, 1.0]), np.zeros(1))
    >>> gains = np.array([[[1.0003], [-0.0572]], [[1.0323], [2.1905]]])  # Theorem 8's, §4
    >>> est = ImpulsiveObserver(system, gains, x0=[0.5, 0.75]).run(traj.y[0], np.zeros(1), t,
    ...                                                          signals=sigma)
    >>> error = np.linalg.norm(traj.x[0] - est.x, axis=-1)
    >>> bool(error[-1] < 0.2 * error[0])  # the error decays across samples and switches
    True
    """

    def __init__(
        self, system, gains, x0=None, P0=None, *, mode_estimate: ModeEstimate = "synchronous"
    ):
        system = _check_system(system)
        n = system.n_states
        self._set_prior(system, np.zeros(n) if x0 is None else x0, np.eye(n) if P0 is None else P0)
        self.G = gain_stack(gains, "gains", (system.n_modes, n, system.n_outputs), "(L, n, m)")
        self.mode_estimate = _check_mode_estimate(mode_estimate)

    def estimated_signal(self, signal: SwitchingSignal) -> SwitchingSignal:
        """The observer's :math:`\\hat\\sigma` for a true switching signal :math:`\\sigma`."""
        return _apply_mode_estimate(self.mode_estimate, signal)

    def init(self, batch_shape=()) -> ImpulsiveState:
        """The initial estimate; ``mode`` is -1 until the first sample sets it."""
        x, P = self._prior_copies(batch_shape)
        return ImpulsiveState(x=x, P=P, mode=np.full(batch_shape, -1, dtype=np.int64))

    def step(
        self,
        state: ImpulsiveState,
        y,
        u=None,
        *,
        dt=None,
        mode,
        segment_modes=None,
        segment_offsets=None,
    ) -> ImpulsiveState:
        """Flow over ``dt`` (skipped when ``None``), then jump with ``y (N, m)``.

        ``mode (N,)`` is :math:`\\hat\\sigma(t_k)`; ``segment_modes (N, S+1)`` and
        ``segment_offsets (N, S)`` describe :math:`\\hat\\sigma` on :math:`[t_{k-1}, t_k)` (as
        :func:`switchest.signals.sample_segments` returns them). Without them the
        previous sample's estimated mode is held over the interval.
        """
        sys = self.system
        x, P = state.x, state.P
        mode = np.asarray(mode)
        if dt is not None:
            if segment_modes is None and np.any(state.mode < 0):
                raise ValueError(
                    "step needs segment_modes when the state has no estimated mode yet "
                    "(dt must be None on the first sample)"
                )
            if segment_modes is not None:
                tr = segment_transitions(sys, dt, segment_modes, segment_offsets)
                F, Gu, Qd = tr.F, tr.G, tr.Qd
            else:
                steps = mode_steps(sys, dt)
                F, Gu, Qd = steps.F[state.mode], steps.G[state.mode], steps.Qd[state.mode]
            x = matvec(F, x)  # exact flow of dx_hat/dt = A x_hat + B u, eq. (2) first line
            if u is not None and u.shape[-1]:
                x = x + matvec(Gu, u)
            P = F @ P @ np.swapaxes(F, -1, -2) + Qd
        x, P = _jump(x, P, y, sys.C[mode], self.G[mode], sys.R[mode])
        return ImpulsiveState(x, P, mode)

    def _output(self, state: ImpulsiveState) -> dict[str, np.ndarray]:
        return {"x": state.x, "P": state.P, "mode": state.mode}

    def run(self, y, u=None, t=None, *, signals) -> Estimate:
        """Observe samples ``y (..., K, m)`` taken at the (aperiodic) times ``t``.

        Parameters
        ----------
        y : array_like, shape (..., K, m)
            Samples :math:`y(t_k)`; NaN (or a masked entry) marks a missing component.
        u : array_like, optional
            Input held on :math:`[t_k, t_{k+1})`: ``(l,)``, ``(K, l)`` or ``(..., K, l)``.
        t : array_like, shape (K,)
            Strictly increasing sample times.
        signals : SwitchingSignal or sequence of SwitchingSignal
            The plant's true switching signal, shared by all trials or one per
            trial (e.g. ``trajectory.signals``); :math:`\\hat\\sigma` is derived from it by
            ``mode_estimate``.

        Returns
        -------
        Estimate
            ``x`` after each jump, the error covariance ``P`` (see the class notes)
            and ``mode`` = :math:`\\hat\\sigma(t_k)`.
        """
        y2, u2, t, batch = self._prepare(y, u, t)
        N = y2.shape[0]
        hat = [self.estimated_signal(s) for s in _per_trial(signals, N)]
        mode_at, seg_m, seg_o = sample_segments(hat, t)
        if (
            np.max(mode_at) >= self.system.n_modes
            or np.max(seg_m, initial=0) >= self.system.n_modes
        ):
            raise ValueError(
                f"signals use a mode beyond the system's modes 0..{self.system.n_modes - 1}"
            )
        # sample k flows over interval k-1; sample 0 has no flow (its entry is never read)
        pad_m = np.concatenate([np.zeros((N, 1, seg_m.shape[-1]), dtype=np.int64), seg_m], axis=1)
        pad_o = np.concatenate([np.zeros((N, 1, seg_o.shape[-1])), seg_o], axis=1)
        per_step = {"mode": mode_at, "segment_modes": pad_m, "segment_offsets": pad_o}
        return self._unflatten(self._loop(y2, u2, t, per_step), batch)


# ---------------------------------------------------------------------- closed loop
@dataclass(frozen=True, eq=False)
class ObserverControlTrajectory:
    """The observer-based closed loop at the samples, after each jump.

    Attributes
    ----------
    t : ndarray, shape (K,)
    x : ndarray, shape (N, K, n)
        Plant state.
    x_hat : ndarray, shape (N, K, n)
        Observer state after the jump.
    mode, mode_hat : ndarray of int, shape (N, K)
        :math:`\\sigma(t_k)` and :math:`\\hat\\sigma(t_k)`.
    signals, mode_signals : tuple of SwitchingSignal
        :math:`\\sigma` and :math:`\\hat\\sigma` of each trial.
    """

    t: np.ndarray
    x: np.ndarray
    x_hat: np.ndarray
    mode: np.ndarray
    mode_hat: np.ndarray
    signals: tuple[SwitchingSignal, ...]
    mode_signals: tuple[SwitchingSignal, ...]

    @property
    def error(self) -> np.ndarray:
        """Observation error :math:`e = x - \\hat x`, shape (N, K, n)."""
        return self.x - self.x_hat


def simulate_observer_control(
    system: SwitchedLinearSystem,
    K,
    G,
    signals,
    t,
    x0,
    x_hat0=None,
    *,
    mode_estimate: ModeEstimate = "synchronous",
    trials: int | None = None,
    rng=None,
) -> ObserverControlTrajectory:
    """Exact simulation of the observer-based control :math:`u = K_{\\hat\\sigma} \\hat x`
    (Etienne §3.2).

    The plant (1), the impulsive observer (2) and the continuous feedback
    :math:`u(t) = K_{\\hat\\sigma(t)} \\hat x(t)` form the extended system (21) in
    :math:`z = [x; x - \\hat x]`: it is linear between events, with the matrix
    :math:`\\mathrm{Acl}[\\sigma, \\hat\\sigma]` of
    :func:`~switchest.analysis.impulsive_lmis.closed_loop_matrices`. It is propagated
    exactly as a switched system over the :math:`L \\cdot L` mode pairs (switches of
    :math:`\\sigma` and of :math:`\\hat\\sigma` anywhere inside a sample interval), and jumps by
    :math:`J[\\sigma(t_k), \\hat\\sigma(t_k)]` at every sample, :math:`t_0` included.

    Parameters
    ----------
    system : SwitchedLinearSystem
        Continuous time; its noise matrices are ignored (the paper's model is
        deterministic).
    K : array_like, shape (L, l, n)
        Controller gains (:math:`u = K \\hat x`, no minus sign).
    G : array_like, shape (L, n, m)
        Observer gains.
    signals : SwitchingSignal, sequence of SwitchingSignal, or callable
        The true switching signal: one shared, one per trial, or a generator
        ``f(rng) -> SwitchingSignal`` called once per trial.
    t : array_like, shape (K,)
        Strictly increasing sample times.
    x0 : array_like, shape (n,) or (N, n)
        Initial plant state.
    x_hat0 : array_like, shape (n,) or (N, n), optional
        Initial observer state (default zero).
    mode_estimate : {"synchronous"} or float or callable, optional
        As in :class:`ImpulsiveObserver`.
    trials : int, optional
        Number of trials N; inferred from the other arguments when omitted.
    rng : Generator, int or None
        Used only when ``signals`` is a generator.

    Returns
    -------
    ObserverControlTrajectory
    """
    from ..analysis.impulsive_lmis import closed_loop_matrices  # the analysis: ~1 s to import

    system = _check_system(system)
    rng = as_rng(rng)
    Acl, J = closed_loop_matrices(system, K, G)
    L, n = system.n_modes, system.n_states
    t = float_array(t, "t", ndim=1)
    check_finite(t, "t")
    if t.size == 0 or np.any(np.diff(t) <= 0):
        raise ValueError("t must be a non-empty, strictly increasing array of sample times")
    x0 = _initial(x0, "x0", n)
    x_hat0 = _initial(np.zeros(n) if x_hat0 is None else x_hat0, "x_hat0", n)
    N = _trial_count(trials, signals, x0, x_hat0)
    if callable(signals) and not isinstance(signals, SwitchingSignal):
        sigma = [signals(child) for child in rng.spawn(N)]
    else:
        sigma = _per_trial(signals, N)
    rule = _check_mode_estimate(mode_estimate)
    sigma_hat = [_apply_mode_estimate(rule, s) for s in sigma]
    for name, sigs in (("signals", sigma), ("mode_estimate", sigma_hat)):
        top = max(int(s.modes.max()) for s in sigs)
        if top >= L:
            raise ValueError(f"{name} uses mode {top}, but the system has modes 0..{L - 1}")
    pairs = [_pair_signal(s, h, L) for s, h in zip(sigma, sigma_hat, strict=True)]
    extended = SwitchedLinearSystem.continuous(Acl.reshape(L * L, 2 * n, 2 * n))
    J = J.reshape(L * L, 2 * n, 2 * n)
    pair_at, seg_m, seg_o = sample_segments(pairs, t)
    z = np.concatenate([np.broadcast_to(x0, (N, n)), np.broadcast_to(x0 - x_hat0, (N, n))], axis=1)
    Z = np.empty((N, t.size, 2 * n))
    z = matvec(J[pair_at[:, 0]], z)  # z(t_0+) = J z(t_0), eq. (21c)
    Z[:, 0] = z
    for k, h in enumerate(np.diff(t)):
        tr = segment_transitions(extended, h, seg_m[:, k], seg_o[:, k])
        z = matvec(J[pair_at[:, k + 1]], matvec(tr.F, z))  # exact flow (21a), then jump (21c)
        Z[:, k + 1] = z
    x, e = Z[..., :n], Z[..., n:]
    return ObserverControlTrajectory(
        t=t,
        x=x,
        x_hat=x - e,
        mode=pair_at // L,
        mode_hat=pair_at % L,
        signals=tuple(sigma),
        mode_signals=tuple(sigma_hat),
    )


# ---------------------------------------------------------------------- helpers
def _pair_signal(sigma: SwitchingSignal, sigma_hat: SwitchingSignal, L: int) -> SwitchingSignal:
    """The signal of the mode pair :math:`\\sigma L + \\hat\\sigma`, switching when either does."""
    times = np.union1d(sigma.times, sigma_hat.times)
    starts = np.concatenate([[-np.inf], times])
    return schedule(times, sigma.at(starts) * L + sigma_hat.at(starts))


def _check_system(system) -> SwitchedLinearSystem:
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    if not system.is_continuous:
        raise ValueError(
            "system must be continuous-time (the impulsive observer is continuous-discrete), "
            f"got domain {system.domain!r}"
        )
    return system


def _check_mode_estimate(rule) -> ModeEstimate:
    if isinstance(rule, str):
        if rule != "synchronous":
            raise ValueError(
                f"mode_estimate must be 'synchronous', a delay >= 0 or a callable, got {rule!r}"
            )
        return rule
    if isinstance(rule, Real) and not isinstance(rule, bool):
        d = float(rule)
        if not np.isfinite(d) or d < 0:
            raise ValueError(f"mode_estimate as a delay must be finite and >= 0, got {rule!r}")
        return d
    if callable(rule):
        return rule
    raise TypeError(
        "mode_estimate must be 'synchronous', a delay >= 0 or a callable, "
        f"got {type(rule).__name__}"
    )


def _apply_mode_estimate(rule: ModeEstimate, signal: SwitchingSignal) -> SwitchingSignal:
    if not isinstance(signal, SwitchingSignal):
        raise TypeError(f"signal must be a SwitchingSignal, got {type(signal).__name__}")
    if isinstance(rule, str):
        return signal
    if isinstance(rule, float):
        return delayed_replica(signal, rule)
    out = rule(signal)
    if not isinstance(out, SwitchingSignal):
        raise TypeError(
            f"mode_estimate(signal) must return a SwitchingSignal, got {type(out).__name__}"
        )
    return out


def _per_trial(signals, N: int) -> list[SwitchingSignal]:
    if isinstance(signals, SwitchingSignal):
        return [signals] * N
    if isinstance(signals, Sequence) and all(isinstance(s, SwitchingSignal) for s in signals):
        if len(signals) == N:
            return list(signals)
        raise ValueError(
            f"signals must hold one SwitchingSignal per trial (N = {N}), got {len(signals)}"
        )
    raise TypeError(
        f"signals must be a SwitchingSignal or a sequence of them, got {type(signals).__name__}"
    )


def _initial(value, name: str, n: int) -> np.ndarray:
    arr = float_array(value, name, ndim=(1, 2))
    if arr.shape[-1] != n:
        raise ValueError(f"{name} must have shape (n,) or (N, n) with n = {n}, got {arr.shape}")
    check_finite(arr, name)
    return arr


def _trial_count(trials, signals, *states) -> int:
    sizes = {s.shape[0] for s in states if s.ndim == 2}
    if isinstance(signals, Sequence) and not isinstance(signals, SwitchingSignal):
        sizes.add(len(signals))
    if trials is not None:
        if (
            isinstance(trials, (bool, np.bool_))
            or not isinstance(trials, (int, np.integer))
            or trials < 1
        ):
            raise ValueError(f"trials must be a positive int, got {trials!r}")
        sizes.add(int(trials))
    if len(sizes) > 1:
        raise ValueError(
            f"trials, signals, x0 and x_hat0 disagree on the number of trials: {sorted(sizes)}"
        )
    return sizes.pop() if sizes else 1


def __getattr__(name: str) -> object:
    """``closed_loop_matrices``, imported from :mod:`switchest.analysis.impulsive_lmis` at its
    first use (PEP 562), so that running the observer does not import the analysis."""
    if name != "closed_loop_matrices":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from ..analysis.impulsive_lmis import closed_loop_matrices

    return closed_loop_matrices
