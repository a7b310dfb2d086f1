"""Estimation from measured data: pandas DataFrames (or CSV files) in and out.

A measurement table has a column ``t`` (sample times, strictly increasing),
input columns ``u0 .. u{l-1}`` and output columns ``y0 .. y{m-1}`` (``u`` and
``y`` alone when there is one of each), and optionally ``mode`` (the known mode
at each sample, 0-based) for the methods that need it. An empty cell in an
output column (or ``NaN``) is a missing sample; anything else that is not a
finite number (``n/a``, ``NA``, ``null``, ``-``, ``inf`` ...) is refused with the
row and column named. Other columns are ignored, but a ``y``/``u`` column the
model does not have is refused, as are a duplicated column name and, in a CSV
file, a row with more or fewer fields than the header.

The methods (:data:`METHODS`), what each needs and where it finds it:

``kalman``, ``switch-time``
    Mode-based Kalman filters (Zhang & Natarajan; Shankar et al.) along the
    ``mode`` column (required); ``[initial]`` starts them.
``imm``, ``imm-ev1``
    IMM and Shankar et al.'s Algorithm 1; modes unknown. The transition matrix
    comes from the switching model (:func:`transition_for`) or ``stay``.
``min-distance``
    Lee, Ping & Shim's mode estimation and switching detection
    (:class:`~switchest.estimators.MinimumDistanceDetector`) on a continuous-time
    model, the output sampled on a *uniform* grid ``t``. The noise bound
    ``v_max``, the windows ``delta`` and ``Delta`` (and ``u_max``,
    ``observer_decay``) come from the model file's ``[noise]`` table; the
    options ``v_max``, ``delta``, ``Delta`` override it. There is no estimate
    until the first window of length ``delta`` has filled, nor from a declared
    switch until the next window has: those rows have empty ``x`` and ``mode``
    (they are kept, not dropped). A missing sample is bridged by holding the
    last complete one, which the detector's guarantees do not cover.
``rsls``
    Wang et al.'s subsystem observer for randomly switched systems
    (:class:`~switchest.estimators.RSLSObserver`). **Here the ``y`` columns hold
    the integrated output** ``z(t) = int_{t_0}^t y`` (Wang et al. eq. (1): the Ito
    output ``dz = C x dt + Xi dw``, e.g. ``Trajectory.y_fine`` of
    ``simulate(..., output="integrated")``) at fine instants ``t`` that include
    every switching instant ``t[0] + kT``; the ``mode`` column (required) gives
    the mode at each instant. ``T`` is ``sampling.period`` or the option
    ``switch_interval``; gains by :func:`rsls_gains`.
``impulsive``
    Etienne et al.'s impulsive observer at (aperiodic) samples
    (:class:`~switchest.estimators.ImpulsiveObserver`), along the switching
    signal of the ``mode`` column (required, :func:`mode_signal`), with gains
    from Theorem 8's LMIs (:func:`impulsive_gains`).

The estimate table has ``t``, the state estimates ``x0 ..``, their standard
deviations ``std_x0 ..`` (methods with a covariance: all but
``min-distance``) and, where the method gives them, ``mode`` (empty where
undefined), ``p_mode0 ..`` and ``switch_time`` (empty where no switch is
estimated or declared).
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from numbers import Real
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.linalg import expm

from ._checks import check_row_stochastic, positive_scalar
from .analysis import (
    critical_interval,
    decay_observer_gains,
    error_dynamics,
    impulsive_observer_search,
    ms_convergence,
    place_gains,
    steady_state,
    subsystem_structure,
)
from .estimators import (
    METHOD_NAMES,
    Estimate,
    Method,
    get_method,
)
from .modelfile import ModelSpec
from .signals import SwitchingSignal, schedule
from .switching import IID, AverageDwell, Dwell, MarkovAtSamples, MarkovContinuous

__all__ = [
    "METHODS",
    "estimate_table",
    "impulsive_gains",
    "mode_signal",
    "read_measurements",
    "rsls_gains",
    "transition_for",
]

METHODS = METHOD_NAMES
"""The method names, :data:`switchest.estimators.registry.METHOD_NAMES`."""
_LEE_SETTINGS = {  # option -> (what it is, CLI flag)
    "v_max": ("the noise bound |v(t)| <= v_max, Lee et al. eq. (2)", "--v-max"),
    "delta": ("the estimation window, Lee et al. condition (3)", "--delta"),
    "Delta": ("the detection delay, Lee et al. condition (4)", "--Delta"),
}
_POLE_SCALES = np.geomspace(0.25, 2.0, 7)  # pole scales rsls_gains compares (i.i.d. switching)


def _columns(prefix: str, count: int) -> list[str]:
    return [prefix] if count == 1 else [f"{prefix}{i}" for i in range(count)]


_SIGNAL_NAME = re.compile(r"[yu]\d*")  # names the model's output and input columns take
_MISSING_TEXT = ("", "nan")  # the only cells that mean "no sample" (case-insensitive, stripped)


@dataclass(frozen=True)
class _Table:
    """A measurement table as given: its cells, a name for messages, the file line of each row."""

    frame: pd.DataFrame
    name: str  # "data" or "<path>: data"
    lines: list[int] | None = None

    def row(self, i: int) -> str:
        return f"{self.name} row {i}" + ("" if self.lines is None else f" (line {self.lines[i]})")


def read_measurements(data: pd.DataFrame | str | Path, spec: ModelSpec) -> dict[str, np.ndarray]:
    """Validate a measurement table against the model; returns ``t``, ``y``, ``u`` (and ``mode``).

    Only an empty cell or ``NaN`` (any case) is a missing value, and only in an
    output column; every other cell must be a finite number (``n/a``, ``NA``,
    ``null``, ``-`` or ``inf`` are refused, not read as missing). Columns other
    than ``t``, the model's ``u``/``y`` columns and ``mode`` are ignored, except
    that a ``y``/``u`` column the model does not have is refused.

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


