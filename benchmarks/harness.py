"""Small timing utilities shared by the switchest benchmarks (not part of the test suite).

* :func:`compare_interleaved` — time k contenders interleaved (A B C A B C ...) by CPU
  time (``time.process_time``), with the load average before and after; a
  :class:`Comparison` gives each contender's min and median per unit of work and the
  ratios of medians and of mins to a reference (:func:`comparison_rows` tabulates them);
* :func:`best_time` — repeat a call and keep the best wall time (``time.perf_counter``),
  for sweeps of one implementation over sizes;
* :func:`single_threaded` — run the measurements with every loaded BLAS limited to one
  thread (threadpoolctl) and switchest's engine at one thread (``set_threads(1)``), and report
  that they were; :func:`engine_threads` sets another engine thread count for a block (a
  thread-scaling measurement);
* :func:`machine_info` — CPU count, load average, library versions and BLAS threads;
* :class:`Section` and :func:`markdown_table` — what a benchmark returns and how it prints.

Under CPU contention a threaded BLAS on 3x3..9x9 matrices has been measured to run a
hundred times slower, so every measurement here runs single-threaded. The
engine's kernels split a batch over every core by default; the benchmarks pin them to one
thread, so that a ratio to a single-threaded peer or yardstick compares like with like.

Why interleaved CPU time: the machine is shared. Wall time charges a contender for the
time other processes held the core; CPU time (user + system, all threads of this
process) does not, and interleaving the contenders round by round exposes them to the
same drift of load, cache and clock frequency, so their ratio holds up where the absolute
numbers move. The load average printed beside each ratio says how busy the machine was.
"""

from __future__ import annotations

import argparse
import gc
import importlib.metadata
import os
import platform
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy
import scipy.linalg  # load SciPy's own BLAS now, so the thread limit reaches it
from threadpoolctl import threadpool_info, threadpool_limits

from switchest.estimators import set_threads, threads

__all__ = [
    "Comparison",
    "Contender",
    "Section",
    "Timing",
    "best_time",
    "blas_report",
    "compare_interleaved",
    "comparison_header",
    "comparison_rows",
    "engine_threads",
    "format_load",
    "format_seconds",
    "machine_info",
    "markdown_table",
    "package_versions",
    "print_sections",
    "quick_flag",
    "single_threaded",
]


@dataclass(frozen=True)
class Timing:
    """Wall times of repeated calls; ``best`` is the minimum, ``result`` the last return value."""

    best: float
    times: tuple[float, ...]
    result: Any = field(repr=False, default=None)

    @property
    def repeats(self) -> int:
        """How many calls were timed."""
        return len(self.times)


def best_time(fn: Callable[[], Any], *, repeat: int = 3, budget: float | None = None) -> Timing:
    """Call ``fn()`` up to ``repeat`` times and keep the best wall time.

    The minimum is the least disturbed run (other processes only ever add time).
    When ``budget`` (seconds) is given, no new call starts once the calls so far
    have used it up, so one slow call is timed once.
    """
    if repeat < 1:
        raise ValueError(f"repeat must be >= 1, got {repeat}")
    times: list[float] = []
    result = None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
        if budget is not None and sum(times) >= budget:
            break
    return Timing(best=min(times), times=tuple(times), result=result)


@dataclass(frozen=True)
class Contender:
    """One contender of an interleaved comparison.

    Parameters
    ----------
    name : str
        Label in tables and the key of the :class:`Comparison`'s dictionaries.
    call : callable
        ``call()`` does the work once; its return value is kept (the last one), so
        the caller can check that the contenders agree. Block on asynchronous work
        inside it (e.g. ``jax.block_until_ready``).
    units : float
        Units of work per call (e.g. trials x steps): times are reported per unit.
    number : int
        Calls per timed sample, for calls too short to time alone; the sample is their
        CPU time divided by ``number``.
    warmup : callable, optional
        Called once before timing (compilation, caches); default ``call`` itself. Give
        a cheap call on a slice of the data when ``call`` is slow.
    """

    name: str
    call: Callable[[], Any]
    units: float = 1.0
    number: int = 1
    warmup: Callable[[], Any] | None = None


