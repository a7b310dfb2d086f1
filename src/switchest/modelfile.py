"""Model files: a switched system with its sampling, switching model and initial state.

A TOML file holds the system (read by :func:`system_from_dict`) and, optionally::

    description = "free text"
    timing = "sample"       # the system's timing: which interval a sample's mode governs, the
                            # one after it ("sample", the default) or the one into it
                            # ("interval"); simulate draws in it, fit and the filters follow it
    [sampling]              # period = T, or tau_min / tau_max for aperiodic sampling;
    period = 0.0005         # duration = default length of a simulation (s)
    duration = 10.0
    [switching]             # a switching model (switchest.switching): kind = dwell |
    kind = "dwell"          # average-dwell | markov | markov-continuous | iid | schedule,
    min_dwell = 0.0009      # and its parameters
    max_dwell = 0.0012
    [initial]               # Gaussian initial state
    mean = [0.0, 100.0]
    cov = [[25.0, 0.0], [0.0, 25.0]]
    [input]                 # the constant input the system runs at (one value per input):
    value = [100.0]         # what simulate uses unless told another
    [states]                # names and units of the states, for tables and figures
    names = ["i_L", "v_0"]
    units = ["A", "V"]
    [noise]                 # bounds for Lee et al.'s conditions (bounded noise):
    v_max = 0.1             # |v| <= v_max, |u| <= u_max, |x| >= x_min; and, optionally,
    u_max = 1.0             # their detector's design: windows delta, Delta and
    x_min = 0.8             # observer_decay (A_i - L_i C_i with poles at -observer_decay ...)

The bounds ``v_max``, ``u_max``, ``x_min`` are finite and non-negative; ``delta``,
``Delta`` and ``observer_decay`` finite and positive. Every error names the file,
the table and the key; an unknown key, at any level, is an error that suggests
the closest valid one.

:func:`load_model` / :func:`save_model` read and write a whole file as a :class:`ModelSpec`;
:func:`load_system` / :func:`save_system` (and :func:`system_from_dict` /
:func:`system_to_dict`) its system alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _toml
from ._checks import as_rng, check_symmetric_psd, did_you_mean
from .signals import SwitchingSignal, aperiodic, periodic
from .switching import KINDS, SwitchingModel
from .system import SwitchedLinearSystem

__all__ = [
    "ModelSpec",
    "load_model",
    "load_system",
    "save_model",
    "save_system",
    "system_from_dict",
    "system_to_dict",
]

_SWITCHING_KEYS = {kind: model.parameters() for kind, model in KINDS.items()}
_SAMPLING_KEYS = {"period", "tau_min", "tau_max", "duration"}
_INITIAL_KEYS = {"mean", "cov"}
_NOISE_BOUNDS = {"v_max", "u_max", "x_min"}  # bounds on |v|, |u|, |x|: zero is meaningful
_NOISE_DESIGN = {"delta", "Delta", "observer_decay"}  # windows (s) and a decay rate (1/s)
_TOP_KEYS = {"domain", "dt", "shared", "modes", "sampling", "switching", "initial", "input",
             "noise", "states", "description", "timing"}
_TIMINGS = ("sample", "interval")
_INPUT_KEYS = {"value"}
_STATES_KEYS = {"names", "units"}


@dataclass(frozen=True, eq=False)
class ModelSpec:
    """A system and how it is exercised.

    Attributes
    ----------
    system : SwitchedLinearSystem
    sampling : dict
        ``{"period": T}`` or ``{"tau_min": a, "tau_max": b}``, plus ``"duration"``.
    switching : SwitchingModel or None
        The switching model (:mod:`switchest.switching`), or None when the file has none.
    initial : tuple of arrays or None
        ``(mean (n,), cov (n, n))``.
    noise : dict
        Bounds such as ``v_max``, ``u_max``, ``x_min`` for bounded-noise analyses,
        and the minimum-distance detector's ``delta``, ``Delta``, ``observer_decay``.
    state_names, state_units : tuple of str
        A name and a unit per state (empty: ``x0, x1, ...`` without units).
    description : str
    input : ndarray, shape (l,), or None
        The constant input the system runs at (``[input] value``), or None when the file
        names none.
    timing : {"sample", "interval"}
        The system's timing (:attr:`SwitchedLinearSystem.timing`, a read-only property): which
        interval the mode of a sample governs in the file's data (:doc:`/conventions`), the
        one after it (``"sample"``, the default) or the one before it (``"interval"``).
    """

    system: SwitchedLinearSystem
    sampling: dict = field(default_factory=dict)
    switching: SwitchingModel | None = None
    initial: tuple[np.ndarray, np.ndarray] | None = None
    noise: dict = field(default_factory=dict)
    description: str = ""
    state_names: tuple[str, ...] = ()
    state_units: tuple[str, ...] = ()
    input: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.system, SwitchedLinearSystem):
            raise TypeError(f"system must be a SwitchedLinearSystem, "
                            f"got {type(self.system).__name__}")
        n = self.system.n_states
        if self.input is not None and np.shape(self.input) != (self.system.n_inputs,):
            raise ValueError(f"input must hold the system's {self.system.n_inputs} input(s), "
                             f"got shape {np.shape(self.input)}")
        for name in ("state_names", "state_units"):
            labels = getattr(self, name)
            if not isinstance(labels, tuple) or not all(isinstance(v, str) for v in labels):
                raise TypeError(f"{name} must be a tuple of str, got {labels!r}")
            if labels and len(labels) != n:
                raise ValueError(f"{name} must name all {n} states, got {len(labels)}")
        sw = self.switching
        if sw is not None and not isinstance(sw, SwitchingModel):
            raise TypeError(f"switching must be a SwitchingModel (switchest.switching) or None, "
                            f"got {type(sw).__name__}")
        L = self.system.n_modes
        if sw is not None and sw.n_modes not in (None, L):
            raise ValueError(f"switching switches among {sw.n_modes} modes, the system has {L}")

    @property
    def timing(self) -> str:
        """The system's timing, the file's top-level ``timing``."""
        return self.system.timing

    @property
    def switches_between_samples(self) -> bool:
        """Whether the switches fall between the samples: a continuous-time system whose
        switching model switches in continuous time, not at the samples."""
        sw = self.switching
        return self.system.is_continuous and sw is not None and not sw.at_samples

    def sample_times(self, t_end: float | None = None, *, rng=None) -> np.ndarray:
        """Sample times on :math:`[0, t_\\mathrm{end}]` (default: the file's duration)."""
        t_end = self._duration(t_end)
        if "period" in self.sampling:
            return periodic(self.sampling["period"], t_end)
        if "tau_min" in self.sampling:
            return aperiodic(self.sampling["tau_min"], self.sampling["tau_max"], t_end,
                             rng=as_rng(rng))
        if not self.system.is_continuous:
            return periodic(self.system.dt, t_end)
        raise ValueError("the model has no [sampling] table: give period or tau_min/tau_max")

    def signal(self, rng, t: np.ndarray) -> SwitchingSignal:
        """Draw one switching signal for the sample times ``t``: ``switching.sample(rng, t)``."""
        if self.switching is None:
            raise ValueError("the model has no [switching] table: give kind and its parameters")
        return self.switching.sample(rng, t)

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
        doc.update(system_to_dict(self.system))
        switching = {} if self.switching is None else self.switching.to_dict()
        for name, table in (("sampling", self.sampling), ("switching", switching),
                            ("noise", self.noise)):
            if table:
                doc[name] = {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v)
                             for k, v in table.items()}
        if self.initial is not None:
            doc["initial"] = {"mean": self.initial[0], "cov": self.initial[1]}
        if self.input is not None:
            doc["input"] = {"value": np.asarray(self.input).tolist()}
        states = {k: list(v) for k, v in (("names", self.state_names),
                                          ("units", self.state_units)) if v}
        if states:
            doc["states"] = states
        modes = doc.pop("modes")
        doc["modes"] = modes  # arrays of tables last
        return doc


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
    system = system_from_dict(doc, source=source)
    description = doc.get("description", "")
    if not isinstance(description, str):
        raise _toml.ModelFileError(_toml.where(source, "description: expected a string"))
    return ModelSpec(
        system=system,
        sampling=_sampling(doc.get("sampling", {}), source),
        switching=_switching(doc.get("switching", {}), source, system.n_modes),
        initial=_initial(doc.get("initial"), source, system.n_states),
        input=_input(doc.get("input"), source, system.n_inputs),
        noise=_noise(doc.get("noise", {}), source),
        description=description,
        **_states(doc.get("states", {}), source, system.n_states),
    )


