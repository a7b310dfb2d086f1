"""The record a fit reads: measurements, inputs, times and known modes, checked and flattened.

``y`` is ``(K, m)`` or ``(N, K, m)`` (NaN = a missing component); everything is brought to
``(N, K, ...)`` once, here, so the expectation and maximization steps see one layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import check_finite, float_array, int_array
from ..system import SwitchedLinearSystem

__all__ = ["Record", "record"]

_Y_LIMIT = float(np.sqrt(np.finfo(float).max))  # 1.34e154: beyond it y^2 overflows


@dataclass(frozen=True, eq=False)
class Record:
    """A checked record of ``N`` trials of ``K`` samples.

    Attributes
    ----------
    y : ndarray, shape (N, K, m)
        Measurements, NaN where missing.
    u : ndarray, shape (N, K, l)
        Inputs, ``u[:, k]`` held over the interval into sample ``k + 1``.
    t : ndarray, shape (K,)
        Sample times.
    modes : ndarray of int64, shape (N, K), or None
        The known mode at each sample, or None (unknown modes).
    """

    y: np.ndarray
    u: np.ndarray
    t: np.ndarray
    modes: np.ndarray | None

    @property
    def shape(self) -> tuple[int, int]:
        """``(N, K)``."""
        return self.y.shape[:2]


def record(system: SwitchedLinearSystem, y, u, t, modes) -> Record:
    """Check and flatten a fit's data (:func:`switchest.learn.fit` documents the arguments)."""
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    if system.timing != "sample":
        raise ValueError(f"system.timing must be 'sample' to fit: the E-steps model the mode of a "
                         f"sample governing the interval after it (docs/conventions.rst), got "
                         f"{system.timing!r}")
    m, l, L = system.n_outputs, system.n_inputs, system.n_modes
    y = float_array(y, "y", masked="nan")
    if y.ndim not in (2, 3) or y.shape[-1] != m:
        raise ValueError(f"y must have shape (K, m) or (N, K, m) with m = {m}, got {y.shape}")
    if np.any(np.isinf(y)):
        raise ValueError("y must not contain infinities (NaN marks a missing component)")
    wild = np.abs(np.where(np.isnan(y), 0.0, y)) > _Y_LIMIT
    if np.any(wild):
        at = tuple(int(i) for i in np.argwhere(wild)[0])
        sample = f"trial {at[0]}, sample {at[1]}" if y.ndim == 3 else f"sample {at[0]}"
        raise ValueError(f"y[{', '.join(map(str, at))}] = {y[at]:.6g} ({sample}) is beyond "
                         f"{_Y_LIMIT:.3g}, where its square overflows the floating-point range: "
                         "no covariance holds it; mark it missing (NaN)")
    y = y.reshape(-1, *y.shape[-2:])
    N, K = y.shape[:2]
    if K < 2 or N == 0:
        raise ValueError(f"y must hold at least one trial of at least two samples, got "
                         f"shape {y.shape}")
    if u is None:
        u = np.zeros((N, K, l))
    else:
        u = float_array(u, "u")
        check_finite(u, "u")
        if u.shape not in ((l,), (K, l), (N, K, l)):
            raise ValueError(f"u must have shape (l,) = ({l},), (K, l) = ({K}, {l}) or "
                             f"(N, K, l) = ({N}, {K}, {l}), got {u.shape}")
        u = np.ascontiguousarray(np.broadcast_to(u, (N, K, l)))
    if t is None:
        if system.is_continuous:
            raise ValueError("t (the sample times) is required for a continuous-time system")
        t = system.dt * np.arange(K)
    t = float_array(t, "t", ndim=1)
    check_finite(t, "t")
    if t.shape != (K,) or np.any(np.diff(t) <= 0):
        raise ValueError(f"t must be strictly increasing of shape (K,) = ({K},), got shape "
                         f"{t.shape}")
    if modes is not None:
        modes = int_array(modes, "modes")
        if modes.shape not in ((K,), (N, K)):
            raise ValueError(f"modes must have shape (K,) = ({K},) or (N, K) = ({N}, {K}), "
                             f"got {modes.shape}")
        if modes.min() < 0 or modes.max() >= L:
            raise ValueError(f"modes must be in 0..{L - 1}, got {modes.min()}..{modes.max()}")
        modes = np.ascontiguousarray(np.broadcast_to(modes, (N, K)), dtype=np.int64)
    return Record(np.ascontiguousarray(y), u, t, modes)
