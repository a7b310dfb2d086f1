"""Boundary validation shared by every public entry point.

Each helper names the offending argument, says what was expected and what was
received, and raises ``ValueError`` (wrong value or shape) or ``TypeError``
(wrong kind of object). Nothing here broadcasts, clips or drops silently.
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Iterable, Sequence
from functools import lru_cache
from numbers import Real

import numpy as np

__all__ = [
    "as_rng",
    "float_array",
    "int_array",
    "check_finite",
    "gain_stack",
    "check_cores",
    "broadcast_batch",
    "check_square_stack",
    "check_symmetric_psd",
    "check_row_stochastic",
    "check_probability_vector",
    "positive_scalar",
    "positive_int",
    "check_bool",
    "check_mode",
    "check_timing",
    "closest_name",
    "did_you_mean",
    "TIMINGS",
    "memory_limit",
    "check_memory",
]

_SYM_RTOL = 1e-9
_INT_MAX = 2**62


def as_rng(rng: np.random.Generator | int | np.random.SeedSequence | None, name: str = "rng"):
    """Return a ``numpy.random.Generator`` from a Generator, a seed or ``None``.

    ``None`` gives a fresh, unseeded generator; pass a seed for reproducible runs.
    """
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, (bool, np.bool_)):  # an int to Python, but never meant as a seed
        raise TypeError(f"{name} must be a numpy Generator, an int seed, a SeedSequence or None, "
                        "got bool")
    if rng is None or isinstance(rng, (int, np.integer, np.random.SeedSequence)):
        if isinstance(rng, (int, np.integer)) and rng < 0:
            raise ValueError(f"{name} must be a non-negative seed, got {rng}")
        return np.random.default_rng(rng)
    raise TypeError(
        f"{name} must be a numpy Generator, an int seed, a SeedSequence or None, "
        f"got {type(rng).__name__}"
    )


def float_array(
    value, name: str, *, ndim: int | Sequence[int] | None = None, masked: str = "error"
) -> np.ndarray:
    """Convert ``value`` to a float64 array, checking its kind and number of dimensions.

    Integers and real floats are accepted. Booleans, complex numbers, dates and
    durations, strings and other objects raise ``TypeError`` naming the dtype:
    converting them would drop information silently (an imaginary part, the meaning
    of a mask or of a date).

    A numpy masked array with masked entries raises ``ValueError`` unless
    ``masked="nan"``: then its masked entries become NaN, the package's mark of a
    missing sample (used for measurements ``y``).
    """
    if masked not in ("error", "nan"):
        raise ValueError(f"masked must be 'error' or 'nan', got {masked!r}")
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be numeric, got {type(value).__name__}")
    mask = np.ma.getmaskarray(value) if isinstance(value, np.ma.MaskedArray) else None
    raw = _as_array(np.ma.getdata(value) if mask is not None else value, name)
    kind = raw.dtype.kind
    if kind == "O":
        bad = [type(v).__name__ for v in raw.flat if not _is_real(v)][:1]
        if bad or raw.size == 0:
            got = f"a {bad[0]}" if bad else "nothing"
            raise TypeError(f"{name} must be a real numeric array, got dtype object holding {got}")
    elif kind not in "iuf":
        raise TypeError(
            f"{name} must be a real numeric array (int or float), got dtype {raw.dtype}"
        )
    try:
        arr = raw.astype(float, copy=False)
    except OverflowError:
        raise ValueError(f"{name} holds a number too large for a float64") from None
    if mask is not None and mask.any():
        if masked == "error":
            raise ValueError(
                f"{name} must not have masked entries, got {int(mask.sum())} masked "
                f"(pass NaN where a value is missing, if {name} allows it)"
            )
        arr = np.where(mask, np.nan, arr)  # a masked entry is a missing sample
    if ndim is not None:
        allowed = (ndim,) if isinstance(ndim, int) else tuple(ndim)
        if arr.ndim not in allowed:
            want = " or ".join(str(d) for d in allowed)
            raise ValueError(
                f"{name} must have {want} dimensions, got shape {arr.shape}"
            )
    return arr


def int_array(value, name: str, *, ndim: int | None = None) -> np.ndarray:
    """Convert ``value`` to an int64 array; floats are accepted only if integral.

    Booleans, complex numbers, strings, objects and masked arrays with masked
    entries are refused.
    """
    if isinstance(value, np.ma.MaskedArray):
        if np.ma.getmaskarray(value).any():
            raise ValueError(f"{name} must not have masked entries")
        value = np.ma.getdata(value)
    arr = _as_array(value, name)
    if arr.dtype == bool or not (
        np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)
    ):
        raise TypeError(f"{name} must hold integers, got dtype {arr.dtype}")
    if np.issubdtype(arr.dtype, np.floating):
        if not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
            raise ValueError(f"{name} must hold integers, got non-integral values")
    if arr.size and (arr.max() > _INT_MAX or arr.min() < -_INT_MAX):
        bad = arr.max() if arr.max() > _INT_MAX else arr.min()
        raise ValueError(f"{name} must hold integers within +-2**62, got {float(bad):g}")
    arr = arr.astype(np.int64)
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimensions, got shape {arr.shape}")
    return arr


def _as_array(value, name: str) -> np.ndarray:
    """``np.asarray(value)``, with a ragged nesting reported under ``name``."""
    try:
        return np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise TypeError(
            f"{name} must be a rectangular numeric array, got a ragged {type(value).__name__}"
        ) from exc


def _is_real(v) -> bool:
    return isinstance(v, (Real, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def check_finite(arr: np.ndarray, name: str) -> None:
    """Raise if ``arr`` holds NaN or infinity."""
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(
            f"{name} must be finite, got {arr[tuple(bad)]} at index {tuple(int(i) for i in bad)}"
        )


def broadcast_batch(shapes: dict[str, tuple[int, ...]]) -> tuple[int, ...]:
    """The broadcast of named batch shapes; ``ValueError`` naming them all when they clash."""
    try:
        return np.broadcast_shapes(*shapes.values())
    except ValueError:
        listed = ", ".join(f"{name} {shape}" for name, shape in shapes.items())
        raise ValueError(f"the batch shapes must broadcast together, got {listed}") from None


def check_cores(arrays: dict[str, np.ndarray], cores: dict[str, str]) -> tuple[int, ...]:
    """Check stacks of vectors and matrices against their core axes; return the batch shape.

    ``cores`` names each array's trailing (core) axes with letters, e.g.
    ``{"x": "n", "P": "nn", "C": "mn"}``: every array must have those axes, one
    letter must stand for one size in every array, and the leading (batch) axes
    must broadcast together. Errors name the array and the axis.
    """
    sizes: dict[str, tuple[int, str]] = {}
    batches = {}
    for name, arr in arrays.items():
        core = cores[name]
        if arr.ndim < len(core):
            raise ValueError(
                f"{name} must have shape (..., {', '.join(core)}), got shape {arr.shape}"
            )
        for letter, size in zip(core, arr.shape[arr.ndim - len(core):]):
            seen = sizes.setdefault(letter, (size, name))
            if seen[0] != size:
                raise ValueError(
                    f"{name} has {letter} = {size} in its shape {arr.shape}, but {seen[1]} has "
                    f"{letter} = {seen[0]}"
                )
        batches[name] = arr.shape[: arr.ndim - len(core)]
    return broadcast_batch(batches)


def gain_stack(value, name: str, shape: tuple[int, int, int], text: str) -> np.ndarray:
    """``value`` as a finite, read-only float array of exactly ``shape`` (one gain per mode),
    ``text`` naming the shape's letters in the error (``"(L, n, m)"``)."""
    arr = float_array(value, name, ndim=3)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {text} = {shape}, got {arr.shape}")
    check_finite(arr, name)
    arr = arr.copy()
    arr.setflags(write=False)
    return arr


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
    check_finite(arr, name)  # NaN would pass every comparison below
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
    """Return ``value`` (a real number or a 0-d real array) as a finite positive float."""
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        value = value[()]
    if (isinstance(value, (bool, np.bool_))
            or not isinstance(value, (Real, np.floating, np.integer))):
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


