"""Small timing utilities shared by the switchest benchmarks (not part of the test suite).

* :func:`best_time` — repeat a call and keep the best wall time (``time.perf_counter``);
* :func:`single_threaded_blas` — run the measurements with every loaded BLAS limited to
  one thread (threadpoolctl) and report that it did;
* :func:`machine_info` — CPU count, load average, library versions and BLAS threads;
* :class:`Section` and :func:`markdown_table` — what a benchmark returns and how it prints.

Under CPU contention a threaded BLAS on 3x3..9x9 matrices has been measured to run a
hundred times slower (DESIGN.md §4), so every measurement here runs single-threaded.
"""

from __future__ import annotations

import argparse
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

__all__ = [
    "Section",
    "Timing",
    "best_time",
    "blas_report",
    "format_seconds",
    "machine_info",
    "markdown_table",
    "print_sections",
    "quick_flag",
    "single_threaded_blas",
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
def single_threaded_blas() -> Iterator[dict[str, Any]]:
    """Limit every loaded BLAS to one thread for the duration of the block.

    Yields a report ``{"before": [...], "inside": [...], "single_threaded": bool}``;
    ``single_threaded`` is True when every library reported one thread inside the
    limit. Import the code under test before entering: a library loaded later is
    not limited.
    """
    before = blas_report()
    with threadpool_limits(limits=1):
        inside = blas_report()
        report = {
            "before": before,
            "inside": inside,
            "single_threaded": bool(inside) and all(lib["threads"] == 1 for lib in inside),
        }
        yield report


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_info() -> dict[str, Any]:
    """CPU, load, Python / NumPy / SciPy versions and the BLAS libraries with their threads."""
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
        "blas": blas_report(),
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
    lines = ["| " + " | ".join(map(str, header)) + " |", "|" + "|".join("---" for _ in header) + "|"]
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
