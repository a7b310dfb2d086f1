"""The command line: the demo runs end to end and prints its comparison; estimate's options and
errors."""

import argparse
import os
import re
import shlex
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from switchest import cli as cli_module
from switchest._checks import TIMINGS
from switchest.cli import main
from switchest.estimators import METHOD_NAMES, get_method
from switchest.modelfile import load_model, save_model
from switchest.simulate import simulate
from switchest.tabular import METHODS, estimate_table


def test_demo_prints_the_comparison(capsys):
    assert main(["demo", "--trials", "2", "--duration", "0.02", "--seed", "1"]) == 0
    out = capsys.readouterr().out
    assert "clairvoyant" in out and "IMM" in out and "RMSE" in out


def test_demo_fits_80_columns_with_every_header_whole(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["demo", "--trials", "2", "--duration", "0.02", "--seed", "1"]) == 0
    out = capsys.readouterr().out
    assert max(map(len, out.splitlines())) <= 80 and "…" not in out
    header = [line.split("┃")[1:-1] for line in out.splitlines() if line.startswith("┃")]
    columns = [" ".join(" ".join(cells).split()) for cells in zip(*header, strict=True)]
    assert columns == ["filter", "i_L (A)", "v_0 (V)", "modes", "t_sw (ms)", "time (s)"]
    words = " ".join(out.split())  # the key, unwrapped
    for key in ("i_L, v_0: RMSE of", "modes: fraction of samples", "t_sw: mean |error|",
                "time: to filter", "-: not estimated"):
        assert key in words


