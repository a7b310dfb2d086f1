"""The measurement table: sampled inputs, outputs and modes as a CSV file or a pandas DataFrame.

A measurement table has a column ``t`` (sample times, strictly increasing),
input columns ``u0 .. u{l-1}`` and output columns ``y0 .. y{m-1}`` (``u`` and
``y`` alone when there is one of each), and optionally ``mode`` (the known mode
at each sample, 0-based) for the methods that need it. An empty cell in an
output column (or ``NaN``) is a missing sample; anything else that is not a
finite number (``n/a``, ``NA``, ``null``, ``-``, ``inf`` ...) is refused with the
row and column named. Other columns are ignored, but a ``y``/``u`` column the
model does not have is refused, as are a duplicated column name and, in a CSV
file, a row with more or fewer fields than the header. A table of several runs
(``switchest simulate --trials N``) has a column ``trial`` (0, 1, ...) ahead of
the others; the reader takes one trial at a time.

:func:`read_measurements` reads and checks a table against a model,
:func:`write_measurements` writes samples (one trial of a
:class:`~switchest.simulate.Trajectory`, say) in the same format,
:func:`simulate_measurements` simulates a model file into such a table, and
:func:`mode_signal` is the switching signal a ``mode`` column stands for.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from numbers import Real
from pathlib import Path

import numpy as np
import pandas as pd

from ._checks import as_rng, check_finite, float_array, int_array, positive_int, positive_scalar
from .modelfile import ModelSpec
from .signals import SwitchingSignal, schedule
from .simulate import simulate

__all__ = ["mode_signal", "read_measurements", "simulate_measurements", "write_measurements"]

_SIGNAL_NAME = re.compile(r"[yu]\d*")  # names the model's output and input columns take
_MISSING_TEXT = ("", "nan")  # the only cells that mean "no sample" (case-insensitive, stripped)


def _columns(prefix: str, count: int) -> list[str]:
    """The names of ``count`` input or output columns: ``prefix`` alone for one."""
    return [prefix] if count == 1 else [f"{prefix}{i}" for i in range(count)]


@dataclass(frozen=True)
class _Table:
    """A measurement table as given: its cells, a name for messages, the file line of each row."""

    frame: pd.DataFrame
    name: str  # "data" or "<path>: data"
    lines: list[int] | None = None

    def row(self, i: int) -> str:
        return f"{self.name} row {i}" + ("" if self.lines is None else f" (line {self.lines[i]})")


def read_measurements(data: pd.DataFrame | str | Path, spec: ModelSpec, *,
                      trial: int | None = None) -> dict[str, np.ndarray]:
    """Validate a measurement table against the model; returns ``t``, ``y``, ``u`` (and ``mode``).

    Only an empty cell or ``NaN`` (any case) is a missing value, and only in an
    output column; every other cell must be a finite number (``n/a``, ``NA``,
    ``null``, ``-`` or ``inf`` are refused, not read as missing). Columns other
    than ``t``, the model's ``u``/``y`` columns and ``mode`` are ignored, except
    that a ``y``/``u`` column the model does not have is refused.

    Parameters
    ----------
    data : DataFrame, str or Path
        The table, or the path of a CSV file holding it.
    spec : ModelSpec
        The model whose inputs, outputs and modes the table must match.
    trial : int, optional
        Which trial to read from a table with a ``trial`` column; needed when it
        holds more than one.

    Returns
    -------
    dict of str to ndarray
        ``t`` ``(K,)``, ``y`` ``(K, m)`` (NaN where missing), ``u`` ``(K, l)``
        and, when the table has the column, ``mode`` ``(K,)`` (int64).

    Raises
    ------
    ValueError
        Naming the file (for a CSV path), the row and the column: a cell that is
        not a finite number, a missing value outside the outputs, unsorted,
        repeated or non-finite times, a missing column, a ``y``/``u`` column more
        than the model has, a duplicated column name, a row with more or fewer
        fields than the header, a mode index out of range, an empty table.
    TypeError
        When ``data`` is neither a DataFrame nor a path.
    """
    if isinstance(data, pd.DataFrame):
        table = _Table(data, "data")
    elif isinstance(data, (str, Path)):
        table = _read_csv(Path(data))
    else:
        raise TypeError(f"data must be a DataFrame or the path of a CSV file, got "
                        f"{type(data).__name__}")
    table = _select_trial(table, trial)
    sys = spec.system
    y_cols = _columns("y", sys.n_outputs)
    u_cols = _columns("u", sys.n_inputs) if sys.n_inputs else []
    need = ["t", *u_cols, *y_cols]
    names = [str(c) for c in table.frame.columns]
    _check_header(table.name, names, need)
    if len(table.frame) == 0:
        raise ValueError(f"{table.name} has no rows; expected at least one sample")
    out = {}
    for col in need + (["mode"] if "mode" in names else []):
        values = _numbers(table, names.index(col), col)
        gone = np.isnan(values)
        if col not in y_cols and gone.any():
            row = int(np.flatnonzero(gone)[0])
            raise ValueError(f"{table.row(row)}, column {col!r}: empty (or NaN); only the "
                             "outputs y may be missing")
        out[col] = values
    t = out["t"]
    steps = np.diff(t)
    if np.any(steps == 0):
        row = int(np.flatnonzero(steps == 0)[0]) + 1
        raise ValueError(f"{table.row(row)}: time {t[row]:g} repeats the previous row; times "
                         "must be unique")
    if np.any(steps < 0):
        row = int(np.flatnonzero(steps < 0)[0]) + 1
        raise ValueError(f"{table.row(row)}: time {t[row]:g} is before the previous row's; sort "
                         "the data by t")
    result = {"t": t, "y": np.stack([out[c] for c in y_cols], axis=-1),
              "u": np.stack([out[c] for c in u_cols], axis=-1) if u_cols else np.zeros((t.size, 0))}
    if "mode" in out:
        modes = out["mode"]
        wrong = (modes != np.round(modes)) | (modes < 0) | (modes >= sys.n_modes)
        if wrong.any():
            row = int(np.flatnonzero(wrong)[0])
            raise ValueError(f"{table.row(row)}, column 'mode': {modes[row]:g} is not a mode "
                             f"index; column 'mode' must hold mode indices 0..{sys.n_modes - 1}")
        result["mode"] = modes.astype(np.int64)
    return result


def _select_trial(table: _Table, trial: int | None) -> _Table:
    """The rows of one trial of a table with a ``trial`` column (the table itself without
    one, where ``trial`` must be None)."""
    names = [str(c) for c in table.frame.columns]
    if "trial" not in names:
        if trial is not None:
            raise ValueError(f"trial={trial!r}: {table.name} has no 'trial' column (it holds one "
                             "run); leave the trial out")
        return table
    if names.count("trial") > 1:
        raise ValueError(f"{table.name}: column 'trial' appears more than once")
    labels = _numbers(table, names.index("trial"), "trial")
    bad = ~np.isfinite(labels) | (labels != np.round(labels)) | (labels < 0)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{table.row(row)}, column 'trial': must be a trial number 0, 1, ...")
    present = np.unique(labels).astype(np.int64)
    if trial is None:
        if present.size > 1:
            raise ValueError(f"{table.name} holds {present.size} trials ({present[0]}.."
                             f"{present[-1]}): choose one (trial=, or --trial)")
        trial = int(present[0])
    elif isinstance(trial, bool) or not isinstance(trial, (int, np.integer)):
        raise TypeError(f"trial must be an int, got {type(trial).__name__}")
    if trial not in present:
        raise ValueError(f"trial={trial}: {table.name} holds trials {present[0]}..{present[-1]}"
                         f" ({present.size} of them)")
    rows = np.flatnonzero(labels == trial)
    frame = table.frame.iloc[rows].drop(columns="trial").reset_index(drop=True)
    lines = None if table.lines is None else [table.lines[i] for i in rows]
    return _Table(frame, f"{table.name} (trial {trial})", lines)


def simulate_measurements(spec: ModelSpec, *, duration: float | None = None, trials: int = 1,
                          u=None, rng=None) -> pd.DataFrame:
    """Simulate a model file into a measurement table (``switchest simulate``).

    The sample times come from the file's ``[sampling]`` (an aperiodic one drawn once and
    shared by the trials), the switching from its ``[switching]`` model (drawn per trial),
    the initial state from its ``[initial]`` Gaussian (zero without one); the noises are the
    system's. The table holds ``t``, the inputs, the outputs, the true ``mode`` and the true
    states ``x0 ..`` (which the reader ignores), with a ``trial`` column first when
    ``trials > 1``: it reads back with :func:`read_measurements` and runs in
    ``switchest estimate``.

    Parameters
    ----------
    spec : ModelSpec
        The model file (:func:`switchest.modelfile.load_model`).
    duration : float, optional
        Seconds (or, for a discrete system, time units) to simulate; default the file's
        ``sampling.duration``.
    trials : int
        Independent runs.
    u : array_like, shape (l,), optional
        A constant input; by default the file's ``[input] value``, zero when it names none.
    rng : numpy.random.Generator, int or None
        The seed of everything drawn.

    Returns
    -------
    DataFrame
    """
    trials = positive_int(trials, "trials")
    if duration is not None:
        duration = positive_scalar(duration, "duration")
    rng = as_rng(rng)
    sys = spec.system
    if spec.switching is None:
        raise ValueError("the model has no [switching] table: simulate needs a switching model")
    if u is None:
        u = spec.input if spec.input is not None else np.zeros(sys.n_inputs)
    u = float_array(u, "u", ndim=1)
    if u.shape != (sys.n_inputs,):
        raise ValueError(f"u must hold the model's {sys.n_inputs} input(s), got {u.size}")
    check_finite(u, "u")
    t = spec.sample_times(duration, rng=rng)
    x0 = spec.initial if spec.initial is not None else np.zeros(sys.n_states)
    traj = simulate(sys, spec.switching, t, x0, u, trials=trials, rng=rng)
    frames = []
    for i in range(trials):
        frame = write_measurements(None, t, traj.y, u=traj.u if sys.n_inputs else None,
                                   x=traj.x, modes=traj.mode, trial=i)
        if trials > 1:
            frame.insert(0, "trial", i)
        frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def _read_csv(path: Path) -> _Table:
    """The cells of a CSV file as text, refusing rows whose field count differs from the header's.

    Read with the csv module rather than pandas, which renames a duplicated header
    (``y0.1``), pads short rows with NaN and reads ``n/a``, ``NA``, ``null``... as
    missing. Blank lines are skipped; a UTF-8 byte-order mark is allowed.
    """
    header, rows, lines = None, [], []
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh, skipinitialspace=True)
            for fields in reader:
                if len(fields) <= 1 and not "".join(fields).strip():
                    continue  # a blank line
                if header is None:
                    header = [f.strip() for f in fields]
                elif len(fields) != len(header):
                    raise ValueError(f"{path}: line {reader.line_num} has {len(fields)} "
                                     f"field(s), the header has {len(header)} "
                                     f"({', '.join(header)})")
                else:
                    rows.append(fields)
                    lines.append(reader.line_num)
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a UTF-8 text file ({exc.reason} at byte "
                         f"{exc.start})") from None
    except csv.Error as exc:
        raise ValueError(f"{path}: line {reader.line_num}: not valid CSV ({exc})") from None
    if header is None:
        raise ValueError(f"{path}: empty file; expected a header line naming the columns t, "
                         "u..., y...")
    return _Table(pd.DataFrame(rows, columns=header, dtype=object), f"{path}: data", lines)


def _check_header(name: str, columns: list[str], need: list[str]) -> None:
    """Refuse a duplicated column name, a missing column, a ``y``/``u`` column the model lacks."""
    seen = set()
    for c in columns:
        if c and c in seen:
            raise ValueError(f"{name}: column {c!r} appears more than once in the header")
        seen.add(c)
    missing = [c for c in need if c not in seen]
    if missing:
        raise ValueError(f"{name} is missing column(s) {missing}; expected {need} (+ optional "
                         f"'mode'), got {columns}")
    extra = [c for c in columns if _SIGNAL_NAME.fullmatch(c) and c not in need]
    if extra:
        raise ValueError(f"{name} has column(s) {extra} the model does not have: its outputs "
                         f"and inputs are {[c for c in need if c != 't']}")


def _numbers(table: _Table, index: int, col: str) -> np.ndarray:
    """Column ``col`` as floats, NaN for a missing value (an empty or NaN cell).

    Text is parsed by ``float`` (exact: the double nearest the decimal), refusing
    what it would read but is no plain number (``1_000``) and every other text.
    """
    cells = table.frame.iloc[:, index]
    if pd.api.types.is_bool_dtype(cells) or pd.api.types.is_complex_dtype(cells):
        raise ValueError(f"{table.name} column {col!r}: holds {cells.dtype} values, expected "
                         "real numbers")
    if pd.api.types.is_numeric_dtype(cells):
        values = cells.to_numpy(dtype=float, na_value=np.nan)
    else:
        values = np.empty(len(cells))
        for row, cell in enumerate(cells.tolist()):
            value = _number(cell)
            if value is None:
                raise ValueError(f"{table.row(row)}, column {col!r}: not a number ({cell!r}); a "
                                 "missing sample is an empty cell or NaN")
            values[row] = value
    bad = np.isinf(values)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{table.row(row)}, column {col!r}: {values[row]} is not a finite number")
    return values


def _number(cell) -> float | None:
    """One cell as a float, NaN if missing, None if it is no number."""
    if isinstance(cell, str):
        text = cell.strip()
        if text.lower() in _MISSING_TEXT:
            return np.nan
        if "_" not in text:
            try:
                return float(text)
            except ValueError:
                pass
    elif isinstance(cell, (Real, np.number)) and not isinstance(cell, (bool, np.bool_)):
        return float(cell)
    elif cell is None or (np.ndim(cell) == 0 and pd.isna(cell)):
        return np.nan
    return None


def write_measurements(path: str | Path | None, t, y, *, u=None, x=None, modes=None,
                       trial: int | None = None) -> pd.DataFrame:
    """Samples as a measurement table, written to a CSV file that :func:`read_measurements` reads.

    The columns are named as the reader expects them: ``t``, the inputs ``u``
    (``u0 ..`` for several), the outputs ``y`` (``y0 ..``), ``mode`` and, last,
    the true states ``x0 ..`` (named like the states of the estimate table; the
    reader ignores them). A missing output (NaN) is written as an empty cell.

    Parameters
    ----------
    path : str, Path or None
        The CSV file to write (replaced if it exists); None only builds the table.
    t : array_like, shape (K,)
        Sample times: finite, strictly increasing, at least one.
    y : array_like, shape (K, m) or (N, K, m)
        Outputs, :math:`m \\ge 1`; NaN marks a missing sample, infinity is refused.
    u : array_like, shape (K, l) or (N, K, l), optional
        Inputs, finite; none (and no ``u`` column) when omitted or :math:`l = 0`.
    x : array_like, shape (K, n) or (N, K, n), optional
        States, finite.
    modes : array_like of int, shape (K,) or (N, K), optional
        The mode at each sample, 0-based.
    trial : int, optional
        The trial to write from the arrays that have a leading trials axis ``N``
        (all those of a :class:`~switchest.simulate.Trajectory`); an array
        without that axis is written as it is. Required when an array has it.

    Returns
    -------
    DataFrame
        The table as written.

    Raises
    ------
    ValueError
        Naming the argument: a shape that does not fit ``t``, times that are not
        finite or not strictly increasing, a non-finite input or state, an
        infinite output, a negative mode, a trials axis without ``trial`` (or
        ``trial`` out of its range, or without any trials axis).
    TypeError
        When ``path`` is neither None nor a path, ``trial`` is not an int, or an
        array does not hold real numbers (integers for ``modes``).
    """
    if path is not None and not isinstance(path, (str, Path)):
        raise TypeError(f"path must be None or the path of a CSV file, got {type(path).__name__}")
    if trial is not None and (isinstance(trial, (bool, np.bool_))
                              or not isinstance(trial, (int, np.integer))):
        raise TypeError(f"trial must be an int, got {type(trial).__name__}")
    times = float_array(t, "t", ndim=1)
    check_finite(times, "t")
    if times.size == 0:
        raise ValueError("t must hold at least one sample time, got none")
    if np.any(np.diff(times) <= 0):
        k = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
        raise ValueError(f"t must be strictly increasing, got t[{k}] = {times[k]:g} after "
                         f"t[{k - 1}] = {times[k - 1]:g}")
    chosen: list[str] = []  # the arguments that had a trials axis

    def one_trial(value: np.ndarray, name: str, *axes: str) -> np.ndarray:
        return _one_trial(value, name, axes, trial, times.size, chosen)

    outputs = one_trial(float_array(y, "y", masked="nan"), "y", "K", "m")
    if np.isinf(outputs).any():
        check_finite(outputs, "y")  # names the first infinite entry
    if outputs.shape[1] == 0:
        raise ValueError(f"y must have at least one output column, got shape {outputs.shape}")
    table = {"t": times}
    if u is not None:
        inputs = one_trial(float_array(u, "u"), "u", "K", "l")
        check_finite(inputs, "u")
        table.update(zip(_columns("u", inputs.shape[1]), inputs.T))
    table.update(zip(_columns("y", outputs.shape[1]), outputs.T))
    if modes is not None:
        mode = one_trial(int_array(modes, "modes"), "modes", "K")
        if np.any(mode < 0):
            k = int(np.flatnonzero(mode < 0)[0])
            raise ValueError(f"modes must be 0-based mode indices, got {mode[k]} at sample {k}")
        table["mode"] = mode
    if x is not None:
        states = one_trial(float_array(x, "x"), "x", "K", "n")
        check_finite(states, "x")
        table.update((f"x{i}", column) for i, column in enumerate(states.T))
    if trial is not None and not chosen:
        raise ValueError(f"trial={trial} chooses among the trials of arrays with a leading "
                         "trials axis, but none has one")
    frame = pd.DataFrame(table)
    if path is not None:
        frame.to_csv(path, index=False)
    return frame


def _one_trial(value: np.ndarray, name: str, axes: tuple[str, ...], trial: int | None,
               samples: int, chosen: list[str]) -> np.ndarray:
    """``value`` of one trial, with the axes ``axes`` and ``samples`` rows.

    An extra leading axis holds trials: then ``trial`` picks one and ``name`` joins ``chosen``.
    """
    if value.ndim == len(axes) + 1:
        if trial is None:
            raise ValueError(f"{name} has a leading trials axis (shape {value.shape}): pass "
                             "trial= to choose the trial to write")
        if not 0 <= trial < value.shape[0]:
            raise ValueError(f"trial must be in 0..{value.shape[0] - 1} ({name} holds "
                             f"{value.shape[0]} trials), got {trial}")
        chosen.append(name)
        value = value[trial]
    elif value.ndim != len(axes):
        one, many = ", ".join(axes), ", ".join(("N", *axes))
        raise ValueError(f"{name} must have shape ({one}{',' * (len(axes) == 1)}) or ({many}), "
                         f"got shape {value.shape}")
    if value.shape[0] != samples:
        raise ValueError(f"{name} has {value.shape[0]} samples (shape {value.shape}), t has "
                         f"{samples}")
    return value


def mode_signal(t: np.ndarray, modes: np.ndarray) -> SwitchingSignal:
    """The switching signal of a ``mode`` column: ``modes[k]`` on :math:`[t_k, t_{k+1})`.

    It switches at the sample where the column changes. This is the synchronous
    mode knowledge of Etienne et al. eq. (3) as far as sampled data allow: exact
    when the switches fall on sample instants; a switch inside :math:`(t_{k-1}, t_k)`
    is taken at :math:`t_k`, i.e. detected late by less than one sampling interval
    (the delayed knowledge of their Assumption 5, with :math:`\\delta \\le \\tau_{\\max}`).

    Parameters
    ----------
    t : ndarray, shape (K,)
        Sample times.
    modes : ndarray of int, shape (K,)
        The mode at each sample.

    Returns
    -------
    SwitchingSignal
    """
    return schedule(np.asarray(t, dtype=float)[1:], modes)
