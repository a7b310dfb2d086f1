"""``switchest fit`` from the command line: simulate, fit, then estimate and check with the fitted
model file; the printed table, the log-likelihood trace, the warnings and the bad inputs.

The data come from a small 2-mode discrete-time Markov jump system written to ``tmp_path`` (no
catalog model file switches as a Markov chain). Statistical checks use a fixed seed and a band
of 3 printed standard errors around the truth for each of the 12 fitted entries: under the
asymptotic normality of the MLE each band misses with probability 0.27 %, all of them hold
with probability about 97 %, and the seed makes the outcome deterministic.
"""

import re
from pathlib import Path

import numpy as np
import pytest

import switchest.plotting
from switchest.cli import _FIT_PARAMETERS, main
from switchest.learn import FitResult
from switchest.learn.em import _PARAMETERS
from switchest.learn.model_files import fitted_model
from switchest.modelfile import ModelSpec, load_model
from switchest.switching import MarkovAtSamples, MarkovContinuous
from switchest.system import SwitchedLinearSystem

TRANSITION = np.array([[0.9, 0.1], [0.2, 0.8]])
Q = np.array([np.diag([0.1, 0.05]), np.diag([0.3, 0.1])])
R = np.array([[[0.2]], [[0.5]]])


def model_file(path: Path, transition=TRANSITION, Q=Q, R=R, *, initial: bool = True) -> Path:
    """A 2-mode discrete-time Markov jump system (n = 2, m = 1) as a TOML model file."""
    def matrix(a) -> str:
        return "[" + ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]"
                               for row in np.atleast_2d(a)) + "]"

    prior = "[initial]\nmean = [0.0, 0.0]\ncov = [[1.0, 0.0], [0.0, 1.0]]\n" if initial else ""
    A = [[[0.9, 0.1], [0.0, 0.8]], [[0.5, -0.3], [0.2, 0.7]]]
    C = [[[1.0, 0.0]], [[1.0, 1.0]]]
    modes = "".join(f"\n[[modes]]\nA = {matrix(A[j])}\nC = {matrix(C[j])}\nQ = {matrix(Q[j])}\n"
                    f"R = {matrix(R[j])}\n" for j in range(2))
    path.write_text(f'description = "a 2-mode Markov jump system"\ndomain = "discrete"\n'
                    f'dt = 1.0\n\n[sampling]\nduration = 1000.0\n\n[switching]\nkind = "markov"\n'
                    f"transition = {matrix(transition)}\n\n{prior}{modes}")
    return path


def printed_rows(out: str) -> dict[str, tuple[float, float]]:
    """The rows of the fitted-parameters table: label -> (fitted, standard error)."""
    rows = {}
    for line in out.splitlines():
        cells = [c.strip() for c in line.split("│")[1:-1]]
        if len(cells) == 4 and re.fullmatch(r"-?[\d.e+-]+", cells[1]):
            rows[cells[0]] = (float(cells[1]), np.nan if cells[2] == "—" else float(cells[2]))
    return rows


def test_fit_names_the_learners_parameters():
    assert _FIT_PARAMETERS == _PARAMETERS


