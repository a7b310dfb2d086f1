"""Model files: exact round trips of every catalog model, and errors that name the key."""

from pathlib import Path

import numpy as np
import pytest

from switchest._toml import ModelFileError
from switchest.measurements import simulate_measurements
from switchest.modelfile import (
    ModelSpec,
    load_model,
    load_system,
    save_model,
    save_system,
    system_from_dict,
    system_to_dict,
)
from switchest.models.catalog import catalog
from switchest.switching import IID, Dwell

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "models"


def same(a: ModelSpec, b: ModelSpec, *, ulps: int = 0) -> bool:
    """Equal specs; arrays within ``ulps`` units in the last place of their largest entry
    (0: bit-identical, as a save/load round trip is: floats are written shortest round-trip)."""
    def equal(x, y):
        x, y = np.asarray(x), np.asarray(y)
        if x.dtype.kind not in "iuf" or y.dtype.kind not in "iuf":  # a name: the switching kind
            return np.array_equal(x, y)
        return x.shape == y.shape and bool(
            np.all(np.abs(x - y) <= ulps * np.spacing(np.max(np.abs(x), initial=0.0))))

    sa, sb = a.system, b.system
    arrays = all(equal(getattr(sa, k), getattr(sb, k)) for k in "ABCQR")
    init = (a.initial is None) == (b.initial is None) and (
        a.initial is None or all(equal(x, y) for x, y in zip(a.initial, b.initial)))
    da, db = (s.switching.to_dict() if s.switching else {} for s in (a, b))
    switching = type(a.switching) is type(b.switching) and da.keys() == db.keys() and all(
        equal(da[k], db[k]) for k in da)
    return (arrays and sa.domain == sb.domain and sa.dt == sb.dt and init and switching
            and a.sampling == b.sampling and a.noise == b.noise and a.description == b.description)


@pytest.mark.parametrize("name", sorted(catalog()))
def test_every_catalog_model_round_trips_exactly(name, tmp_path):
    spec = catalog()[name]
    back = load_model(save_model(spec, tmp_path / f"{name}.toml"))
    assert same(spec, back)
    t = back.sample_times(rng=0)
    assert back.signal(np.random.default_rng(0), t).modes.max() < spec.system.n_modes


@pytest.mark.parametrize("name", sorted(catalog()))
def test_shipped_example_files_match_the_catalog(name):
    # The catalog recomputes some matrices on every call (the smart grid's A and Q are matrix
    # exponentials: a Pade approximant, scaling and squaring, a few hundred operations on 2x2
    # and 4x4 blocks); their last bits differ between CPUs and BLAS builds, by a few ulps of the
    # largest entry for such well-conditioned matrices (1 ulp measured): 32 ulps.
    assert same(catalog()[name], load_model(EXAMPLES / f"{name}.toml"), ulps=32), (
        f"examples/models/{name}.toml is stale: regenerate it with "
        f"save_model(catalog()[{name!r}], ...)")


GOOD = """
domain = "continuous"
[shared]
C = [[1.0, 0.0]]
R = [[0.5]]
[sampling]
period = 0.1
[switching]
kind = "markov"
transition = [[0.9, 0.1], [0.2, 0.8]]
[[modes]]
A = [[0.0, 1.0], [-1.0, 0.0]]
[[modes]]
A = [[-1.0, 0.0], [0.0, -2.0]]
"""


def test_a_hand_written_file_reads(tmp_path):
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    spec = load_model(path)
    assert spec.system.n_modes == 2 and spec.system.n_outputs == 1
    np.testing.assert_array_equal(spec.system.R[1], [[0.5]])
    assert load_system(path).n_states == 2


