"""The registry of methods is the one front door: every row resolves, builds its estimator from
a model file and runs it with the keywords it takes, and a new row alone is offered by
estimate_table and ``switchest estimate --method``."""

import subprocess
import sys
from importlib import import_module
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from switchest.cli import main
from switchest.estimators import (
    Estimator,
    IMMFilter,
    Method,
    RBPFilter,
    SwitchTimeKalmanFilter,
    get_method,
    methods,
    methods_with,
    registry,
)
from switchest.modelfile import load_model
from switchest.simulate import simulate
from switchest.tabular import estimate_table

BOOST = Path(__file__).resolve().parents[2] / "examples" / "models" / "shankar-boost.toml"


# ------------------------------------------------------------------ the table
_READ = """
import sys
from switchest.estimators.registry import methods, methods_with
print([(m.name, m.options, m.description, m.needs_modes) for m in methods()], methods_with("grid"))
print(" ".join(sys.modules))
"""


def test_reading_the_table_imports_no_estimator():
    """Names, options and descriptions come without an estimator module, scipy, pandas or numba
    (what lets the command line's parser read them: checked in a fresh interpreter)."""
    done = subprocess.run([sys.executable, "-c", _READ], capture_output=True, text=True,
                          check=True)
    loaded = set(done.stdout.splitlines()[-1].split())
    estimators = {m for m in loaded if m.startswith("switchest.estimators")}
    assert estimators == {"switchest.estimators", "switchest.estimators.base",
                          "switchest.estimators.registry"}
    assert not [m for m in ("scipy", "pandas", "numba", "switchest.engine") if m in loaded]


@pytest.mark.parametrize("entry", methods(), ids=lambda m: m.name)
def test_every_row_names_an_estimator_and_a_builder(entry):
    assert issubclass(entry.estimator, Estimator)
    module, _, name = entry.builder.partition(":")
    assert callable(getattr(import_module(module, "switchest.estimators"), name))
    assert entry.switching in ("modes", "signals", None)
    assert entry.transition in ("required", "optional", "unused")


def test_options_are_looked_up_by_method():
    assert methods_with("grid") == ("switch-time", "imm-between", "imm-ev1")
    assert methods_with("smooth") == ("imm", "imm-between", "gpb1", "gpb2")
    assert methods_with("proposal") == ()  # a constructor's keyword, no user option


# ------------------------------------------------------------------ build
@pytest.fixture(scope="module")
def boost():
    """The boost converter's model file and 0.02 s of its data (41 samples)."""
    spec = load_model(BOOST)
    t = spec.sample_times(0.02)
    traj = simulate(spec.system, lambda r: spec.signal(r, t), t, spec.initial, u=np.array([100.0]),
                    rng=3)
    data = pd.DataFrame({"t": t, "u": 100.0, "y": traj.y[0, :, 0], "mode": traj.mode[0]})
    return spec, data


def test_build_passes_the_constructors_keywords_on(boost):
    spec, data = boost
    t = data["t"].to_numpy()
    est = get_method("switch-time").build(spec, t, grid=2, switch_time="marginal")
    assert isinstance(est, SwitchTimeKalmanFilter)
    assert (est.grid, est.switch_time) == (2, "marginal")
    assert isinstance(get_method("rbpf").build(spec, t, particles=10, seed=4), RBPFilter)


def test_build_refuses_what_does_not_apply(boost):
    spec, data = boost
    t = data["t"].to_numpy()
    with pytest.raises(ValueError, match="grid applies to method 'switch-time' or 'imm-between' "
                                         "or 'imm-ev1' only, got method 'kalman'"):
        get_method("kalman").build(spec, t, grid=3)
    with pytest.raises(TypeError, match=r"takes the seed of its random numbers as seed=, got "
                                        r"rng="):
        get_method("rbpf").build(spec, t, rng=1)
    with pytest.raises(TypeError, match="unexpected keyword argument 'proposal'"):
        get_method("imm").build(spec, t, proposal="optimal")
    with pytest.raises(TypeError, match="spec must be a ModelSpec .* got SwitchedLinearSystem"):
        get_method("imm").build(spec.system, t)


# ------------------------------------------------------------------ run
class _Recorder:
    """Stands for an estimator: returns what its ``run`` or ``smooth`` was called with."""

    def run(self, y, u, t, **told):
        return "run", u, told

    def smooth(self, y, u, t):
        return "smooth", u, {}


