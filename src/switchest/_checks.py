"""Boundary validation shared by every public entry point.

Each helper names the offending argument, says what was expected and what was
received, and raises ``ValueError`` (wrong value or shape) or ``TypeError``
(wrong kind of object). Nothing here broadcasts, clips or drops silently.
"""

from __future__ import annotations

from collections.abc import Sequence
from numbers import Real

import numpy as np

__all__ = [
    "as_rng",
    "float_array",
    "int_array",
    "check_finite",
    "check_square_stack",
    "check_symmetric_psd",
    "check_row_stochastic",
    "check_probability_vector",
    "positive_scalar",
    "positive_int",
    "check_mode",
]

_SYM_RTOL = 1e-9


def as_rng(rng: np.random.Generator | int | np.random.SeedSequence | None, name: str = "rng"):
    """Return a ``numpy.random.Generator`` from a Generator, a seed or ``None``.

    ``None`` gives a fresh, unseeded generator; pass a seed for reproducible runs.
    """
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or isinstance(rng, (int, np.integer, np.random.SeedSequence)):
        if isinstance(rng, (int, np.integer)) and rng < 0:
            raise ValueError(f"{name} must be a non-negative seed, got {rng}")
        return np.random.default_rng(rng)
    raise TypeError(
        f"{name} must be a numpy Generator, an int seed, a SeedSequence or None, "
        f"got {type(rng).__name__}"
    )


def float_array(value, name: str, *, ndim: int | Sequence[int] | None = None) -> np.ndarray:
    """Convert ``value`` to a float64 array, checking its number of dimensions."""
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be numeric, got {type(value).__name__}")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a numeric array, got {type(value).__name__}") from exc
    if ndim is not None:
        allowed = (ndim,) if isinstance(ndim, int) else tuple(ndim)
        if arr.ndim not in allowed:
            want = " or ".join(str(d) for d in allowed)
            raise ValueError(
                f"{name} must have {want} dimensions, got shape {arr.shape}"
            )
    return arr


def int_array(value, name: str, *, ndim: int | None = None) -> np.ndarray:
    """Convert ``value`` to an int64 array; floats are accepted only if integral."""
    arr = np.asarray(value)
    if arr.dtype == bool or not (
        np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)
    ):
        raise TypeError(f"{name} must hold integers, got dtype {arr.dtype}")
    if np.issubdtype(arr.dtype, np.floating):
        if not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
            raise ValueError(f"{name} must hold integers, got non-integral values")
    arr = arr.astype(np.int64)
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimensions, got shape {arr.shape}")
    return arr


def check_finite(arr: np.ndarray, name: str) -> None:
    """Raise if ``arr`` holds NaN or infinity."""
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(
            f"{name} must be finite, got {arr[tuple(bad)]} at index {tuple(int(i) for i in bad)}"
        )


def check_square_stack(arr: np.ndarray, name: str) -> None:
    """Raise unless the last two axes of ``arr`` are square."""
    if arr.ndim < 2 or arr.shape[-1] != arr.shape[-2]:
        raise ValueError(f"{name} must be square in its last two axes, got shape {arr.shape}")


def check_symmetric_psd(arr: np.ndarray, name: str, *, definite: bool = False) -> np.ndarray:
    """Check a stack of matrices is symmetric positive (semi)definite; return it symmetrized.

    Symmetry is judged relative to the largest entry (``rtol = 1e-9``); definiteness
    by the smallest eigenvalue, with a tolerance of ``1e-12`` times the largest for
    semidefiniteness.
    """
    check_square_stack(arr, name)
    scale = max(float(np.max(np.abs(arr), initial=0.0)), np.finfo(float).tiny)
    asym = float(np.max(np.abs(arr - np.swapaxes(arr, -1, -2)), initial=0.0))
    kind = "positive definite" if definite else "positive semidefinite"
    if asym > _SYM_RTOL * scale:
        raise ValueError(f"{name} must be symmetric {kind}, got asymmetry {asym:.3g}")
    sym = 0.5 * (arr + np.swapaxes(arr, -1, -2))
    if sym.shape[-1] == 0:
        return sym
    eig = np.linalg.eigvalsh(sym)
    lowest = float(eig.min())
    if definite:
        if lowest <= 1e-14 * scale or lowest <= 0.0:
            raise ValueError(f"{name} must be symmetric {kind}, got eigenvalue {lowest:.3g}")
    elif lowest < -1e-12 * scale:
        raise ValueError(f"{name} must be symmetric {kind}, got eigenvalue {lowest:.3g}")
    return sym


def check_row_stochastic(P, name: str = "transition", *, n: int | None = None) -> np.ndarray:
    """Validate a transition matrix with ``P[i, j]`` = P(next = j | now = i); rows sum to 1."""
    P = float_array(P, name, ndim=2)
    check_square_stack(P, name)
    if n is not None and P.shape[0] != n:
        raise ValueError(f"{name} must be {n}x{n} (one row per mode), got shape {P.shape}")
    check_finite(P, name)
    if np.any(P < 0):
        raise ValueError(f"{name} must have non-negative entries, got minimum {P.min():.3g}")
    rows = P.sum(axis=1)
    worst = int(np.argmax(np.abs(rows - 1.0)))
    if abs(rows[worst] - 1.0) > 1e-9:
        raise ValueError(
            f"{name} rows must sum to 1 (P[i, j] = P(j next | i now)), "
            f"got row {worst} summing to {rows[worst]:.12g}"
        )
    return P


def check_probability_vector(p, name: str, *, n: int | None = None) -> np.ndarray:
    """Validate a probability vector: non-negative, finite, sums to 1."""
    p = float_array(p, name, ndim=1)
    if n is not None and p.shape[0] != n:
        raise ValueError(f"{name} must have length {n} (one entry per mode), got {p.shape[0]}")
    check_finite(p, name)
    if np.any(p < 0):
        raise ValueError(f"{name} must be non-negative, got minimum {p.min():.3g}")
    if abs(p.sum() - 1.0) > 1e-9:
        raise ValueError(f"{name} must sum to 1, got {p.sum():.12g}")
    return p


def positive_scalar(value, name: str, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a finite positive (or non-negative) float."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (Real, np.floating, np.integer)):
        raise TypeError(f"{name} must be a real scalar, got {type(value).__name__}")
    v = float(value)
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        want = "non-negative" if allow_zero else "positive"
        raise ValueError(f"{name} must be a finite {want} number, got {value!r}")
    return v


def positive_int(value, name: str) -> int:
    """Return ``value`` as an int >= 1; bools and floats are refused."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an int, got {type(value).__name__}")
    if value < 1:
        raise ValueError(f"{name} must be a positive int, got {value}")
    return int(value)


def check_mode(value, n_modes: int, name: str) -> int:
    """Return ``value`` as a 0-based mode index in ``0..n_modes-1``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an int mode index, got {type(value).__name__}")
    if not 0 <= value < n_modes:
        raise ValueError(f"{name} must be a mode index in 0..{n_modes - 1}, got {value}")
    return int(value)
