"""Malformed model files and CSV data files give a clear error naming the file, or a valid result.

Property-based (hypothesis): each example starts from a valid shipped model file or a valid
measurement table, damages it at random (key typos, wrong types, non-numeric cells, ragged rows,
extra or duplicated columns), and loads it. The only acceptable outcomes are a ValueError/TypeError
whose message names the file, or a result that passes the checks a valid one must pass; any other
exception fails the test. Then one test per class of bad input pins its message.
"""

import copy
import csv
import io
import string
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from switchest import SwitchedLinearSystem
from switchest._toml import ModelFileError, dumps
from switchest.measurements import read_measurements
from switchest.modelfile import load_model

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "models"
BASES = {name: tomllib.loads((EXAMPLES / f"{name}.toml").read_text())
         for name in ("lee-fsk", "shankar-boost", "zhang-two-mode", "etienne-academic")}
LEE = load_model(EXAMPLES / "lee-fsk.toml")  # 2 outputs, 1 input, 2 modes
FAST = settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# -------------------------------------------------------------- strategies
KEY_CHARS = string.ascii_letters + string.digits + "_"
values = st.one_of(
    st.text(max_size=8),
    st.booleans(),
    st.integers(-5, 5),
    st.floats(allow_nan=True, allow_infinity=True),
    st.lists(st.floats(-10, 10), max_size=3),
    st.lists(st.lists(st.floats(-10, 10), max_size=3), max_size=3),  # ragged matrices too
    st.lists(st.text(max_size=3), min_size=1, max_size=2),
    st.lists(st.booleans(), min_size=1, max_size=2),
)


def typo(draw, key: str) -> str:
    """A misspelling of ``key``: a character dropped, doubled, replaced, or the case changed."""
    i = draw(st.integers(0, max(len(key) - 1, 0)))
    kind = draw(st.sampled_from(["drop", "double", "replace", "case"]))
    if kind == "case":
        return key.swapcase() if key.swapcase() != key else key + "x"
    if not key:
        return "x"
    if kind == "replace":
        other = draw(st.sampled_from(KEY_CHARS.replace(key[i], "")))
        return key[:i] + other + key[i + 1:]
    return key[:i] + (key[i] * 2 if kind == "double" else "") + key[i + 1:]


def tables(doc: dict) -> list[tuple[str, dict]]:
    """Every table of a parsed model file, with its name: the top level, the tables, each mode."""
    found = [("", doc)] + [(k, v) for k, v in doc.items() if isinstance(v, dict)]
    return found + [(f"modes[{i}]", m) for i, m in enumerate(doc.get("modes", []))]


@st.composite
def damaged_model(draw) -> dict:
    """A shipped model file with one to three keys misspelt, retyped, added or removed."""
    doc = copy.deepcopy(draw(st.sampled_from(list(BASES.values()))))
    for _ in range(draw(st.integers(1, 3))):
        _, table = draw(st.sampled_from(tables(doc)))
        keys = sorted(table)
        action = draw(st.sampled_from(["typo", "retype", "add", "remove"] if keys else ["add"]))
        if action == "add":
            table[draw(st.text(KEY_CHARS, min_size=1, max_size=8))] = draw(values)
            continue
        key = draw(st.sampled_from(keys))
        if action == "typo":
            table[typo(draw, key)] = table.pop(key)
        elif action == "retype" and not (key == "modes" and table is doc):
            table[key] = draw(values)
        else:
            del table[key]
    return doc


CELLS = ["n/a", "NA", "N/A", "null", "NULL", "-", "--", "none", "None", "?", "inf", "-inf", "1e999",
         "abc", "1,5", "0x10", "1_000", "True", "", " ", "nan", "NaN", " 2.5 ", "+3", "1e-3"]


