"""Speed of the exact batched simulator on the vehicle of Shankar et al. §V.B.

Two workloads, both T = 0.5 s, u = 1, 1 000 samples (t = 0 .. 499.5 s), initial
state drawn from N(0, I):

* **fixed schedule, 10 000 trials** — the paper's maneuver (mode 0 until 1.65 s,
  mode 1 until 2.75 s, mode 2 until 3.9 s, then mode 0; Figs 3-4) repeated every
  10 s over the horizon. One signal shared by all trials: its switches fall
  strictly inside sample intervals, so every trial takes an exact two-segment
  transition at each of them.
* **random dwell times, 1 000 trials** — each trial its own signal, dwell times
  uniform in [1, 3] s, the next mode uniform among the others
  (:func:`switchest.signals.dwell_time`); the time to draw the signals alone is
  reported beside the whole simulation.

Run: ``python benchmarks/bench_simulate.py [--quick]`` (``--quick``: a twentieth of the
trials).
"""

from __future__ import annotations

import numpy as np
from harness import (
    Section,
    best_time,
    format_seconds,
    markdown_table,
    print_sections,
    quick_flag,
    single_threaded,
)

from switchest.models import vehicle_2d, vehicle_maneuver
from switchest.signals import SwitchingSignal, dwell_time, periodic, schedule
from switchest.simulate import simulate

T = 0.5
SAMPLES = 1000
FIXED_TRIALS = 10_000
RANDOM_TRIALS = 1000
MIN_DWELL, MAX_DWELL = 1.0, 3.0
SEED = 20240605
PERIOD = 10.0  # the maneuver's horizon in the paper


def repeated_maneuver(t_end: float) -> SwitchingSignal:
    """The paper's maneuver, repeated every :data:`PERIOD` seconds up to ``t_end``."""
    one = vehicle_maneuver(T=T, t_end=PERIOD).signal  # switches at 1.65, 2.75, 3.9 s
    reps = int(np.ceil(t_end / PERIOD))
    times = np.concatenate([one.times + PERIOD * r for r in range(reps)])
    modes = np.concatenate([one.modes[:1]] + [one.modes[1:]] * reps)
    keep = times < t_end
    return schedule(times[keep], modes[: keep.sum() + 1])


def _row(label: str, trials: int, samples: int, timing, switches: float) -> tuple:
    per = timing.best / (trials * samples)
    return (label, f"{trials} x {samples}", f"{switches:.1f}", format_seconds(timing.best),
            format_seconds(per), f"{1e-6 / per:.2f}", timing.repeats)


def run(*, quick: bool = False) -> list[Section]:
    """Time both workloads; one section with one row per measurement."""
    system = vehicle_2d(measurement_variance=0.05, process_noise=1e-3)
    fixed_trials = FIXED_TRIALS // 20 if quick else FIXED_TRIALS
    random_trials = RANDOM_TRIALS // 20 if quick else RANDOM_TRIALS
    t = periodic(T, T * (SAMPLES - 1))
    t_end = float(t[-1]) + T
    x0 = (np.zeros(4), np.eye(4))
    u = np.ones(1)

    signal = repeated_maneuver(t_end)
    fixed = best_time(lambda: simulate(system, signal, t, x0, u, trials=fixed_trials, rng=SEED),
                      repeat=3, budget=20.0)
    traj = fixed.result
    out_bytes = sum(a.nbytes for a in (traj.x, traj.y, traj.u, traj.mode))
    del traj

    def draw(rng):
        return dwell_time(system.n_modes, t_end, MIN_DWELL, MAX_DWELL, rng=rng)

    randoms = best_time(lambda: simulate(system, draw, t, x0, u, trials=random_trials, rng=SEED),
                        repeat=3, budget=20.0)
    mean_switches = float(np.mean([s.n_switches for s in randoms.result.signals]))
    children = np.random.default_rng(SEED).spawn(random_trials)
    signals_only = best_time(lambda: [draw(c) for c in children], repeat=3, budget=10.0)

    rows = [
        _row("fixed maneuver schedule (shared signal)", fixed_trials, SAMPLES, fixed,
             signal.n_switches),
        _row("random dwell-time signal per trial (whole simulate)", random_trials, SAMPLES, randoms,
             mean_switches),
        (f"... of which drawing the {random_trials} signals", "", "",
         format_seconds(signals_only.best), "", "", signals_only.repeats),
    ]
    table = markdown_table(["workload", "trials x samples", "switches per trial",
                            "wall time (best)", "per trial-sample", "M trial-samples / s",
                            "runs timed"], rows)
    notes = (
        f"output arrays of the fixed-schedule run (x, y, u, mode): {out_bytes / 2**20:.0f} MiB.",
        ("every switch falls inside a sample interval: those intervals use exact two-segment "
         "transitions composed from the dyadic table (switchest.dyadic), the others the cached "
         "per-mode step."),
    )
    return [Section(f"Simulation: vehicle, T = {T} s, {SAMPLES} samples", table, notes)]


def main(argv=None) -> None:
    quick = quick_flag(__doc__.splitlines()[0], argv)
    with single_threaded() as blas:
        print(f"BLAS and engine at one thread: {blas['single_threaded']}")
        print_sections(run(quick=quick))


if __name__ == "__main__":
    main()