def test_estimate_help_fits_80_columns_and_keeps_names_whole(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    with pytest.raises(SystemExit) as done:
        main(["estimate", "--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert max(map(len, out.splitlines())) <= 80
    assert not [line for line in out.splitlines() if line.rstrip().endswith("-")]
    words = " ".join(out.split())  # unwrapped: a name split at a hyphen would read "min- dis"
    for name in METHOD_NAMES:
        assert f" {name}: " in words, name
    assert "min-distance: minimum-distance mode estimation" in words


def test_bad_arguments_exit_with_one_line(capsys):
    assert main(["demo", "--trials", "0"]) == 2
    err = capsys.readouterr().err
    assert err == ("error: argument --trials: expected a positive integer, got 0 "
                   "(see 'switchest demo --help')\n")


# ------------------------------------------------------------- estimate: options of the new methods
EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "models"


@pytest.fixture(scope="module")
def lee_csv(tmp_path_factory):
    """1.5 s of lee-fsk (601 rows on its 2.5 ms grid), noise-free: enough for one estimation
    window."""
    spec = load_model(EXAMPLES / "lee-fsk.toml")
    t = spec.sample_times(1.5)
    traj = simulate(spec.system, lambda r: spec.signal(r, t), t, spec.initial, u=np.array([0.01]),
                    rng=0)
    df = pd.DataFrame({"t": t, "u": 0.01, "y0": traj.y[0, :, 0], "y1": traj.y[0, :, 1]})
    path = tmp_path_factory.mktemp("lee") / "lee.csv"
    df.to_csv(path, index=False)
    return spec, df, path


def test_estimate_help_lists_every_method_and_the_integrated_output(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["estimate", "--help"])
    assert exc.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert all(m in out for m in METHODS)
    assert "for rsls the y columns are the integrated output" in out
    assert all(flag in out for flag in ("--v-max", "--delta", "--Delta", "--switch-interval"))


def test_the_parser_offers_the_registered_methods():
    """--method offers the registry's names, read from it (tabular offers them too), --timing
    the package's timings."""
    parser = cli_module._parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    choices = {a.dest: a.choices for a in commands.choices["estimate"]._actions}
    assert tuple(choices["method"]) == METHOD_NAMES == METHODS
    assert tuple(choices["timing"]) == TIMINGS


def test_the_data_help_names_the_methods_that_need_the_mode_column(capsys):
    with pytest.raises(SystemExit):
        main(["estimate", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    named = re.search(r"needed by ([a-z0-9, -]+)\)", out).group(1).split(", ")
    assert named == [m for m in METHOD_NAMES if get_method(m).needs_modes]


# what no command's --help may import: each takes from a tenth of a second to over a second
_HEAVY = ("scipy", "numba", "pandas", "matplotlib", "cvxpy", "switchest.experiments",
          "switchest.engine", "switchest.tabular")
# of the estimators, the parser reads the registry of the methods only (with the package and its
# protocol, base, which imports numpy and the core that `import switchest` loads already)
_REGISTRY = {"switchest.estimators", "switchest.estimators.base", "switchest.estimators.registry"}
_HELP = """
import sys
from switchest.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
print(" ".join(sys.modules))
"""


@pytest.mark.parametrize("command", [[], ["demo"], ["list"], ["run"], ["reproduce"],
                                     ["estimate"], ["check"], ["report"]])
def test_help_imports_none_of_the_heavy_modules(command):
    """``switchest [command] --help`` answers at once: it imports neither the experiments, the
    estimators (but their registry), scipy, numba, pandas nor matplotlib (checked in a fresh
    interpreter)."""
    done = subprocess.run([sys.executable, "-c", _HELP, *command, "--help"], capture_output=True,
                          text=True, check=True)
    loaded = set(done.stdout.splitlines()[-1].split())  # the line after the help
    assert not [m for m in _HEAVY if m in loaded], sorted(loaded)
    assert {m for m in loaded if m.startswith("switchest.estimators")} <= _REGISTRY, sorted(loaded)


def test_min_distance_options_override_the_model_file(lee_csv, tmp_path):
    spec, df, path = lee_csv
    out = tmp_path / "e.csv"
    assert main(["estimate", "--model", str(EXAMPLES / "lee-fsk.toml"), "--data", str(path),
                 "--method",
                 "min-distance", "--v-max", "0.2", "--delta", "0.5", "--Delta", "0.75", "--out",
                 str(out)]) == 0
    api = estimate_table(spec, df, method="min-distance", v_max=0.2, delta=0.5, Delta=0.75)
    cli = pd.read_csv(out)
    # the same computation in this process; the CLI's table goes through a CSV file read back by
    # pandas' parser, which is not guaranteed correctly rounded: 1 ulp (NaN where both are NaN)
    np.testing.assert_allclose(cli.to_numpy(dtype=float),
                               api.to_numpy(dtype=float, na_value=np.nan),
                               rtol=np.finfo(float).eps, atol=0, equal_nan=True)
    # the first estimate comes one window after t = 0: 0.5 s here, the file's delta = 0.25 s
    # otherwise
    first = {w: int(np.flatnonzero(table["x0"].notna())[0]) for w, table in
             (("option", cli), ("file", estimate_table(spec, df, method="min-distance")))}
    assert first == {"option": 200, "file": 100}


def test_estimate_errors_name_the_model_tables(lee_csv, tmp_path, capsys):
    spec, _, path = lee_csv
    model = save_model(replace(spec, noise={k: v for k, v in spec.noise.items() if k != "v_max"}),
                       tmp_path / "no-bound.toml")
    args = ["estimate", "--model", str(model), "--data", str(path), "--out",
            str(tmp_path / "e.csv")]
    assert main([*args, "--method", "min-distance"]) == 2
    err = capsys.readouterr().err
    # [noise] is shown, not eaten as rich markup
    assert "add v_max to the model file's [noise] table or pass --v-max" in err
    assert main([*args, "--method", "min-distance", "--v-max=-1"]) == 2
    assert "argument --v-max: expected a finite positive number, got -1" in capsys.readouterr().err
    assert main([*args, "--method", "imm", "--switch-interval", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "switch_interval applies to method 'rsls' only, got method 'imm'" in err


def test_simulate_then_estimate_from_the_shell(tmp_path, capsys):
    model = Path(__file__).resolve().parents[1] / "examples" / "models" / "shankar-boost.toml"
    data, est = tmp_path / "d.csv", tmp_path / "e.csv"
    assert main(["simulate", "--model", str(model), "--duration", "0.05", "--trials", "2",
                 "--input", "100", "--seed", "3", "--out", str(data)]) == 0
    assert "2 trials of 101 samples" in capsys.readouterr().out
    assert main(["estimate", "--model", str(model), "--data", str(data), "--method",
                 "switch-time", "--out", str(est)]) == 2
    assert "--trial" in capsys.readouterr().err
    png = tmp_path / "e.png"
    assert main(["estimate", "--model", str(model), "--data", str(data), "--method",
                 "switch-time", "--trial", "1", "--out", str(est), "--plot", str(png)]) == 0
    assert png.stat().st_size > 10_000  # states with bands, truth, measurements
    window = tmp_path / "w.png"
    assert main(["estimate", "--model", str(model), "--data", str(data), "--method",
                 "switch-time", "--trial", "1", "--out", str(est), "--plot", str(window),
                 "--window", "0.01:0.02"]) == 0
    assert window.stat().st_size > 10_000  # a part of the record
    truth = pd.read_csv(data).query("trial == 1")
    estimate = pd.read_csv(est)
    rmse = np.sqrt(np.mean((estimate["x1"].to_numpy() - truth["x1"].to_numpy()) ** 2))
    assert rmse < np.sqrt(5.0)  # v_0 better than its raw measurement (R = 5 V^2)
    assert main(["simulate", "--model", str(model), "--input", "1,x", "--out",
                 str(data)]) == 2
    assert "--input must be comma-separated numbers" in capsys.readouterr().err


def test_the_multiple_model_methods_from_the_shell(tmp_path, capsys):
    """GPB2 smoothed and the particle filter on simulated data of the vehicle; each estimate
    table is complete, the particle filter's is reproducible from its seed, and the options
    a method does not take are refused by name."""
    model = Path(__file__).resolve().parents[1] / "examples" / "models" / "shankar-vehicle.toml"
    data = tmp_path / "d.csv"
    assert main(["simulate", "--model", str(model), "--duration", "30", "--input", "1",
                 "--seed", "2", "--out", str(data)]) == 0
    args = ["estimate", "--model", str(model), "--data", str(data), "--stay", "0.9"]
    tables = {}
    for name, extra in (("gpb2-smoothed", ["--method", "gpb2", "--smooth"]),
                        ("rbpf", ["--method", "rbpf", "--particles", "200", "--seed", "4"]),
                        ("rbpf-again", ["--method", "rbpf", "--particles", "200", "--seed", "4"])):
        out = tmp_path / f"{name}.csv"
        assert main([*args, *extra, "--out", str(out)]) == 0, name
        tables[name] = pd.read_csv(out)
    for table in tables.values():
        assert {"t", "x0", "std_x0", "mode", "p_mode0"} <= set(table.columns)
        assert np.all(np.isfinite(table[["x0", "x1", "x2", "x3"]].to_numpy()))
    pd.testing.assert_frame_equal(tables["rbpf"], tables["rbpf-again"])
    capsys.readouterr()
    assert main([*args, "--method", "kalman", "--smooth", "--out", str(tmp_path / "k.csv")]) == 2
    said = capsys.readouterr().err
    assert "smooth applies to method 'imm' or 'imm-between' or 'gpb1' or 'gpb2' only" in said
    assert main([*args, "--method", "imm", "--particles", "9", "--out",
                 str(tmp_path / "i.csv")]) == 2
    assert "particles applies to method 'rbpf' only" in capsys.readouterr().err


def test_timing_selects_the_interval_a_mode_governs(tmp_path, capsys):
    """--timing: the default is the model file's (here "sample", the timing simulate draws),
    Bar-Shalom's "interval" is another filter (the vehicle's modes differ in their dynamics),
    and methods without modes to time refuse it."""
    model = Path(__file__).resolve().parents[1] / "examples" / "models" / "shankar-vehicle.toml"
    data = tmp_path / "d.csv"
    assert main(["simulate", "--model", str(model), "--duration", "20", "--input", "1",
                 "--seed", "3", "--out", str(data)]) == 0
    args = ["estimate", "--model", str(model), "--data", str(data), "--stay", "0.9",
            "--method", "imm"]
    tables = {}
    for name, extra in (("default", []), ("sample", ["--timing", "sample"]),
                        ("interval", ["--timing", "interval"])):
        out = tmp_path / f"{name}.csv"
        assert main([*args, *extra, "--out", str(out)]) == 0, name
        tables[name] = pd.read_csv(out)
    pd.testing.assert_frame_equal(tables["default"], tables["sample"])
    states = ["x0", "x1", "x2", "x3"]
    assert np.abs(tables["interval"][states].to_numpy()
                  - tables["sample"][states].to_numpy()).max() > 1e-6
    capsys.readouterr()
    assert main([*args[:-1], "kalman", "--timing", "interval", "--out",
                 str(tmp_path / "k.csv")]) == 2
    assert ("timing applies to method 'imm' or 'gpb1' or 'gpb2' or 'rbpf' only"
            in capsys.readouterr().err)
    assert main([*args, "--timing", "later", "--out", str(tmp_path / "x.csv")]) == 2
    assert "invalid choice: 'later'" in capsys.readouterr().err


def test_run_ends_with_its_figures_and_the_report_command(tmp_path, capsys, monkeypatch):
    """``run NAME`` closes with the folder and names of its figures and the ``report`` command
    that builds the page, a command that runs as printed."""
    monkeypatch.setenv("COLUMNS", "250")
    out = tmp_path / "my out"
    assert main(["run", "shankar-lemma2", "--quick", "--workers", "1", "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-2] == f"figures (1) in {out / 'figures'}{os.sep}: shankar-lemma2.png"
    assert (out / "figures" / "shankar-lemma2.png").is_file()
    said, _, command = lines[-1].partition(": ")
    assert said == "HTML page of the results"
    argv = shlex.split(command)
    assert argv == ["switchest", "report", "--store", str(out / "results.sqlite"), "--out",
                    str(out)]
    assert main(argv[1:]) == 0
    assert "report: " in capsys.readouterr().out
    assert main(["run", "shankar-lemma1", "--quick", "--workers", "1", "--out", str(out)]) == 0
    assert capsys.readouterr().out.splitlines()[-2] == "figures: none for this experiment"


def test_tables_fit_80_columns_and_keep_every_label(tmp_path, capsys, monkeypatch):
    """In a pipe or a log (80 columns) no column is squeezed away: every row still starts with
    its label, and no line is wider than the terminal."""
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["run", "shankar-lemma1", "--quick", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert max(len(line) for line in out.splitlines()) <= 80
    first_cells = [line.split("│")[1].strip() for line in out.splitlines()
                   if line.startswith("│")]
    for label in ("Lemma 1's", "smallest eigenvalue", "corrected statement"):
        assert any(cell.startswith(label.split()[0]) for cell in first_cells), label
    model = Path(__file__).resolve().parents[1] / "examples" / "models" / "wang-ieee5bus.toml"
    assert main(["check", "--model", str(model)]) == 0
    out = capsys.readouterr().out
    assert max(len(line) for line in out.splitlines()) <= 80
    first_cells = [line.split("│")[1].strip() for line in out.splitlines()
                   if line.startswith("│")]
    assert sum(1 for cell in first_cells if len(cell) >= 4) >= 5  # labels, not slivers


def test_estimate_smooths_the_boost_converter(tmp_path, capsys):
    """Issue 35: Kim's smoother wrote states of 1e127 here and exited 0; the two-filter smoother
    (the default) gives finite estimates within the filtered ones' range, and says that its
    model of the switches (at the samples) is not the file's (between them), naming
    ``imm-between``, whose smoother models them there and beats its filter."""
    model = EXAMPLES / "shankar-boost.toml"
    data = tmp_path / "d.csv"
    assert main(["simulate", "--model", str(model), "--seed", "1", "--out", str(data)]) == 0
    said, tables = {}, {}
    for method in ("imm", "imm-between"):
        for extra in ([], ["--smooth"]):
            out = tmp_path / f"{method}{len(extra)}.csv"
            capsys.readouterr()
            assert main(["estimate", "--model", str(model), "--data", str(data), "--method",
                         method, *extra, "--out", str(out)]) == 0
            said[method, bool(extra)] = capsys.readouterr().err
            tables[method, bool(extra)] = pd.read_csv(out)
    assert "switches fall between the samples" in said["imm", True]
    assert "use method 'imm-between'" in said["imm", True]
    assert not any("switches fall between the samples" in said[key] for key in
                   [("imm", False), ("imm-between", False), ("imm-between", True)])
    for method in ("imm", "imm-between"):
        f, s = tables[method, False], tables[method, True]
        assert np.all(np.isfinite(s[["x0", "x1"]].to_numpy()))
        assert np.median(s["std_x1"]) < np.median(f["std_x1"])  # the whole record knows more
    truth = pd.read_csv(data)[["x0", "x1"]].to_numpy()

    def rmse(key):
        return np.sqrt(np.mean((tables[key][["x0", "x1"]].to_numpy() - truth) ** 2, axis=0))

    assert np.all(rmse(("imm-between", True)) < rmse(("imm-between", False)))
    assert np.all(rmse(("imm-between", False)) < rmse(("imm", False)))
    assert tables["imm-between", True]["switch_time"].notna().sum() > 10


def test_the_engines_repair_warning_is_one_line(tmp_path, capsys):
    """The IEEE 5-bus file (unstable A, Q = 0) makes imm-between repair a covariance: the CLI
    says it as one ``warning:`` line, not as Python's warning with file, line and source."""
    model = EXAMPLES / "wang-ieee5bus.toml"
    data, out = tmp_path / "d.csv", tmp_path / "e.csv"
    assert main(["simulate", "--model", str(model), "--seed", "0", "--out", str(data)]) == 0
    capsys.readouterr()
    assert main(["estimate", "--model", str(model), "--data", str(data), "--method",
                 "imm-between", "--out", str(out)]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert any(line.startswith("warning: the state covariance P is singular") for line in lines)
    assert not any("RuntimeWarning" in line or ".py:" in line for line in lines)


def test_estimate_writes_the_outlier_flags_and_counts_them(tmp_path, capsys):
    model = EXAMPLES / "shankar-boost.toml"
    data, out = tmp_path / "d.csv", tmp_path / "e.csv"
    assert main(["simulate", "--model", str(model), "--seed", "2", "--input", "100",
                 "--out", str(data)]) == 0
    frame = pd.read_csv(data)
    frame.loc[40, "y"] = 1e6  # one wild sample, far beyond the gate
    frame.to_csv(data, index=False)
    capsys.readouterr()
    assert main(["estimate", "--model", str(model), "--data", str(data), "--method", "imm",
                 "--gate", "15.1", "--out", str(out)]) == 0  # chi-square 0.9999 of one output
    table = pd.read_csv(out)
    assert table["outlier"].dtype == bool and table["outlier"][40] and table["outlier"].sum() == 1
    assert "1 of 201 measurements were rejected" in capsys.readouterr().err


class _Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_eta_waits_for_a_round_of_the_workers_then_uses_the_finished_tasks():
    """The issue's run: 10 tasks of 40 s on 2 workers. No ETA until both workers finish a
    task; then the time per task of the run (20 s) times the 8 left: 160 s, counting down."""
    clock = _Clock()
    eta = cli_module._Eta(workers=2, clock=clock)
    assert str(eta) == ""  # before the runner's first report
    eta.update(0, 10)
    clock.now += 39.0
    eta.update(0, 10)  # a poll, nothing finished
    assert eta.seconds() is None and str(eta) == ""
    clock.now += 1.0
    eta.update(1, 10)
    assert eta.seconds() is None  # one worker's task says little of the other's
    eta.update(2, 10)
    assert eta.seconds() == pytest.approx(160.0) and str(eta) == "ETA 0:02:40"
    clock.now += 15.0
    assert eta.seconds() == pytest.approx(145.0)  # counts down between tasks
    clock.now += 1000.0
    assert eta.seconds() == 0.0  # late: not negative
    eta.update(10, 10)
    assert str(eta) == ""  # done


def test_eta_of_a_resumed_run_counts_only_its_own_tasks():
    clock = _Clock()
    eta = cli_module._Eta(workers=4, clock=clock)
    eta.update(7, 10)  # 7 stored by an earlier run: 3 left, fewer than the workers
    clock.now += 30.0
    eta.update(9, 10)
    assert eta.seconds() is None  # 2 of the 3 left finished: not yet all of them at once
    eta = cli_module._Eta(workers=1, clock=clock)
    eta.update(7, 10)
    clock.now += 30.0
    eta.update(8, 10)
    assert eta.seconds() == pytest.approx(60.0) and str(eta) == "ETA 0:01:00"
