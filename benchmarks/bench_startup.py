"""Start-up of a new process that filters, against the floor of NumPy and SciPy (issue 13).

The issue's claim: a new process that runs a small IMM, GPB2 and switching-time filter uses at
most a few CPU-seconds in all and imports neither numba nor llvmlite, and it costs at most 2x
``python -c "import numpy, scipy.linalg"`` (child CPU, interleaved). Measured exactly so, with
two child processes of this interpreter, interleaved A B A B ... for the rounds:

* **A** — ``python -c "import numpy, scipy.linalg"``, the floor any such process pays;
* **B** — a script (:data:`FILTERS`) that imports switchest and runs ``IMMFilter``,
  ``GPB2Filter`` and ``SwitchTimeKalmanFilter`` (``grid=5``, modes given) on 10 trials x 50
  samples of the boost converter (``switchest.models.boost_converter()``, 0.5 ms sampling,
  100 V input, ``boost_switching``), then reports whether ``numba`` or ``llvmlite`` is in its
  ``sys.modules``. The data are simulated once by this process (as README.md's first session
  does) and read by B from an ``.npz`` file, so that B's cost is its imports and its filters.

Each child is timed by its CPU time, user + system, from the deltas of
``resource.getrusage(RUSAGE_CHILDREN)`` around it (the child has ended and been reaped), wall
time beside it. Both children run with switchest's engine and BLAS at one thread
(``SWITCHEST_THREADS``, ``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS``, ``MKL_NUM_THREADS`` = 1),
so they start the same libraries the same way. Nothing compiles at run time: one untimed round
first only writes the bytecode caches and fills the page cache. Reported: medians and mins of
each, the ratio of the medians B / A and the median of the per-round ratios, the load average.

Run: ``python benchmarks/bench_startup.py [--quick]`` (``--quick``: 3 rounds instead of 15).
"""

from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from harness import Section, markdown_table, print_sections, quick_flag

from switchest.models import (
    BOOST_INPUT_VOLTAGE,
    BOOST_SAMPLE_PERIOD,
    boost_converter,
    boost_switching,
)
from switchest.simulate import simulate

ROUNDS = 15
QUICK_ROUNDS = 3
TRIALS, SAMPLES = 10, 50
TARGET_RATIO = 2.0
FEW_CPU_SECONDS = 3.0  # "at most a few CPU-seconds", read as 3
FLOOR = ["-c", "import numpy, scipy.linalg"]
FILTERS = """\
import json
import sys

import numpy as np

from switchest.estimators import GPB2Filter, IMMFilter, SwitchTimeKalmanFilter
from switchest.models import boost_converter

data = np.load(sys.argv[1])
y, mode, t, u = data["y"], data["mode"], data["t"], data["u"]
system = boost_converter()
x0, P0 = np.array([0.0, 100.0]), np.diag([100.0, 100.0])
transition = np.array([[0.6, 0.4], [0.4, 0.6]])
estimates = [
    IMMFilter(system, transition, x0, P0).run(y, u, t),
    GPB2Filter(system, transition, x0, P0).run(y, u, t),
    SwitchTimeKalmanFilter(system, x0, P0, grid=5).run(y, u, t, modes=mode),
]
assert all(np.isfinite(e.x).all() for e in estimates)
print(json.dumps({name: name in sys.modules for name in ("numba", "llvmlite")}))
"""
LABELS = {
    "floor": 'A: `python -c "import numpy, scipy.linalg"`',
    "filters": (f"B: import switchest; IMMFilter, GPB2Filter, SwitchTimeKalmanFilter "
                f"(boost converter, {TRIALS} trials x {SAMPLES} samples)"),
}
SINGLE_THREADED = {name: "1" for name in ("SWITCHEST_THREADS", "OPENBLAS_NUM_THREADS",
                                          "OMP_NUM_THREADS", "MKL_NUM_THREADS")}


def write_data(path: Path) -> None:
    """Simulate the boost converter as README.md's first session does; save y, mode, t, u."""
    system = boost_converter()
    t = BOOST_SAMPLE_PERIOD * np.arange(SAMPLES)
    u = np.array([BOOST_INPUT_VOLTAGE])
    t_end = float(t[-1]) + BOOST_SAMPLE_PERIOD
    traj = simulate(system, lambda rng: boost_switching(rng, t_end=t_end), t,
                    x0=np.array([0.0, 100.0]), u=u, trials=TRIALS, rng=1)
    np.savez(path, y=traj.y, mode=traj.mode, t=t, u=u)


