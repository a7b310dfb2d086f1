"""BLAS held to one thread for the duration of a library call.

switchest's linear algebra is on small matrices (a few states across, stacked over modes and
trials). A threaded BLAS gains nothing there and, on a loaded machine, loses a great deal: its
worker threads spin for cores that other processes hold. ``simulate`` of the boost converter
(200 trials, fresh switch times) took 4-26 s instead of 1 s beside a busy process on a 2-core
machine, burning 4-25 times the CPU.

:func:`one_blas_thread` sets every thread pool threadpoolctl finds (BLAS and OpenMP) to one
thread when a thread's outermost call enters and restores the sizes it found when that call
leaves; calls inside it only check a flag. Entering costs about 16 us (threadpoolctl's cached
controller; ``threadpool_limits`` costs 1.6 ms, as it looks for the libraries each time), so it
wraps whole public calls, never a per-step helper.

:func:`cores` counts the cores this process may run on, for the pools of worker processes (the
experiment runner's) and for the engine's threads (:mod:`switchest.engine._parallel`).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from threadpoolctl import get_cached_controller

__all__ = ["cores", "one_blas_thread"]

_inside = threading.local()  # .active: this thread is inside a one_blas_thread call


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the body (``with one_blas_thread():``) or a function (``@one_blas_thread()``) with
    BLAS at one thread; the pools' sizes are restored when the outermost such call of the
    thread leaves, exception or not.

    The pools are process-wide: threadpoolctl lets the first thread that limits OpenBLAS
    control it until that thread's limit ends.
    """
    if getattr(_inside, "active", False):
        yield
        return
    _inside.active = True
    try:
        with get_cached_controller().limit(limits=1):
            yield
    finally:
        _inside.active = False


def cores() -> int:
    """The number of cores this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1
