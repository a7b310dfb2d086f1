"""Switching models: the laws a switching signal is drawn from.

A model is a small frozen object holding its parameters, validated when it is built,
with one method, ``sample(rng, t)``, that draws a :class:`~switchest.signals.SwitchingSignal`
for the sample times ``t`` (from the generators of :mod:`switchest.signals`, which consume the
``rng`` exactly as when called directly). :func:`switchest.simulate.simulate` accepts a model
and draws one signal per trial.

Each model is the ``[switching]`` table of a model file (:mod:`switchest.modelfile`), whose
``kind`` names the class; ``to_dict`` writes that table and :meth:`SwitchingModel.from_dict`
reads it:

==================  =================  ===========================================
kind                class              parameters (``*``: optional)
==================  =================  ===========================================
dwell               Dwell              min_dwell, max_dwell, initial_mode*
average-dwell       AverageDwell       tau_a, N0, rate*, initial_mode*
markov              MarkovAtSamples    transition, initial*
markov-continuous   MarkovContinuous   rates, initial_mode*
iid                 IID                p
schedule            Schedule           times, modes
==================  =================  ===========================================

``Dwell`` and ``AverageDwell`` also hold the number of modes they switch among
(``n_modes``, not written to the file: it is the system's).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import KW_ONLY, MISSING, dataclass, fields
from typing import ClassVar

import numpy as np

from ._checks import check_mode, check_probability_vector, check_row_stochastic, float_array
from .signals import (
    SwitchingSignal,
    _check_average_dwell,
    _check_dwell_bounds,
    _check_initial,
    _check_n_modes,
    _check_rates,
    _sample_times,
    average_dwell_time,
    dwell_time,
    iid_at_samples,
    markov_at_samples,
    markov_continuous,
    schedule,
)

__all__ = [
    "IID",
    "KINDS",
    "AverageDwell",
    "Dwell",
    "MarkovAtSamples",
    "MarkovContinuous",
    "Schedule",
    "SwitchingModel",
]


class SwitchingModel(ABC):
    """Base of the switching models: ``sample``, ``to_dict`` and ``from_dict``.

    Attributes
    ----------
    kind : str
        The model file's name of the model (``[switching] kind``).
    at_samples : bool
        True when switches happen only at the sample instants (a dwell of at least one
        sampling interval), False when they fall anywhere in time.
    """

    kind: ClassVar[str]
    at_samples: ClassVar[bool] = False

    @abstractmethod
    def sample(self, rng, t) -> SwitchingSignal:
        """Draw one switching signal for the strictly increasing sample times ``t (K,)``.

        Models switching in continuous time draw on ``[0, t[-1] + (t[-1] - t[-2]))``, one
        sampling interval past the last sample (``[0, t[0] + 1)`` for a single sample).
        """

    @property
    def dwell_time(self) -> float | None:
        """The least time between consecutive switches the model guarantees, or None."""
        return None

    @classmethod
    def parameters(cls) -> dict[str, bool]:
        """The model file's parameter names of this kind, each mapped to whether it is required."""
        return {f.name: f.default is MISSING for f in fields(cls)
                if f.name != "n_modes" and f.init}

    def to_dict(self) -> dict:
        """The ``[switching]`` table: ``{"kind": ..., <parameters>}`` of plain Python values.

        Parameters left at None (their default) are omitted.
        """
        out: dict = {"kind": self.kind}
        for name in self.parameters():
            value = getattr(self, name)
            if value is not None:
                out[name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out

    @classmethod
    def from_dict(cls, table: dict, *, n_modes: int) -> SwitchingModel:
        """The model of a ``[switching]`` table (``table["kind"]`` picks the class).

        Parameters
        ----------
        table : dict
            ``{"kind": ..., <parameters>}`` as :meth:`to_dict` writes it.
        n_modes : int
            The number of modes of the system the model drives: given to the models that
            hold it, checked against the size of the others' matrices.

        Raises
        ------
        ValueError
            For an unknown kind (or one that is not ``cls``'s when called on a subclass),
            an unknown or missing parameter, or a model with another number of modes.
        """
        if not isinstance(table, dict):
            raise TypeError(f"table must be a dict, got {type(table).__name__}")
        kind = table.get("kind")
        model = KINDS.get(kind) if isinstance(kind, str) else None
        if model is None or not issubclass(model, cls):
            want = sorted(KINDS) if cls is SwitchingModel else [cls.kind]
            raise ValueError(f"table['kind'] must be one of {want}, got {kind!r}")
        params = {k: v for k, v in table.items() if k != "kind"}
        known = model.parameters()
        for key in params:
            if key not in known:
                raise ValueError(f"table[{key!r}] is not a parameter of kind {kind!r} "
                                 f"(it takes {', '.join(known)})")
        for key, required in known.items():
            if required and key not in params:
                raise ValueError(f"table[{key!r}] is required for kind {kind!r}")
        if "n_modes" in {f.name for f in fields(model)}:
            return model(n_modes, **params)
        out = model(**params)
        if out.n_modes not in (None, n_modes):
            raise ValueError(f"a {kind!r} model of {out.n_modes} modes cannot drive "
                             f"n_modes = {n_modes}")
        return out


def _horizon(t) -> float:
    """One sampling interval past the last sample time (1 past a single one)."""
    t = _sample_times(t)
    return float(t[-1]) + (float(t[-1] - t[-2]) if t.size > 1 else 1.0)


def _store(model: SwitchingModel, **checked) -> None:
    """Write the checked parameters onto the frozen ``model`` (from its ``__post_init__``)."""
    for name, value in checked.items():
        object.__setattr__(model, name, value)


def _frozen(value: np.ndarray) -> np.ndarray:
    value = np.array(value)
    value.setflags(write=False)
    return value


@dataclass(frozen=True, eq=False)
class Dwell(SwitchingModel):
    """Dwell times drawn uniformly in ``[min_dwell, max_dwell]``, the next mode among the others.

    The dwell-time switching of Shankar et al. §II (every dwell at least :math:`\\tau_d` =
    ``min_dwell``); drawn by :func:`~switchest.signals.dwell_time`.

    Parameters
    ----------
    n_modes : int
        Number of modes :math:`L \\ge 2`.
    min_dwell, max_dwell : float
        Bounds of the dwell times, :math:`0 < \\mathrm{min\\_dwell} \\le \\mathrm{max\\_dwell}`.
    initial_mode : int, keyword-only
        Mode on ``[0, first switch)``; default 0.
    """

    kind: ClassVar[str] = "dwell"
    n_modes: int
    min_dwell: float
    max_dwell: float
    _: KW_ONLY
    initial_mode: int = 0

    def __post_init__(self) -> None:
        n_modes = _check_n_modes(self.n_modes)
        lo, hi = _check_dwell_bounds(self.min_dwell, self.max_dwell)
        _store(self, n_modes=n_modes, min_dwell=lo, max_dwell=hi,
               initial_mode=check_mode(self.initial_mode, n_modes, "initial_mode"))

    @property
    def dwell_time(self) -> float:
        """``min_dwell``."""
        return self.min_dwell

    def sample(self, rng, t) -> SwitchingSignal:
        """Draw one signal (see :meth:`SwitchingModel.sample`)."""
        return dwell_time(self.n_modes, _horizon(t), self.min_dwell, self.max_dwell, rng=rng,
                          initial_mode=self.initial_mode)


@dataclass(frozen=True, eq=False)
class AverageDwell(SwitchingModel):
    """Average dwell time ``tau_a`` with chatter bound ``N0``:
    :math:`N(s, t) \\le N_0 + (t - s) / \\tau_a`.

    Etienne et al. Definition 2; drawn by :func:`~switchest.signals.average_dwell_time`
    (switch attempts at ``rate``, accepted while the budget allows).

    Parameters
    ----------
    n_modes : int
        Number of modes :math:`L \\ge 2`.
    tau_a : float
        Average dwell time, positive.
    N0 : float
        Chatter bound, :math:`N_0 \\ge 1`.
    rate : float or None, keyword-only
        Intensity of the switch attempts; None (default) means :math:`2 / \\tau_a`.
    initial_mode : int, keyword-only
        Mode on ``[0, first switch)``; default 0.
    """

    kind: ClassVar[str] = "average-dwell"
    n_modes: int
    tau_a: float
    N0: float
    _: KW_ONLY
    rate: float | None = None
    initial_mode: int = 0

    def __post_init__(self) -> None:
        n_modes = _check_n_modes(self.n_modes)
        tau_a, N0, rate = _check_average_dwell(self.tau_a, self.N0, self.rate)
        _store(self, n_modes=n_modes, tau_a=tau_a, N0=N0, rate=rate,
               initial_mode=check_mode(self.initial_mode, n_modes, "initial_mode"))

    def sample(self, rng, t) -> SwitchingSignal:
        """Draw one signal (see :meth:`SwitchingModel.sample`)."""
        return average_dwell_time(self.n_modes, _horizon(t), self.tau_a, self.N0, rng=rng,
                                  rate=self.rate, initial_mode=self.initial_mode)


@dataclass(frozen=True, eq=False)
class MarkovAtSamples(SwitchingModel):
    """A discrete-time Markov chain that switches only at the sample instants.

    Drawn by :func:`~switchest.signals.markov_at_samples`.

    Parameters
    ----------
    transition : array_like, shape (L, L)
        ``transition[i, j]`` = :math:`\\Pr(\\text{mode } j \\text{ at } k+1 \\mid
        \\text{mode } i \\text{ at } k)`; rows sum to 1.
    initial : int, array_like of shape (L,) or None, keyword-only
        The mode at ``t[0]``, or the probabilities it is drawn from; None (default):
        uniform.
    """

    kind: ClassVar[str] = "markov"
    at_samples: ClassVar[bool] = True
    transition: np.ndarray
    _: KW_ONLY
    initial: int | np.ndarray | None = None

    def __post_init__(self) -> None:
        P = _frozen(check_row_stochastic(self.transition, "transition"))
        initial = _check_initial(self.initial, P.shape[0])
        _store(self, transition=P,
               initial=_frozen(initial) if isinstance(initial, np.ndarray) else initial)

    @property
    def n_modes(self) -> int:
        """Number of modes L."""
        return self.transition.shape[0]

    def sample(self, rng, t) -> SwitchingSignal:
        """Draw one signal (see :meth:`SwitchingModel.sample`)."""
        return markov_at_samples(self.transition, t, rng=rng, initial=self.initial)


@dataclass(frozen=True, eq=False)
class MarkovContinuous(SwitchingModel):
    """A continuous-time Markov chain: switches at any instant, exponential holding times.

    Drawn by :func:`~switchest.signals.markov_continuous`.

    Parameters
    ----------
    rates : array_like, shape (L, L)
        Generator matrix: ``rates[i, j]`` (:math:`i \\ne j`) the rate of jumps from i to j, rows
        summing to zero.
    initial_mode : int, keyword-only
        Mode on ``[0, first switch)``; default 0.
    """

    kind: ClassVar[str] = "markov-continuous"
    rates: np.ndarray
    _: KW_ONLY
    initial_mode: int = 0

    def __post_init__(self) -> None:
        rates = _frozen(_check_rates(self.rates))
        _store(self, rates=rates,
               initial_mode=check_mode(self.initial_mode, rates.shape[0], "initial_mode"))

    @property
    def n_modes(self) -> int:
        """Number of modes L."""
        return self.rates.shape[0]

    def sample(self, rng, t) -> SwitchingSignal:
        """Draw one signal (see :meth:`SwitchingModel.sample`)."""
        return markov_continuous(self.rates, _horizon(t), rng=rng, initial_mode=self.initial_mode)


@dataclass(frozen=True, eq=False)
class IID(SwitchingModel):
    """Modes drawn independently with probabilities ``p`` on each sample interval.

    The random switching of Wang et al. §2; drawn by :func:`~switchest.signals.iid_at_samples`.

    Parameters
    ----------
    p : array_like, shape (L,)
        Mode probabilities, non-negative, summing to 1.
    """

    kind: ClassVar[str] = "iid"
    at_samples: ClassVar[bool] = True
    p: np.ndarray

    def __post_init__(self) -> None:
        _store(self, p=_frozen(check_probability_vector(self.p, "p")))

    @property
    def n_modes(self) -> int:
        """Number of modes L."""
        return self.p.shape[0]

    def sample(self, rng, t) -> SwitchingSignal:
        """Draw one signal (see :meth:`SwitchingModel.sample`)."""
        return iid_at_samples(self.p, t, rng=rng)


@dataclass(frozen=True, eq=False)
class Schedule(SwitchingModel):
    """A fixed schedule: switch to ``modes[s+1]`` at ``times[s]``; ``sample`` ignores the rng.

    Parameters
    ----------
    times : array_like, shape (S,)
        Switch instants, finite; strictly increasing once repeated modes are merged.
    modes : array_like of int, shape (S+1,)
        Modes (0-based); a mode may repeat, as in :func:`~switchest.signals.schedule`.
    """

    kind: ClassVar[str] = "schedule"
    times: np.ndarray
    modes: np.ndarray

    def __post_init__(self) -> None:
        schedule(self.times, self.modes)  # validates both
        _store(self, times=_frozen(float_array(self.times, "times", ndim=1)),
               modes=_frozen(np.asarray(self.modes, dtype=np.int64)))

    @property
    def n_modes(self) -> None:
        """None: a schedule names modes, it does not fix their number."""
        return None

    @property
    def signal(self) -> SwitchingSignal:
        """The scheduled signal (repeated modes merged)."""
        return schedule(self.times, self.modes)

    @property
    def dwell_time(self) -> float | None:
        """The least time between two of its switches; None with fewer than two."""
        times = self.signal.times
        return float(np.min(np.diff(times))) if times.size > 1 else None

    def sample(self, rng, t) -> SwitchingSignal:
        """The scheduled signal, whatever ``rng`` (``t`` is checked, not used)."""
        _sample_times(t)
        return self.signal


KINDS: dict[str, type[SwitchingModel]] = {
    model.kind: model
    for model in (Dwell, AverageDwell, MarkovAtSamples, MarkovContinuous, IID, Schedule)
}
"""The model classes by their model-file ``kind``."""