def check_bool(value, name: str) -> bool:
    """Return ``value`` as a bool; only ``True``/``False`` (Python or numpy) are accepted."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {type(value).__name__}")
    return bool(value)


def check_mode(value, n_modes: int, name: str) -> int:
    """Return ``value`` as a 0-based mode index in ``0..n_modes-1``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an int mode index, got {type(value).__name__}")
    if not 0 <= value < n_modes:
        raise ValueError(f"{name} must be a mode index in 0..{n_modes - 1}, got {value}")
    return int(value)


# When the mode of sample k acts, for the multiple-model filters: "sample" (the package's
# convention: it governs y_k and the interval [t_k, t_{k+1})) or "interval" (Bar-Shalom's: it
# governs y_k and the interval into t_k). See docs/conventions.rst.
TIMINGS = ("sample", "interval")


def check_timing(value, name: str = "timing") -> str:
    """Return ``value`` if it is one of :data:`TIMINGS`."""
    if not isinstance(value, str):
        raise TypeError(f"{name} must be one of {TIMINGS}, got {type(value).__name__}")
    if value not in TIMINGS:
        raise ValueError(f"{name} must be one of {TIMINGS}, got {value!r}"
                         + did_you_mean(value, TIMINGS, before="; "))
    return value


def closest_name(name: str, valid: Iterable[str]) -> str | None:
    """The name among ``valid`` a user most likely meant by ``name``, or None.

    A name differing only in case (``IMM`` for ``imm``) wins; otherwise the closest in
    spelling (:func:`difflib.get_close_matches`, ratio at least 0.6: ``kalmann`` for
    ``kalman``, ``v_mx`` for ``v_max``).
    """
    valid = sorted(valid)
    name = str(name)
    close = ([v for v in valid if v.lower() == name.lower()]
             or difflib.get_close_matches(name, valid, n=1))
    return close[0] if close else None


def did_you_mean(name: str, valid: Iterable[str], *, before: str = "", after: str = "") -> str:
    """``"did you mean 'x'?"`` for the :func:`closest_name` ``x`` of ``name`` among ``valid``
    (framed by ``before`` and ``after``), or ``""`` when none is close: the hint of every
    error about an unknown name (methods, reproductions, model-file keys, command-line
    options)."""
    close = closest_name(name, valid)
    return "" if close is None else f"{before}did you mean {close!r}?{after}"


@lru_cache(maxsize=1)
def memory_limit() -> int:
    """Bytes one call may plan to allocate: half of the machine's physical memory.

    Read with ``os.sysconf``; 4 GiB where the platform does not report it.
    """
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        total = 0
    return total // 2 if total > 0 else 4 * 2**30


def check_memory(nbytes: float, what: str) -> None:
    """Refuse up front a computation whose arrays would not fit in :func:`memory_limit`.

    ``what`` names the arguments that set the size and how it is counted, e.g.
    ``"trials = 100000000: the outputs (N K (n + m + l + 1) floats)"``; the message
    adds the estimate and the limit.
    """
    limit = memory_limit()
    if nbytes > limit:
        raise ValueError(
            f"{what} would take about {_gib(nbytes)}, more than the limit of {_gib(limit)} "
            "(half of this machine's physical memory); reduce the size"
        )


def _gib(nbytes: float) -> str:
    return f"{nbytes / 2**30:.3g} GiB"
