"""A batch's trials split over threads: every core in one call, the same numbers on any count.

The kernels release the GIL and treat trials independently, in blocks of lanes. A wrapper
hands :func:`over_trials` a function that runs the kernel on a contiguous range of trials
(slices of its per-trial arrays: a slice of the first axis of a C-contiguous array is itself
C-contiguous, so no copy is made) and gets back the merged status and repair report. The
ranges are whole lane blocks, so a trial meets the same block neighbours and the same
arithmetic whatever the thread count.

The thread count is a process-wide setting, like BLAS's: :func:`set_threads` (the
experiment runner gives each of its worker processes its share of the cores, so that its
processes and these threads do not oversubscribe the machine), else the environment variable
``SWITCHEST_THREADS``, else every core this process may run on. A batch too small to gain
from threads (fewer than two blocks, or fewer than :data:`MIN_WORK` trial-samples per thread)
runs on the calling thread.
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .._threads import cores

__all__ = ["CHUNKS", "MIN_WORK", "MixtureOutput", "Report", "Reported", "over_trials",
           "run_split", "run_values", "set_threads", "threads"]

CHUNKS = 4
"""Ranges of trials per thread that :func:`over_trials` cuts a batch into."""

MIN_WORK = 20_000
"""Fewest trial-samples worth a thread of their own (a dispatch costs tens of microseconds;
a trial-sample of the IMM about 0.1-1 microseconds)."""

_setting: int | None = None
_pool: tuple[int, int, ThreadPoolExecutor] | None = None  # (pid, size, pool)
_lock = threading.Lock()


def set_threads(count: int | None) -> None:
    """Run the engine's kernels on ``count`` threads in this process (None: the default,
    ``SWITCHEST_THREADS`` or every core)."""
    global _setting
    if count is not None:
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise ValueError(f"threads must be a positive integer or None, got {count!r}")
    _setting = count


def threads() -> int:
    """The thread count the kernels use in this process (see the module docstring)."""
    if _setting is not None:
        return _setting
    value = os.environ.get("SWITCHEST_THREADS", "")
    if value:
        try:
            count = int(value)
        except ValueError:
            count = 0
        if count < 1:
            raise ValueError(f"SWITCHEST_THREADS must be a positive integer, got {value!r}")
        return count
    return cores()


class Report(NamedTuple):
    """A kernel call's outcome."""

    status: int
    repaired: int = 0
    smallest_eigenvalue: float = math.inf


@dataclass(kw_only=True)
class Reported:
    """The last attributes of every kernel's output, its :class:`Report`.

    Attributes
    ----------
    status : int
        ``OK`` (0) or the failure code that stopped the kernel (outputs then incomplete);
        :func:`switchest.engine.raise_for_status` turns it into an exception.
    repaired : int
        How many covariances (of a mode, trial and sample) were repaired to their rounding
        level (``se_repair``, ``engine/c/linalg.c``);
        :func:`switchest.engine.warn_for_repairs` warns about them.
    smallest_eigenvalue : float
        The smallest eigenvalue a repaired covariance had (``inf`` if none was).
    """

    status: int
    repaired: int = 0
    smallest_eigenvalue: float = math.inf


@dataclass
class MixtureOutput(Reported):
    """The first attributes of every multiple-model kernel's output (IMM and GPB banks,
    IMM-EV1, RBPF, Kim's smoother), for every trial and sample.

    Attributes
    ----------
    x, P : ndarray, shapes (N, K, n), (N, K, n, n)
        The combined estimate: mean and covariance of the mixture of the hypotheses'
        posteriors (IMM-EV1: of its destinations', or the posterior of its MAP path).
    mode_prob : ndarray, shape (N, K, L)
        The mode probabilities (IMM-EV1: the normalized path weights of the destinations).
    mode : ndarray of int64, shape (N, K)
        The most probable mode (the first on a tie).
    """

    x: np.ndarray
    P: np.ndarray
    mode_prob: np.ndarray
    mode: np.ndarray