def load_system(path: str | Path) -> SwitchedLinearSystem:
    """Read the system of a TOML model file (layout: :func:`system_from_dict`).

    The file's other tables (sampling, switching, initial state) are read by
    :func:`load_model`; here they are allowed and ignored.
    """
    return system_from_dict(_toml.read(path), source=str(path))


def save_system(system: SwitchedLinearSystem, path: str | Path) -> Path:
    """Write ``system`` as a TOML model file that :func:`load_system` reads back exactly."""
    if not isinstance(system, SwitchedLinearSystem):
        raise TypeError(f"system must be a SwitchedLinearSystem, got {type(system).__name__}")
    path = Path(path)
    path.write_text(_toml.dumps(system_to_dict(system)), encoding="utf-8")
    return path


def system_to_dict(system: SwitchedLinearSystem) -> dict:
    """The layout :func:`system_from_dict` reads; matrices equal in all modes go to ``[shared]``."""
    doc: dict = {"domain": system.domain}
    if system.dt is not None:
        doc["dt"] = system.dt
    if system.timing != "sample":  # the default is not written
        doc["timing"] = system.timing
    shared, per_mode = {}, [{} for _ in range(system.n_modes)]
    for key in "ABCQR":
        arr = getattr(system, key)
        if arr.size == 0 or (key in "QR" and not np.any(arr)):
            continue  # no input / no noise: the defaults say so
        if system.n_modes > 1 and np.all(arr == arr[:1]):
            shared[key] = arr[0]
        else:
            for i in range(system.n_modes):
                per_mode[i][key] = arr[i]
    if shared:
        doc["shared"] = shared
    doc["modes"] = per_mode
    return doc