@st.composite
def damaged_csv(draw) -> tuple[str, list[list[str]]]:
    """A valid lee-fsk measurement table (2 outputs, 1 input, mode), damaged one to three times."""
    k = draw(st.integers(1, 6))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    rows = [["t", "u", "y0", "y1", "mode"]] + [
        [repr(0.0025 * i), repr(float(rng.normal())), repr(float(rng.normal())),
         repr(float(rng.normal())), str(int(rng.integers(2)))] for i in range(k)]
    for _ in range(draw(st.integers(1, 3))):
        r = draw(st.integers(0, len(rows) - 1))
        c = draw(st.integers(0, len(rows[r]) - 1)) if rows[r] else 0
        action = draw(st.sampled_from(["cell", "text", "short", "long", "column", "duplicate",
                                       "rename", "order"]))
        if action in ("cell", "text") and rows[r] and r > 0:
            rows[r][c] = draw(st.sampled_from(CELLS) if action == "cell" else st.text(max_size=6))
        elif action == "short" and rows[r]:
            rows[r].pop(c)
        elif action == "long":
            rows[r].append(draw(st.sampled_from(CELLS)))
        elif action == "column":
            name = draw(st.sampled_from(["y2", "y", "u1", "u0", "y10", "extra", "mode", "t"]))
            rows = [row + [name if i == 0 else draw(st.sampled_from(CELLS))]
                    for i, row in enumerate(rows)]
        elif action == "duplicate" and len(rows[0]) > 1:
            h = draw(st.integers(0, len(rows[0]) - 1))
            rows[0][h] = rows[0][(h + 1) % len(rows[0])]
        elif action == "rename" and rows[0]:
            h = draw(st.integers(0, len(rows[0]) - 1))
            rows[0][h] = typo(draw, rows[0][h])
        elif action == "order" and len(rows) > 2:
            rows[1], rows[-1] = rows[-1], rows[1]
    text = io.StringIO()
    csv.writer(text).writerows(rows)
    return text.getvalue(), rows


# -------------------------------------------------------------- the properties
@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("inputs")


@FAST
@given(doc=damaged_model())
def test_damaged_model_files_give_a_clear_error_or_a_valid_model(doc, folder):
    path = folder / "damaged.toml"
    try:
        path.write_text(dumps(doc), encoding="utf-8")
    except (TypeError, UnicodeEncodeError):  # a value TOML cannot hold: no file to load
        return
    try:
        spec = load_model(path)
    except (ValueError, TypeError) as exc:
        assert str(path) in str(exc), exc
        return
    assert isinstance(spec.system, SwitchedLinearSystem)
    assert all(np.all(np.isfinite(getattr(spec.system, k))) for k in "ABCQR")
    assert all(np.isfinite(v) and v >= 0 for v in spec.noise.values())
    assert all(np.isfinite(v) and v > 0 for v in spec.sampling.values())


@FAST
@given(case=damaged_csv())
def test_damaged_csv_files_give_a_clear_error_or_valid_measurements(case, folder):
    text, _ = case
    path = folder / "damaged.csv"
    path.write_text(text, encoding="utf-8", newline="")
    try:
        meas = read_measurements(path, LEE)
    except (ValueError, TypeError) as exc:
        assert str(path) in str(exc), exc
        return
    t, y, u = meas["t"], meas["y"], meas["u"]
    assert t.ndim == 1 and np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)
    assert y.shape == (t.size, 2) and u.shape == (t.size, 1) and np.all(np.isfinite(u))
    assert not np.any(np.isinf(y))
    assert "mode" not in meas or np.all((meas["mode"] >= 0) & (meas["mode"] < 2))



# -------------------------------------------------------------- one test per class: model files
MODEL_HEAD = 'domain = "continuous"\n[[modes]]\nA = [[-1.0, 0.0], [0.0, -2.0]]\n'


