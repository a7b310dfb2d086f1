"""The ``switchest`` command line.

An error the user can cause (an option value, a model or data file, an output
path, a results store, a scheduler address) is reported as one line on stderr
naming the option or the file and what was expected, with exit code 2. Any other
exception is a bug in switchest: one line says so, exit code 1. With ``--debug``
(before or after the command) the exception propagates with its traceback,
except for errors in the command line itself. Ctrl-C exits with code 130; an
interrupted ``run`` or ``reproduce`` says how many tasks are stored and the
command that resumes it. Long runs show a progress bar with an ETA on a terminal.

The commands import what they use when they run: the experiments, the estimators, pandas and
matplotlib take seconds to import, and ``switchest --help`` needs none of them. The parser takes
the methods of ``estimate`` (names, options, descriptions) from their registry
(:mod:`switchest.estimators.registry`), which imports no estimator.
"""

from __future__ import annotations

import argparse
import math
import os
import shlex
import sys
import textwrap
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from rich.console import Console
from rich.markup import escape

from . import __version__
from ._checks import TIMINGS, closest_name, did_you_mean
from .estimators.registry import methods, methods_with

if TYPE_CHECKING:
    import numpy as np
    from rich.table import Table

    from .certify import Check
    from .experiments import Store
    from .learn import FitResult
    from .modelfile import ModelSpec
    from .system import SwitchedLinearSystem

DEMO_MAX_SAMPLES = 10**6
"""Most trials x samples ``switchest demo`` simulates and filters (about 0.3 GB)."""

_DEMO_BYTES_PER_SAMPLE = 300  # peak memory per trial and sample of the demo: 230-330 B measured


class _UsageError(Exception):
    """An error in the command line itself (an option value, a path): exit code 2."""


class _Interrupted(Exception):
    """A run stopped by Ctrl-C, its tasks so far stored (``run``: the runner's
    ``RunInterrupted``): exit code 130."""

    def __init__(self, run):
        super().__init__(str(run))
        self.run = run


class _HelpFormatter(argparse.HelpFormatter):
    """argparse's help, wrapped at spaces only: a method name (``min-distance``) or a term
    (``pseudo-Bayesian``) is never split at its hyphen."""

    def _split_lines(self, text: str, width: int) -> list[str]:
        return textwrap.wrap(" ".join(text.split()), width, break_on_hyphens=False)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, raised rather than printed with the usage,
    and which suggests the closest name (:func:`~switchest._checks.did_you_mean`) for an
    unknown command, option or choice (``--method kalmann``: did you mean 'kalman'?)."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _HelpFormatter)  # the commands' parsers too
        super().__init__(*args, **kwargs)
        self.commands: dict[str, argparse.ArgumentParser] = {}
        """The parsers of the commands (``switchest run``, ...), set by :func:`_parser`."""

    def error(self, message: str) -> NoReturn:
        raise _UsageError(f"{message} (see '{self.prog} --help')")

    def parse_args(self, args=None, namespace=None):  # noqa: D102 (argparse's)
        args = sys.argv[1:] if args is None else list(args)
        self._check_options(args)
        return super().parse_args(args, namespace)

    def _check_options(self, args: list[str]) -> None:
        """Refuse an unknown ``--option`` of the command line with the closest one, before
        argparse parses it: argparse would first report a required option as missing (the one
        misspelt) or list the unknown one among 'unrecognized arguments' without a hint.
        Unique prefixes (``--meth``) are argparse's abbreviations and pass."""
        parser: argparse.ArgumentParser = self
        for arg in args:
            if arg == "--":
                return
            if not arg.startswith("--"):  # a value (a negative number too), or the command
                if parser is self and arg in self.commands:
                    parser = self.commands[arg]
                continue
            option = arg.partition("=")[0]
            known = [o for action in parser._actions for o in action.option_strings
                     if o.startswith("--")]
            if not any(o.startswith(option) for o in known):
                close = closest_name(option[2:], [o[2:] for o in known])  # names, not dashes
                hint = "" if close is None else f"; did you mean '--{close}'?"
                parser.error(f"unrecognized option {option}{hint}")

    def _check_value(self, action: argparse.Action, value) -> None:
        """argparse's check of a ``choices`` value, with the closest choice suggested."""
        if action.choices is not None and value not in action.choices:
            choices = ", ".join(map(repr, action.choices))
            hint = did_you_mean(value, action.choices, before="; ")
            raise argparse.ArgumentError(
                action, f"invalid choice: {value!r} (choose from {choices}){hint}")


# ---------------------------------------------------------------------- option types (type=)
def _integer(low: int, what: str, high: int | None = None) -> Callable[[str], int]:
    """An int option in ``low..high``; ``what`` says what is expected."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"expected {what}, got {value}")
        return value

    return parse


def _real(what: str, *, high: float = math.inf) -> Callable[[str], float]:
    """A finite float option in ``(0, high]``; ``what`` says what is expected."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not (math.isfinite(value) and 0 < value <= high):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text}")
        return value

    return parse


def _time_window(text: str) -> tuple[float, float]:
    """``--window T0:T1``: two finite times in seconds, ``T0 < T1``."""
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        t0, t1 = (float(v) for v in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected T0:T1, two times in seconds, got {text!r}"
                                         ) from None
    if not (math.isfinite(t0) and math.isfinite(t1) and t0 < t1):
        raise argparse.ArgumentTypeError(f"expected T0:T1 with finite T0 < T1, got {text}")
    return t0, t1


def _existing_file(text: str) -> Path:
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"no such file: {text}")
    if not path.is_file():
        kind = "a folder" if path.is_dir() else "not a regular file"
        raise argparse.ArgumentTypeError(f"expected a file, {text} is {kind}")
    return path


def _workers(text: str) -> int:
    """``--workers``: an int from 1 to the runner's ``MAX_WORKERS``."""
    from .experiments.runner import MAX_WORKERS

    return _integer(1, f"an integer from 1 to {MAX_WORKERS}", MAX_WORKERS)(text)


_positive = _integer(1, "a positive integer")
_seed = _integer(0, "a non-negative integer")
_duration = _real("a finite positive number of seconds")
_window = _real("a finite positive number")
_gate = _real("a finite positive normalized innovation squared")
_probability = _real("a probability in (0, 1]", high=1.0)