def test_simulate_fit_estimate_check_from_the_shell(tmp_path, capsys, monkeypatch):
    truth = model_file(tmp_path / "truth.toml")
    start = model_file(tmp_path / "start.toml", np.array([[0.8, 0.2], [0.3, 0.7]]), 1.5 * Q,
                       0.7 * R)
    data, fitted, png = tmp_path / "d.csv", tmp_path / "fitted.toml", tmp_path / "ll.png"
    # seed 3: the maximum is interior (with seed 7 mode 0's Q is singular there, a boundary
    # maximum the fit names in a warning; 2 seeds of 0..7 put it there)
    assert main(["simulate", "--model", str(truth), "--duration", "1500", "--trials", "2",
                 "--seed", "3", "--out", str(data)]) == 0
    capsys.readouterr()
    traces = []
    draw = switchest.plotting.curves
    monkeypatch.setattr(switchest.plotting, "curves",
                        lambda path, x, series, **kw: (traces.append(series["log-likelihood"]),
                                                       draw(path, x, series, **kw))[1])
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["fit", "--model", str(start), "--data", str(data), "--out", str(fitted),
                 "--plot", str(png)]) == 0
    out, err = capsys.readouterr()
    assert err == ""  # no warning on identifiable data with known modes
    assert max(len(line) for line in out.splitlines()) <= 80
    said = " ".join(out.split())  # rich wraps the summary line at 80 columns
    assert "2 trials x 1501 samples, known modes" in said and ", converged;" in said
    assert png.stat().st_size > 5_000
    trace = traces[0]
    assert trace.size > 2 and trace[-1] > trace[0]
    # exact EM: monotone up to the rounding of a sum of 3002 log-densities (~1e-12 relative)
    assert np.all(np.diff(trace) >= -1e-10 * np.abs(trace[1:]))

    rows = printed_rows(out)
    spec = load_model(fitted)
    expected = {f"transition {i}→{j}": (spec.switching.transition[i, j], TRANSITION[i, j])
                for i in range(2) for j in range(2)}
    for name, fit_stack, true_stack in (("Q", spec.system.Q, Q), ("R", spec.system.R, R)):
        for j in range(2):
            for a, b in zip(*np.triu_indices(true_stack.shape[1])):
                expected[f"{name} mode {j} [{a},{b}]"] = (fit_stack[j, a, b], true_stack[j, a, b])
    assert set(rows) == set(expected)
    for label, (in_file, true) in expected.items():
        value, se = rows[label]
        assert value == pytest.approx(in_file, rel=1e-5, abs=1e-6), label  # printed with .6g
        assert abs(in_file - true) <= 3 * se, (label, in_file, true, se)
    assert isinstance(spec.switching, MarkovAtSamples)
    np.testing.assert_array_equal(spec.system.A, load_model(truth).system.A)  # not estimated
    assert spec.initial is not None and spec.sampling == {"duration": 1000.0}

    assert main(["estimate", "--model", str(fitted), "--data", str(data), "--trial", "1",
                 "--method", "imm", "--out", str(tmp_path / "e.csv")]) == 0
    assert main(["check", "--model", str(fitted)]) == 0
    capsys.readouterr()
    assert main(["fit", "--model", str(start), "--data", str(data), "--trial", "1",
                 "--estimate", "R", "--max-iter", "3", "--out", str(fitted)]) == 0
    out = capsys.readouterr().out
    assert ("1501 samples, known modes (mode column), switches at the samples: 3 iterations, "
            "stopped at --max-iter 3") in " ".join(out.split())
    assert set(printed_rows(out)) == {"R mode 0 [0,0]", "R mode 1 [0,0]"}
    kept = load_model(fitted)
    np.testing.assert_array_equal(kept.system.Q, 1.5 * Q)  # not estimated: the start's
    np.testing.assert_array_equal(kept.switching.transition, [[0.8, 0.2], [0.3, 0.7]])


def test_a_mode_never_visited_is_named_in_a_warning(tmp_path, capsys):
    truth = model_file(tmp_path / "m.toml", np.array([[1.0, 0.0], [0.5, 0.5]]))
    data = tmp_path / "d.csv"
    assert main(["simulate", "--model", str(truth), "--duration", "200", "--out",
                 str(data)]) == 0
    text = data.read_text().splitlines()
    column = text[0].split(",").index("mode")
    rows = [line.split(",") for line in text[1:]]
    for row in rows:
        row[column] = "0"  # the chain starts in a random mode: make it mode 0 throughout
    data.write_text("\n".join([text[0], *(",".join(r) for r in rows)]) + "\n")
    capsys.readouterr()
    assert main(["fit", "--model", str(truth), "--data", str(data), "--max-iter", "5",
                 "--out", str(tmp_path / "f.toml")]) == 0
    err = capsys.readouterr().err
    assert "warning: mode 1 was never visited" in err


