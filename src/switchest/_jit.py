"""How switchest compiles its loops: numba ``njit``, cached on disk, numpy's error model.

``cache=True`` keeps the machine code beside the sources, so only the first process after an
install compiles; ``error_model="numpy"`` drops numba's zero-division checks (callers check
every divisor first) and lets the compiler vectorize the loops.

numba keys a cached function on its own source file only, yet the machine code also holds the
functions it calls from other files (``_compiled/linalg.py`` inlined into every kernel): after
an edit of ``linalg.py`` alone, the kernels of ``bank.py`` would load stale from the cache. So
each cache directory carries a digest of every source that compiled code is built from
(:data:`_SOURCES`), and a directory whose digest differs is emptied of its cached functions
before the first of them is loaded.
"""

from __future__ import annotations

import hashlib
from functools import cache
from pathlib import Path

from numba import njit

__all__ = ["borrow", "jit", "started_afresh"]

_PACKAGE = Path(__file__).resolve().parent
_SOURCES = ("_jit.py", "dyadic.py", "estimators/_compiled/*.py")
"""Files (globs relative to the package) whose code ends up in compiled functions."""
_STAMP = "switchest-jit-sources.sha256"
_AFRESH: set[str] = set()
"""The cache directories this process found without the current digest and emptied."""

_njit = njit(cache=True, error_model="numpy", _nrt=True)
_njit_borrowing = njit(cache=True, error_model="numpy", _nrt=False)


def jit(function):
    """``function`` compiled by numba (``njit``, ``cache=True``, numpy's error model), its
    cache directory cleared first if the compiled sources changed since it was filled."""
    return _cached(_njit(function))


def borrow(function):
    """``function`` compiled as :func:`jit` does, but without numba's reference counting: for a
    function that allocates no array and returns none, so that it only borrows its caller's.

    A compiled function counts a reference to each array it is given on entry and releases it
    on return, an atomic increment and decrement per array and call. numba removes the pair in
    a function that calls no other, but keeps it in one that does: in the Kalman kernel's step
    (:mod:`.estimators._compiled.kalman_kernel`), whose equations pass a dozen arrays on to
    their parts, these counts took a quarter of the time. Compiled with numba's runtime off
    (its ``_nrt`` option), such a function counts nothing, and numba refuses to compile any
    code in it that needs the runtime (an allocation, a sort): the compile error names it.
    Functions it calls keep their own settings.
    """
    return _cached(_njit_borrowing(function))


def started_afresh() -> bool:
    """Whether this process found a cache directory of compiled code without the stamp of the
    current sources (the first run after an install, or after the sources changed) and started
    it anew: its functions will be compiled, not loaded."""
    return bool(_AFRESH)


def _cached(dispatcher):
    """``dispatcher`` once its cache directory is cleared of functions compiled from other
    sources (:func:`_refresh`)."""
    directory = getattr(getattr(dispatcher, "_cache", None), "_cache_path", None)
    if directory is not None:
        _refresh(directory)
    return dispatcher


@cache
def _digest() -> str:
    """SHA-256 of the compiled sources, in a fixed order."""
    digest = hashlib.sha256()
    for pattern in _SOURCES:
        for path in sorted(_PACKAGE.glob(pattern)):
            digest.update(path.relative_to(_PACKAGE).as_posix().encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()


@cache
def _refresh(directory: str) -> None:
    """Delete the cached functions (``*.nbi``, ``*.nbc``) of ``directory`` unless its stamp
    holds the current digest, then write the stamp (once per directory and process)."""
    folder, digest = Path(directory), _digest()
    stamp = folder / _STAMP
    try:
        if stamp.is_file() and stamp.read_text() == digest:
            return
        for pattern in ("*.nbi", "*.nbc"):
            for path in folder.glob(pattern):
                path.unlink(missing_ok=True)
        folder.mkdir(parents=True, exist_ok=True)
        stamp.write_text(digest)
        _AFRESH.add(directory)
    except OSError:  # a directory this process may not write: left to numba as it is
        return