# ---------------------------------------------------------------------- output paths
def _output_folder(path: Path, option: str) -> Path:
    """Create the folder ``path`` (and its parents) or say why it cannot be one."""
    for place in (path, *path.parents):
        if place.exists() and not place.is_dir():
            where = "it is" if place == path else "it is under"
            raise _UsageError(f"{option} {path}: expected a folder, {where} the file {place}")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _UsageError(f"{option} {path}: cannot create this folder ({exc.strerror})") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise _UsageError(f"{option} {path}: the folder is not writable")
    return path


def _output_file(path: Path, option: str, suffixes: tuple[str, ...] = ()) -> Path:
    """Check that the file ``path`` can be written: its folder exists and is writable."""
    if path.is_dir():
        raise _UsageError(f"{option} {path}: expected a file name, it is a folder")
    if suffixes and path.suffix.lower().lstrip(".") not in suffixes:
        raise _UsageError(f"{option} {path}: expected a file name ending in one of "
                          f"{', '.join('.' + s for s in suffixes)}")
    folder = path.parent
    if not folder.is_dir():
        what = "is a file" if folder.exists() else "does not exist"
        raise _UsageError(f"{option} {path}: its folder {folder} {what}")
    if not os.access(folder, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise _UsageError(f"{option} {path}: not writable")
    return path


# ---------------------------------------------------------------------- library calls
def certify(spec: ModelSpec) -> list[Check]:
    """:func:`switchest.certify.certify` (a name of this module, as tests replace it)."""
    from .certify import certify as checks

    return checks(spec)


def run_experiment(*args, **kwargs) -> list[tuple[dict, dict]]:
    """:func:`switchest.experiments.run_experiment` (a name of this module, as tests replace
    it)."""
    from .experiments import run_experiment as run

    return run(*args, **kwargs)


def _store_path(args: argparse.Namespace) -> Path:
    return Path(args.store) if args.store else Path(args.out) / "results.sqlite"


def _open_store(args: argparse.Namespace) -> Store:
    """The store of ``--store`` (or OUT/results.sqlite), or a usage error naming the option."""
    from .experiments import Store

    option = "--store" if args.store else "--out"
    try:
        return Store(_store_path(args))
    except (ValueError, OSError) as exc:
        raise _UsageError(f"{option}: {exc}") from None


# ---------------------------------------------------------------------- demo
def _check_demo_size(trials: int, duration: float) -> None:
    """Refuse a demo too short to score or too large to hold in memory, before simulating."""
    import numpy as np

    from .models.shankar import BOOST_SAMPLE_PERIOD, BoostTable1

    samples = np.floor(duration / BOOST_SAMPLE_PERIOD + 1e-9) + 1  # a float: may exceed any int
    start = BoostTable1.transient  # the samples Table I's recipe leaves out of the scores
    if samples <= start:
        raise _UsageError(
            f"--duration {duration:g}: the demo scores the filters after their first "
            f"{start} samples (T = {BOOST_SAMPLE_PERIOD * 1e3:g} ms); give at least "
            f"{start * BOOST_SAMPLE_PERIOD:g} s")
    if trials * samples > DEMO_MAX_SAMPLES:
        gigabytes = trials * samples * _DEMO_BYTES_PER_SAMPLE / 1e9
        raise _UsageError(
            f"--trials {trials} x {samples:.0f} samples (--duration {duration:g} s at T = "
            f"{BOOST_SAMPLE_PERIOD * 1e3:g} ms) would need about {gigabytes:.3g} GB; the demo is "
            f"limited to {DEMO_MAX_SAMPLES:,} trials x samples (about "
            f"{DEMO_MAX_SAMPLES * _DEMO_BYTES_PER_SAMPLE / 1e9:.2g} GB): lower --trials or "
            "--duration")


def demo(trials: int, duration: float, seed: int, console: Console) -> Table:
    """Simulate the boost converter of Shankar et al. §V.A and compare four filters, in the
    setting of the Table I reproduction (:class:`~switchest.models.shankar.BoostTable1`: model,
    prior, switching, methods), scored after its transient (``BoostTable1.transient`` samples)."""
    from rich.table import Table

    from .experiments.shankar import table1_estimate
    from .metrics import mode_accuracy, rmse, switch_time_error
    from .models.shankar import BOOST_SAMPLE_PERIOD, BoostTable1

    setting = BoostTable1()
    t_start = time.perf_counter()
    traj = setting.simulate(duration, trials, seed)
    console.print(
        f"simulated {trials} trials x {traj.t.size} samples of the boost converter "
        f"(T = {BOOST_SAMPLE_PERIOD * 1e3:g} ms, switches every 1.2 ms, then random in "
        f"[0.9, 1.2] ms from 0.02 s) in {time.perf_counter() - t_start:.2f} s"
    )
    filters = {"clairvoyant (true switch times)": ("clairvoyant", None),
               "switch-time KF, g = 1": ("grid", 1), "switch-time KF, g = 5": ("grid", 5),
               "switch-time KF, g = 5, merged": ("marginal", 5),
               "IMM (modes unknown)": ("imm", None)}
    start = setting.transient
    # short headers and a key, so that the table fits 80 columns with every header whole
    table = Table(title=f"Boost converter, scored after the first {start} samples",
                  caption="i_L, v_0: RMSE of the inductor current and the output voltage; "
                          "modes: fraction of samples whose mode is estimated right; t_sw: "
                          "mean |error| of the estimated switching instants; merged: the grid's "
                          "instants weighed by their likelihood (beyond the paper); time: to "
                          "filter; -: not estimated", caption_justify="left")
    table.add_column("filter", no_wrap=True)
    for col in ("i_L (A)", "v_0 (V)", "modes", "t_sw (ms)", "time (s)"):
        table.add_column(col, justify="right")
    true_switch = traj.switch_times()
    for name, (method, g) in filters.items():
        t_start = time.perf_counter()
        est = table1_estimate(setting, method, traj, g=g)
        elapsed = time.perf_counter() - t_start
        r = rmse(est.x, traj.x, start=start).overall
        acc = "-" if est.mode is None else f"{mode_accuracy(est.mode, traj.mode, start=start):.3f}"
        err = ("-" if est.switch_time is None
               else f"{1e3 * switch_time_error(est.switch_time, true_switch).mean():.3f}")
        table.add_row(name, f"{r[0]:.3f}", f"{r[1]:.3f}", acc, err, f"{elapsed:.2f}")
    return table


# ---------------------------------------------------------------------- run, reproduce, report
def _summary_table(summary) -> Table:
    """Paper vs measured values of one experiment with the verdict at the printed precision
    (:mod:`switchest.experiments.verdict`); reasons, fits and run details as a caption."""
    from rich.table import Table

    from .experiments.verdict import Verdict, printed_number

    colour = {Verdict.REPRODUCED: "green", Verdict.WITHIN_ERROR: "green", Verdict.FITTED: "blue",
              Verdict.EXPLAINED: "yellow", Verdict.DIFFERS: "red", Verdict.DERIVED: "dim"}
    table = Table(title=escape(summary.title), title_justify="left", caption_justify="left")
    # every column may fold, so that at 80 columns (a pipe, a log) none is squeezed to nothing
    # (rich's min_width is not honoured when it collapses a table: the table then overflows)
    table.add_column("quantity", overflow="fold")
    for col in ("paper", "ours"):
        table.add_column(col, justify="right", overflow="fold")
    for col in ("unit", "verdict"):
        table.add_column(col, overflow="fold")
    notes = []

    def fmt(v, se=None) -> str:
        if v is None:
            return "—"
        if isinstance(v, str):
            return escape(v)
        return f"{v:.6g}" + ("" if se is None else f" ± {se:.2g}")

    for row in summary.rows:
        printed = printed_number(row.paper)
        style = colour[row.verdict]
        quantity = f"  ↳ {row.reading}: {row.quantity}" if row.reading else row.quantity
        table.add_row(escape(quantity), fmt(row.paper if printed is None else str(printed)),
                      fmt(row.measured, row.se), escape(row.unit),
                      f"[{style}]{row.verdict.value}[/{style}]")
        said = [str(why) for why in (row.fit, row.explanation) if why is not None]
        if row.details:
            said.append(row.details)
        if said:
            notes.append(escape(f"{row.quantity}: {'; '.join(said)}"))
    table.caption = "\n".join(notes) or None
    return table


def _print_compact(summary, console: Console) -> None:
    """One line of the printed items an experiment judges, by verdict, then the rows that
    differ unexplained."""
    from collections import Counter

    from .experiments.items import items_of
    from .experiments.verdict import Verdict

    counts = Counter(item.verdict for item in
                     items_of(summary.experiment, [(summary.experiment, r) for r in summary.rows]))
    derived = sum(row.verdict is Verdict.DERIVED for row in summary.rows)
    parts = [f"{counts[v]} {v.value}" for v in Verdict if counts[v]]
    if derived:
        parts.append(f"{derived} derived rows")
    console.print(f"[bold]{escape(summary.title)}[/bold]: printed items {escape(', '.join(parts))}")
    for row in summary.rows:
        if row.verdict is Verdict.DIFFERS:
            console.print(f"  [red]differs[/red]: {escape(row.quantity)}: paper "
                          f"{escape(str(row.paper))}, ours {escape(_short(row.measured))}")


def _short(value) -> str:
    return value if isinstance(value, str) else f"{value:.6g}"


class _Eta:
    """The time left of a run, from the tasks it has finished, as the progress bar's text.

    The runner reports ``update(finished, total)`` at its start (the tasks already stored),
    after each task and while it waits. The estimate is the run's time per finished task
    (its time since the start over the tasks finished since: all workers together) times the
    tasks left, counted down since the last one finished. It is shown only once ``workers``
    tasks have finished: before a round of every worker, the first tasks to finish say little
    of the others (and when no more tasks are left than workers, all run at once and none is
    shown). ``str()`` is the text: empty until then and once every task is done.
    """

    def __init__(self, workers: int, clock: Callable[[], float] = time.perf_counter):
        self.workers, self.clock = workers, clock
        self.start: float | None = None
        self.last = 0.0  # when the latest task finished
        self.base = self.done = self.total = 0

    def update(self, done: int, total: int) -> None:
        now = self.clock()
        if self.start is None:
            self.start, self.base, self.done, self.last = now, done, done, now
        if done != self.done:
            self.last = now
        self.done, self.total = done, total

    def seconds(self) -> float | None:
        """The estimated seconds left, or None while it would mean nothing."""
        if self.start is None:
            return None
        finished, left = self.done - self.base, self.total - self.done
        if left <= 0 or finished < max(1, min(self.workers, self.total - self.base)):
            return None
        per_task = (self.last - self.start) / finished
        return max(0.0, per_task * left - (self.clock() - self.last))

    def __str__(self) -> str:
        seconds = self.seconds()
        if seconds is None:
            return ""
        minutes, sec = divmod(round(seconds), 60)
        return f"ETA {minutes // 60}:{minutes % 60:02d}:{sec:02d}"


def _run(chosen: list[str], args: argparse.Namespace, console: Console) -> Store:
    """Run (or resume) each named experiment into the store; print its summary; return the store."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from .experiments import get

    out = _output_folder(Path(args.out), "--out")
    store = _open_store(args)
    plans = []
    for name in chosen:  # every experiment's parameters are checked before any runs
        experiment = get(name)
        overrides = {}
        if getattr(args, "trials", None) is not None:
            if "trials" not in experiment.defaults:
                raise _UsageError(f"--trials: experiment {name} has no trials parameter (its "
                                  f"parameters: {', '.join(sorted(experiment.defaults))})")
            overrides["trials"] = args.trials
        try:
            plans.append((experiment, experiment.params(quick=args.quick, **overrides)))
        except ValueError as exc:
            raise _UsageError(f"--trials {args.trials}: {exc}" if overrides else str(exc)) from None
    for experiment, params in plans:
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TimeElapsedColumn(), TextColumn("{task.fields[eta]}"))  # str(_Eta) each frame
        with Progress(*columns, console=console, transient=True,
                      disable=not console.is_terminal) as progress:
            eta = _Eta(args.workers)
            bar = progress.add_task(experiment.name, total=None, eta=eta)
            start = time.perf_counter()

            def on_done(done: int, total: int, bar=bar, eta=eta) -> None:
                eta.update(done, total)
                progress.update(bar, completed=done, total=total)

            try:
                results = run_experiment(
                    experiment, params, store=store, seed=args.seed, workers=args.workers,
                    scheduler=args.scheduler, on_done=on_done,
                )
            except OSError as exc:
                if args.scheduler is None:
                    raise
                raise _UsageError(f"--scheduler {args.scheduler}: {exc}") from None
        summary = experiment.summarize(params, results, out / "figures")
        if args.command == "run":
            console.print(_summary_table(summary))
        else:  # several experiments: a line each and what differs; every row is in the report
            _print_compact(summary, console)
        console.print(f"[dim]{escape(experiment.name)}: {len(results)} tasks, "
                      f"{time.perf_counter() - start:.1f} s[/dim]")
        if args.command == "run":  # the report of several experiments names their figures
            console.print(_figures_line(summary.figures, out / "figures"))
        else:
            console.print()
    return store


def _figures_line(figures: list[Path], folder: Path) -> str:
    """Where ``switchest run`` wrote an experiment's figures: the folder and the file names
    (paths elsewhere in full)."""
    if not figures:
        return "figures: none for this experiment"
    names = [str(Path(f).relative_to(folder)) if Path(f).is_relative_to(folder) else str(f)
             for f in figures]
    return escape(f"figures ({len(names)}) in {folder}{os.sep}: {', '.join(names)}")


def _cmd_run(args: argparse.Namespace, console: Console) -> int:
    from .experiments import RunInterrupted, names, write_report

    started = time.perf_counter()
    chosen = [args.name] if args.command == "run" else (names() if args.all else args.names)
    if not chosen:
        raise _UsageError("name the reproductions to run, or pass --all")
    unknown = [n for n in chosen if n not in names()]
    if unknown:
        said = [n + did_you_mean(n, names(), before=" (", after=")") for n in unknown]
        raise _UsageError(f"unknown reproduction(s) {', '.join(said)}; see 'switchest list'")
    try:
        store = _run(chosen, args, console)
    except RunInterrupted as exc:
        if args.debug:
            raise
        raise _Interrupted(exc) from None
    if args.command == "run":
        report = shlex.join(["switchest", "report", "--store", str(store.path), "--out",
                             args.out])
        console.print(f"HTML page of the results: [bold]{escape(report)}[/bold]", highlight=False)
    if args.command == "reproduce":
        with _report_progress(console) as progress:
            report = write_report(store, args.out, chosen, command=args.command_line,
                                  wall_seconds=time.perf_counter() - started, progress=progress)
        console.print(f"report: [bold]{escape(str(report))}[/bold]  "
                      f"(results store: {escape(str(store.path))})")
    return 0


@contextmanager
def _report_progress(console: Console) -> Iterator[Callable[[str, int, int], None]]:
    """A status line while the report's figures are drawn: ``progress(name, done, total)``."""
    with console.status("writing the report…") as status:
        def progress(name: str, done: int, total: int) -> None:
            status.update(f"writing the report: {name} ({done + 1} of {total})")
            if not console.is_terminal:
                console.print(f"[dim]report: {escape(name)} ({done + 1} of {total})[/dim]")

        yield progress


def _cmd_report(args: argparse.Namespace, console: Console) -> int:
    from .experiments import Store, write_report

    _output_folder(Path(args.out), "--out")
    try:
        store = Store(args.store, read_only=True)
    except (ValueError, OSError) as exc:
        raise _UsageError(f"--store: {exc}") from None
    with _report_progress(console) as progress:
        report = write_report(store, args.out, command=args.command_line, progress=progress)
    console.print(f"report: [bold]{escape(str(report))}[/bold]")
    return 0


# ---------------------------------------------------------------------- demo, list, estimate, check
def _cmd_demo(args: argparse.Namespace, console: Console) -> int:
    _check_demo_size(args.trials, args.duration)
    console.print(demo(args.trials, args.duration, args.seed, console))
    return 0


def _cmd_list(args: argparse.Namespace, console: Console) -> int:
    from rich.table import Table

    from .experiments import get, names

    table = Table(title="switchest reproductions")
    for col in ("name", "paper", "what"):
        table.add_column(col)
    for name in names():
        e = get(name)
        table.add_row(escape(name), escape(e.paper), escape(e.title))
    console.print(table)
    return 0


def _cmd_estimate(args: argparse.Namespace, console: Console) -> int:
    from .estimators import TimingWarning
    from .modelfile import load_model
    from .tabular import ImplausibleEstimateWarning, estimate_table

    out = _output_file(Path(args.out), "--out")
    plot = args.plot and _output_file(Path(args.plot), "--plot", ("png", "pdf", "svg"))
    if args.window is not None and plot is None:
        raise _UsageError("--window chooses the part of the record --plot draws: give --plot")
    spec = load_model(args.model)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ImplausibleEstimateWarning)
        warnings.simplefilter("always", TimingWarning)
        table = estimate_table(spec, args.data, method=args.method, grid=args.grid,
                               refine=args.refine, switch_time=args.switch_time,
                               estimate=args.reported, stay=args.stay, v_max=args.v_max,
                               delta=args.delta, Delta=args.Delta,
                               switch_interval=args.switch_interval, smooth=args.smooth,
                               particles=args.particles, seed=args.seed, timing=args.timing,
                               gate=args.gate, trial=args.trial)
    if plot is not None:  # the window checked before anything is written
        from .plotting import window_mask

        try:
            window_mask(table["t"].to_numpy(), args.window)
        except ValueError as exc:
            raise _UsageError(str(exc).replace("t_window", "--window")) from None
    errors = Console(stderr=True, soft_wrap=True, highlight=False)
    for warning in caught:
        _say(errors, "warning", str(warning.message))
    table.to_csv(out, index=False)
    console.print(f"{len(table)} samples estimated with {args.method}: "
                  f"[bold]{escape(str(out))}[/bold]")
    if "outlier" in table and table["outlier"].any():
        _say(errors, "warning", f"{int(table['outlier'].sum())} of {len(table)} measurements "
             "were rejected by the filter's outlier gate and treated as missing (column "
             "'outlier')")
    if plot is not None:
        _plot_estimate(plot, spec, table, args)
        console.print(f"figure: {escape(str(plot))}")
    return 0