def test_run_tells_each_method_what_it_takes_and_nothing_else():
    t, y, u = np.arange(4.0), np.zeros((4, 1)), np.zeros((4, 1))
    modes, signal, segments = np.array([0, 0, 1, 1]), object(), object()
    known = {"modes": modes, "signals": signal, "segments": segments}
    rec = _Recorder()
    assert get_method("kalman").run(rec, y, u, t, **known) == ("run", u, {"modes": modes,
                                                                          "segments": segments})
    assert get_method("switch-time").run(rec, y, u, t, modes=modes) == ("run", u,
                                                                        {"modes": modes})
    assert get_method("imm").run(rec, y, u, t, **known) == ("run", u, {})
    assert get_method("imm").run(rec, y, u, t, smooth=True) == ("smooth", u, {})
    assert get_method("impulsive").run(rec, y, u, t, **known) == ("run", u, {"signals": signal})
    # without a signal, the one the modes switch by at the samples
    told = get_method("impulsive").run(rec, y, u, t, modes=modes)[2]["signals"]
    np.testing.assert_array_equal(told.times, [2.0])
    np.testing.assert_array_equal(told.modes, [0, 1])
    # Wang et al.'s model has no input: an input without columns is none
    assert get_method("rsls").run(rec, y, np.zeros((4, 0)), t, modes=modes) == (
        "run", None, {"modes": modes})


def test_run_refuses_what_the_method_cannot_take():
    t, y, u, rec = np.arange(4.0), np.zeros((4, 1)), np.zeros((4, 1)), _Recorder()
    with pytest.raises(ValueError, match="method 'kalman' needs modes, the known mode at each "
                                         "sample"):
        get_method("kalman").run(rec, y, u, t)
    with pytest.raises(ValueError, match="method 'impulsive' needs signals, the switching "
                                         "signal, or modes"):
        get_method("impulsive").run(rec, y, u, t)
    with pytest.raises(ValueError, match=r"smooth applies to method 'imm' or 'imm-between' or "
                                         r"'gpb1' or 'gpb2' only, got method 'kalman'"):
        get_method("kalman").run(rec, y, u, t, modes=np.zeros(4, int), smooth=True)
    with pytest.raises(TypeError, match="smooth must be True or False, got str"):
        get_method("imm").run(rec, y, u, t, smooth="yes")
    with pytest.raises(ValueError, match=r"u must be None or have no columns: method 'rsls' "
                                         r"takes no input, got shape \(4, 1\)"):
        get_method("rsls").run(rec, y, u, t, modes=np.zeros(4, int))


# ------------------------------------------------------------------ a new method is one row
class ToyFilter(IMMFilter):
    """A method the package does not know: the IMM filter under another name."""


_TOY = Method("toy", f"{__name__}:ToyFilter", None, "required", ("stay", "timing"),
              "the IMM filter under another name", "none")


@pytest.mark.filterwarnings("ignore::switchest.tabular.ImplausibleEstimateWarning")
def test_a_new_method_is_one_registry_row(boost, monkeypatch, tmp_path, capsys):
    """A row added to the table, and nothing else, is offered by estimate_table (with the user
    options it names, refused for the others) and by ``switchest estimate --method`` (its
    choices, its help, the help of its options)."""
    spec, data = boost
    monkeypatch.setitem(registry._TABLE, "toy", _TOY)
    toy = estimate_table(spec, data, method="toy", stay=0.8, timing="sample")
    imm = estimate_table(spec, data, method="imm", stay=0.8, timing="sample")
    pd.testing.assert_frame_equal(toy, imm, check_exact=True)
    with pytest.raises(ValueError, match="grid applies to method 'switch-time' or 'imm-between' "
                                         "or 'imm-ev1' only, got method 'toy'"):
        get_method("toy").build(spec, data["t"].to_numpy(), grid=3)
    with pytest.raises(ValueError, match="timing applies to method 'imm' or 'gpb1' or 'gpb2' or "
                                         "'rbpf' or 'toy' only, got method 'kalman'"):
        estimate_table(spec, data, method="kalman", timing="sample")

    with pytest.raises(SystemExit):
        main(["estimate", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "toy: the IMM filter under another name" in out
    assert "imm-ev1, toy: per-sample probability of staying in a mode" in out
    assert "rbpf, toy: which interval the mode of a sample governs" in out
    path, est = tmp_path / "data.csv", tmp_path / "est.csv"
    data.to_csv(path, index=False)
    assert main(["estimate", "--model", str(BOOST), "--data", str(path), "--method", "toy",
                 "--stay", "0.8", "--timing", "sample", "--out", str(est)]) == 0
    # the same computation in this process, through a CSV file read back by pandas' parser
    np.testing.assert_allclose(pd.read_csv(est).to_numpy(dtype=float), toy.to_numpy(dtype=float),
                               rtol=1e-15, atol=0, equal_nan=True)