MALFORMED = [
    ('domain = "continuous"\n[[modes]]\nA = [[1.0, 0.0], [0.0, 1.0]]\n[[modes]]\n'
     'A = [[1.0, 0.0], [0.0]]\n',
     r"modes\[1\]\.A: expected a matrix of numbers"),
    ('domain = "continuous"\n[[modes]]\nA = [[1.0, 0.0], [0.0, 1.0]]\n[[modes]]\n'
     'A = [[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]\n',
     r"modes\[1\]\.A: expected 2x2, got 2x3"),
    ('domain = "hybrid"\n[[modes]]\nA = [[1.0]]\n',
     r"domain: expected \"continuous\" or \"discrete\""),
    ('domain = "discrete"\n[[modes]]\nA = [[1.0]]\n', r"dt: required for a discrete-time system"),
    ('domain = "continuous"\n', r"modes: at least one \[\[modes\]\] table is required"),
    ('domain = "continuous"\n[shared]\nC = [[1.0]]\n[[modes]]\nA = [[1.0]]\nC = [[2.0]]\n',
     r"modes\[0\]\.C: also given in \[shared\]"),
    ('domain = "continuous"\n[[modes]]\nA = [[1.0]]\nR = [[-1.0]]\n',
     r"modes\[0\]\.R must be symmetric positive definite"),
    ('domain = "continuous"\n[[modes]]\nA = [[1.0]]\nZ = 3\n', r"modes\[0\]\.Z: unknown key"),
    ('domain = "continuous"\n[[modes]]\nA = [[1.0]]\n[[modes]]\nA = [[2.0]]\n[switching]\n'
     'kind = "markov"\ntransition = [[0.5, 0.6], [0.5, 0.5]]\n',
     r"switching: transition rows must sum to 1"),
    ('domain = "continuous"\n[[modes]]\nA = [[1.0]]\n[sampling]\nperiod = -0.1\n',
     r"sampling\.period: expected a finite positive number"),
    ('domain = "continuous"\n[[modes]]\nA = [[1.0]]\n[initial]\nmean = [0.0, 1.0]\n',
     r"initial\.mean: expected 1, got 2"),
    ('domain = "continuous"\n[[modes]]\nA = [[1.0]]\n[switching]\nkind = "dwell"\n'
     'min_dwell = 1.0\n',
     r"switching\.max_dwell: required for kind 'dwell'"),
    ('domain = "continuous"\n[[modes\nA = 1\n', r"not valid TOML"),
    ('domain = "continuous"\n[[modes]]\nA = [["-1.0", 0.0], [0.0, -2.0]]\n',
     r"modes\[0\]\.A: expected numbers, got '-1\.0'"),
    ('domain = "continuous"\n[[modes]]\nA = [[-1.0, true], [0.0, -2.0]]\n',
     r"modes\[0\]\.A: expected numbers, got True"),
]


@pytest.mark.parametrize("text, match", MALFORMED, ids=[m for _, m in MALFORMED])
def test_malformed_files_name_the_file_and_key(text, match, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ModelFileError, match=match) as exc:
        load_model(path)
    assert str(path) in str(exc.value)


def test_missing_file():
    with pytest.raises(ModelFileError, match="no such model file"):
        load_model("/nonexistent/model.toml")


@pytest.mark.parametrize("reader", [load_model, load_system])
def test_undecodable_file_names_the_file(reader, tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'domain = "continuous"\n# caf\xe9\n[[modes]]\nA = [[-1.0]]\n')
    with pytest.raises(ModelFileError, match="not a UTF-8 text file") as exc:
        reader(path)
    assert str(path) in str(exc.value)


@pytest.mark.parametrize("name", sorted(catalog()))
def test_a_system_alone_round_trips_exactly(name, tmp_path):
    system = catalog()[name].system
    back = load_system(save_system(system, tmp_path / "system.toml"))
    assert back.domain == system.domain and back.dt == system.dt
    for key in "ABCQR":
        np.testing.assert_array_equal(getattr(back, key), getattr(system, key))
    assert system_to_dict(back).keys() == system_to_dict(system).keys()


def test_a_system_file_ignores_the_other_tables(tmp_path):
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    assert load_system(path).n_modes == 2