def _plot_estimate(path: Path, spec, table, args: argparse.Namespace) -> None:
    """The figure of ``switchest estimate --plot``: states with their bands, the data's
    measurements of them and true values (columns ``x0 ..``, as ``simulate`` writes), the
    mode probabilities and the estimated switching instants."""
    import pandas as pd

    from .measurements import read_measurements
    from .plotting import estimate_figure, measured_states

    meas = read_measurements(args.data, spec, trial=args.trial)
    data = pd.read_csv(args.data)
    if "trial" in data:
        data = data[data["trial"] == (args.trial if args.trial is not None else data["trial"][0])]
    n = spec.system.n_states
    state_cols = [f"x{i}" for i in range(n)]  # the estimate's, and the data's true states
    std_cols = [f"std_x{i}" for i in range(n)]
    prob_cols = [c for c in table.columns if c.startswith("p_mode")]
    estimate_figure(
        path, table["t"].to_numpy(), table[state_cols].to_numpy(),
        std=table[std_cols].to_numpy() if set(std_cols) <= set(table.columns) else None,
        truth=data[state_cols].to_numpy() if set(state_cols) <= set(data.columns) else None,
        measured=measured_states(spec.system.C, meas["y"]),
        mode_prob=table[prob_cols].to_numpy() if prob_cols else None,
        true_mode=meas.get("mode"),
        switch_times=table["switch_time"].dropna().to_numpy() if "switch_time" in table else (),
        names=spec.state_names, units=spec.state_units,
        title=f"{Path(args.model).name}: {args.method}", t_window=args.window)


