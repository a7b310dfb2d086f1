"""Model files: a switched system with its sampling, switching model and initial state.

A TOML file holds the system (read by :meth:`SwitchedLinearSystem.from_dict`)
and, optionally::

    description = "free text"
    [sampling]              # period = T, or tau_min / tau_max for aperiodic sampling;
    period = 0.0005         # duration = default length of a simulation (s)
    duration = 10.0
    [switching]             # kind = dwell | average-dwell | markov | markov-continuous | iid | schedule
    kind = "dwell"
    min_dwell = 0.0009
    max_dwell = 0.0012
    [initial]               # Gaussian initial state
    mean = [0.0, 100.0]
    cov = [[25.0, 0.0], [0.0, 25.0]]
    [noise]                 # bounds for Lee et al.'s conditions (bounded noise):
    v_max = 0.1             # |v| <= v_max, |u| <= u_max, |x| >= x_min; and, optionally,
    u_max = 1.0             # their detector's design: windows delta, Delta and
    x_min = 0.8             # observer_decay (A_i - L_i C_i with poles at -observer_decay ...)

The bounds ``v_max``, ``u_max``, ``x_min`` are finite and non-negative; ``delta``,
``Delta`` and ``observer_decay`` finite and positive. Every error names the file,
the table and the key; an unknown key, at any level, is an error that suggests
the closest valid one.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _toml
from ._checks import as_rng, check_symmetric_psd
from .signals import (
    SwitchingSignal,
    aperiodic,
    average_dwell_time,
    dwell_time,
    iid_at_samples,
    markov_at_samples,
    markov_continuous,
    periodic,
    schedule,
)
from .system import SwitchedLinearSystem

__all__ = ["ModelSpec", "load_model", "save_model"]

_SWITCHING_KEYS = {
    "dwell": {"min_dwell", "max_dwell", "initial_mode"},
    "average-dwell": {"tau_a", "N0", "rate", "initial_mode"},
    "markov": {"transition", "initial"},
    "markov-continuous": {"rates", "initial_mode"},
    "iid": {"p"},
    "schedule": {"times", "modes"},
}
_SAMPLING_KEYS = {"period", "tau_min", "tau_max", "duration"}
_INITIAL_KEYS = {"mean", "cov"}
_NOISE_BOUNDS = {"v_max", "u_max", "x_min"}  # bounds on |v|, |u|, |x|: zero is meaningful
_NOISE_DESIGN = {"delta", "Delta", "observer_decay"}  # windows (s) and a decay rate (1/s)


@dataclass(frozen=True, eq=False)
class ModelSpec:
    """A system and how it is exercised.

    Attributes
    ----------
    system : SwitchedLinearSystem
    sampling : dict
        ``{"period": T}`` or ``{"tau_min": a, "tau_max": b}``, plus ``"duration"``.
    switching : dict
        ``{"kind": ..., <parameters>}`` (see the module docstring), or empty.
    initial : tuple of arrays or None
        ``(mean (n,), cov (n, n))``.
    noise : dict
        Bounds such as ``v_max``, ``u_max``, ``x_min`` for bounded-noise analyses,
        and the minimum-distance detector's ``delta``, ``Delta``, ``observer_decay``.
    description : str
    """

    system: SwitchedLinearSystem
    sampling: dict = field(default_factory=dict)
    switching: dict = field(default_factory=dict)
    initial: tuple[np.ndarray, np.ndarray] | None = None
    noise: dict = field(default_factory=dict)
    description: str = ""

    def sample_times(self, t_end: float | None = None, *, rng=None) -> np.ndarray:
        """Sample times on ``[0, t_end]`` (default: the file's duration)."""
        t_end = self._duration(t_end)
        if "period" in self.sampling:
            return periodic(self.sampling["period"], t_end)
        if "tau_min" in self.sampling:
            return aperiodic(self.sampling["tau_min"], self.sampling["tau_max"], t_end, rng=as_rng(rng))
        if not self.system.is_continuous:
            return periodic(self.system.dt, t_end)
        raise ValueError("the model has no [sampling] table: give period or tau_min/tau_max")

    def signal(self, rng, t: np.ndarray) -> SwitchingSignal:
        """Draw one switching signal for the sample times ``t`` from the switching model."""
        if not self.switching:
            raise ValueError("the model has no [switching] table: give kind and its parameters")
        return _draw_signal(self.switching, self.system.n_modes, rng, np.asarray(t, dtype=float))

    def _duration(self, t_end) -> float:
        if t_end is not None:
            return float(t_end)
        if "duration" not in self.sampling:
            raise ValueError("give t_end: the model file sets no sampling.duration")
        return float(self.sampling["duration"])

    def to_dict(self) -> dict:
        """The TOML layout (see the module docstring)."""
        doc = {}
        if self.description:
            doc["description"] = self.description
        doc.update(self.system.to_dict())
        for name, table in (("sampling", self.sampling), ("switching", self.switching), ("noise", self.noise)):
            if table:
                doc[name] = {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in table.items()}
        if self.initial is not None:
            doc["initial"] = {"mean": self.initial[0], "cov": self.initial[1]}
        modes = doc.pop("modes")
        doc["modes"] = modes  # arrays of tables last
        return doc


def _draw_signal(sw: dict, L: int, rng, t: np.ndarray) -> SwitchingSignal:
    kind = sw["kind"]
    t_end = float(t[-1]) + (float(t[-1] - t[-2]) if t.size > 1 else 1.0)
    if kind == "dwell":
        return dwell_time(L, t_end, sw["min_dwell"], sw["max_dwell"], rng=rng, initial_mode=sw.get("initial_mode", 0))
    if kind == "average-dwell":
        return average_dwell_time(L, t_end, sw["tau_a"], sw["N0"], rng=rng, rate=sw.get("rate"),
                                  initial_mode=sw.get("initial_mode", 0))
    if kind == "markov":
        return markov_at_samples(sw["transition"], t, rng=rng, initial=sw.get("initial"))
    if kind == "markov-continuous":
        return markov_continuous(sw["rates"], t_end, rng=rng, initial_mode=sw.get("initial_mode", 0))
    if kind == "iid":
        return iid_at_samples(sw["p"], t, rng=rng)
    return schedule(sw["times"], sw["modes"])


def save_model(spec: ModelSpec, path: str | Path) -> Path:
    """Write ``spec`` as a TOML model file; :func:`load_model` reads it back exactly."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(_toml.dumps(spec.to_dict()), encoding="utf-8")
    return path


def load_model(path: str | Path) -> ModelSpec:
    """Read a TOML model file.

    Raises
    ------
    ModelFileError
        (a ValueError) naming the file, the table and the key of anything
        malformed: unknown keys (with the closest valid one), wrong types, shapes
        or values; also for a file that is not UTF-8 TOML or does not exist.
    """
    source = str(path)
    doc = _toml.read(path)
    system = SwitchedLinearSystem.from_dict(doc, source=source)
    description = doc.get("description", "")
    if not isinstance(description, str):
        raise _toml.ModelFileError(_toml.where(source, "description: expected a string"))
    return ModelSpec(
        system=system,
        sampling=_sampling(doc.get("sampling", {}), source),
        switching=_switching(doc.get("switching", {}), source, system.n_modes),
        initial=_initial(doc.get("initial"), source, system.n_states),
        noise=_noise(doc.get("noise", {}), source),
        description=description,
    )


def _table(value, source: str, name: str) -> dict:
    if not isinstance(value, dict):
        raise _toml.ModelFileError(_toml.where(source, f"{name}: expected a table"))
    return value


def _sampling(table, source: str) -> dict:
    table = _table(table, source, "sampling")
    for key in table:
        if key not in _SAMPLING_KEYS:
            raise _toml.unknown_key(source, "sampling", key, _SAMPLING_KEYS)
    out = {k: _toml.number(v, _toml.where(source, f"sampling.{k}"), positive=True) for k, v in table.items()}
    if "period" in out and ("tau_min" in out or "tau_max" in out):
        raise _toml.ModelFileError(_toml.where(source, "sampling.period: give either period or tau_min/tau_max"))
    if ("tau_min" in out) != ("tau_max" in out):
        raise _toml.ModelFileError(_toml.where(source, "sampling.tau_max: tau_min and tau_max come together"))
    if "tau_min" in out and out["tau_max"] < out["tau_min"]:
        raise _toml.ModelFileError(_toml.where(source, f"sampling.tau_max: must be >= tau_min = {out['tau_min']}"))
    return out


def _switching(table, source: str, L: int) -> dict:
    table = _table(table, source, "switching")
    if not table:
        return {}
    kind = table.get("kind")
    if not isinstance(kind, str) or kind not in _SWITCHING_KEYS:
        close = (difflib.get_close_matches(kind, _SWITCHING_KEYS, n=1)
                 if isinstance(kind, str) else [])
        hint = f"did you mean {close[0]!r}? " if close else ""
        raise _toml.ModelFileError(_toml.where(source, f"switching.kind: {hint}expected one of "
                                                       f"{sorted(_SWITCHING_KEYS)}, got {kind!r}"))
    for key in table:
        if key != "kind" and key not in _SWITCHING_KEYS[kind]:
            owners = sorted(k for k, keys in _SWITCHING_KEYS.items() if key in keys)
            if not owners:
                raise _toml.unknown_key(source, "switching", key, _SWITCHING_KEYS[kind] | {"kind"})
            takes = ", ".join(sorted(_SWITCHING_KEYS[kind]))
            raise _toml.ModelFileError(_toml.where(
                source, f"switching.{key}: not a parameter of kind {kind!r} (it is one of kind "
                        f"{owners[0]!r}); kind {kind!r} takes {takes}"))
    out = {"kind": kind}
    at = lambda k: _toml.where(source, f"switching.{k}")
    try:
        for key, value in table.items():
            if key in ("kind",):
                continue
            if key in ("min_dwell", "max_dwell", "tau_a", "N0", "rate"):
                out[key] = _toml.number(value, at(key), positive=True)
            elif key == "initial_mode" or (key == "initial" and not isinstance(value, list)):
                if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < L:
                    raise _toml.ModelFileError(f"{at(key)}: expected a mode index in 0..{L - 1}, "
                                               f"got {value!r}")
                out[key] = value
            elif key in ("transition", "rates"):
                out[key] = _toml.matrix(value, at(key), shape=(L, L))
            elif key in ("p", "initial"):  # probabilities (initial: or a mode index, above)
                out[key] = _toml.matrix(value, at(key), shape=(L,), ndim=1)
            elif key == "times":
                out[key] = _toml.matrix(value, at(key), ndim=1)
            elif key == "modes":
                indices = isinstance(value, list) and all(
                    isinstance(v, int) and not isinstance(v, bool) and 0 <= v < L for v in value)
                if not indices:
                    raise _toml.ModelFileError(f"{at(key)}: expected a list of mode indices in "
                                               f"0..{L - 1}, got {value!r}")
                out[key] = np.asarray(value, dtype=np.int64)
        missing = {"dwell": ["min_dwell", "max_dwell"], "average-dwell": ["tau_a", "N0"], "markov": ["transition"],
                   "markov-continuous": ["rates"], "iid": ["p"], "schedule": ["times", "modes"]}[kind]
        for key in missing:
            if key not in out:
                raise _toml.ModelFileError(f"{at(key)}: required for kind {kind!r}")
        # the generators validate the parameters (stochastic rows, dwell bounds, ...):
        # draw a signal over a few of its switches
        _draw_signal(out, L, np.random.default_rng(0), np.arange(3.0) * _time_scale(out))
    except _toml.ModelFileError:
        raise
    except (TypeError, ValueError) as exc:
        raise _toml.ModelFileError(_toml.where(source, f"switching: {exc}")) from None
    return out


def _time_scale(sw: dict) -> float:
    """A time over which the switching model makes a few switches (probing its parameters)."""
    if "min_dwell" in sw:
        return sw["min_dwell"]
    if "tau_a" in sw:
        return min(sw["tau_a"], 1.0 / sw["rate"]) if "rate" in sw else sw["tau_a"]
    if "rates" in sw:
        return 1.0 / max(float(np.max(np.abs(sw["rates"]))), 1.0)
    return 1.0


def _initial(table, source: str, n: int):
    if table is None:
        return None
    table = _table(table, source, "initial")
    for key in table:
        if key not in _INITIAL_KEYS:
            raise _toml.unknown_key(source, "initial", key, _INITIAL_KEYS)
    if "mean" not in table:
        raise _toml.ModelFileError(_toml.where(source, "initial.mean: required (cov defaults to "
                                                       "zero)"))
    mean = _toml.matrix(table["mean"], _toml.where(source, "initial.mean"), shape=(n,), ndim=1)
    cov = _toml.matrix(table.get("cov", np.zeros((n, n)).tolist()), _toml.where(source, "initial.cov"),
                       shape=(n, n))
    try:
        cov = check_symmetric_psd(cov, "initial.cov")
    except ValueError as exc:
        raise _toml.ModelFileError(_toml.where(source, str(exc))) from None
    return mean, cov


def _noise(table, source: str) -> dict:
    table = _table(table, source, "noise")
    out = {}
    for key, value in table.items():
        if key not in _NOISE_BOUNDS | _NOISE_DESIGN:
            raise _toml.unknown_key(source, "noise", key, _NOISE_BOUNDS | _NOISE_DESIGN)
        at = _toml.where(source, f"noise.{key}")
        out[key] = _toml.number(value, at, positive=key in _NOISE_DESIGN)
        if out[key] < 0:
            raise _toml.ModelFileError(f"{at}: a bound on a norm must be >= 0, got {value!r}")
    return out
