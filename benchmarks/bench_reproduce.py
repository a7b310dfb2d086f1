"""Time of every paper reproduction at full size, as a user runs it.

Each experiment runs as ``switchest run NAME --workers 2 --out DIR`` in a child process with a
fresh results store (nothing is reused), one after another. Reported per experiment: its tasks,
the wall time, and the CPU time of the child and its worker processes
(``resource.getrusage(RUSAGE_CHILDREN)``, user + system), with the load average before and
after; the issue's targets are ``shankar-table1`` within 120 CPU-s and the whole set within 10
minutes of wall time on two cores. Nothing compiles at run time (switchest's engine is built
at install), so the first experiment pays no more than the others. The runner gives each of its
worker processes its share of the cores for the engine's threads (one each with two workers on
two cores); the child inherits this process's environment, as a user's command would.

Run: ``python benchmarks/bench_reproduce.py [--quick]`` (``--quick``: the ``--quick`` sizes).
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from harness import Section, format_seconds, markdown_table, print_sections, quick_flag

from switchest.experiments import get, names

WORKERS = 2


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _load() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg()[:1])


def run(*, quick: bool = False) -> list[Section]:
    rows, total_wall, total_cpu = [], 0.0, 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for exp in map(get, names()):
            params = exp.params(quick=quick)
            argv = [sys.executable, "-m", "switchest", "run", exp.name, "--workers", str(WORKERS),
                    "--out", str(Path(tmp) / exp.name), *(["--quick"] if quick else [])]
            before, cpu0, start = _load(), _children_cpu(), time.perf_counter()
            subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            wall, cpu = time.perf_counter() - start, _children_cpu() - cpu0
            total_wall, total_cpu = total_wall + wall, total_cpu + cpu
            rows.append((exp.name, len(exp.tasks(params)), format_seconds(wall),
                         format_seconds(cpu), before, _load()))
    rows.append(("**all**", "", format_seconds(total_wall), format_seconds(total_cpu), "", ""))
    table = markdown_table(["experiment", "tasks", "wall", "CPU (all processes)",
                            "load before", "load after"], rows)
    size = "--quick sizes" if quick else "full size"
    notes = (f"each experiment run alone, {WORKERS} workers, a fresh store; {size}.",
             "targets (full size): shankar-table1 <= 120 CPU-s; all <= 10 min wall on 2 cores.")
    return [Section(f"Reproductions: `switchest run NAME` at {size}", table, notes)]


def main(argv=None) -> None:
    print_sections(run(quick=quick_flag(__doc__.splitlines()[0], argv)))


if __name__ == "__main__":
    main()