def system_from_dict(doc: dict, *, source: str = "<model>") -> SwitchedLinearSystem:
    """Build the system of a parsed model file.

    Layout::

        domain = "continuous"        # or "discrete", with dt = <step>
        timing = "sample"            # or "interval" (SwitchedLinearSystem.timing; optional)
        [shared]                     # matrices common to every mode (optional)
        C = [[0.0, 1.0]]
        R = [[5.0]]
        [[modes]]                    # one table per mode, in mode order
        A = [[-4000.0, 0.0], [0.0, -42.55]]
        B = [[2000.0], [0.0]]

    Each of A, B, C, Q, R is given either once in ``[shared]`` or in every mode;
    B, C, Q, R default as in :meth:`SwitchedLinearSystem.continuous`. The other tables
    of a model file are allowed (and not read). Errors name the file, the table and the
    key (``"m.toml: modes[2].A: expected 4x4, got 4x3"``).
    """
    if not isinstance(doc, dict):
        raise TypeError(f"doc must be a dict (a parsed model file), got {type(doc).__name__}")
    for key in doc:
        if key not in _TOP_KEYS:
            raise _toml.unknown_key(source, "", key, _TOP_KEYS)
    domain, dt = _time_base(doc, source)
    timing = doc.get("timing", "sample")
    if not isinstance(timing, str) or timing not in _TIMINGS:
        raise _toml.ModelFileError(_toml.where(
            source, f"timing: expected one of {', '.join(map(repr, _TIMINGS))}, got {timing!r}"))
    values, shared = _matrix_entries(doc, source)
    arrays = _matrices(values, shared, source)
    build = SwitchedLinearSystem.continuous if domain == "continuous" else (
        lambda *a, **kw: SwitchedLinearSystem.discrete(*a, dt=dt, **kw))
    try:
        return build(*(arrays.get(k) for k in "ABCQR"), timing=timing)
    except (TypeError, ValueError) as exc:
        raise _toml.ModelFileError(f"{source}: {exc}") from None


def _fail(source: str, text: str) -> _toml.ModelFileError:
    return _toml.ModelFileError(_toml.where(source, text))


def _time_base(doc: dict, source: str) -> tuple[str, float | None]:
    """``domain`` and ``dt`` (None for a continuous-time system)."""
    domain = doc.get("domain")
    if domain not in ("continuous", "discrete"):
        raise _fail(source, f"domain: expected \"continuous\" or \"discrete\", got {domain!r}")
    if domain == "continuous":
        if "dt" in doc:
            raise _fail(source, "dt: only a discrete-time system has a step")
        return domain, None
    if "dt" not in doc:
        raise _fail(source, "dt: required for a discrete-time system")
    return domain, _toml.number(doc["dt"], _toml.where(source, "dt"), positive=True)