def _cmd_simulate(args: argparse.Namespace, console: Console) -> int:
    from .measurements import simulate_measurements
    from .modelfile import load_model

    out = _output_file(Path(args.out), "--out")
    spec = load_model(args.model)
    u = None if args.input is None else _numbers_option(args.input, "--input")
    table = simulate_measurements(spec, duration=args.duration, trials=args.trials, u=u,
                                  rng=args.seed)
    table.to_csv(out, index=False)
    runs = f"{args.trials} trials of " if args.trials > 1 else ""
    console.print(f"{runs}{table['t'].nunique()} samples simulated from {escape(str(args.model))}: "
                  f"[bold]{escape(str(out))}[/bold]")
    return 0


def _numbers_option(text: str, option: str) -> list[float]:
    """Comma-separated numbers of a command-line option."""
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise _UsageError(f"{option} must be comma-separated numbers, got {text!r}") from None


def _cmd_check(args: argparse.Namespace, console: Console) -> int:
    from rich.table import Table

    from .modelfile import load_model

    spec = load_model(args.model)
    table = Table(title=escape(f"switchest check: {args.model}"), title_justify="left",
                  caption="margin: positive when the condition holds, zero or negative when "
                          "it fails (— where none is defined)", caption_justify="left")
    # the paper under the condition, not a column of its own: at 80 columns the detail gets
    # the width and the table half the lines
    table.add_column("condition (paper)", overflow="fold")
    for col in ("verdict", "margin"):
        table.add_column(col, overflow="fold")
    table.add_column("detail", overflow="fold")
    marks = {True: "[green]holds[/green]", False: "[red]fails[/red]", None: "[yellow]n/a[/yellow]"}
    checks = certify(spec)
    for c in checks:
        margin = "—" if c.margin is None else f"{c.margin:.3g}"
        paper = f"\n[dim]{escape(c.paper)}[/dim]" if c.paper else ""
        table.add_row(escape(c.name) + paper, marks[c.verdict], margin, escape(c.detail))
    console.print(table)
    console.print(_methods_line(checks))
    return 0