def _children_cpu() -> tuple[float, float]:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime, usage.ru_stime


def timed_child(argv: list[str], env: dict[str, str], cwd: Path) -> tuple[float, float, float,
                                                                           str]:
    """User CPU, system CPU and wall seconds of one child process, and its stdout."""
    (user0, sys0), start = _children_cpu(), time.perf_counter()
    done = subprocess.run([sys.executable, *argv], check=True, cwd=cwd, env=env,
                          stdout=subprocess.PIPE, text=True)
    wall = time.perf_counter() - start
    user1, sys1 = _children_cpu()
    return user1 - user0, sys1 - sys0, wall, done.stdout


def run(*, quick: bool = False) -> list[Section]:
    """Time A and B in interleaved rounds; one section with the table."""
    rounds = QUICK_ROUNDS if quick else ROUNDS
    env = {**os.environ, **SINGLE_THREADED}
    user = {name: [] for name in LABELS}
    system = {name: [] for name in LABELS}
    wall = {name: [] for name in LABELS}
    imported = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        write_data(tmp / "data.npz")
        (tmp / "filters.py").write_text(FILTERS)
        argvs = {"floor": FLOOR, "filters": [str(tmp / "filters.py"), str(tmp / "data.npz")]}
        for argv in argvs.values():  # untimed: bytecode caches, page cache
            timed_child(argv, env, tmp)
        load_before = os.getloadavg()[0]
        for _ in range(rounds):
            for name, argv in argvs.items():
                u, s, w, out = timed_child(argv, env, tmp)
                user[name].append(u)
                system[name].append(s)
                wall[name].append(w)
                if name == "filters":
                    imported.append(json.loads(out.strip().splitlines()[-1]))
        load_after = os.getloadavg()[0]
    cpu = {name: [u + s for u, s in zip(user[name], system[name])] for name in LABELS}
    med = {name: statistics.median(cpu[name]) for name in LABELS}
    rows = [(LABELS[name], f"{med[name]:.3f} s", f"{min(cpu[name]):.3f} s",
             f"{statistics.median(user[name]):.3f} s", f"{statistics.median(system[name]):.3f} s",
             f"{statistics.median(wall[name]):.3f} s", f"{med[name] / med['floor']:.2f}")
            for name in LABELS]
    table = markdown_table(["child process", "median CPU (user + sys)", "min CPU", "median user",
                            "median sys", "median wall", "median CPU / A's"], rows)
    ratio = med["filters"] / med["floor"]
    paired = statistics.median(b / a for a, b in zip(cpu["floor"], cpu["filters"]))
    ok_ratio = "meets" if max(ratio, paired) <= TARGET_RATIO else "does NOT meet"
    ok_cpu = "meets" if med["filters"] <= FEW_CPU_SECONDS else "does NOT meet"
    loaded = {name: sum(d[name] for d in imported) for name in ("numba", "llvmlite")}
    none_loaded = not any(loaded.values())
    notes = (
        (f"B / A = **{ratio:.2f}x** (ratio of the medians), {paired:.2f}x (median of the "
         f"{rounds} per-round ratios) — {ok_ratio} the issue's target of at most "
         f"{TARGET_RATIO:.0f}x."),
        (f"B uses {med['filters']:.2f} CPU-s (median) in all — {ok_cpu} 'at most a few "
         f"CPU-seconds' (read as {FEW_CPU_SECONDS:.0f})."),
        ("numba and llvmlite in B's `sys.modules`: "
         + ("**neither**, in every round" if none_loaded else
            f"**numba in {loaded['numba']}, llvmlite in {loaded['llvmlite']} of {rounds} "
            "rounds**") + "."),
        (f"{rounds} interleaved rounds (A, B, A, B, ...) after an untimed one; child CPU from "
         "`resource.getrusage(RUSAGE_CHILDREN)` deltas; both children with SWITCHEST_THREADS, "
         "OPENBLAS_NUM_THREADS, OMP_NUM_THREADS, MKL_NUM_THREADS = 1; 1-minute load "
         f"{load_before:.2f} -> {load_after:.2f}; B's data simulated beforehand by the parent."),
    )
    return [Section("Start-up: a new process that filters, against `import numpy, scipy.linalg`",
                    table, notes)]


if __name__ == "__main__":
    print_sections(run(quick=quick_flag(__doc__.splitlines()[0])))
