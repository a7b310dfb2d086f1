"""The estimator protocol shared by every estimator: ``init -> step -> run -> Estimate``.

A filter is configured once; ``init(batch_shape)`` returns its prior state (a
frozen dataclass of arrays), ``step(state, y, u, dt=..., ...)`` processes one
sample and returns the new state, and ``run(y, u, t, ...)`` processes a whole
record and collects an :class:`Estimate`. ``step`` predicts over ``dt`` (skipped
when ``dt is None``: the first sample) and then updates with ``y``.
:class:`Estimator` declares the protocol and its conventions; the methods a user
selects by name are listed in :mod:`switchest.estimators.registry`.

``run`` validates its arguments: NaN in ``y`` marks a missing measurement, and so
does a masked entry of a numpy masked ``y`` (a masked ``u`` is an error); an
estimate that would not fit in memory is refused before the first step.
"""

from __future__ import annotations

import math
import re
import textwrap
import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._checks import (
    check_finite,
    check_memory,
    check_probability_vector,
    check_row_stochastic,
    check_symmetric_psd,
    check_timing,
    float_array,
    int_array,
)
from ..system import SwitchedLinearSystem

__all__ = ["Estimate", "Estimator", "TimingWarning"]

_INT64, _FLOAT64 = np.dtype(np.int64), np.dtype(np.float64)
_INT_MAX = 2**62  # int_array's bound

# The Parameters entries of the configuration the multiple-model filters share, ``system,
# transition, x0, P0, *, mode_prob0`` (checked by Estimator._set_prior and _set_mode_prior),
# written once: a class decorated with _with_mode_model_parameters names them in its docstring
# by the line "{mode model parameters}".
_MODE_MODEL_PARAMETERS = """\
system : SwitchedLinearSystem
transition : array_like, shape (L, L)
    ``transition[i, j]`` :math:`= \\Pr(\\text{mode } j \\text{ at } k+1 \\mid
    \\text{mode } i \\text{ at } k)`, rows sum to 1.
x0, P0 : array_like
    Prior mean and covariance of the state at the first sample, the same for every mode.
mode_prob0 : array_like, shape (L,), optional
    Prior mode probabilities at the first sample (keyword-only); uniform by default."""


class TimingWarning(UserWarning):
    """A multiple-model filter runs in another timing than its system's or its data's
    (:doc:`/conventions`): which interval the mode of a sample governs differs, so its
    estimates are of a model other than the data's."""


def _with_mode_model_parameters(cls: type) -> type:
    """The class with :data:`_MODE_MODEL_PARAMETERS` in place of its docstring's marker line."""
    if cls.__doc__ is not None:  # (None under python -OO)
        cls.__doc__ = re.sub(r"^([ \t]*)\{mode model parameters\}$",
                             lambda line: textwrap.indent(_MODE_MODEL_PARAMETERS, line[1]),
                             cls.__doc__, count=1, flags=re.MULTILINE)
    return cls


@dataclass(frozen=True, eq=False)
class Estimate:
    """What a filter returns, with the batch shape of the measurements it was given.

    Attributes
    ----------
    x : ndarray, shape (..., K, n)
        State estimate after each sample's measurement.
    P : ndarray, shape (..., K, n, n) or None
        Its covariance as the filter reports it (None for methods without one,
        e.g. the minimum-distance detector).
    mode_prob : ndarray, shape (..., K, L) or None
        Mode probabilities, where the method gives them.
    mode : ndarray of int, shape (..., K) or None
        Estimated mode at each sample.
    switch_time : ndarray, shape (..., K) or None
        Estimated switching instant inside :math:`(t_{k-1}, t_k)`; NaN where the method
        estimates no switch in that interval.
    loglik : ndarray, shape (..., K) or None
        Log-likelihood of each measurement given the past, where defined.
    outlier : ndarray of bool, shape (..., K) or None
        True where the filter rejected the measurement (its innovation overflowed or
        failed the filter's ``gate``) and treated the sample as missing; given by the
        filters with a ``gate`` option.
    """

    x: np.ndarray
    P: np.ndarray | None = None
    mode_prob: np.ndarray | None = None
    mode: np.ndarray | None = None
    switch_time: np.ndarray | None = None
    loglik: np.ndarray | None = None
    outlier: np.ndarray | None = None