@dataclass(frozen=True)
class Comparison:
    """CPU and wall seconds per call of each contender, round by round, and the load."""

    names: tuple[str, ...]
    units: dict[str, float]
    cpu: dict[str, tuple[float, ...]]
    wall: dict[str, tuple[float, ...]]
    results: dict[str, Any] = field(repr=False)
    load_before: tuple[float, float, float]
    load_after: tuple[float, float, float]

    def calls(self, name: str) -> int:
        """How many samples of ``name`` were timed."""
        return len(self.cpu[name])

    def min(self, name: str) -> float:
        """Least CPU seconds per unit of work of ``name`` (the least disturbed sample)."""
        return min(self.cpu[name]) / self.units[name]

    def median(self, name: str) -> float:
        """Median CPU seconds per unit of work of ``name``."""
        return float(np.median(self.cpu[name])) / self.units[name]

    def wall_median(self, name: str) -> float:
        """Median wall seconds per unit of work of ``name`` (for reference only)."""
        return float(np.median(self.wall[name])) / self.units[name]

    def ratio(self, name: str, reference: str) -> tuple[float, float]:
        """``(ratio of medians, ratio of mins)`` of ``name`` to ``reference`` per unit of work."""
        return (self.median(name) / self.median(reference), self.min(name) / self.min(reference))


def compare_interleaved(
    contenders: Sequence[Contender],
    *,
    rounds: int = 5,
    budget: float | None = None,
    warm_up: bool = True,
) -> Comparison:
    """Time ``contenders`` interleaved by CPU time: A B C, A B C, ... for ``rounds`` rounds.

    Each contender is first warmed up once (untimed). Each timed sample is the CPU time
    (``time.process_time``: user + system of every thread of this process) of ``number``
    calls divided by ``number``; the wall time (``time.perf_counter``) is recorded beside
    it. The garbage collector runs, untimed, before every sample. With ``budget`` (CPU
    seconds), a contender whose samples have used it up sits out the remaining rounds
    (each contender is timed at least once), so one slow contender does not stretch the
    run; the others keep their rounds. ``os.getloadavg()`` is read before and after.
    """
    if rounds < 1:
        raise ValueError(f"rounds must be >= 1, got {rounds}")
    names = tuple(c.name for c in contenders)
    if len(set(names)) != len(names):
        raise ValueError(f"contender names must be unique, got {names}")
    if warm_up:
        for c in contenders:
            (c.warmup or c.call)()
    cpu: dict[str, list[float]] = {c.name: [] for c in contenders}
    wall: dict[str, list[float]] = {c.name: [] for c in contenders}
    results: dict[str, Any] = {}
    load_before = os.getloadavg()
    for _ in range(rounds):
        for c in contenders:
            if budget is not None and cpu[c.name] and sum(cpu[c.name]) * c.number >= budget:
                continue
            results.pop(c.name, None)  # free the previous result before the next call
            gc.collect()
            start_cpu, start_wall = time.process_time(), time.perf_counter()
            for _ in range(c.number):
                result = c.call()
            cpu[c.name].append((time.process_time() - start_cpu) / c.number)
            wall[c.name].append((time.perf_counter() - start_wall) / c.number)
            results[c.name] = result
    return Comparison(
        names=names,
        units={c.name: float(c.units) for c in contenders},
        cpu={k: tuple(v) for k, v in cpu.items()},
        wall={k: tuple(v) for k, v in wall.items()},
        results=results,
        load_before=load_before,
        load_after=os.getloadavg(),
    )


def format_load(comparison: Comparison) -> str:
    """The 1-minute load average before and after a comparison, e.g. ``'0.91 -> 0.95'``."""
    return f"{comparison.load_before[0]:.2f} -> {comparison.load_after[0]:.2f}"


def comparison_header(unit: str, reference: str) -> list[str]:
    """Column titles matching :func:`comparison_rows`."""
    return [f"median per {unit} (CPU)", "min (CPU)", f"median / {reference}",
            f"min / {reference}", "samples", f"wall median per {unit}", "load (1 min)"]


def comparison_rows(comparison: Comparison, reference: str, *, prefix: Sequence[Any] = (),
                    labels: dict[str, str] | None = None,
                    names: Sequence[str] | None = None) -> list[list[Any]]:
    """One table row per contender: ``prefix`` cells, its label, then :func:`comparison_header`.

    Ratios are to ``reference`` (its own row shows 1), per unit of work; the load is the
    1-minute load average before and after the comparison. ``names`` picks and orders the
    contenders (default: all, in the order they ran).
    """
    labels = labels or {}
    rows = []
    for name in comparison.names if names is None else names:
        med, low = comparison.ratio(name, reference)
        rows.append([*prefix, labels.get(name, name), format_seconds(comparison.median(name)),
                     format_seconds(comparison.min(name)), f"{med:.3g}", f"{low:.3g}",
                     comparison.calls(name), format_seconds(comparison.wall_median(name)),
                     format_load(comparison)])
    return rows


