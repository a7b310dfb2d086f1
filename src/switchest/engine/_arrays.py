"""Boundary checks of the compiled kernels' arrays: shapes that agree and indices in range.

The kernels index their tables without bounds checks, so every array is checked here, once
per call, before it reaches compiled code; each is converted to the one type the kernels are
written for (C-contiguous float64, int64 indices). An array that is already of that type is
passed as it is; a read-only one (such as the cached transitions of
:mod:`switchest.discretize`) is copied, as the bindings take writeable arrays.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np

from .._checks import float_array, int_array

__all__ = ["all_ready", "checked", "floats", "indices", "check_gate", "replicated"]

_FLOAT64, _INT64 = np.dtype(np.float64), np.dtype(np.int64)


def checked(sizes: dict[str, int], layout: str, *values) -> list[np.ndarray]:
    """``values`` checked and converted in order, as :func:`floats` and :func:`indices` do.

    ``layout`` holds one word per value, ``name:axes`` for a float array and
    ``name:axes<bound`` for an index array into a table of ``sizes[bound]`` entries, e.g.
    ``"y:NKm trans:NK<M"``; the letters bind in ``sizes`` as the values are checked, so the
    first array to disagree with the others is the one named in the error.
    """
    return [floats(value, name, axes, sizes) if bound is None
            else indices(value, name, axes, sizes, bound)
            for value, (name, axes, bound) in zip(values, _words(layout), strict=True)]


@cache
def _words(layout: str) -> tuple[tuple[str, str, str | None], ...]:
    """``layout`` of :func:`checked` as ``(name, axes, bound or None)`` per value."""
    words = []
    for word in layout.split():
        name, spec = word.split(":")
        axes, _, bound = spec.partition("<")
        words.append((name, axes, bound or None))
    return tuple(words)


def floats(value, name: str, axes: str, sizes: dict[str, int]) -> np.ndarray:
    """``value`` as a C-contiguous float64 array whose axes are named by ``axes``.

    ``axes`` names each axis by one letter (``"NKm"``); ``sizes`` maps the letters bound so far
    to their sizes and is extended with the new ones, so arrays that share a letter must agree.
    """
    arr = _ready(value, _FLOAT64)
    if arr is None:
        if type(value) is np.ndarray and value.dtype is _FLOAT64:  # strided or read-only
            arr = np.array(value, order="C")  # (float_array has nothing to convert)
        else:
            arr = np.require(float_array(value, name),
                             requirements=["C_CONTIGUOUS", "WRITEABLE"])
    return _bind(arr, name, axes, sizes)


def indices(value, name: str, axes: str, sizes: dict[str, int], bound: str) -> np.ndarray:
    """``value`` as a C-contiguous int64 array of shape ``axes``, each entry in
    ``0..sizes[bound] - 1`` (an index into a table of that many entries)."""
    arr = _ready(value, _INT64)
    if arr is None:
        arr = np.require(int_array(value, name), requirements=["C_CONTIGUOUS", "WRITEABLE"])
    arr = _bind(arr, name, axes, sizes)
    if arr.size:
        lo, hi = arr.min(), arr.max()
        if lo < 0 or hi >= sizes[bound]:
            int_array(arr, name)  # beyond +-2**62: its message, as for any other array
            raise ValueError(
                f"{name} must index 0..{sizes[bound] - 1} ({bound} = {sizes[bound]} entries), "
                f"got {lo}..{hi}"
            )
    return arr


def all_ready(values, shapes) -> bool:
    """Whether every one of ``values`` is already a float64 array of the kernels' type
    (:func:`_ready`) of exactly its shape in ``shapes``: nothing to convert or check, the
    fast path of a caller that would otherwise pass them through :func:`checked` (which it
    still does when this is False, for the conversion or the error naming the argument)."""
    for value, shape in zip(values, shapes):
        if type(value) is not np.ndarray or value.dtype is not _FLOAT64 or value.shape != shape:
            return False
        flags = value.flags
        if not (flags.c_contiguous and flags.writeable):
            return False
    return True


def replicated(value: np.ndarray, lead: tuple[int, ...]) -> np.ndarray:
    """A new C-contiguous float64 array ``(*lead, *value.shape)`` holding ``value`` at every
    index of ``lead`` (what ``np.tile`` of a prior over trials and modes gives, at the cost of
    one allocation and one copy)."""
    out = np.empty((*lead, *value.shape))
    out[...] = value
    return out


def check_gate(gate) -> float:
    """The gate on the normalized innovation squared: a positive number or ``inf``."""
    if isinstance(gate, (bool, np.bool_)) or not isinstance(gate, (int, float, np.number)):
        raise TypeError(f"gate must be a positive number or inf, got {type(gate).__name__}")
    if math.isnan(gate) or gate <= 0:
        raise ValueError(f"gate must be a positive number or inf, got {gate}")
    return float(gate)


def _ready(value, dtype) -> np.ndarray | None:
    """``value`` itself if it is already of the kernels' type (a plain, C-contiguous,
    writeable ndarray of ``dtype``: nothing to convert or check but its shape), else None.

    The dtype is compared by identity (numpy's native float64 and int64 dtypes are single
    objects): any other, equal or not, takes the converting path, which is exact either way.
    """
    if type(value) is np.ndarray and value.dtype is dtype:
        flags = value.flags
        if flags.c_contiguous and flags.writeable:
            return value
    return None


def _bind(arr: np.ndarray, name: str, axes: str, sizes: dict[str, int]) -> np.ndarray:
    """``arr`` once its shape agrees with ``axes`` and ``sizes`` (extended with new letters)."""
    shape = arr.shape
    if len(shape) == len(axes):
        for a, s in zip(axes, shape):
            if sizes.setdefault(a, s) != s:
                break
        else:
            return arr
    expected = ", ".join(f"{a}={sizes[a]}" if a in sizes else a for a in axes)
    raise ValueError(f"{name} must have shape ({', '.join(axes)}) = ({expected}), got {shape}")