def _matrix_entries(doc: dict, source: str) -> tuple[dict, dict]:
    """Where each of A, B, C, Q, R is given: ``{key: [(location, value), ...] or None}``.

    One entry when the matrix is in ``[shared]``, one per mode otherwise; also returns the
    ``[shared]`` table.
    """
    modes = doc.get("modes")
    if not isinstance(modes, list) or not modes or not all(isinstance(m, dict) for m in modes):
        raise _fail(source, "modes: at least one [[modes]] table is required")
    shared = doc.get("shared", {})
    if not isinstance(shared, dict):
        raise _fail(source, "shared: expected a table")
    tables = [("shared", shared)] + [(f"modes[{i}]", m) for i, m in enumerate(modes)]
    for table, entries in tables:
        for key in entries:
            if key not in ("A", "B", "C", "Q", "R"):
                raise _toml.unknown_key(source, table, key, "ABCQR")
    values = {}
    for key in "ABCQR":
        given = [i for i, m in enumerate(modes) if key in m]
        if key in shared and given:
            raise _fail(source, f"modes[{given[0]}].{key}: also given in [shared]; give it once")
        if given and len(given) != len(modes):
            missing = next(i for i in range(len(modes)) if i not in given)
            raise _fail(source, f"modes[{missing}].{key}: missing (given for other modes; give "
                                "it per mode or in [shared])")
        values[key] = ([("shared." + key, shared[key])] if key in shared
                       else [(f"modes[{i}].{key}", m[key]) for i, m in enumerate(modes)]
                       if given else None)
    if values["A"] is None:
        raise _fail(source, "modes[0].A: missing (A is required, per mode or in [shared])")
    return values, shared


def _matrices(values: dict, shared: dict, source: str) -> dict[str, np.ndarray]:
    """The given matrices, shapes checked across modes; Q, R symmetric PSD (R definite)."""
    n = _toml.matrix(values["A"][0][1], _toml.where(source, values["A"][0][0])).shape[0]
    m = None
    shapes = {"A": (n, n), "B": (n, None), "C": (None, n), "Q": (n, n)}
    arrays = {}
    for key in "ABCQR":
        if values[key] is None:
            continue
        want = shapes.get(key, (m, m))
        mats = [_toml.matrix(v, _toml.where(source, at), shape=want) for at, v in values[key]]
        for (at, _), mat in zip(values[key][1:], mats[1:]):
            if mat.shape != mats[0].shape:
                raise _fail(source, f"{at}: expected {_dims(mats[0].shape)} like "
                                    f"{values[key][0][0]}, got {_dims(mat.shape)}")
        if key in "QR":
            for (at, _), mat in zip(values[key], mats):
                try:
                    check_symmetric_psd(mat, at, definite=key == "R")
                except ValueError as exc:
                    raise _fail(source, str(exc)) from None
        if key == "C":
            m = mats[0].shape[0]
        arrays[key] = mats[0] if key in shared else np.stack(mats)
    if "R" in arrays and m is None and arrays["R"].shape[-1] != n:  # C defaults to the identity
        raise _fail(source, f"R: expected {n}x{n} (C is the identity), got "
                            f"{_dims(arrays['R'].shape[-2:])}")
    return arrays


def _dims(shape: tuple[int, ...]) -> str:
    return "x".join(map(str, shape))


def _table(value, source: str, name: str, keys=None) -> dict:
    """``value`` checked to be a table (of no key outside ``keys``, where given)."""
    if not isinstance(value, dict):
        raise _toml.ModelFileError(_toml.where(source, f"{name}: expected a table"))
    for key in () if keys is None else value:
        if key not in keys:
            raise _toml.unknown_key(source, name, key, keys)
    return value


def _sampling(table, source: str) -> dict:
    table = _table(table, source, "sampling", _SAMPLING_KEYS)
    out = {k: _toml.number(v, _toml.where(source, f"sampling.{k}"), positive=True)
           for k, v in table.items()}
    if "period" in out and ("tau_min" in out or "tau_max" in out):
        raise _fail(source, "sampling.period: give either period or tau_min/tau_max")
    if ("tau_min" in out) != ("tau_max" in out):
        raise _fail(source, "sampling.tau_max: tau_min and tau_max come together")
    if "tau_min" in out and out["tau_max"] < out["tau_min"]:
        raise _fail(source, f"sampling.tau_max: must be >= tau_min = {out['tau_min']}")
    return out