def transition_for(spec: ModelSpec, T: float, *, stay: float | None = None) -> np.ndarray:
    """A per-sample mode transition matrix for IMM filters, from the model's switching model.

    ``markov`` gives its matrix; ``iid`` repeats ``p`` in every row;
    ``markov-continuous`` gives ``expm(rates T)``; ``dwell`` and ``average-dwell``
    stay with probability ``1 - T / mean dwell`` (at most one switch per sample)
    and move uniformly to the others; ``stay`` overrides all of these.
    """
    L = spec.system.n_modes
    sw = spec.switching
    if stay is not None:
        stay = positive_scalar(stay, "stay")
        if stay > 1:
            raise ValueError(f"stay must be a probability, got {stay}")
        P = np.full((L, L), (1 - stay) / max(L - 1, 1))
        np.fill_diagonal(P, stay)
        return P
    if isinstance(sw, MarkovAtSamples):
        return check_row_stochastic(sw.transition)
    if isinstance(sw, IID):
        return np.tile(sw.p, (L, 1))
    if isinstance(sw, MarkovContinuous):
        P = expm(sw.rates * T)
        return P / P.sum(axis=1, keepdims=True)
    if isinstance(sw, (Dwell, AverageDwell)):
        mean_dwell = 0.5 * (sw.min_dwell + sw.max_dwell) if isinstance(sw, Dwell) else sw.tau_a
        return transition_for(spec, T, stay=max(1e-6, 1.0 - T / mean_dwell))
    kind = None if sw is None else sw.kind
    raise ValueError(f"the model's switching model ({kind!r}) implies no transition matrix: "
                     "give stay")


def estimate_table(spec: ModelSpec, data: pd.DataFrame | str | Path, *, method: str, grid: int = 5,
                   refine: bool = False, stay: float | None = None, v_max: float | None = None,
                   delta: float | None = None, Delta: float | None = None,
                   switch_interval: float | None = None) -> pd.DataFrame:
    """Run ``method`` on measured data; returns a table of estimates per sample.

    Parameters
    ----------
    spec : ModelSpec
        The model file (:func:`switchest.modelfile.load_model`).
    data : DataFrame or path of a CSV file
        The measurement table (module docstring; for ``rsls`` the ``y`` columns
        are the integrated output).
    method : str
        One of :data:`METHODS`.
    grid, refine : int, bool
        Switching-time grid points per interval (``switch-time``, ``imm-ev1``) and
        the refinement beyond the grid (``switch-time``).
    stay : float, optional
        Per-sample probability of staying in a mode (``imm``, ``imm-ev1``).
    v_max, delta, Delta : float, optional
        ``min-distance`` only: noise bound (Lee et al. eq. (2)), estimation window
        and detection delay (conditions (3), (4)); each overrides the model
        file's ``[noise]`` entry of the same name.
    switch_interval : float, optional
        ``rsls`` only: the switching interval ``T`` (Wang et al. Assumption 1);
        overrides ``sampling.period``.

    Returns
    -------
    DataFrame
        ``t``, ``x0 ..``, ``std_x0 ..`` (where the method has a covariance), and
        where the method gives them ``mode`` (nullable integers, empty where
        undefined), ``p_mode0 ..``, ``switch_time`` (NaN where none).
    """
    entry = get_method(method)
    options = {"grid": grid, "refine": refine, "stay": stay, "v_max": v_max, "delta": delta,
               "Delta": Delta, "switch_interval": switch_interval}
    for name in ("v_max", "delta", "Delta", "switch_interval"):  # no default: refused elsewhere
        if options[name] is not None:
            if name not in entry.options:
                owners = " or ".join(repr(m) for m in METHODS if name in get_method(m).options)
                raise ValueError(f"{name} applies to method {owners} only, got method {method!r}")
            options[name] = positive_scalar(options[name], name)
    meas = read_measurements(data, spec)
    modes = _modes(meas, method) if entry.needs_modes else None
    return _table(meas["t"], _RUNNERS[method](entry, spec, meas, options, modes))


