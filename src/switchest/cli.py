"""The ``switchest`` command line."""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from rich.console import Console
from rich.table import Table

from . import __version__
from .estimators import IMMFilter, ModeKalmanFilter, SwitchTimeKalmanFilter
from .metrics import mode_accuracy, rmse, switch_time_error
from .models import BOOST_INPUT_VOLTAGE, BOOST_SAMPLE_PERIOD, boost_converter, boost_switching
from .signals import periodic
from .simulate import simulate


def demo(trials: int, duration: float, seed: int, console: Console) -> Table:
    """Simulate the boost converter of Shankar et al. §V.A and compare four filters."""
    system = boost_converter()
    t = periodic(BOOST_SAMPLE_PERIOD, duration)
    u = np.array([BOOST_INPUT_VOLTAGE])
    x0, P0 = np.array([0.0, 100.0]), np.diag([100.0, 100.0])
    t_start = time.perf_counter()
    traj = simulate(system, lambda rng: boost_switching(rng, t_end=duration), t, x0, u=u,
                    trials=trials, rng=seed)
    console.print(
        f"simulated {trials} trials x {t.size} samples of the boost converter "
        f"(T = {BOOST_SAMPLE_PERIOD * 1e3:g} ms, switches every 1.2 ms, then random in "
        f"[0.9, 1.2] ms from 0.02 s) in {time.perf_counter() - t_start:.2f} s"
    )
    filters = {
        "clairvoyant (true switch times)": lambda: ModeKalmanFilter(system, x0, P0).run(
            traj.y, u, t, modes=traj.mode, segments=traj.segments()),
        "switch-time KF, g = 1": lambda: SwitchTimeKalmanFilter(system, x0, P0, grid=1).run(
            traj.y, u, t, modes=traj.mode),
        "switch-time KF, g = 5": lambda: SwitchTimeKalmanFilter(system, x0, P0, grid=5).run(
            traj.y, u, t, modes=traj.mode),
        "IMM (modes unknown)": lambda: IMMFilter(system, [[0.5, 0.5], [0.5, 0.5]], x0, P0).run(traj.y, u, t),
    }
    table = Table(title="Boost converter: RMSE after the first 10 samples")
    table.add_column("filter", no_wrap=True)
    for col in ("RMSE i_L (A)", "RMSE v_0 (V)", "mode accuracy", "switch-time error (ms)", "time (s)"):
        table.add_column(col, justify="right")
    true_switch = traj.switch_times()
    for name, run in filters.items():
        t_start = time.perf_counter()
        est = run()
        elapsed = time.perf_counter() - t_start
        r = rmse(est.x, traj.x, start=10).overall
        acc = "-" if est.mode is None else f"{mode_accuracy(est.mode, traj.mode, start=10):.3f}"
        err = "-" if est.switch_time is None else f"{1e3 * switch_time_error(est.switch_time, true_switch).mean():.3f}"
        table.add_row(name, f"{r[0]:.3f}", f"{r[1]:.3f}", acc, err, f"{elapsed:.2f}")
    return table


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="switchest", description="Estimation in switched linear systems.")
    parser.add_argument("--version", action="version", version=f"switchest {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p_demo = sub.add_parser("demo", help="simulate the boost converter and compare filters")
    p_demo.add_argument("--trials", type=int, default=20)
    p_demo.add_argument("--duration", type=float, default=0.1, help="seconds of operation")
    p_demo.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    console = Console()
    if args.command == "demo":
        if args.trials < 1 or args.duration <= 0:
            parser.error("--trials must be >= 1 and --duration > 0")
        console.print(demo(args.trials, args.duration, args.seed, console))
    return 0


if __name__ == "__main__":
    sys.exit(main())
