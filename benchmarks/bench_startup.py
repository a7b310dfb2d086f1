"""Start-up of a new process from the on-disk numba cache, against the dependencies' own floor.

Issue 13 asks that a second process (the kernels already compiled and cached on disk) start in
under a second. What a process pays before switchest does anything is measured beside it: the
interpreter, importing NumPy, SciPy's ``linalg`` and numba, and numba's one-time set-up of its
typing and target context when it loads its first cached function (a trivial ``njit(cache=True)``
function, not switchest's). Each script runs in a child process, the scripts interleaved
(A B C D A B ...), timed by the child's CPU time (``resource.getrusage(RUSAGE_CHILDREN)``, user +
system) and wall time; medians and mins over the rounds, the load average beside them. The
kernels and the trivial function are compiled once before the timed rounds.

Run: ``python benchmarks/bench_startup.py [--quick]`` (``--quick``: 3 rounds instead of 7).
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

from harness import Section, markdown_table, print_sections, quick_flag

from switchest.estimators._compiled.warmup import warm_up

FLOOR = """\
import numpy, scipy.linalg, numba

@numba.njit(cache=True)
def twice(x):
    return 2.0 * x

twice(1.0)
"""
FILTERS = """\
import numpy as np
from switchest.estimators import IMMFilter, ModeKalmanFilter
from switchest.models import vehicle_2d

system = vehicle_2d()
t = np.arange(100) * 0.5
stay = np.full((3, 3), 0.05) + 0.85 * np.eye(3)
y = np.random.default_rng(0).normal(size=(5, 100, 2))
IMMFilter(system, stay, np.zeros(4), np.eye(4)).run(y, np.ones(1), t)
ModeKalmanFilter(system, np.zeros(4), np.eye(4)).run(y, np.ones(1), t,
                                                     modes=np.zeros((5, 100), int))
"""
SCRIPTS = {
    "Python alone": "pass\n",
    "import numpy, scipy.linalg, numba": "import numpy, scipy.linalg, numba\n",
    "... and load one cached njit function (numba's floor)": FLOOR,
    "import switchest.estimators": "import switchest.estimators\n",
    "switchest: IMMFilter.run and ModeKalmanFilter.run (vehicle, 5 trials x 100 samples)":
        FILTERS,
}


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _time(path: Path) -> tuple[float, float]:
    """CPU and wall seconds of ``python path`` in a child process."""
    cpu0, start = _children_cpu(), time.perf_counter()
    subprocess.run([sys.executable, str(path)], check=True, cwd=path.parent)
    return _children_cpu() - cpu0, time.perf_counter() - start


def run(*, quick: bool = False) -> list[Section]:
    """Time every script in interleaved rounds; one section with the table."""
    rounds = 3 if quick else 7
    warm_up()
    with tempfile.TemporaryDirectory() as tmp:
        paths = {}
        for i, (name, text) in enumerate(SCRIPTS.items()):
            paths[name] = Path(tmp) / f"script_{i}.py"
            paths[name].write_text(textwrap.dedent(text))
        for path in paths.values():  # fill the caches (the trivial function's included)
            _time(path)
        load_before = os.getloadavg()[0]
        cpu = {name: [] for name in SCRIPTS}
        wall = {name: [] for name in SCRIPTS}
        for _ in range(rounds):
            for name, path in paths.items():
                c, w = _time(path)
                cpu[name].append(c)
                wall[name].append(w)
        load_after = os.getloadavg()[0]
    floor = statistics.median(cpu["... and load one cached njit function (numba's floor)"])
    rows = [(name, f"{statistics.median(cpu[name]):.2f} s", f"{min(cpu[name]):.2f} s",
             f"{statistics.median(wall[name]):.2f} s",
             f"{statistics.median(cpu[name]) - floor:+.2f} s") for name in SCRIPTS]
    table = markdown_table(["child process", "median CPU", "min CPU", "median wall",
                            "median CPU - numba's floor"], rows)
    mine = statistics.median(cpu[list(SCRIPTS)[-1]])
    verdict = "meets" if mine < 1.0 else "does NOT meet"
    notes = (
        f"{rounds} interleaved rounds; load (1 min) {load_before:.2f} -> {load_after:.2f}.",
        (f"a process that filters with switchest from the on-disk cache: {mine:.2f} CPU-s, "
         f"{verdict} issue 13's 'under a second'; of it, {floor:.2f} CPU-s is what any process "
         "importing NumPy, SciPy and numba and loading one cached function pays on this machine, "
         f"so switchest's own share (its imports, kernel loads, discretization) is "
         f"{mine - floor:.2f} CPU-s."),
    )
    return [Section("Start-up of a new process from the on-disk cache", table, notes)]


if __name__ == "__main__":
    print_sections(run(quick=quick_flag(__doc__.splitlines()[0])))