# ------------------------------------------------------------------ one runner per method family
def _filter(entry: Method, spec: ModelSpec, meas: dict, options: dict, modes) -> Estimate:
    """The Kalman-type filters, ``entry.estimator(system, [transition,] x0, P0, **options)``.

    A required transition matrix comes from the switching model (:func:`transition_for`) or
    ``stay``; an optional one (Shankar et al.'s Algorithm 1 uses none) only when ``stay`` is
    given or the switching model is a Markov chain.
    """
    t, y, u = meas["t"], meas["y"], meas["u"]
    explicit = options["stay"] is not None or isinstance(spec.switching, MarkovAtSamples)
    args = []
    if entry.transition == "required" or (entry.transition == "optional" and explicit):
        T = float(np.median(np.diff(t))) if t.size > 1 else 1.0
        args.append(transition_for(spec, T, stay=options["stay"]))
    elif entry.transition == "optional":
        args.append(None)
    chosen = {name: options[name] for name in ("grid", "refine") if name in entry.options}
    est = entry.estimator(spec.system, *args, *_prior(spec), **chosen)
    return est.run(y, u, t, **({} if modes is None else {"modes": modes}))


def _min_distance(entry: Method, spec: ModelSpec, meas: dict, options: dict, modes) -> Estimate:
    """Lee, Ping & Shim's detector with the model's bounds and windows.

    Options override ``[noise]``. ``u_max`` (used only by the detector's assumption check) and the
    observer gains (``observer_decay``,
    :func:`~switchest.analysis.min_distance_design.decay_observer_gains`; otherwise the detector's
    default) come from ``[noise]`` alone.
    """
    noise = spec.noise
    settings = {name: options[name] for name in entry.options}
    for name, value in settings.items():
        if value is None:
            if name not in noise:
                what, flag = _LEE_SETTINGS[name]
                raise ValueError(f"method 'min-distance' needs {name}, {what}: add {name} to the "
                                 f"model file's [noise] table or pass {flag} ({name}= in Python)")
            settings[name] = noise[name]
    decay = noise.get("observer_decay")
    gains = None if decay is None else decay_observer_gains(spec.system, decay)
    detector = entry.estimator(spec.system, **settings, u_max=noise.get("u_max", 0.0),
                               observer_gains=gains)
    # refuses a non-uniform grid naming the sample
    return detector.run(meas["y"], meas["u"], meas["t"])


def _rsls(entry: Method, spec: ModelSpec, meas: dict, options: dict, modes) -> Estimate:
    """Wang et al.'s observer on the integrated output, along the ``mode`` column."""
    T = options["switch_interval"]
    T = spec.sampling.get("period") if T is None else T
    if T is None:
        raise ValueError("method 'rsls' needs the switching interval T (Wang et al. Assumption 1): "
                         "set sampling.period in the model file or pass --switch-interval "
                         "(switch_interval= in Python)")
    observer = entry.estimator(spec.system, rsls_gains(spec, T), T, *_prior(spec))
    return observer.run(meas["y"], t=meas["t"], modes=modes)