class Estimator(ABC):
    """The protocol of every estimator, with the configuration and the time
    loop they share.

    Notes
    -----
    The conventions every estimator follows:

    Constructor
        ``Estimator(system, ..., x0, P0, *, options)``: the
        :class:`~switchest.system.SwitchedLinearSystem` first, then the method's own
        required configuration (a transition matrix, observer gains, a switching
        interval), then the prior mean ``x0 (n,)`` and covariance ``P0 (n, n)`` of the
        state at the first sample, then keyword-only options (``grid``, ``gate``, ...).
        A method without a prior has no ``x0, P0`` (the minimum-distance detector
        estimates the state from each window); a method with a default prior gives
        ``x0, P0`` defaults (the impulsive observer: zero and the identity).
    ``init(batch_shape=())``
        The state before the first sample, a frozen dataclass of arrays whose leading
        axes are ``batch_shape``.
    ``step(state, y, u=None, *, dt=None, **per_sample)``
        One sample ``y (*batch, m)``: predict over ``dt`` with the input ``u`` held over
        the interval into the sample (skipped when ``dt`` is None: the first sample),
        then update; NaN in ``y`` skips the update of that component. Returns the new
        state and changes nothing else: an estimator keeps no state of its own.
    ``run(y, u=None, t=None, **per_sample)``
        A whole record ``y (..., K, m)`` at the sample times ``t (K,)`` (optional for a
        discrete-time system) with the inputs ``u`` (``(l,)``, ``(K, l)`` or
        ``(..., K, l)``, ``u[k]`` held on :math:`[t_k, t_{k+1})`) -> :class:`Estimate` with the
        batch shape of ``y``. What the method knows of the switching is given by keyword:
        per-sample arrays ``(K,)`` or ``(..., K)`` such as ``modes=`` (the true or
        believed mode at each sample), or, for a method that follows a continuous-time
        switching signal, ``signals=``. Two runs of one estimator are independent: the
        result of a run depends only on its arguments and the configuration.
    """

    system: SwitchedLinearSystem

    @abstractmethod
    def init(self, batch_shape: tuple[int, ...] = ()) -> Any:
        """The state before the first sample, replicated over ``batch_shape``."""

    @abstractmethod
    def step(self, state: Any, y, u=None, *, dt: float | None = None, **per_sample) -> Any:
        """Predict over ``dt`` (skipped when None) with ``u`` held, then update with ``y``."""

    @abstractmethod
    def run(self, y, u=None, t=None, **per_sample) -> Estimate:
        """Estimate over the whole record ``y (..., K, m)`` sampled at ``t (K,)``."""

    def _set_prior(self, system, x0, P0) -> None:
        if not isinstance(system, SwitchedLinearSystem):
            raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
        n = system.n_states
        x0 = float_array(x0, "x0", ndim=1)
        if x0.shape != (n,):
            raise ValueError(f"x0 must have shape (n,) = ({n},), got {x0.shape}")
        check_finite(x0, "x0")
        P0 = float_array(P0, "P0", ndim=2)
        if P0.shape != (n, n):
            raise ValueError(f"P0 must have shape (n, n) = ({n}, {n}), got {P0.shape}")
        check_finite(P0, "P0")
        self.system = system
        self.x0 = x0
        self.P0 = check_symmetric_psd(P0, "P0")

    def _set_mode_prior(self, transition, mode_prob0, *, optional_transition: bool = False) -> None:
        """Validate and keep the mode model of the multiple-model filters: ``transition``
        ``(L, L)`` (``transition[i, j]`` =
        :math:`\\Pr(\\text{mode } j \\text{ at } k+1 \\mid \\text{mode } i \\text{ at } k)`, rows
        summing to 1) and ``mode_prob0`` ``(L,)`` (uniform when None), with their logarithms
        (``-inf`` for an impossible switch). With ``optional_transition`` a ``transition`` of
        None is kept as None, every switch weighted alike (its logarithm zero)."""
        L = self.system.n_modes
        if optional_transition and transition is None:
            self.transition = None
        else:
            self.transition = check_row_stochastic(transition, "transition", n=L)
        p0 = np.full(L, 1.0 / L) if mode_prob0 is None else mode_prob0
        self.mode_prob0 = check_probability_vector(p0, "mode_prob0", n=L)
        with np.errstate(divide="ignore"):
            self._log_transition = (np.zeros((L, L)) if self.transition is None
                                    else np.log(self.transition))
            self._log_p0 = np.log(self.mode_prob0)

    def _set_timing(self, timing) -> None:
        """Keep the filter's ``timing``: the system's when None (set :meth:`_set_prior` first);
        an explicit other one is named in a :class:`TimingWarning`."""
        if timing is None:
            self.timing = self.system.timing
            return
        self.timing = check_timing(timing)
        if self.timing != self.system.timing:
            warnings.warn(f"{type(self).__name__} runs in the {self.timing!r} timing, its system "
                          f"in the {self.system.timing!r} one (which interval a sample's mode "
                          "governs, docs/conventions.rst): its estimates are of a model other "
                          "than the system's", TimingWarning, stacklevel=3)

    def _check_data_timing(self, data_timing) -> None:
        """Name in a :class:`TimingWarning` data drawn in another timing than the filter's
        (``data_timing``, e.g. :attr:`switchest.simulate.Trajectory.timing`; None: unknown)."""
        if data_timing is not None and check_timing(data_timing, "data_timing") != self.timing:
            warnings.warn(f"{type(self).__name__} runs in the {self.timing!r} timing, the data "
                          f"were drawn in the {data_timing!r} one (which interval a sample's "
                          "mode governs, docs/conventions.rst): its estimates are of a model "
                          "other than the data's", TimingWarning, stacklevel=3)

    def _prior_copies(self, shape) -> tuple[np.ndarray, np.ndarray]:
        """The prior ``x0``, ``P0`` replicated over ``shape`` (trials, or trials and modes) as
        writeable arrays ``(*shape, n)``, ``(*shape, n, n)``: the start of ``init``'s state."""
        n = self.system.n_states
        return (np.broadcast_to(self.x0, (*shape, n)).copy(),
                np.broadcast_to(self.P0, (*shape, n, n)).copy())

    # ------------------------------------------------------------------ the loop
    def _loop(self, y, u, t, per_step: dict[str, np.ndarray] | None = None) -> Estimate:
        """Run ``step`` over time on prepared ``y (N, K, m)``, ``u (N, K, l)``, ``t (K,)``.

        ``per_step`` maps a keyword of ``step`` to an array whose axis 1 is time;
        entry ``k`` is passed with sample ``k``.
        """
        N, K, _ = y.shape
        state = self.init((N,))
        fields: dict[str, np.ndarray] = {}
        for k in range(K):
            extra = {key: val[:, k] for key, val in (per_step or {}).items()}
            dt = None if k == 0 else t[k] - t[k - 1]
            u_prev = u[:, k - 1] if k else u[:, 0]
            state = self.step(state, y[:, k], u_prev, dt=dt, **extra)
            for name, value in self._output(state).items():
                if k == 0:  # outputs are written in place: no list of K arrays to stack at the end
                    fields[name] = np.empty((N, K, *value.shape[1:]), dtype=value.dtype)
                fields[name][:, k] = value
        return Estimate(**fields)

    def _prepare(self, y, u, t):
        """Validate measurements, inputs and times; flatten the batch axes to one.

        NaN in ``y`` marks a missing measurement, and so does a masked entry when
        ``y`` is a numpy masked array; ``u`` must be complete (no NaN, no mask).
        """
        sys = self.system
        if type(y) is not np.ndarray or y.dtype is not _FLOAT64:  # (else float_array's: y)
            y = float_array(y, "y", masked="nan")
        if y.ndim < 2 or y.shape[-1] != sys.n_outputs:
            raise ValueError(
                f"y must have shape (..., K, m) with m = {sys.n_outputs} outputs, got {y.shape}"
            )
        if np.isinf(y).any():
            raise ValueError("y must not contain infinities (NaN marks a missing measurement)")
        batch, K = y.shape[:-2], y.shape[-2]
        if K == 0:
            raise ValueError("y must hold at least one sample, got K = 0")
        if 0 in batch:
            raise ValueError(f"y must hold at least one trial, got batch shape {batch}")
        N = math.prod(batch)
        n, L = sys.n_states, sys.n_modes
        check_memory(  # the Estimate: x, P, mode probabilities and per-sample scalars
            8 * N * K * (n * n + n + L + 4),
            f"{type(self).__name__}.run on y of shape {y.shape} (N K (n^2 + n + L + 4) floats "
            f"for the estimate, n = {n}, L = {L})",
        )
        l = sys.n_inputs
        if u is None:  # no input: zeros, nothing to check
            u = np.zeros((N, K, l))
        else:
            if type(u) is not np.ndarray or u.dtype is not _FLOAT64:  # (else float_array's: u)
                u = float_array(u, "u")
            if not np.isfinite(u).all():
                check_finite(u, "u")  # its message
            if u.shape == (l,) or u.shape == (K, l):  # held by every trial: a copy per trial,
                held = np.empty((*batch, K, l))  # as the kernels take it
                held[...] = u
                u = held
            elif u.shape != (*batch, K, l):
                raise ValueError(
                    f"u must have shape (l,) = ({l},), (K, l) = ({K}, {l}) or {(*batch, K, l)}, "
                    f"got {u.shape}"
                )
        t = self._times(t, K)
        return y.reshape(N, K, -1), u.reshape(N, K, l), t, batch

    def _times(self, t, K) -> np.ndarray:
        sys = self.system
        if t is None:
            if sys.is_continuous:
                raise ValueError("t (the sample times) is required for a continuous-time system")
            return sys.dt * np.arange(K)
        key = None
        if type(t) is np.ndarray and t.dtype is _FLOAT64 and t.shape == (K,) and K <= 4096:
            key = t.tobytes()  # times checked before (the same values) pass again
            if key in self.__dict__.get("_valid_times", ()):
                return t
        if type(t) is not np.ndarray or t.dtype is not _FLOAT64 or t.ndim != 1:
            t = float_array(t, "t", ndim=1)  # (else its result: t)
        if not np.isfinite(t).all():
            check_finite(t, "t")  # its message
        if t.shape != (K,):
            raise ValueError(f"t must have shape (K,) = ({K},), got {t.shape}")
        step = t[1:] - t[:-1]  # np.diff's
        if (step <= 0).any():
            raise ValueError("t must be strictly increasing")
        if not sys.is_continuous and np.any(np.abs(step - sys.dt) > 1e-9 * sys.dt):
            raise ValueError(f"t must be spaced by the discrete system's dt = {sys.dt:g}")
        if key is not None:
            valid = self.__dict__.setdefault("_valid_times", set())
            if len(valid) >= 8:
                valid.clear()
            valid.add(key)
        return t

    def _modes(self, modes, batch, K, name="modes") -> np.ndarray:
        """Per-sample modes ``(K,)`` or ``(*batch, K)`` -> ``(N, K)``, validated, C-contiguous."""
        given = modes
        fast = type(modes) is np.ndarray and modes.dtype is _INT64 and modes.size > 0
        if fast:  # int64 already: int_array's checks are its range, made once with ours
            lo, hi = modes.min(), modes.max()
            if hi > _INT_MAX or lo < -_INT_MAX:
                int_array(modes, name)  # its message
        else:
            modes = int_array(modes, name)
        if modes.shape != (K,) and modes.shape != (*batch, K):
            raise ValueError(f"{name} must have shape (K,) = ({K},) or {(*batch, K)}, "
                             f"got {modes.shape}")
        L = self.system.n_modes
        if not fast:
            lo, hi = modes.min(), modes.max()  # on the array given, before broadcasting
        if lo < 0 or hi >= L:
            raise ValueError(f"{name} must be in 0..{L - 1}, got {lo}..{hi}")
        if modes.shape == (K,):
            modes = np.broadcast_to(modes, (*batch, K))
        modes = np.ascontiguousarray(modes.reshape(-1, K))
        # a new array, as int_array's conversion gives: never a view of the caller's
        return modes.copy() if fast and np.may_share_memory(modes, given) else modes

    @staticmethod
    def _unflatten(est: Estimate, batch) -> Estimate:
        if len(batch) == 1:  # the batch axis is the flattened one: nothing to reshape
            return est

        def shape(a):
            return None if a is None else a.reshape(*batch, *a.shape[1:])

        return Estimate(**{f: shape(getattr(est, f)) for f in Estimate.__dataclass_fields__})
