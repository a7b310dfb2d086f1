"""The estimator protocol shared by every filter: ``init -> step -> run -> Estimate``.

A filter is configured once; ``init(batch_shape)`` returns its prior state (a
frozen dataclass of arrays), ``step(state, y, u, dt=..., ...)`` processes one
sample and returns the new state, and ``run(y, u, t, ...)`` loops ``step`` over
time and collects an :class:`Estimate`. ``step`` predicts over ``dt`` (skipped
when ``dt is None``: the first sample) and then updates with ``y``.

``run`` validates its arguments: NaN in ``y`` marks a missing measurement, and so
does a masked entry of a numpy masked ``y`` (a masked ``u`` is an error); an
estimate that would not fit in memory is refused before the first step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_finite, check_memory, check_symmetric_psd, float_array, int_array
from ..system import SwitchedLinearSystem

__all__ = ["Estimate", "Estimator"]


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
        Estimated switching instant inside ``(t_{k-1}, t_k)``; NaN where the method
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


class Estimator:
    """Common configuration and the time loop; subclasses supply ``init`` and ``step``."""

    system: SwitchedLinearSystem

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
        y = float_array(y, "y", masked="nan")
        if y.ndim < 2 or y.shape[-1] != sys.n_outputs:
            raise ValueError(
                f"y must have shape (..., K, m) with m = {sys.n_outputs} outputs, got {y.shape}"
            )
        if np.any(np.isinf(y)):
            raise ValueError("y must not contain infinities (NaN marks a missing measurement)")
        batch, K = y.shape[:-2], y.shape[-2]
        if K == 0:
            raise ValueError("y must hold at least one sample, got K = 0")
        if 0 in batch:
            raise ValueError(f"y must hold at least one trial, got batch shape {batch}")
        N = int(np.prod(batch, dtype=np.int64))
        n, L = sys.n_states, sys.n_modes
        check_memory(  # the Estimate: x, P, mode probabilities and per-sample scalars
            8 * N * K * (n * n + n + L + 4),
            f"{type(self).__name__}.run on y of shape {y.shape} (N K (n^2 + n + L + 4) floats "
            f"for the estimate, n = {n}, L = {L})",
        )
        l = sys.n_inputs
        if u is None:
            u = np.zeros((*batch, K, l))
        u = float_array(u, "u")
        check_finite(u, "u")
        if u.shape == (l,) or u.shape == (K, l):
            u = np.broadcast_to(u, (*batch, K, l))
        elif u.shape != (*batch, K, l):
            raise ValueError(
                f"u must have shape (l,) = ({l},), (K, l) = ({K}, {l}) or {(*batch, K, l)}, got {u.shape}"
            )
        t = self._times(t, K)
        return y.reshape(N, K, -1), u.reshape(N, K, l), t, batch

    def _times(self, t, K) -> np.ndarray:
        sys = self.system
        if t is None:
            if sys.is_continuous:
                raise ValueError("t (the sample times) is required for a continuous-time system")
            return sys.dt * np.arange(K)
        t = float_array(t, "t", ndim=1)
        check_finite(t, "t")
        if t.shape != (K,):
            raise ValueError(f"t must have shape (K,) = ({K},), got {t.shape}")
        if np.any(np.diff(t) <= 0):
            raise ValueError("t must be strictly increasing")
        if not sys.is_continuous and np.any(np.abs(np.diff(t) - sys.dt) > 1e-9 * sys.dt):
            raise ValueError(f"t must be spaced by the discrete system's dt = {sys.dt:g}")
        return t

    def _modes(self, modes, batch, K, name="modes") -> np.ndarray:
        """Per-sample modes ``(K,)`` or ``(*batch, K)`` -> ``(N, K)``, validated."""
        modes = int_array(modes, name)
        if modes.shape == (K,):
            modes = np.broadcast_to(modes, (*batch, K))
        if modes.shape != (*batch, K):
            raise ValueError(f"{name} must have shape (K,) = ({K},) or {(*batch, K)}, got {modes.shape}")
        L = self.system.n_modes
        if np.any((modes < 0) | (modes >= L)):
            raise ValueError(f"{name} must be in 0..{L - 1}, got {modes.min()}..{modes.max()}")
        return modes.reshape(-1, K)

    @staticmethod
    def _unflatten(est: Estimate, batch) -> Estimate:
        def shape(a):
            return None if a is None else a.reshape(*batch, *a.shape[1:])

        return Estimate(**{f: shape(getattr(est, f)) for f in Estimate.__dataclass_fields__})