def over_trials(run_range: Callable[[int, int], Report], trials: int, samples: int, *,
                block: int) -> Report:
    """``run_range(begin, end)`` over ``0 .. trials`` in ranges of whole blocks of ``block``
    trials on the threads, merged: the first failing range's status (in trial order), the
    repairs summed, the smallest eigenvalue over all.

    The batch is cut into about :data:`CHUNKS` ranges per thread, which the threads take in
    turn as they finish their last: on a machine where another process holds part of a core,
    the threads that run faster take more ranges instead of waiting for the slowest.
    """
    count = _thread_count(trials, samples, block)
    if count == 1:
        return run_range(0, trials)
    blocks = math.ceil(trials / block)
    ranges = min(blocks, count * CHUNKS, max(count, trials * samples // MIN_WORK))
    per = math.ceil(blocks / ranges)
    bounds = [(i * per * block, min((i + 1) * per * block, trials)) for i in range(ranges)]
    bounds = [(a, b) for a, b in bounds if a < b]
    results: list[Report | None] = [None] * len(bounds)
    turns = iter(range(len(bounds)))  # next() on a shared iterator: one range to one thread
    turn_lock = threading.Lock()

    def work() -> None:
        while True:
            with turn_lock:
                i = next(turns, None)
            if i is None:
                return
            results[i] = run_range(*bounds[i])

    pool = _executor(count - 1)
    others = [pool.submit(work) for _ in range(count - 1)]
    work()  # the calling thread takes ranges too, then waits for the others
    for future in others:
        future.result()
    status = next((s for s, _, _ in results if s != 0), 0)
    return Report(status, sum(r for _, r, _ in results), min(e for _, _, e in results))


def run_split(kernel: Callable[..., int], args: list[tuple[object, bool]], *, trials: int,
              samples: int, block: int) -> Report:
    """``kernel(*args, report)`` over the trials, split by :func:`over_trials`.

    ``args`` pairs each argument with whether it is per trial (an array whose first axis is
    the ``trials``, sliced to each range: inputs and outputs alike) or shared (a table, a
    setting, an array whose first axis of length 1 serves every trial). The kernel's last
    argument is its report, ``(2,)``: the covariances it repaired and the smallest eigenvalue
    one had; it returns its status.
    """
    if _thread_count(trials, samples, block) == 1:  # the calling thread: no slices to take
        return _call(kernel, [value for value, _ in args])

    def run_range(begin: int, end: int) -> Report:
        return _call(kernel, [value[begin:end] if per_trial else value
                              for value, per_trial in args])

    return over_trials(run_range, trials, samples, block=block)


def run_values(kernel: Callable[..., int], values: tuple, per_trial: tuple[bool, ...], *,
               trials: int, samples: int, block: int) -> Report:
    """:func:`run_split` with the arguments and whether each is per trial given apart: on the
    calling thread alone the kernel takes ``values`` as they are (no pairs to build)."""
    if _thread_count(trials, samples, block) == 1:
        return _call(kernel, values)
    return run_split(kernel, list(zip(values, per_trial, strict=True)), trials=trials,
                     samples=samples, block=block)


def _call(kernel: Callable[..., int], values) -> Report:
    """``kernel(*values, report)`` with a new report: its status and the report's two entries."""
    report = np.empty(2)
    status = kernel(*values, report)
    return Report(int(status), int(report[0]), float(report[1]))


def _thread_count(trials: int, samples: int, block: int) -> int:
    """How many threads a batch of ``trials x samples`` in blocks of ``block`` is worth."""
    worth = min(math.ceil(trials / block), (trials * max(samples, 1)) // MIN_WORK)
    if worth <= 1:  # a small batch: the setting (an environment look-up) is not needed
        return 1
    return min(threads(), worth)


def _executor(size: int) -> ThreadPoolExecutor:
    """This process's pool of at least ``size`` worker threads (made anew after a fork)."""
    global _pool
    with _lock:
        pid = os.getpid()
        if _pool is None or _pool[0] != pid or _pool[1] < size:
            _pool = (pid, size, ThreadPoolExecutor(max_workers=size,
                                                   thread_name_prefix="switchest-engine"))
        return _pool[2]