def test_fitted_switching_of_a_continuous_time_chain():
    """A markov-continuous model gets the fitted generator where one exists, else a per-sample
    chain; a model whose transition matrix was not fitted keeps its switching model."""
    system = SwitchedLinearSystem.continuous(-np.eye(1)[None].repeat(2, 0), None,
                                             np.ones((2, 1, 1)), np.ones((2, 1, 1)),
                                             np.ones((2, 1, 1)))
    rates = np.array([[-1.0, 1.0], [2.0, -2.0]])
    spec = ModelSpec(system=system, sampling={"period": 0.1},
                     switching=MarkovContinuous(rates, initial_mode=1),
                     initial=(np.zeros(1), np.eye(1)))
    P = np.array([[0.9, 0.1], [0.2, 0.8]])
    result = FitResult(system, P, np.zeros(1), True, 1, {}, rates=2 * rates)
    fitted, note = fitted_model(spec, result, ("transition", "Q"), Path("d.csv"))
    assert isinstance(fitted.switching, MarkovContinuous) and "generator" in note
    np.testing.assert_array_equal(fitted.switching.rates, 2 * rates)
    assert fitted.switching.initial_mode == 1 and "Fitted by switchest fit" in fitted.description
    no_generator = FitResult(system, P, np.zeros(1), True, 1, {}, rates=None)
    fitted, note = fitted_model(spec, no_generator, ("transition",), Path("d.csv"))
    assert isinstance(fitted.switching, MarkovAtSamples) and "switches at the samples" in note
    np.testing.assert_array_equal(fitted.switching.transition, P)
    fitted, note = fitted_model(spec, no_generator, ("Q",), Path("d.csv"))
    assert fitted.switching is spec.switching and "kept" in note


def test_bad_inputs_get_one_clear_line(tmp_path, capsys):
    model = model_file(tmp_path / "m.toml")
    data = tmp_path / "d.csv"
    assert main(["simulate", "--model", str(model), "--duration", "20", "--trials", "2",
                 "--out", str(data)]) == 0
    capsys.readouterr()
    out = str(tmp_path / "f.toml")
    cases = [
        (["--data", str(tmp_path / "none.csv")], "no such file"),
        (["--estimate", "transition,Qd"], "--estimate: unknown parameter(s) 'Qd'; expected "
                                          "comma-separated names among transition"),
        (["--estimate", "tranistion,q,xyz"], "--estimate: unknown parameter(s) 'tranistion', "
                                             "'q', 'xyz'; expected comma-separated names among "
                                             "transition, A, B, C, Q, R; did you mean "
                                             "'transition' for 'tranistion', 'Q' for 'q'? (see"),
        (["--shared", "QQ"], "--shared: unknown parameter(s) 'QQ'; expected comma-separated "
                             "names among A, B, C, Q, R; did you mean 'Q' for 'QQ'? (see"),
        (["--estimate", "transition", "--trial", "5"], "trial=5"),
        (["--max-iter", "0"], "--max-iter: expected a positive integer"),
    ]
    for extra, message in cases:
        argv = ["fit", "--model", str(model), "--data", str(data), "--out", out, *extra]
        assert main(argv) == 2, extra
        err = capsys.readouterr().err
        assert message in err and len(err.splitlines()) == 1, (extra, err)
    assert main(["fit", "--model", str(model), "--data", str(data), "--out",
                 str(tmp_path / "f.csv")]) == 2
    assert "expected a file name ending in one of .toml" in capsys.readouterr().err
    bare = model_file(tmp_path / "bare.toml", initial=False)
    assert main(["fit", "--model", str(bare), "--data", str(data), "--out", out]) == 2
    assert "needs an [initial] table" in capsys.readouterr().err
    rows = data.read_text().splitlines()
    t = rows[0].split(",").index("t")
    shifted = [rows[0]] + [",".join(str(float(v) + 0.5) if i == t and r.startswith("1,") else v
                                    for i, v in enumerate(r.split(","))) for r in rows[1:]]
    data.write_text("\n".join(shifted) + "\n")
    assert main(["fit", "--model", str(model), "--data", str(data), "--out", out]) == 2
    assert "trial 1 is sampled at other times than trial 0" in capsys.readouterr().err