def _methods_line(checks: list[Check]) -> str:
    """The closing line of ``switchest check``: the methods whose conditions hold, fail or are
    undecided (:func:`switchest.certify.method_verdicts`), and those no check certifies."""
    from .certify import method_verdicts
    from .estimators.registry import METHOD_NAMES

    said = method_verdicts(checks)
    groups = [("[green]conditions hold[/green]", [m for m, v in said.items() if v is True]),
              ("[red]fail[/red]", [m for m, v in said.items() if v is False]),
              ("[yellow]undecided or not applicable[/yellow]",
               [m for m, v in said.items() if v is None]),
              ("no conditions checked", [m for m in METHOD_NAMES if m not in said])]
    parts = [f"{label}: {', '.join(names) if names else 'none'}" for label, names in groups[:1]]
    parts += [f"{label}: {', '.join(names)}" for label, names in groups[1:] if names]
    return "methods whose " + "; ".join(parts)


# ---------------------------------------------------------------------- fit
_FIT_PARAMETERS = ("transition", "A", "B", "C", "Q", "R")
"""What ``switchest fit --estimate`` may name: :func:`switchest.learn.fit`'s ``estimate``
names, repeated so that building the parser does not import the learner (tests/test_learn_cli.py
holds them equal)."""


def _names(allowed: tuple[str, ...]) -> Callable[[str], tuple[str, ...]]:
    """An option of comma-separated names among ``allowed``."""
    def parse(text: str) -> tuple[str, ...]:
        names = tuple(name.strip() for name in text.split(","))
        unknown = [name for name in names if name not in allowed]
        if unknown:
            hints = [f"{close!r} for {n!r}" for n in unknown
                     if (close := closest_name(n, allowed)) is not None]
            raise argparse.ArgumentTypeError(
                f"unknown parameter(s) {', '.join(repr(n) for n in unknown)}; expected "
                f"comma-separated names among {', '.join(allowed)}"
                + (f"; did you mean {', '.join(hints)}?" if hints else ""))
        return tuple(dict.fromkeys(names))
    return parse


_fit_parameters = _names(_FIT_PARAMETERS)
"""``--estimate``: comma-separated names among :data:`_FIT_PARAMETERS`."""
_fit_shared = _names(_FIT_PARAMETERS[1:])
"""``--shared``: comma-separated matrices among ``A, B, C, Q, R``."""


