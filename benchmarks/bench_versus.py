"""The same workloads under this checkout and under a reference installation of switchest.

For a change of engine (the numba kernels before, the C engine now) the question is how each
public estimator's cost moved. Both installations run the same code here, the public API being
the same: each workload (:data:`WORKLOADS`) runs in a child process of either installation —
**this** one (this interpreter, with the source tree it imports switchest from first on the
path) and the **reference** (``--reference PYTHON``, with ``--reference-path SRC`` first on its
path, e.g. the numba engine's last commit checked out in a worktree) — interleaved A B A B by
subprocess for the rounds. Each child (:mod:`versus_workloads`) reads the same data, simulated
once here, calls its workload once untimed (numba's load or compile in an installation that
has numba kernels is excluded so) and times only the calls after it, by CPU time
(``time.process_time``), repeating them for at least 0.2 CPU-s. Both children run with the
engine at one thread (``SWITCHEST_THREADS=1``; numba ignores it) and BLAS at one thread
(``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS``, ``MKL_NUM_THREADS`` = 1). A child that imported
switchest from elsewhere than its installation's path stops the benchmark.

Workloads, on the boost converter (:func:`bench_switch_time.boost_data`: process noise 1,
R = 5 V^2, 0.5 ms sampling, 100 V, Table I's switching, prior N([0, 100], 25 I); modes given
where the method takes them; IMM, GPB2 and the RBPF with the transition matrix 0.6 / 0.4):
``ModeKalmanFilter.run`` and ``IMMFilter.run`` at 10 x 200 and 1 000 x 200 (L = 2),
``GPB2Filter.run`` 1 000 x 200, ``SwitchTimeKalmanFilter`` grid and refine at g = 1, 3, 5 on
20 x 2 000 (as ``bench_switch_time.py``), ``IMMEV1Filter.run`` (g = 5) on the same,
``RBPFilter.run`` 100 x 200 with 200 particles (seeded: the same random streams); and
``IMMFilter.smooth`` 1 000 x 200 on the vehicle of ``bench_imm.py`` (L = 3: on the converter
Kim's smoother warns that it diverged, a mode leaving a contracting direction unobserved). Reported
per workload: the median (and min) CPU seconds per call of each installation, the ratio this /
reference of the medians and of the mins, each one's median warm-up CPU (the first call: the
reference's compile or cache load shows there), and the largest difference of the estimates
(x, and P where there is one) relative to the largest value.

Run: ``python benchmarks/bench_versus.py --reference PYTHON --reference-path SRC [--quick]
[--rounds N] [--workloads NAME,...]`` (``--quick``: 100 trials instead of 1 000, 4 x 100 for
the switching-time workloads, 10 x 200 x 50 particles for the RBPF, 2 rounds; ``--list``
names the workloads). ``run_all.py`` runs it when given ``--reference`` and
``--reference-path``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from bench_imm import vehicle_data
from bench_switch_time import P0 as BOOST_P0
from bench_switch_time import X0 as BOOST_X0
from bench_switch_time import boost_data
from harness import Section, format_seconds, markdown_table, print_sections

import switchest

HERE = Path(__file__).resolve().parent
CHILD = HERE / "versus_workloads.py"
ROUNDS = 5
QUICK_ROUNDS = 2
ENV = {name: "1" for name in ("SWITCHEST_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                              "MKL_NUM_THREADS")}


@dataclass(frozen=True)
class Workload:
    """One workload: the estimator ``kind``, its data set, trials and settings."""

    key: str
    kind: str
    dataset: str  # a key of SIZES
    trials: int
    quick_trials: int
    grid: int = 0
    particles: int = 0
    quick_particles: int = 0

    def label(self, quick: bool, samples: int) -> str:
        names = {"kalman": "ModeKalmanFilter.run", "imm": "IMMFilter.run",
                 "gpb2": "GPB2Filter.run", "grid": "SwitchTimeKalmanFilter grid",
                 "refine": "SwitchTimeKalmanFilter refine", "imm-ev1": "IMMEV1Filter.run",
                 "imm-smooth": "IMMFilter.smooth", "rbpf": "RBPFilter.run"}
        text = f"{names[self.kind]} {self.trials_for(quick)} x {samples}"
        if self.grid:
            text += f", g = {self.grid}"
        if self.particles:
            text += f" x {self.quick_particles if quick else self.particles} particles"
        return text

    def trials_for(self, quick: bool) -> int:
        return self.quick_trials if quick else self.trials


WORKLOADS = [
    Workload("kalman-10", "kalman", "short", 10, 10),
    Workload("kalman-1000", "kalman", "short", 1_000, 100),
    Workload("imm-10", "imm", "short", 10, 10),
    Workload("imm-1000", "imm", "short", 1_000, 100),
    Workload("gpb2-1000", "gpb2", "short", 1_000, 100),
    *(Workload(f"{kind}-g{g}", kind, "long", 20, 4, grid=g)
      for kind in ("grid", "refine") for g in (1, 3, 5)),
    Workload("imm-ev1-g5", "imm-ev1", "long", 20, 4, grid=5),
    Workload("imm-smooth-1000", "imm-smooth", "vehicle", 1_000, 100),
    Workload("rbpf-100", "rbpf", "short", 100, 10, particles=200, quick_particles=50),
]
SIZES = {  # data set: (trials, samples) in full and with --quick
    "short": ((1_000, 200), (100, 200)),  # boost converter
    "long": ((20, 2_000), (4, 100)),  # boost converter, as bench_switch_time.py
    "vehicle": ((1_000, 200), (100, 200)),  # as bench_imm.py
}
BOOST_TRANSITION = np.array([[0.6, 0.4], [0.4, 0.6]])  # a switch about every 2.4 samples


@dataclass(frozen=True)
class Installation:
    """A python interpreter and the directory put first on its path."""

    name: str
    python: str
    path: Path

    def env(self) -> dict[str, str]:
        return {**os.environ, **ENV, "PYTHONPATH": str(self.path)}


def this_installation() -> Installation:
    """This interpreter and the directory it imports switchest from."""
    return Installation("this", sys.executable, Path(switchest.__file__).resolve().parents[1])


def write_data(directory: Path, quick: bool) -> dict[str, Path]:
    """Simulate each data set once (with this checkout); the ``.npz`` files the children read."""
    paths = {}
    for dataset, (full, small) in SIZES.items():
        trials, samples = small if quick else full
        if dataset == "vehicle":
            _, transition, x0, P0, traj = vehicle_data(trials, samples)
            t, u, system = traj.t, np.ones(1), "vehicle"
        else:
            _, t, u, traj = boost_data(trials, samples)
            transition, x0, P0, system = BOOST_TRANSITION, BOOST_X0, BOOST_P0, "boost"
        paths[dataset] = directory / f"{dataset}.npz"
        np.savez(paths[dataset], y=traj.y, mode=traj.mode, t=t, u=u, x0=x0, P0=P0,
                 transition=transition, system=system)
    return paths


def run_child(inst: Installation, spec: dict) -> dict:
    """One child process of ``inst`` on ``spec``; its report, checked to come from ``inst``."""
    done = subprocess.run([inst.python, str(CHILD), json.dumps(spec)], env=inst.env(),
                          cwd=CHILD.parent, stdout=subprocess.PIPE, text=True, check=True)
    report = json.loads(done.stdout.strip().splitlines()[-1])
    where = Path(report["switchest"]).resolve()
    if not where.is_relative_to(inst.path.resolve()):
        raise RuntimeError(f"the {inst.name} child imported switchest from {where}, not from "
                           f"{inst.path}")
    return report


def relative_difference(a: Path, b: Path) -> float:
    """Largest |this - reference| over x and P, relative to the largest |reference| value."""
    worst = 0.0
    with np.load(a) as this, np.load(b) as ref:
        for key in ref.files:
            if key in this.files:
                scale = max(float(np.abs(ref[key]).max()), np.finfo(float).tiny)
                worst = max(worst, float(np.abs(this[key] - ref[key]).max()) / scale)
    return worst


def run(*, quick: bool = False, reference: str | None = None,
        reference_path: str | Path | None = None, rounds: int | None = None,
        workloads: list[str] | None = None) -> list[Section]:
    """Every workload, this checkout and the reference interleaved; one table."""
    if reference is None or reference_path is None:
        raise ValueError("bench_versus needs a reference: --reference PYTHON "
                         "--reference-path SRC")
    rounds = rounds or (QUICK_ROUNDS if quick else ROUNDS)
    chosen = [w for w in WORKLOADS if workloads is None or w.key in workloads]
    unknown = set(workloads or ()) - {w.key for w in WORKLOADS}
    if unknown:
        raise ValueError(f"unknown workloads {sorted(unknown)}; known: "
                         f"{', '.join(w.key for w in WORKLOADS)}")
    sides = (this_installation(), Installation("reference", reference, Path(reference_path)))
    rows, origins = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        data = write_data(tmp, quick)
        for w in chosen:
            cpu = {s.name: [] for s in sides}
            warm = {s.name: [] for s in sides}
            saved = {s.name: tmp / f"{w.key}-{s.name}.npz" for s in sides}
            load_before = os.getloadavg()[0]
            for r in range(rounds):
                for side in sides:
                    spec = {"kind": w.kind, "data": str(data[w.dataset]),
                            "trials": w.trials_for(quick), "grid": w.grid,
                            "particles": w.quick_particles if quick else w.particles,
                            "save": str(saved[side.name]) if r == 0 else None}
                    print(f"bench_versus: {w.key}, round {r + 1}/{rounds}, {side.name}",
                          file=sys.stderr, flush=True)
                    report = run_child(side, spec)
                    cpu[side.name].append(report["cpu"])
                    warm[side.name].append(report["warmup_cpu"])
                    origins[side.name] = (Path(report["switchest"]).parent,
                                          report["numba_loaded"])
            load_after = os.getloadavg()[0]
            med = {k: statistics.median(v) for k, v in cpu.items()}
            low = {k: min(v) for k, v in cpu.items()}
            samples = SIZES[w.dataset][1 if quick else 0][1]
            rows.append([w.label(quick, samples), format_seconds(med["this"]),
                         format_seconds(med["reference"]),
                         f"**{med['this'] / med['reference']:.3g}**",
                         f"{low['this'] / low['reference']:.3g}",
                         format_seconds(statistics.median(warm["this"])),
                         format_seconds(statistics.median(warm["reference"])),
                         f"{relative_difference(saved['this'], saved['reference']):.1e}",
                         rounds, f"{load_before:.2f} -> {load_after:.2f}"])
    table = markdown_table(["workload", "this: median CPU per call", "reference: median",
                            "this / reference (medians)", "(mins)", "this: warm-up CPU",
                            "reference: warm-up CPU", "max |difference| / max |value|",
                            "rounds", "load (1 min)"], rows)
    notes = [
        *(f"{name}: switchest from `{where}` ({sys.executable if name == 'this' else reference}"
          f"), numba {'imported' if numba else 'not imported'} by the workload"
          for name, (where, numba) in origins.items()),
        (f"{rounds} interleaved rounds per workload (this, reference, this, ...), each a child "
         "process that times only its workload after an untimed warm-up call: CPU time per "
         "call, calls repeated for at least 0.2 CPU-s; SWITCHEST_THREADS and BLAS threads = 1 "
         "in both."),
        ("warm-up CPU: the first call in each child (median over the rounds), untimed in the "
         "ratios; an installation with numba kernels loads them from its on-disk cache there, "
         "or compiles them if its cache is cold (then in the first round)."),
        ("difference: the largest |x_this - x_reference| and |P_this - P_reference| over every "
         "trial and sample, relative to the largest |value| of the reference (same data, same "
         "seed)."),
    ]
    size = "--quick sizes" if quick else "full size"
    return [Section(f"This checkout against the reference installation ({size})", table,
                    tuple(notes))]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference", help="the reference installation's python interpreter")
    parser.add_argument("--reference-path", type=Path,
                        help="a directory put first on the reference's path (its src/)")
    parser.add_argument("--quick", action="store_true", help="smaller sizes, for a smoke run")
    parser.add_argument("--rounds", type=int, help="interleaved rounds per workload")
    parser.add_argument("--workloads", help="comma-separated workload names (default: all)")
    parser.add_argument("--list", action="store_true", help="name the workloads and stop")
    args = parser.parse_args(argv)
    if args.list:
        for w in WORKLOADS:
            print(f"{w.key}: {w.label(False, SIZES[w.dataset][0][1])}")
        return
    if args.reference is None or args.reference_path is None:
        parser.error("--reference and --reference-path are required")
    print_sections(run(quick=args.quick, reference=args.reference,
                       reference_path=args.reference_path, rounds=args.rounds,
                       workloads=args.workloads.split(",") if args.workloads else None))


if __name__ == "__main__":
    main()