def blas_report() -> list[dict[str, Any]]:
    """The BLAS/OpenMP libraries loaded in this process and their current thread counts."""
    return [
        {
            "library": os.path.basename(lib["filepath"]),
            "api": lib["internal_api"],
            "version": lib.get("version"),
            "threads": lib["num_threads"],
            "threading_layer": lib.get("threading_layer"),
            "architecture": lib.get("architecture"),
        }
        for lib in threadpool_info()
    ]


@contextmanager
def single_threaded() -> Iterator[dict[str, Any]]:
    """Limit every loaded BLAS and switchest's engine to one thread for the block.

    Yields a report ``{"before": [...], "inside": [...], "engine_threads": int,
    "single_threaded": bool}``: the BLAS libraries with their thread counts before and inside
    the limit, the engine's thread count inside (``switchest.estimators.threads()``), and
    whether every library reported one thread and the engine ran on one. Import the code
    under test before entering: a BLAS loaded later is not limited (the engine's setting is
    process-wide and holds for code imported later too). The engine's previous count is
    restored on leaving.
    """
    before = blas_report()
    with threadpool_limits(limits=1), engine_threads(1):
        inside = blas_report()
        report = {
            "before": before,
            "inside": inside,
            "engine_threads": threads(),
            "single_threaded": (bool(inside) and all(lib["threads"] == 1 for lib in inside)
                                and threads() == 1),
        }
        yield report


@contextmanager
def engine_threads(count: int) -> Iterator[None]:
    """Run switchest's engine on ``count`` threads inside the block
    (``switchest.estimators.set_threads``), then restore the count it had."""
    previous = threads()
    set_threads(count)
    try:
        yield
    finally:
        set_threads(previous)


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


PEERS = ("numba", "filterpy", "dynamax", "jax", "jaxlib")


def package_versions(names: Sequence[str] = PEERS) -> dict[str, str]:
    """Installed versions of the named distributions (``'not installed'`` where missing)."""
    versions = {}
    for name in names:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions


def machine_info() -> dict[str, Any]:
    """CPU, load, Python / NumPy / SciPy versions, the BLAS libraries with their threads and
    the engine's default thread count (and ``SWITCHEST_THREADS``, if set)."""
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        usable = os.cpu_count()
    return {
        "cpu": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "usable_cpus": usable,
        "loadavg": os.getloadavg(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "peers": package_versions(),
        "blas": blas_report(),
        "engine_threads_default": threads(),
        "SWITCHEST_THREADS": os.environ.get("SWITCHEST_THREADS"),
    }


def format_seconds(seconds: float) -> str:
    """A duration with a readable unit: ``'1.23 s'``, ``'45.6 ms'``, ``'7.89 us'``."""
    if seconds >= 1.0:
        return f"{seconds:.3g} s"
    if seconds >= 1e-3:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds * 1e6:.3g} us"


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A GitHub-flavoured markdown table; cells are converted with ``str``."""
    lines = ["| " + " | ".join(map(str, header)) + " |",
             "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(map(str, row)) + " |" for row in rows]
    return "\n".join(lines)


@dataclass(frozen=True)
class Section:
    """One result of a benchmark: a title, a markdown table and notes printed under it."""

    title: str
    table: str
    notes: tuple[str, ...] = ()

    def markdown(self) -> str:
        """The section as markdown (a level-3 heading, the table, the notes as bullets)."""
        parts = [f"### {self.title}", "", self.table]
        if self.notes:
            parts += [""] + [f"- {note}" for note in self.notes]
        return "\n".join(parts) + "\n"


def print_sections(sections: Sequence[Section]) -> None:
    """Print sections to stdout as markdown."""
    for section in sections:
        print(section.markdown())
    sys.stdout.flush()


def quick_flag(description: str, argv: Sequence[str] | None = None) -> bool:
    """Parse the one option every benchmark script takes, ``--quick``."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--quick", action="store_true", help="smaller sizes, for a smoke run")
    return parser.parse_args(argv).quick
