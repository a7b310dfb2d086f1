"""How the cost of IMMEV1Filter.run scales with steps K, trials N, grid g and modes L.

Shankar et al. Algorithm 1 evaluates, at every sample, every (predecessor,
destination) mode pair at every one of the g grid switching times for every
trial: ``N L^2 g`` predictions and innovation likelihoods, then ``N L``
updates. The vehicle of §V.B (:func:`switchest.models.vehicle_2d`, T = 0.5 s,
u = 1) is measured with its three modes and with 2- and 5-mode variants: the
first two modes only, or two more modes whose inputs push along and against the
diagonal (``B = [0, 1, 0, 1]'`` and ``[0, -1, 0, -1]'``). Data: asynchronous
switches with dwell times uniform in [1, 3] s (several samples apart, switches
strictly inside intervals).

One parameter varies at a time around the base point N = 100, K = 100, g = 5,
L = 3 (the K sweep at N = 100); the sizes keep the whole script well under three
minutes on two shared cores. The "slope" column is the log-log slope of the run
time against the row above (1 = linear). For scale, the g sweep also times
:class:`switchest.estimators.IMMFilter` (transition 0.9 / 0.05) on the same data.

Run: ``python benchmarks/bench_imm_ev1.py [--quick]``.
"""

from __future__ import annotations

import math

import numpy as np
from bench_imm import transition_matrix
from harness import (
    Section,
    best_time,
    format_seconds,
    markdown_table,
    print_sections,
    quick_flag,
    single_threaded,
)

from switchest.discretize import pairwise_grid
from switchest.estimators import IMMEV1Filter, IMMFilter
from switchest.models import vehicle_2d
from switchest.signals import dwell_time
from switchest.simulate import simulate
from switchest.system import SwitchedLinearSystem

T = 0.5
SEED = 20240604
EXTRA_INPUTS = np.array([[0.0, 1.0, 0.0, 1.0], [0.0, -1.0, 0.0, -1.0]])
MIN_DWELL, MAX_DWELL = 1.0, 3.0

# (swept parameter, values, fixed values of the others)
SWEEPS = {
    "default": [
        ("K", (100, 200, 400), {"N": 100, "g": 5, "L": 3}),
        ("N", (50, 100, 200, 500), {"K": 100, "g": 5, "L": 3}),
        ("g", (1, 2, 5, 10), {"N": 100, "K": 100, "L": 3}),
        ("L", (2, 3, 5), {"N": 100, "K": 100, "g": 5}),
    ],
    "quick": [
        ("K", (10, 20, 40), {"N": 20, "g": 5, "L": 3}),
        ("N", (50, 100, 200, 500), {"K": 5, "g": 5, "L": 3}),
        ("g", (1, 2, 5, 10), {"N": 50, "K": 5, "L": 3}),
        ("L", (2, 3, 5), {"N": 50, "K": 5, "g": 5}),
    ],
}


def vehicle_variant(L: int) -> SwitchedLinearSystem:
    """The vehicle with its first ``L`` modes; modes 3 and 4 add the :data:`EXTRA_INPUTS`."""
    base = vehicle_2d(measurement_variance=0.05, process_noise=1e-3)
    inputs = np.concatenate([base.B[:, :, 0], EXTRA_INPUTS])
    if not 2 <= L <= inputs.shape[0]:
        raise ValueError(f"L must be in 2..{inputs.shape[0]}, got {L}")
    return SwitchedLinearSystem.continuous(A=base.A[0], B=inputs[:L, :, None], C=base.C[0],
                                           Q=base.Q[0], R=base.R[0])


def simulated(system: SwitchedLinearSystem, trials: int, steps: int):
    """A batch of trajectories with per-trial random dwell-time switching."""
    t = T * np.arange(steps)
    t_end = float(t[-1]) + T
    L = system.n_modes
    return simulate(
        system,
        lambda rng: dwell_time(L, t_end, MIN_DWELL, MAX_DWELL, rng=rng),
        t,
        (np.zeros(4), np.eye(4)),
        np.ones(1),
        trials=trials,
        rng=SEED,
    )


def sweep(name: str, values, fixed: dict, systems: dict, data: dict) -> Section:
    """Time ``IMMEV1Filter.run`` for each value of one parameter; one table."""
    rows = []
    previous = None
    for value in values:
        cfg = {**fixed, name: value}
        N, K, g, L = cfg["N"], cfg["K"], cfg["g"], cfg["L"]
        system, traj = systems[L], data[L]
        y, u, t = traj.y[:N, :K], traj.u[:N, :K], traj.t[:K]
        filt = IMMEV1Filter(system, x0=np.zeros(4), P0=np.eye(4), grid=g, epsilon=1e-9)
        pairwise_grid(system, T, g)  # warm the discretization cache: time the filter, not expm
        timing = best_time(lambda filt=filt, y=y, u=u, t=t: filt.run(y, u, t), repeat=3, budget=3.0)
        hypotheses = N * L * L * g
        slope = "" if previous is None else (
            f"{math.log(timing.best / previous[1]) / math.log(value / previous[0]):.2f}")
        previous = (value, timing.best)
        rows.append((N, K, g, L, format_seconds(timing.best), format_seconds(timing.best / K),
                     format_seconds(timing.best / (N * K)),
                     format_seconds(timing.best / (hypotheses * K)), slope))
    table = markdown_table(
        ["N", "K", "g", "L", "run (best)", "per step", "per trial-step", "per hypothesis-step",
         f"slope vs {name}"], rows)
    notes = [("a hypothesis-step is one (trial, predecessor, destination, grid point) "
              "prediction + likelihood: N L^2 g of them per step.")]
    if name == "g":
        N, K, L = fixed["N"], fixed["K"], fixed["L"]
        traj = data[L]
        imm = IMMFilter(systems[L], transition_matrix(L), np.zeros(4), np.eye(4))
        ref = best_time(lambda: imm.run(traj.y[:N, :K], traj.u[:N, :K], traj.t[:K]), repeat=3,
                        budget=3.0)
        notes.append(f"for scale: IMMFilter (L = {L}, no switch-time search) on the same "
                     f"{N} x {K} data takes {format_seconds(ref.best)}, "
                     f"{format_seconds(ref.best / (N * K))} per trial-step.")
    fixed_text = ", ".join(f"{k} = {v}" for k, v in fixed.items())
    return Section(f"IMMEV1Filter.run: scaling with {name} ({fixed_text})", table, tuple(notes))


def run(*, quick: bool = False) -> list[Section]:
    """All four sweeps; returns one section per sweep."""
    plan = SWEEPS["quick" if quick else "default"]
    modes = sorted({L for name, vals, fixed in plan
                    for L in (vals if name == "L" else (fixed["L"],))})
    trials = max(max(vals) if name == "N" else fixed["N"] for name, vals, fixed in plan)
    steps = max(max(vals) if name == "K" else fixed["K"] for name, vals, fixed in plan)
    systems = {L: vehicle_variant(L) for L in modes}
    data = {L: simulated(systems[L], trials, steps) for L in modes}
    return [sweep(name, values, fixed, systems, data) for name, values, fixed in plan]


def main(argv=None) -> None:
    quick = quick_flag(__doc__.splitlines()[0], argv)
    with single_threaded() as blas:
        print(f"BLAS and engine at one thread: {blas['single_threaded']}")
        print_sections(run(quick=quick))


if __name__ == "__main__":
    main()