def _switching(table, source: str, L: int) -> SwitchingModel | None:
    """The ``[switching]`` table's model: keys and values checked here, naming the file and key;
    the model's own validation (stochastic rows, dwell bounds, ...) at its construction."""
    table = _table(table, source, "switching")
    if not table:
        return None
    kind = table.get("kind")
    if not isinstance(kind, str) or kind not in _SWITCHING_KEYS:
        hint = did_you_mean(kind, _SWITCHING_KEYS, after=" ") if isinstance(kind, str) else ""
        raise _fail(source, f"switching.kind: {hint}expected one of {sorted(_SWITCHING_KEYS)}, "
                            f"got {kind!r}")
    keys = _SWITCHING_KEYS[kind]
    for key in table:
        if key != "kind" and key not in keys:
            owners = sorted(k for k, params in _SWITCHING_KEYS.items() if key in params)
            if not owners:
                raise _toml.unknown_key(source, "switching", key, {*keys, "kind"})
            raise _fail(source, f"switching.{key}: not a parameter of kind {kind!r} (it is one "
                                f"of kind {owners[0]!r}); kind {kind!r} takes "
                                f"{', '.join(sorted(keys))}")
    try:
        out = {"kind": kind}
        out.update((k, _switching_value(k, v, _toml.where(source, f"switching.{k}"), L))
                   for k, v in table.items() if k != "kind")
        for key, required in keys.items():
            if required and key not in out:
                raise _fail(source, f"switching.{key}: required for kind {kind!r}")
        return SwitchingModel.from_dict(out, n_modes=L)
    except _toml.ModelFileError:
        raise
    except (TypeError, ValueError) as exc:
        raise _fail(source, f"switching: {exc}") from None


def _switching_value(key: str, value, at: str, L: int):
    """One parameter of a ``[switching]`` table, of the type and shape its key takes."""
    if key in ("min_dwell", "max_dwell", "tau_a", "N0", "rate"):
        return _toml.number(value, at, positive=True)
    if key == "initial_mode" or (key == "initial" and not isinstance(value, list)):
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < L:
            raise _toml.ModelFileError(f"{at}: expected a mode index in 0..{L - 1}, got {value!r}")
        return value
    if key in ("transition", "rates"):
        return _toml.matrix(value, at, shape=(L, L))
    if key in ("p", "initial"):  # probabilities (initial: or a mode index, above)
        return _toml.matrix(value, at, shape=(L,), ndim=1)
    if key == "times":
        return _toml.matrix(value, at, ndim=1)
    indices = isinstance(value, list) and all(  # key == "modes"
        isinstance(v, int) and not isinstance(v, bool) and 0 <= v < L for v in value)
    if not indices:
        raise _toml.ModelFileError(f"{at}: expected a list of mode indices in 0..{L - 1}, "
                                   f"got {value!r}")
    return np.asarray(value, dtype=np.int64)


def _initial(table, source: str, n: int):
    if table is None:
        return None
    table = _table(table, source, "initial", _INITIAL_KEYS)
    if "mean" not in table:
        raise _toml.ModelFileError(_toml.where(source, "initial.mean: required (cov defaults to "
                                                       "zero)"))
    mean = _toml.matrix(table["mean"], _toml.where(source, "initial.mean"), shape=(n,), ndim=1)
    cov = _toml.matrix(table.get("cov", np.zeros((n, n)).tolist()),
                       _toml.where(source, "initial.cov"), shape=(n, n))
    try:
        cov = check_symmetric_psd(cov, "initial.cov")
    except ValueError as exc:
        raise _toml.ModelFileError(_toml.where(source, str(exc))) from None
    return mean, cov


def _input(table, source: str, n_inputs: int) -> np.ndarray | None:
    """The ``[input]`` table's constant ``value`` (one finite number per input), or None."""
    if table is None:
        return None
    table = _table(table, source, "input", _INPUT_KEYS)
    if "value" not in table:
        raise _toml.ModelFileError(_toml.where(source, "input.value: required"))
    value = _toml.matrix(table["value"], _toml.where(source, "input.value"), shape=(n_inputs,),
                         ndim=1)
    if not np.all(np.isfinite(value)):
        raise _toml.ModelFileError(_toml.where(source, "input.value: expected finite numbers"))
    return value


def _states(table, source: str, n: int) -> dict:
    """``state_names``, ``state_units`` of the ``[states]`` table: lists of n strings."""
    table = _table(table, source, "states", _STATES_KEYS)
    out = {}
    for key, value in table.items():
        at = _toml.where(source, f"states.{key}")
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise _toml.ModelFileError(f"{at}: expected a list of strings, got {value!r}")
        if len(value) != n:
            raise _toml.ModelFileError(f"{at}: expected one per state ({n}), got {len(value)}")
        out[f"state_{key}"] = tuple(value)
    return out


def _noise(table, source: str) -> dict:
    table = _table(table, source, "noise", _NOISE_BOUNDS | _NOISE_DESIGN)
    out = {}
    for key, value in table.items():
        at = _toml.where(source, f"noise.{key}")
        out[key] = _toml.number(value, at, positive=key in _NOISE_DESIGN)
        if out[key] < 0:
            raise _toml.ModelFileError(f"{at}: a bound on a norm must be >= 0, got {value!r}")
    return out
