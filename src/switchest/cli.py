"""The ``switchest`` command line."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from . import __version__
from .estimators import IMMFilter, ModeKalmanFilter, SwitchTimeKalmanFilter
from .certify import certify
from .experiments import Store, get, names, run_experiment, write_report
from .experiments.report import AGREE
from .modelfile import load_model
from .plotting import curves
from .tabular import METHODS, estimate_table
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


def _summary_table(summary) -> Table:
    """Paper vs measured values of one experiment, with their ratio; row notes as a caption."""
    table = Table(title=summary.title, title_justify="left", caption_justify="left")
    table.add_column("quantity", overflow="fold")
    for col in ("paper", "ours", "ours/paper", "unit"):
        table.add_column(col, justify="right", no_wrap=True)
    notes = []
    for row in summary.rows:
        ratio = row.ratio
        style = "" if ratio is None else ("green" if abs(ratio - 1) <= AGREE else "red")
        fmt = (lambda v: "—" if v is None else (v if isinstance(v, str) else f"{v:.4g}"))
        table.add_row(row.quantity, fmt(row.paper), fmt(row.measured),
                      "—" if ratio is None else f"[{style}]{ratio:.3f}[/{style}]", row.unit)
        if row.note:
            notes.append(f"{row.quantity}: {row.note}")
    table.caption = "\n".join(notes) or None
    return table


def _run(names: list[str], args, console: Console) -> Path:
    """Run (or resume) each named experiment into the store; print its summary; return the store path."""
    out = Path(args.out)
    store = Store(Path(args.store) if args.store else out / "results.sqlite")
    for name in names:
        experiment = get(name)
        overrides = {"trials": args.trials} if getattr(args, "trials", None) else {}
        params = experiment.params(quick=args.quick, **overrides)
        with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                      TimeElapsedColumn(), console=console, transient=True) as progress:
            bar = progress.add_task(name, total=None)
            start = time.perf_counter()
            results = run_experiment(
                experiment, params, store=store, seed=args.seed, workers=args.workers,
                scheduler=args.scheduler,
                on_done=lambda done, total: progress.update(bar, completed=done, total=total),
            )
        summary = experiment.summarize(params, results, out / "figures")
        console.print(_summary_table(summary))
        console.print(f"[dim]{name}: {len(results)} tasks, {time.perf_counter() - start:.1f} s[/dim]\n")
    return store.path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="switchest", description="Estimation in switched linear systems.")
    parser.add_argument("--version", action="version", version=f"switchest {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p_demo = sub.add_parser("demo", help="simulate the boost converter and compare filters")
    p_demo.add_argument("--trials", type=int, default=20)
    p_demo.add_argument("--duration", type=float, default=0.1, help="seconds of operation")
    p_demo.add_argument("--seed", type=int, default=0)

    sub.add_parser("list", help="list the registered paper reproductions")

    def runner_options(p):
        p.add_argument("--quick", action="store_true", help="fewer trials, shorter runs (minutes, not hours)")
        p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                       help="local worker processes (default: the machine's cores)")
        p.add_argument("--scheduler", default=None, help="address of a Dask scheduler to run the tasks on")
        p.add_argument("--seed", type=int, default=0)
        p.add_argument("--out", default="out", help="output folder (figures, report, default store)")
        p.add_argument("--store", default=None, help="results store (default OUT/results.sqlite)")

    p_run = sub.add_parser("run", help="run (or resume) one reproduction")
    p_run.add_argument("name")
    p_run.add_argument("--trials", type=int, default=None, help="override the number of trials")
    runner_options(p_run)
    p_rep = sub.add_parser("reproduce", help="run several reproductions and write the report")
    p_rep.add_argument("names", nargs="*")
    p_rep.add_argument("--all", action="store_true", help="every registered reproduction")
    runner_options(p_rep)
    p_est = sub.add_parser("estimate", help="estimate states and modes from measured data (CSV)")
    p_est.add_argument("--model", required=True, help="TOML model file")
    p_est.add_argument("--data", required=True,
                       help="CSV with columns t, u..., y... (empty y cells: missing samples) and mode (the known "
                            "mode, needed by kalman, switch-time, rsls, impulsive); for rsls the y columns are the "
                            "integrated output at fine instants t including every switching instant t0 + kT")
    p_est.add_argument("--method", required=True, choices=METHODS,
                       help="kalman, switch-time (known modes); imm, imm-ev1 (modes unknown); min-distance (Lee et "
                            "al., uniform t); rsls (Wang et al., integrated output); impulsive (Etienne et al.)")
    p_est.add_argument("--grid", type=int, default=5, help="switching-time grid points per interval")
    p_est.add_argument("--refine", action="store_true", help="refine the grid maximum (switch-time)")
    p_est.add_argument("--stay", type=float, default=None, help="per-sample probability of staying in a mode")
    p_est.add_argument("--v-max", type=float, default=None,
                       help="min-distance: noise bound |v| <= v_max (default: the model's noise.v_max)")
    p_est.add_argument("--delta", type=float, default=None,
                       help="min-distance: estimation window delta, a multiple of the time step (default: "
                            "noise.delta)")
    p_est.add_argument("--Delta", type=float, default=None,
                       help="min-distance: detection delay Delta (default: noise.Delta)")
    p_est.add_argument("--switch-interval", type=float, default=None,
                       help="rsls: switching interval T, modes change only at t0 + kT (default: sampling.period)")
    p_est.add_argument("--out", required=True, help="CSV of the estimates")
    p_est.add_argument("--plot", default=None, help="PNG figure of the estimates")
    p_check = sub.add_parser("check", help="certify what switchest can about a model file")
    p_check.add_argument("--model", required=True, help="TOML model file")
    p_report = sub.add_parser("report", help="write the HTML report of a results store")
    p_report.add_argument("--store", required=True)
    p_report.add_argument("--out", default="out")

    args = parser.parse_args(argv)
    console = Console()
    if args.command == "demo":
        if args.trials < 1 or args.duration <= 0:
            parser.error("--trials must be >= 1 and --duration > 0")
        console.print(demo(args.trials, args.duration, args.seed, console))
    elif args.command == "list":
        table = Table(title="switchest reproductions")
        for col in ("name", "paper", "what"):
            table.add_column(col)
        for name in names():
            e = get(name)
            table.add_row(name, e.paper, e.title)
        console.print(table)
    elif args.command in ("run", "reproduce"):
        if args.workers < 1:
            parser.error("--workers must be >= 1")
        chosen = [args.name] if args.command == "run" else (names() if args.all else args.names)
        if not chosen:
            parser.error("name the reproductions to run, or pass --all")
        unknown = [n for n in chosen if n not in names()]
        if unknown:
            parser.error(f"unknown reproduction(s) {unknown}; see 'switchest list'")
        store_path = _run(chosen, args, console)
        if args.command == "reproduce":
            report = write_report(Store(store_path), args.out, chosen)
            console.print(f"report: [bold]{report}[/bold]  (results store: {store_path})")
    elif args.command == "estimate":
        try:
            spec = load_model(args.model)
            table = estimate_table(spec, args.data, method=args.method, grid=args.grid, refine=args.refine,
                                   stay=args.stay, v_max=args.v_max, delta=args.delta, Delta=args.Delta,
                                   switch_interval=args.switch_interval)
        except (ValueError, OSError) as exc:
            console.print(f"[red]error:[/red] {escape(str(exc))}")  # messages name [tables] of the model file
            return 2
        table.to_csv(args.out, index=False)
        console.print(f"{len(table)} samples estimated with {args.method}: [bold]{args.out}[/bold]")
        if args.plot:
            states = table.filter(regex=r"^x\d+$").to_numpy()  # NaN rows (no estimate) leave gaps
            switches = table["switch_time"].dropna().to_numpy() if "switch_time" in table else ()
            curves(args.plot, table["t"].to_numpy(), {args.method: states}, xlabel="t",
                   ylabel=[f"x{i}" for i in range(states.shape[1])], markers=switches,
                   title=f"{args.model}: {args.method}" + ("; dotted: estimated switches" if len(switches) else ""))
            console.print(f"figure: {args.plot}")
    elif args.command == "check":
        try:
            spec = load_model(args.model)
        except (ValueError, OSError) as exc:
            console.print(f"[red]error:[/red] {escape(str(exc))}")
            return 2
        table = Table(title=f"switchest check: {args.model}", title_justify="left")
        for col in ("condition", "verdict", "margin", "paper", "detail"):
            table.add_column(col, overflow="fold")
        marks = {True: "[green]holds[/green]", False: "[red]fails[/red]", None: "[yellow]n/a[/yellow]"}
        for c in certify(spec):
            table.add_row(c.name, marks[c.verdict], "—" if c.margin is None else f"{c.margin:.3g}", c.paper,
                          c.detail)
        console.print(table)
    elif args.command == "report":
        if not Path(args.store).exists():
            parser.error(f"--store {args.store} does not exist")
        console.print(f"report: [bold]{write_report(Store(args.store), args.out)}[/bold]")
    return 0


if __name__ == "__main__":
    sys.exit(main())