def test_system_from_dict_refuses_a_non_dict():
    with pytest.raises(TypeError, match=r"doc must be a dict .* got list"):
        system_from_dict([1, 2])


def test_save_system_refuses_a_model(tmp_path):
    with pytest.raises(TypeError, match="system must be a SwitchedLinearSystem, got ModelSpec"):
        save_system(catalog()["zhang-two-mode"], tmp_path / "x.toml")


def test_the_switching_table_reads_as_a_model(tmp_path):
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    sw = load_model(path).switching
    assert sw.kind == "markov" and sw.at_samples
    np.testing.assert_allclose(sw.transition, [[0.9, 0.1], [0.2, 0.8]])


def test_a_file_without_switching_has_none(tmp_path):
    path = tmp_path / "plain.toml"
    path.write_text('domain = "continuous"\n[[modes]]\nA = [[-1.0]]\n')
    spec = load_model(path)
    assert spec.switching is None
    with pytest.raises(ValueError, match=r"no \[switching\] table"):
        spec.signal(0, np.arange(3.0))


def test_model_spec_checks_its_switching_model():
    system = catalog()["zhang-two-mode"].system
    with pytest.raises(TypeError, match=r"switching must be a SwitchingModel .* got dict"):
        ModelSpec(system, switching={"kind": "iid", "p": [0.5, 0.5]})
    with pytest.raises(ValueError, match="switching switches among 3 modes, the system has 2"):
        ModelSpec(system, switching=IID([0.2, 0.3, 0.5]))
    assert ModelSpec(system, switching=Dwell(2, 1.0, 2.0)).switching.min_dwell == 1.0


def test_the_input_table_is_read_written_and_checked(tmp_path):
    spec = load_model(EXAMPLES / "shankar-boost.toml")
    np.testing.assert_array_equal(spec.input, [100.0])  # v_in = 100 V, Shankar et al. §V.A
    again = load_model(save_model(spec, tmp_path / "again.toml"))
    np.testing.assert_array_equal(again.input, spec.input)
    text = (EXAMPLES / "shankar-boost.toml").read_text()
    for bad, match in [("value = [100.0, 1.0]", r"input\.value"), ("valeu = [100.0]", "value"),
                       ("value = [nan]", "finite")]:
        path = tmp_path / "bad.toml"
        path.write_text(text.replace("value = [100.0]", bad))
        with pytest.raises(ValueError, match=match):
            load_model(path)


def test_simulate_runs_at_the_files_input_by_default():
    spec = load_model(EXAMPLES / "shankar-boost.toml")
    table = simulate_measurements(spec, duration=0.002, rng=0)
    assert np.all(table["u"] == 100.0)
    assert np.all(simulate_measurements(spec, duration=0.002, u=[0.0], rng=0)["u"] == 0.0)


def test_the_timing_key_is_read_written_and_checked(tmp_path):
    spec = load_model(EXAMPLES / "shankar-boost.toml")
    assert spec.timing == "sample"  # the default: the timing simulate draws
    text = (EXAMPLES / "shankar-boost.toml").read_text()
    path = tmp_path / "interval.toml"
    path.write_text('timing = "interval"\n' + text)
    spec = load_model(path)
    assert spec.timing == "interval"
    assert load_model(save_model(spec, tmp_path / "again.toml")).timing == "interval"
    path.write_text('timing = "intervals"\n' + text)
    with pytest.raises(ValueError, match="timing: expected one of 'sample', 'interval'"):
        load_model(path)


@pytest.mark.parametrize("name, between", [
    ("shankar-boost", True),  # continuous time, dwell-time switching in continuous time
    ("wang-example1", False),  # continuous time, switching at the samples
    ("zhang-two-mode", False),  # discrete time
])
def test_whether_the_switches_fall_between_the_samples(name, between):
    assert load_model(EXAMPLES / f"{name}.toml").switches_between_samples is between