def rsls_gains(spec: ModelSpec, T: float) -> np.ndarray:
    """Sub-observer gains for Wang et al.'s observer when the user gives none.

    Per-mode pole placement (Wang et al. §4.2, §6;
    :func:`~switchest.analysis.place_gains`) with one free scale ``s``: mode i's
    observable sub-state gets the poles ``-s rho_i (1, 1.25, 1.5, ...)``,
    ``rho_i = max(max|eig A22^i|, 1 / T)`` (as fast as the mode's own dynamics and
    at least one time constant per switching interval). With i.i.d. switching
    (``switching.kind = "iid"``, probabilities ``p``) ``s`` is the one of seven
    log-spaced values from 0.25 to 2 that minimizes the exact steady-state mean-square error
    ``tr Phi V Phi'`` (:func:`~switchest.analysis.steady_state`, Wang et al.
    eq. (21) corrected) among the designs that pass the exact mean-square test
    (:func:`~switchest.analysis.ms_convergence`): §5.2's design, restricted to
    this one-parameter family. Other switching models (outside Wang et al.'s
    i.i.d. assumption) get ``s = 1``, unchecked.

    Why this design rather than the others of :mod:`switchest.analysis.subsystem_observers`:
    the Kalman-Bucy gains (§4.1) need no choice but ignore the random switching —
    the paper's Example 1 shows them diverging (exact MS spectral radius 1.079 on
    ``wang-example1``) and on ``wang-ieee5bus`` (an eigenvalue 0, no process noise)
    the Riccati equation has no stabilizing solution. The unrestricted §5.2
    optimum (:func:`~switchest.analysis.optimal_gains`) needs an MS-stable start
    and a Nelder-Mead search over every gain entry (about ten minutes on
    ``wang-ieee5bus``); the one-parameter search costs a few milliseconds per
    candidate. On ``wang-example1`` it gives ``tr V_x = 0.602`` (the full optimum
    0.532), on ``wang-ieee5bus`` 0.0519 (the paper's first pole set 0.0517). Scales
    above 2 are not tried: the gains grow like the cube of the scale and only
    amplify the output noise (on ``wang-ieee5bus`` the error at scale 2 is ten
    times that at scale 1).

    Returns
    -------
    ndarray, shape (L, n, m)
        Gains in state coordinates.

    Raises
    ------
    ValueError
        With i.i.d. switching, when no candidate is mean-square convergent.
    """
    system = spec.system
    T = positive_scalar(T, "T")
    structure = subsystem_structure(system)
    rates = [max(float(np.max(np.abs(np.linalg.eigvals(A22)), initial=0.0)), 1.0 / T)
             for A22 in structure.A22]

    def design(scale: float) -> np.ndarray:
        return place_gains(structure, [-scale * r * (1.0 + 0.25 * np.arange(A22.shape[0]))
                                       if A22.size else None
                                       for r, A22 in zip(rates, structure.A22)])

    if not isinstance(spec.switching, IID):
        return design(1.0)
    p = spec.switching.p
    best, best_mu, radius = None, np.inf, np.inf
    for scale in _POLE_SCALES:
        gains = design(scale)
        dyn = error_dynamics(system, gains, T, structure=structure)
        ms = ms_convergence(dyn, p)
        radius = min(radius, ms.radius)
        mu = steady_state(dyn, p).mu_x if ms.holds else np.inf
        if 0.0 < mu < best_mu:
            best, best_mu = gains, mu
    if best is None:
        limit = critical_interval(system, p, structure=structure).fast_observer
        raise ValueError(
            f"method 'rsls': no default sub-observer design is mean-square convergent at T = {T:g} "
            f"(smallest spectral radius {radius:.4g} >= 1, Wang et al. Theorem 1); fast enough "
            f"sub-observers converge only for T < {limit:.4g} (critical interval): design gains "
            "with switchest.analysis.place_gains and run switchest.estimators.RSLSObserver")
    return best


def _impulsive(entry: Method, spec: ModelSpec, meas: dict, options: dict, modes) -> Estimate:
    """Etienne et al.'s impulsive observer along the switching signal of the ``mode`` column."""
    signal = mode_signal(meas["t"], modes)
    observer = entry.estimator(spec.system, impulsive_gains(spec, meas["t"]), *_prior(spec))
    return observer.run(meas["y"], meas["u"], meas["t"], signals=signal)


def mode_signal(t: np.ndarray, modes: np.ndarray) -> SwitchingSignal:
    """The switching signal of a ``mode`` column: ``modes[k]`` on ``[t_k, t_{k+1})``.

    It switches at the sample where the column changes. This is the synchronous
    mode knowledge of Etienne et al. eq. (3) as far as sampled data allow: exact
    when the switches fall on sample instants; a switch inside ``(t_{k-1}, t_k)``
    is taken at ``t_k``, i.e. detected late by less than one sampling interval
    (the delayed knowledge of their Assumption 5, with ``delta <= tau_max``).
    """
    return schedule(np.asarray(t, dtype=float)[1:], modes)


