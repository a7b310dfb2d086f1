"""Estimation from measured data: pandas DataFrames (or CSV files) in and out.

A measurement table has a column ``t`` (sample times, strictly increasing),
input columns ``u0 .. u{l-1}`` and output columns ``y0 .. y{m-1}`` (``u`` and
``y`` alone when there is one of each), and optionally ``mode`` (the known mode
at each sample, 0-based) for the methods that need it. An empty cell in an
output column is a missing sample; anything else that is not a number is
refused with the row and column named.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from scipy.linalg import expm

from ._checks import check_row_stochastic, positive_scalar
from .estimators import Estimate, IMMEV1Filter, IMMFilter, ModeKalmanFilter, SwitchTimeKalmanFilter
from .modelfile import ModelSpec

__all__ = ["METHODS", "read_measurements", "estimate_table", "transition_for"]

METHODS = ("kalman", "switch-time", "imm", "imm-ev1")


def _columns(prefix: str, count: int) -> list[str]:
    return [prefix] if count == 1 else [f"{prefix}{i}" for i in range(count)]


def read_measurements(data: pd.DataFrame | str | Path, spec: ModelSpec) -> dict[str, np.ndarray]:
    """Validate a measurement table against the model; returns ``t``, ``y``, ``u`` (and ``mode``).

    Raises ValueError naming the row and column of a non-numeric cell, unsorted or
    duplicated times, a missing column or an input gap.
    """
    if not isinstance(data, pd.DataFrame):
        data = pd.read_csv(data, skipinitialspace=True)
    sys = spec.system
    y_cols, u_cols = _columns("y", sys.n_outputs), _columns("u", sys.n_inputs) if sys.n_inputs else []
    need = ["t", *u_cols, *y_cols]
    missing = [c for c in need if c not in data.columns]
    if missing:
        raise ValueError(f"data is missing column(s) {missing}; expected {need} (+ optional 'mode'), "
                         f"got {list(data.columns)}")
    out = {}
    for col in need + (["mode"] if "mode" in data.columns else []):
        values = pd.to_numeric(data[col], errors="coerce")
        bad = values.isna() & data[col].notna() & (data[col].astype(str).str.strip() != "")
        if bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            raise ValueError(f"data row {row}, column {col!r}: not a number ({data[col].iloc[row]!r})")
        arr = values.to_numpy(dtype=float)
        if col != "y" and not col.startswith("y") and np.isnan(arr).any():
            row = int(np.flatnonzero(np.isnan(arr))[0])
            raise ValueError(f"data row {row}, column {col!r}: empty; only outputs may be missing")
        out[col] = arr
    t = out["t"]
    steps = np.diff(t)
    if np.any(steps == 0):
        row = int(np.flatnonzero(steps == 0)[0]) + 1
        raise ValueError(f"data row {row}: time {t[row]:g} repeats the previous row; times must be unique")
    if np.any(steps < 0):
        row = int(np.flatnonzero(steps < 0)[0]) + 1
        raise ValueError(f"data row {row}: time {t[row]:g} is before the previous row's; sort the data by t")
    result = {"t": t, "y": np.stack([out[c] for c in y_cols], axis=-1),
              "u": np.stack([out[c] for c in u_cols], axis=-1) if u_cols else np.zeros((t.size, 0))}
    if "mode" in out:
        modes = out["mode"]
        if np.any(modes != np.round(modes)) or np.any((modes < 0) | (modes >= sys.n_modes)):
            raise ValueError(f"data column 'mode' must hold mode indices 0..{sys.n_modes - 1}")
        result["mode"] = modes.astype(np.int64)
    return result


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
    kind = sw.get("kind")
    if kind == "markov":
        return check_row_stochastic(sw["transition"])
    if kind == "iid":
        return np.tile(np.asarray(sw["p"], dtype=float), (L, 1))
    if kind == "markov-continuous":
        P = expm(np.asarray(sw["rates"]) * T)
        return P / P.sum(axis=1, keepdims=True)
    if kind in ("dwell", "average-dwell"):
        mean_dwell = 0.5 * (sw["min_dwell"] + sw["max_dwell"]) if kind == "dwell" else sw["tau_a"]
        return transition_for(spec, T, stay=max(1e-6, 1.0 - T / mean_dwell))
    raise ValueError(f"the model's switching model ({kind!r}) implies no transition matrix: give stay")


def estimate_table(spec: ModelSpec, data: pd.DataFrame | str | Path, *, method: str, grid: int = 5,
                   refine: bool = False, stay: float | None = None) -> pd.DataFrame:
    """Run ``method`` on measured data; returns a table of estimates per sample.

    Columns: ``t``, the state estimates ``x0 ..``, their standard deviations
    ``std_x0 ..``, and where the method gives them ``mode``, ``p_mode0 ..`` and
    ``switch_time`` (empty where no switch is estimated).
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if spec.initial is None:
        raise ValueError("the model file needs an [initial] table (mean, cov) to start the filter")
    meas = read_measurements(data, spec)
    t, y, u = meas["t"], meas["y"], meas["u"]
    x0, P0 = spec.initial
    sys = spec.system
    if method in ("kalman", "switch-time") and "mode" not in meas:
        raise ValueError(f"method {method!r} needs the known modes: add a 'mode' column to the data")
    if method == "kalman":
        est = ModeKalmanFilter(sys, x0, P0).run(y, u, t, modes=meas["mode"])
    elif method == "switch-time":
        est = SwitchTimeKalmanFilter(sys, x0, P0, grid=grid, refine=refine).run(y, u, t, modes=meas["mode"])
    elif method == "imm":
        T = float(np.median(np.diff(t))) if t.size > 1 else 1.0
        est = IMMFilter(sys, transition_for(spec, T, stay=stay), x0, P0).run(y, u, t)
    else:  # Shankar Algorithm 1 uses no transition prior; an explicit one is used when given
        explicit = stay is not None or spec.switching.get("kind") == "markov"
        transition = transition_for(spec, float(np.median(np.diff(t))), stay=stay) if explicit else None
        est = IMMEV1Filter(sys, transition, x0=x0, P0=P0, grid=grid).run(y, u, t)
    return _table(t, est)


def _table(t: np.ndarray, est: Estimate) -> pd.DataFrame:
    n = est.x.shape[-1]
    cols = {"t": t}
    cols.update({f"x{i}": est.x[:, i] for i in range(n)})
    std = np.sqrt(np.clip(np.diagonal(est.P, axis1=-2, axis2=-1), 0.0, None))
    cols.update({f"std_x{i}": std[:, i] for i in range(n)})
    if est.mode is not None:
        cols["mode"] = est.mode
    if est.mode_prob is not None:
        cols.update({f"p_mode{j}": est.mode_prob[:, j] for j in range(est.mode_prob.shape[-1])})
    if est.switch_time is not None:
        cols["switch_time"] = est.switch_time
    return pd.DataFrame(cols)