def _fit_table(start: SwitchedLinearSystem, start_transition: np.ndarray | None,
               result: FitResult) -> Table:
    """The fitted parameters beside their standard errors and starting values: every entry of
    the transition matrix, the upper triangle of each fitted noise block (entries held at zero
    left out), every entry of a fitted ``A``, ``B``, ``C``; a matrix tied across the modes
    (``--shared``) once."""
    import numpy as np
    from rich.table import Table

    table = Table(title="fitted parameters", title_justify="left", caption_justify="left",
                  caption="± : standard error (— where none exists: a mode never visited, "
                          "A, B, C when both the dynamics and C are fitted, a maximum on the "
                          "boundary); noise entries held at zero not shown")
    table.add_column("parameter", overflow="fold")
    for col in ("fitted", "±", "start"):
        table.add_column(col, justify="right", overflow="fold")

    def number(value, digits: str = ".6g") -> str:
        return "—" if value is None or not np.isfinite(value) else format(value, digits)

    se = result.se
    if "transition" in se:
        L = result.transition.shape[0]
        for i in range(L):
            for j in range(L):
                table.add_row(f"transition {i}→{j}", number(result.transition[i, j]),
                              number(se["transition"][i, j], ".2g"),
                              number(None if start_transition is None else
                                     start_transition[i, j]))
    for name in ("A", "B", "C", "Q", "R"):
        if name not in se:
            continue
        fitted, first = getattr(result.system, name), getattr(start, name)
        one = fitted.shape[0] > 1 and name in result.shared
        for j in [0] if one else range(fitted.shape[0]):
            where = "all modes" if one else f"mode {j}"
            if name in "QR":
                idx = np.flatnonzero(np.diag(first[j]) > 0)  # fit holds the others at zero
                entries = [(a, b) for a in idx for b in idx if a <= b]
            else:
                entries = list(np.ndindex(fitted.shape[1:]))
            for a, b in entries:
                table.add_row(f"{name} {where} [{a},{b}]", number(fitted[j, a, b]),
                              number(se[name][j, a, b], ".2g"), number(first[j, a, b]))
    return table


def _print_fit_warnings(caught: list, trace: np.ndarray) -> None:
    """Print the fit's RuntimeWarnings (unvisited or unobservable modes, likelihood drops) as
    one line each on stderr, as ``estimate`` prints its ImplausibleEstimateWarning; of the
    drops of the log-likelihood (one warning per iteration) the first, then one line counting
    the others from the trace. Other warnings go to :func:`warnings.showwarning`."""
    import numpy as np

    errors = Console(stderr=True, soft_wrap=True, highlight=False)
    drops = 0
    for warning in caught:
        if not issubclass(warning.category, RuntimeWarning):
            warnings.showwarning(warning.message, warning.category, warning.filename,
                                 warning.lineno)
        elif "log-likelihood decreased" in str(warning.message) and drops:
            drops += 1
        else:
            drops += "log-likelihood decreased" in str(warning.message)
            _say(errors, "warning", str(warning.message))
    if drops > 1:
        best = int(np.argmax(trace))
        _say(errors, "warning", f"the log-likelihood decreased at {drops - 1} more iterations; "
                                f"its largest value {trace[best]:.10g} was at iteration {best}, "
                                f"the last is {trace[-1]:.10g} (--plot draws the trace)")


def _cmd_fit(args: argparse.Namespace, console: Console) -> int:
    import numpy as np
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from .learn import fit
    from .learn.model_files import fitted_model, read_trials, start_transition
    from .modelfile import load_model, save_model

    out = _output_file(Path(args.out), "--out", ("toml",))
    plot = args.plot and _output_file(Path(args.plot), "--plot", ("png", "pdf", "svg"))
    spec = load_model(args.model)
    if spec.initial is None:
        raise ValueError(f"{args.model}: the model file needs an [initial] table (mean, cov): "
                         "the prior of the state at the first sample, which fit holds fixed")
    data = read_trials(args.data, spec, args.trial)
    start = start_transition(spec, data["t"])
    switch_times = args.switch_times or ("between" if spec.switches_between_samples
                                         else "samples")
    if switch_times == "samples" and spec.switches_between_samples and data["mode"] is None:
        # (with the modes known the fit's own check of the innovations says it from the data)
        _say(Console(stderr=True, soft_wrap=True, highlight=False), "warning",
             "the model file's switches fall between the samples; --switch-times samples holds "
             "each mode over the interval after its sample, and the fitted noise takes the "
             "mis-timed switches in (on the boost converter R = 5 fits as 10.7 so): "
             "--switch-times between models them")
    columns = (TextColumn("EM"), BarColumn(), MofNCompleteColumn(),
               TextColumn("log-likelihood {task.fields[loglik]}"), TimeElapsedColumn())
    with (warnings.catch_warnings(record=True) as caught,
          Progress(*columns, console=console, transient=True,
                   disable=not console.is_terminal) as bar):
        warnings.simplefilter("always", RuntimeWarning)
        task = bar.add_task("EM", total=args.max_iter, loglik="…")
        result = fit(spec.system, data["y"], data["u"], data["t"], transition=start,
                     x0=spec.initial[0], P0=spec.initial[1], modes=data["mode"],
                     estimate=args.estimate, shared=args.shared, switch_times=switch_times,
                     grid=args.grid, max_iter=args.max_iter, tol=args.tol, rng=0,
                     progress=lambda i, loglik: bar.update(
                         task, completed=i + 1, total=max(args.max_iter, i + 1),
                         loglik=f"{loglik:.10g}"))
    _print_fit_warnings(caught, result.loglik)
    fitted, note = fitted_model(spec, result, args.estimate, Path(args.data))
    save_model(fitted, out)
    trace = result.loglik
    modes = "known modes (mode column)" if data["mode"] is not None else "unknown modes"
    modes += (f", switches between the samples (instants marginalized on a grid of "
              f"{args.grid})" if switch_times == "between" else ", switches at the samples")
    stop = ("converged" if result.converged else
            f"[yellow]stopped at --max-iter {args.max_iter} without converging[/yellow]")
    runs = f"{data['trials']} trials x " if data["trials"] > 1 else ""
    how = ("" if result.ascent_from is None else
           f" ({result.ascent_from} of EM, then direct ascent)")
    console.print(f"EM on {runs}{data['t'].size} samples, {modes}: {result.iterations} "
                  f"iterations{how}, {stop}; log-likelihood {trace[0]:.10g} → {trace[-1]:.10g}")
    if result.outliers:
        console.print(f"{result.outliers} sample(s) rejected by the outlier gate, fitted as "
                      "missing")
    console.print(_fit_table(spec.system, start, result))
    console.print(f"switching model: {escape(note)}")
    console.print(f"fitted model: [bold]{escape(str(out))}[/bold]")
    if plot is not None:
        from .plotting import curves

        curves(plot, np.arange(trace.size), {"log-likelihood": trace},
               xlabel="iteration" + ("" if result.ascent_from is None else
                                     f" (direct ascent from {result.ascent_from})"),
               ylabel="log-likelihood", title=f"{Path(args.model).name}: EM, {modes}")
        console.print(f"figure: {escape(str(plot))}")
    return 0