@pytest.mark.parametrize("text, match", [
    ('domian = "continuous"\n[[modes]]\nA = [[1.0]]\n',
     r": domian: unknown key; did you mean 'domain'\? expected one of description, domain, dt, "),
    (MODEL_HEAD + "[noise]\nv_mx = 0.1\n", r"noise\.v_mx: unknown key; did you mean 'v_max'\?"),
    (MODEL_HEAD + "[noise]\ndelta_t = 0.1\n",
     r"noise\.delta_t: unknown key; did you mean 'delta'\?"),
    (MODEL_HEAD + "[sampling]\nperoid = 0.1\n",
     r"sampling\.peroid: unknown key; did you mean 'period'"),
    (MODEL_HEAD + "[initial]\nmean = [0.0, 0.0]\ncovar = [[1.0, 0.0], [0.0, 1.0]]\n",
     r"initial\.covar: unknown key; did you mean 'cov'\?"),
    ('domain = "continuous"\n[[modes]]\na = [[1.0]]\n',
     r"modes\[0\]\.a: unknown key; did you mean 'A'\?"),
    ('domain = "continuous"\n[shared]\nCC = [[1.0]]\n[[modes]]\nA = [[1.0]]\n',
     r"shared\.CC: unknown key; did you mean 'C'\?"),
    (MODEL_HEAD + '[switching]\nkind = "markv"\n', r"switching\.kind: did you mean 'markov'\?"),
    (MODEL_HEAD + '[switching]\nkind = "dwell"\nmin_dwel = 1.0\nmax_dwell = 2.0\n',
     r"switching\.min_dwel: unknown key; did you mean 'min_dwell'\?"),
    (MODEL_HEAD + '[switching]\nkind = "dwell"\nmin_dwell = 1.0\nmax_dwell = 2.0\ntau_a = 1.0\n',
     r"switching\.tau_a: not a parameter of kind 'dwell' \(it is one of kind 'average-dwell'\)"),
    (MODEL_HEAD + "[unknown_table]\nx = 1\n", r"unknown_table: unknown key; expected one of"),
])
def test_unknown_keys_at_every_level_name_file_table_key_and_suggest(text, match, tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(text)
    with pytest.raises(ModelFileError, match=match) as exc:
        load_model(path)
    assert str(exc.value).startswith(f"{path}: ")


@pytest.mark.parametrize("entry, match", [
    ("v_max = -0.1", r"noise\.v_max: a bound on a norm must be >= 0, got -0.1"),
    ("u_max = -1", r"noise\.u_max: a bound on a norm must be >= 0, got -1"),
    ("x_min = nan", r"noise\.x_min: expected a finite number, got nan"),
    ("delta = 0.0", r"noise\.delta: expected a finite positive number, got 0.0"),
    ("Delta = -1.0", r"noise\.Delta: expected a finite positive number, got -1.0"),
    ("observer_decay = inf", r"noise\.observer_decay: expected a finite positive number, got inf"),
    ('v_max = "0.1"', r"noise\.v_max: expected a number, got '0.1'"),
])
def test_noise_values_are_validated(entry, match, tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(MODEL_HEAD + f"[noise]\n{entry}\n")
    with pytest.raises(ModelFileError, match=match):
        load_model(path)


def test_noise_bounds_of_zero_are_valid(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(MODEL_HEAD + "[noise]\nv_max = 0.0\nu_max = 0\nx_min = 0.5\n")
    assert load_model(path).noise == {"v_max": 0.0, "u_max": 0.0, "x_min": 0.5}


@pytest.mark.parametrize("switching, match", [
    ('kind = "schedule"\ntimes = [1.0]\nmodes = [0, true]',
     r"switching\.modes: expected a list of mode"),
    ('kind = "schedule"\ntimes = [1.0]\nmodes = [0, 2]',
     r"switching\.modes: .* in 0\.\.1, got \[0, 2\]"),
    ('kind = "markov"\ntransition = [[0.5, 0.5], [0.5, 0.5]]\ninitial = true',
     r"switching\.initial: expected a mode index in 0\.\.1, got True"),
])
def test_switching_mode_indices_are_checked(switching, match, tmp_path):
    path = tmp_path / "m.toml"
    second = "[[modes]]\nA = [[-3.0, 0.0], [0.0, -4.0]]\n"
    path.write_text(f"{MODEL_HEAD}{second}[switching]\n{switching}")
    with pytest.raises(ModelFileError, match=match):
        load_model(path)


def test_a_file_that_is_not_utf8_is_named(tmp_path):
    path = tmp_path / "m.toml"
    path.write_bytes(b'domain = "continuous"\n\xff\n')
    with pytest.raises(ModelFileError, match=r"m\.toml: not a UTF-8 text file: .* byte 0xff"):
        load_model(path)


def test_a_fast_switching_model_loads(tmp_path):
    """Parameters are probed over a few dwell times, not over a fixed 3 s: a 1 microsecond dwell
    (a million switches a second, 3 million in 3 s) is valid and loads at once."""
    path = tmp_path / "m.toml"
    path.write_text(MODEL_HEAD + "[[modes]]\nA = [[-3.0, 0.0], [0.0, -4.0]]\n[switching]\n"
                    'kind = "dwell"\nmin_dwell = 1e-6\nmax_dwell = 2e-6\n')
    assert load_model(path).switching.min_dwell == 1e-6


# -------------------------------------------------------------- one test per class: CSV files
CSV_HEAD = "t,u,y0,y1,mode\n0,0.01,1.0,0.0,0\n"


@pytest.mark.parametrize("text, match", [
    (CSV_HEAD + "0.0025,0.01,n/a,0.0,0\n",
     r"data row 1 \(line 3\), column 'y0': not a number \('n/a'\)"),
    (CSV_HEAD + "0.0025,0.01,NA,0.0,0\n", r"column 'y0': not a number \('NA'\)"),
    (CSV_HEAD + "0.0025,0.01,null,0.0,0\n", r"column 'y0': not a number \('null'\)"),
    (CSV_HEAD + "0.0025,0.01,-,0.0,0\n", r"column 'y0': not a number \('-'\)"),
    (CSV_HEAD + "0.0025,n/a,1.0,0.0,0\n", r"column 'u': not a number \('n/a'\)"),
    (CSV_HEAD + "0.0025,0.01,inf,0.0,0\n", r"column 'y0': inf is not a finite number"),
    ("t,u,y0,y1,y2\n0,0.01,1.0,0.0,3.0\n",
     r"data has column\(s\) \['y2'\] the model does not have"),
    ("t,u,u1,y0,y1\n0,0.01,1.0,0.0,3.0\n",
     r"\['u1'\] the model does not have: its outputs and inputs are \['u', 'y0', 'y1'\]"),
    ("t,u,y0,y0,y1\n0,0.01,1.0,0.0,3.0\n",
     r"data: column 'y0' appears more than once in the header"),
    (CSV_HEAD + "0.0025,0.01,1.0,0\n", r": line 3 has 4 field\(s\), the header has 5"),
    (CSV_HEAD + "0.0025,0.01,1.0,0.0,0,7\n", r": line 3 has 6 field\(s\), the header has 5"),
    (CSV_HEAD + "inf,0.01,1.0,0.0,0\n",
     r"row 1 \(line 3\), column 't': inf is not a finite number"),
    (CSV_HEAD + "nan,0.01,1.0,0.0,0\n",
     r"column 't': empty \(or NaN\); only the outputs y may be missing"),
    (CSV_HEAD + "-1,0.01,1.0,0.0,0\n", r"row 1 \(line 3\): time -1 is before the previous row's"),
    (CSV_HEAD + "0,0.01,1.0,0.0,0\n", r"row 1 \(line 3\): time 0 repeats the previous row"),
    (CSV_HEAD + "0.0025,0.01,1.0,0.0,0.5\n", r"column 'mode': 0.5 is not a mode index"),
    ("t,u,y0,y1\n", r"data has no rows"),
    ("", r"empty file; expected a header line"),
])
def test_bad_csv_files_name_file_row_and_column(text, match, tmp_path):
    path = tmp_path / "d.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=match) as exc:
        read_measurements(path, LEE)
    assert str(exc.value).startswith(f"{path}: ")


def test_only_empty_and_nan_cells_are_missing_samples(tmp_path):
    path = tmp_path / "d.csv"
    path.write_text("t,u,y0,y1\n0,0.01,,NaN\n0.0025,0.01, nan ,2.5\n0.005,0.01,1e-3,+3\n")
    meas = read_measurements(path, LEE)
    np.testing.assert_array_equal(meas["y"], [[np.nan, np.nan], [np.nan, 2.5], [1e-3, 3.0]])


def test_csv_numbers_are_read_exactly(tmp_path):
    """Cells are parsed by ``float`` (correctly rounded): repr round-trips bit for bit."""
    values = np.random.default_rng(0).normal(size=50) * 10.0 ** np.arange(-25, 25)
    path = tmp_path / "d.csv"
    rows = "".join(f"{i},0,{float(v)!r},0\n" for i, v in enumerate(values))
    path.write_text("t,u,y0,y1\n" + rows)
    np.testing.assert_array_equal(read_measurements(path, LEE)["y"][:, 0], values)


def test_a_dataframe_is_held_to_the_same_rules():
    import pandas as pd

    df = pd.DataFrame({"t": [0.0, 1.0], "u": [0.0, 0.0], "y0": [1.0, 2.0], "y1": ["n/a", 1.0]})
    with pytest.raises(ValueError, match=r"^data row 0, column 'y1': not a number \('n/a'\)"):
        read_measurements(df, LEE)
    with pytest.raises(ValueError, match=r"data has column\(s\) \['y5'\]"):
        read_measurements(df.assign(y1=1.0, y5=0.0), LEE)
    with pytest.raises(ValueError, match=r"column 'y0': holds complex128 values, expected real"):
        read_measurements(df.assign(y1=1.0, y0=[1j, 2.0]), LEE)
    with pytest.raises(TypeError, match="must be a DataFrame or the path of a CSV file, got list"):
        read_measurements([[0.0, 1.0]], LEE)