def impulsive_gains(spec: ModelSpec, t: np.ndarray) -> np.ndarray:
    """Observer gains from Etienne et al. Theorem 8 for the model's sampling and dwell time.

    The sampling bounds are ``sampling.tau_min`` / ``tau_max`` (or ``period`` for
    both, Assumption 2) and the dwell time is ``switching.tau_a`` (kind
    ``average-dwell``) or ``min_dwell`` (kind ``dwell``), Assumption 1. The
    scalars ``(alpha, mu_s, mu_c)``, which the paper fixes by hand (Remark 12),
    are searched for the largest guaranteed decay rate
    (:func:`~switchest.analysis.impulsive_observer_search`, the search
    ``switchest check`` also runs). The sample times ``t`` must keep to the
    bounds the gains are designed for.

    Raises
    ------
    ValueError
        When the model lacks the bounds or the dwell time, ``t`` leaves the
        bounds, or the LMIs give no certificate (with the synthesis' diagnostic).
    """
    smp, sw = spec.sampling, spec.switching
    lo, hi = smp.get("tau_min", smp.get("period")), smp.get("tau_max", smp.get("period"))
    if lo is None:
        raise ValueError("method 'impulsive' needs the sampling bounds (Etienne et al. "
                         "Assumption 2): set sampling.tau_min and sampling.tau_max (or "
                         "sampling.period) in the model file")
    dwell = (sw.tau_a if isinstance(sw, AverageDwell)
             else sw.min_dwell if isinstance(sw, Dwell) else None)
    if dwell is None:
        raise ValueError("method 'impulsive' needs a dwell time (Etienne et al. Assumption 1): a "
                         "[switching] table of kind 'average-dwell' (tau_a) or 'dwell' "
                         f"(min_dwell), got {getattr(sw, 'kind', None)!r}")
    steps = np.diff(np.asarray(t, dtype=float))
    outside = (steps < lo * (1 - 1e-9)) | (steps > hi * (1 + 1e-9))
    if outside.any():
        row = int(np.flatnonzero(outside)[0]) + 1
        raise ValueError(f"method 'impulsive': data row {row} is {steps[row - 1]:.6g} after the "
                         f"previous row, outside the model's sampling bounds [{lo:g}, {hi:g}] the "
                         "gains are designed for (Etienne et al. Assumption 2); widen "
                         "sampling.tau_min / tau_max")
    best = impulsive_observer_search(spec.system, lo, hi, dwell).best
    if not best.holds:
        raise ValueError(f"method 'impulsive': Theorem 8's LMIs give no observer for sampling in "
                         f"[{lo:g}, {hi:g}] and dwell time {dwell:g} (Etienne et al.): {best.note}")
    return best.G


#: How estimate_table builds and runs each registered method (every name of METHODS).
_RUNNERS = {"kalman": _filter, "switch-time": _filter, "imm": _filter, "imm-ev1": _filter,
            "min-distance": _min_distance, "rsls": _rsls, "impulsive": _impulsive}


# ---------------------------------------------------------------------- shared pieces
def _modes(meas: dict, method: str) -> np.ndarray:
    if "mode" not in meas:
        raise ValueError(f"method {method!r} needs the known modes: add a 'mode' column to the "
                         "data")
    return meas["mode"]


def _prior(spec: ModelSpec) -> tuple[np.ndarray, np.ndarray]:
    if spec.initial is None:
        raise ValueError("the model file needs an [initial] table (mean, cov) to start the filter")
    return spec.initial


def _table(t: np.ndarray, est: Estimate) -> pd.DataFrame:
    n = est.x.shape[-1]
    cols = {"t": t}
    cols.update({f"x{i}": est.x[:, i] for i in range(n)})
    if est.P is not None:
        std = np.sqrt(np.clip(np.diagonal(est.P, axis1=-2, axis2=-1), 0.0, None))
        cols.update({f"std_x{i}": std[:, i] for i in range(n)})
    if est.mode is not None:  # -1 (undefined, e.g. inside a detection window) -> empty
        cols["mode"] = pd.Series(est.mode, dtype="Int64").where(est.mode >= 0)
    if est.mode_prob is not None:
        cols.update({f"p_mode{j}": est.mode_prob[:, j] for j in range(est.mode_prob.shape[-1])})
    if est.switch_time is not None:
        cols["switch_time"] = est.switch_time
    return pd.DataFrame(cols)