# ---------------------------------------------------------------------- the parser and main
def _help(text: str) -> str:
    """``text`` as an argparse help string (its ``%`` escaped)."""
    return text.replace("%", "%%")


def _applies(option: str, text: str) -> str:
    """The help of ``switchest estimate``'s ``option``: ``text`` after the registered methods
    it applies to (:func:`~switchest.estimators.registry.methods_with`)."""
    return _help(f"{', '.join(methods_with(option))}: {text}")


def _parser() -> _Parser:
    parser = _Parser(prog="switchest", description="Estimation in switched linear systems.")
    parser.add_argument("--version", action="version", version=f"switchest {__version__}")
    debug = argparse.ArgumentParser(add_help=False)  # --debug before or after the command
    debug.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                       help="show the traceback of an error")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", required=True)
    parser.commands = sub.choices

    def command(name: str, run: Callable, **kwargs) -> argparse.ArgumentParser:
        p = sub.add_parser(name, parents=[debug], **kwargs)
        p.set_defaults(run=run)
        return p

    p_demo = command("demo", _cmd_demo, help="simulate the boost converter and compare filters")
    p_demo.add_argument("--trials", type=_positive, default=20)
    p_demo.add_argument("--duration", type=_duration, default=0.1, help="seconds of operation")
    p_demo.add_argument("--seed", type=_seed, default=0)

    command("list", _cmd_list, help="list the registered paper reproductions")

    def runner_options(p):
        p.add_argument("--quick", action="store_true",
                       help="fewer trials, shorter runs (minutes, not hours)")
        p.add_argument("--workers", type=_workers, default=os.cpu_count() or 1,
                       help="local worker processes (default: the machine's cores)")
        p.add_argument("--scheduler", default=None,
                       help="address of a Dask scheduler to run the tasks on")
        p.add_argument("--seed", type=_seed, default=0)
        p.add_argument("--out", default="out",
                       help="output folder (figures, report, default store)")
        p.add_argument("--store", default=None, help="results store (default OUT/results.sqlite)")

    p_run = command("run", _cmd_run, help="run (or resume) one reproduction")
    p_run.add_argument("name")
    p_run.add_argument("--trials", type=_positive, default=None,
                       help="override the number of trials")
    runner_options(p_run)
    p_rep = command("reproduce", _cmd_run, help="run several reproductions and write the report")
    p_rep.add_argument("names", nargs="*")
    p_rep.add_argument("--all", action="store_true", help="every registered reproduction")
    runner_options(p_rep)
    p_est = command("estimate", _cmd_estimate,
                    help="estimate states and modes from measured data (CSV)")
    p_est.add_argument("--model", required=True, type=_existing_file, help="TOML model file")
    known = ", ".join(m.name for m in methods() if m.needs_modes)
    p_est.add_argument("--data", required=True, type=_existing_file,
                       help="CSV with columns t, u..., y... (empty or NaN y cells: missing "
                            f"samples) and mode (the known mode, needed by {known}); for rsls "
                            "the y columns are the integrated output at fine instants t "
                            "including every switching instant t0 + kT")
    p_est.add_argument("--method", required=True, choices=[m.name for m in methods()],
                       metavar="METHOD",  # the help lists them, each with what it does
                       help=_help(" | ".join(f"{m.name}: {m.description}" for m in methods())))
    p_est.add_argument("--grid", type=_positive, default=5,
                       help=_applies("grid", "switching-time grid points per interval"))
    p_est.add_argument("--refine", action="store_true",
                       help=_applies("refine", "refine the grid maximum"))
    p_est.add_argument("--switch-time", choices=("marginal", "max"), default=None,
                       help=_applies("switch_time", "weigh the grid's candidate instants by "
                                     "their likelihood (marginal, the default without "
                                     "--refine: the covariance counts the instant's "
                                     "uncertainty) or take the likelihood's maximizer (max, "
                                     "the paper's eq. (23); its covariance is conditional on "
                                     "the chosen instant)"))
    p_est.add_argument("--reported", choices=("mixture", "map"), default=None,
                       help=_applies("estimate", "the estimate reported: the mixture of every "
                                     "destination's posterior (mixture, the default), or the "
                                     "MAP destination's (map, the paper's)"))
    p_est.add_argument("--stay", type=_probability, default=None,
                       help=_applies("stay", "per-sample probability of staying in a mode"))
    p_est.add_argument("--v-max", type=_window, default=None,
                       help=_applies("v_max", "noise bound |v| <= v_max (default: the model's "
                                              "noise.v_max)"))
    p_est.add_argument("--delta", type=_window, default=None,
                       help=_applies("delta", "estimation window delta, a multiple of the time "
                                              "step (default: noise.delta)"))
    p_est.add_argument("--Delta", type=_window, default=None,
                       help=_applies("Delta", "detection delay Delta (default: noise.Delta)"))
    p_est.add_argument("--switch-interval", type=_window, default=None,
                       help=_applies("switch_interval", "switching interval T, modes change only "
                                                        "at t0 + kT (default: sampling.period)"))
    p_est.add_argument("--smooth", action="store_true",
                       help=_applies("smooth", "smoothed estimates given the whole record "
                                               "(two-filter smoother) instead of filtered ones"))
    p_est.add_argument("--particles", type=_positive, default=None,
                       help=_applies("particles", "number of particles (default 1000)"))
    p_est.add_argument("--seed", type=_seed, default=None,
                       help=_applies("seed", "seed of the particles' random numbers (default 0)"))
    p_est.add_argument("--timing", choices=TIMINGS, default=None,
                       help=_applies("timing", "which interval the mode of a sample governs: "
                                               "'sample' the one after it, as simulate draws; "
                                               "'interval' the one before it (Bar-Shalom's "
                                               "IMM); default: the model file's timing, that "
                                               "of its data (docs: Conventions)"))
    p_est.add_argument("--gate", type=_gate, default=None,
                       help=_applies("gate", "outlier gate: a measurement whose normalized "
                                             "innovation squared exceeds it is treated as "
                                             "missing and flagged (column outlier; e.g. 15.1, "
                                             "chi-square 0.9999 of one output)"))
    p_est.add_argument("--trial", type=_seed, default=None,
                       help="which trial to estimate, in a CSV with a trial column")
    p_est.add_argument("--out", required=True, help="CSV of the estimates")
    p_est.add_argument("--plot", default=None, help="figure of the estimates (.png, .pdf, .svg)")
    p_est.add_argument("--window", type=_time_window, default=None, metavar="T0:T1",
                       help="draw only the part of the record from T0 to T1 s in --plot")
    p_sim = command("simulate", _cmd_simulate,
                    help="simulate a model file into a measurement CSV (for estimate)")
    p_sim.add_argument("--model", required=True, type=_existing_file, help="TOML model file")
    p_sim.add_argument("--duration", type=_duration, default=None,
                       help="time to simulate (default: the model's sampling.duration)")
    p_sim.add_argument("--trials", type=_positive, default=1,
                       help="independent runs (a trial column when more than one)")
    p_sim.add_argument("--input", default=None,
                       help="constant input, comma-separated (default: the model file's [input] "
                            "value, zero without one)")
    p_sim.add_argument("--seed", type=_seed, default=0)
    p_sim.add_argument("--out", required=True, help="CSV of t, u, y, mode and the true x")
    p_fit = command("fit", _cmd_fit,
                    help="fit the transition matrix and noises of a model file to data (EM)")
    p_fit.add_argument("--model", required=True, type=_existing_file,
                       help="TOML model file: the starting point, and its [initial] prior")
    p_fit.add_argument("--data", required=True, type=_existing_file,
                       help="measurement CSV (as for estimate); with a mode column the modes "
                            "are known (exact EM), otherwise estimated (approximate E-step)")
    p_fit.add_argument("--estimate", type=_fit_parameters, default=("transition", "Q", "R"),
                       help="what to fit, comma-separated among transition, A, B (discrete "
                            "time), C, Q, R (default: transition,Q,R)")
    p_fit.add_argument("--shared", type=_fit_shared, default=(),
                       help="estimated matrices tied across the modes, comma-separated among "
                            "A, B, C, Q, R (default: none, each mode its own)")
    p_fit.add_argument("--switch-times", choices=("samples", "between"), default=None,
                       help="whether the switches fall at the samples or between them "
                            "(instants marginalized on a grid); default between for a "
                            "continuous-time model whose switching model switches in "
                            "continuous time, else samples")
    p_fit.add_argument("--grid", type=_positive, default=16,
                       help="switch instants per interval of --switch-times between")
    p_fit.add_argument("--max-iter", type=_positive, default=200,
                       help="most iterations: of EM, then of the direct ascent that finishes "
                            "an EM that crawls or whose E-step is approximate")
    p_fit.add_argument("--tol", type=_window, default=1e-3,
                       help="stop when an iteration gains, and EM's estimate of the gain still "
                            "to come is, at most this many nats of log-likelihood")
    p_fit.add_argument("--trial", type=_seed, default=None,
                       help="fit one trial of a CSV with a trial column (default: all at once)")
    p_fit.add_argument("--out", required=True, help="fitted TOML model file")
    p_fit.add_argument("--plot", default=None,
                       help="figure of the log-likelihood trace (.png, .pdf, .svg)")
    p_check = command("check", _cmd_check, help="certify what switchest can about a model file")
    p_check.add_argument("--model", required=True, type=_existing_file, help="TOML model file")
    p_report = command("report", _cmd_report, help="write the HTML report of a results store")
    p_report.add_argument("--store", required=True, type=_existing_file)
    p_report.add_argument("--out", default="out")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``switchest`` with ``argv`` (default: the process's arguments); return the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    errors = Console(stderr=True, soft_wrap=True, highlight=False)
    debug = False
    try:
        args = _parser().parse_args(argv)
        args.command_line = shlex.join(["switchest", *argv])
        debug = args.debug
        with warnings.catch_warnings():
            if not debug:  # each warning one line; --debug keeps Python's form
                warnings.showwarning = lambda message, *_: _say(errors, "warning", str(message))
            return args.run(args, Console())
    except _UsageError as exc:
        _say(errors, "error", str(exc))
        return 2
    except _Interrupted as exc:
        run = exc.run
        _say(errors, "interrupted", f"{run.stored} of {run.total} tasks of {run.experiment} are "
                                    f"stored in {_store_path(args)}")
        _say(errors, "resume with", args.command_line)
        return 130
    except KeyboardInterrupt:
        if debug:
            raise
        _say(errors, "interrupted", "stopped by Ctrl-C")
        return 130
    except (ValueError, OSError) as exc:  # the library's and the file system's word on the input
        if debug:
            raise
        _say(errors, "error", str(exc) or type(exc).__name__)
        return 2
    except Exception as exc:  # anything else is a bug: say so in one line
        if debug:
            raise
        _say(errors, "internal error", f"{type(exc).__name__}: {exc} -- a bug in switchest; re-run "
                                       "with --debug for the traceback and report it")
        return 1


def _say(console: Console, label: str, message: str) -> None:
    """One line on stderr: ``label: message`` (line breaks folded, markup shown as text)."""
    line = " ".join(part.strip() for part in message.splitlines())
    console.print(f"[bold red]{label}:[/bold red] {escape(line)}")


if __name__ == "__main__":
    sys.exit(main())
