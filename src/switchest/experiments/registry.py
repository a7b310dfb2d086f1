"""The registry of named paper reproductions.

An experiment is a recipe: parameters that default to the paper's (and a
``quick`` preset for demos and tests), a function that splits the work into
independent tasks (a configuration and a block of trials), a function that runs
one task from its seed and returns JSON-able numbers, and a function that turns
all finished tasks into a :class:`Summary` — the paper's printed values beside
ours, the setup, notes on every disagreement — and figures.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._checks import did_you_mean, positive_int
from .verdict import Explanation, Fit, Verdict, judge, printed_number

__all__ = ["Experiment", "Row", "Summary", "register", "get", "names", "EXPERIMENTS", "MAX_BLOCKS"]


_COMPREHENSION = re.compile(r"(\.<locals>\.<(?:listcomp|genexpr|dictcomp|setcomp)>)+$")
"""A comprehension's own frame (Python 3.11): a row built in one is its function's."""


@dataclass(frozen=True)
class Row:
    """One compared quantity: the paper's printed value and ours.

    Attributes
    ----------
    quantity : str
    measured : float or str
        Ours: a number or a word.
    paper : float, str or None
        The printed value: a number (a string keeps the printed digits, trailing zeros
        included: ``"0.150"``), a word, or None where the paper prints none (the row is then
        *derived*: shown, not counted).
    unit : str
    details : str
        Run details (timings, the settings used, what else the run shows): shown, and never
        part of the verdict.
    se : float, optional
        Standard error of a Monte Carlo ``measured``.
    trials : int, optional
        The number of trials behind ``measured``.
    item : str, optional
        The printed item of the paper this row judges (a key of its paper's catalogue,
        :mod:`.printed_items`); by default the quantity itself.
    reading : str
        Non-empty for an alternative reading of the item (another formula, another setting):
        a sub-row, shown under the item and not counted.
    explanation : Explanation, optional
        The reason a difference is explained, with its evidence.
    fit : Fit, optional
        Set when ``measured`` comes from a parameter chosen to match the paper.
    source : str
        The function that built the row (``module:function``); filled in from the caller
        when not given.
    """

    quantity: str
    measured: float | str
    paper: float | str | None = None
    unit: str = ""
    details: str = ""
    se: float | None = None
    trials: int | None = None
    item: str | None = None
    reading: str = ""
    explanation: Explanation | None = None
    fit: Fit | None = None
    source: str = ""

    def __post_init__(self):
        if not self.source:  # the caller of the generated __init__ built this row
            caller = sys._getframe(2)
            module = caller.f_globals.get("__name__", "?").removeprefix("switchest.")
            function = _COMPREHENSION.sub("", caller.f_code.co_qualname)
            object.__setattr__(self, "source", f"{module}:{function}")

    @property
    def key(self) -> str:
        """The printed item this row belongs to."""
        return self.quantity if self.item is None else self.item

    @property
    def ratio(self) -> float | None:
        """measured / paper, where both are numbers and the paper's is non-zero."""
        printed = printed_number(self.paper)
        numeric = isinstance(self.measured, (int, float)) and not isinstance(self.measured, bool)
        if printed is not None and numeric and printed != 0:
            return float(self.measured) / float(printed)
        return None

    @property
    def verdict(self) -> Verdict:
        """Reproduced, within sampling error, matched by a fitted reading, differs (explained
        by a reason or not), or derived (:func:`~switchest.experiments.verdict.judge`)."""
        return judge(self.paper, self.measured, se=self.se, explanation=self.explanation,
                     fit=self.fit)


@dataclass(frozen=True)
class Summary:
    """What an experiment reports: compared rows, the setup, notes and figure files."""

    experiment: str
    title: str
    setup: str
    rows: list[Row]
    notes: list[str] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)

    def lines(self, width: int = 64) -> list[str]:
        """One line per row: the quantity (cut to ``width`` characters), the printed value
        (``-`` where the paper prints none), ours and the unit."""
        def text(value) -> str:
            if value is None:
                return "-"
            return f"{value:.4g}" if isinstance(value, float) else str(value)

        return [f"{row.quantity[:width]:{width}s} paper {text(row.paper):>9}  ours "
                f"{text(row.measured)} {row.unit}".rstrip() for row in self.rows]


Task = dict  # a JSON-able configuration; its "block" entry (if any) selects the trials' seed


@dataclass(frozen=True)
class Experiment:
    """A named reproduction.

    Attributes
    ----------
    name, paper, title : str
    defaults : dict
        Parameters, defaulting to the paper's setup.
    quick : dict
        Overrides for ``--quick`` (fewer trials, shorter runs).
    tasks : callable
        ``tasks(params) -> list[dict]``: independent task configurations. Tasks
        sharing a ``"block"`` value get the same seed, so every configuration sees
        the same simulated data for a block of trials. Configurations that differ
        only in what they run on that data (methods, gains, noise levels) are best
        one task that simulates the block once: it lists them under ``"variants"``
        (:func:`~switchest.experiments.scoring.split_variants`).
    run_task : callable
        ``run_task(config, rng) -> dict``: JSON-able results of one task; with
        ``"variants"``, ``{"variants": [...]}``, one result per variant.
    summarize : callable
        ``summarize(params, results, out_dir) -> Summary``, ``results`` being the
        list of ``(config, result)`` pairs; figures are written under ``out_dir``.
    """

    name: str
    paper: str
    title: str
    defaults: dict
    quick: dict
    tasks: Callable[[dict], list[Task]]
    run_task: Callable[[Task, np.random.Generator], dict]
    summarize: Callable[[dict, list[tuple[Task, dict]], Path], Summary]

    def params(self, *, quick: bool = False, **overrides) -> dict:
        """The parameters of a run: defaults, then the quick preset, then overrides.

        Overrides that are ``None`` (options left unset) are skipped.

        Raises
        ------
        ValueError
            For a parameter the experiment does not have; a trial count (``trials``,
            ``block_size``, ``blocks``, ``cases_per_block``) that is not a positive
            int (``TypeError`` if not an int at all); or more than :data:`MAX_BLOCKS`
            trial blocks.
        """
        params = dict(self.defaults)
        if quick:
            params.update(self.quick)
        unknown = set(overrides) - set(params)
        if unknown:
            raise ValueError(f"{self.name} has no parameter(s) {sorted(unknown)}; "
                             f"it has {sorted(params)}")
        params.update({k: v for k, v in overrides.items() if v is not None})
        for name in _COUNTS:
            if name in params:
                params[name] = positive_int(params[name], name)
        _check_blocks(params)
        return params


MAX_BLOCKS = 10_000
"""Most trial blocks a run may plan. Every block is one task per configuration, held in
memory while planning and kept as a row of the store. The papers' largest setups have 10
blocks; a thousand times that, at their task sizes (up to minutes each), is months of
computing, and a larger count is a typo (``--trials 100000000`` once hung in planning)."""

_COUNTS = ("trials", "block_size", "blocks", "cases_per_block")


def _check_blocks(params: dict) -> None:
    """Refuse a run of more than MAX_BLOCKS trial blocks before it is planned."""
    if "trials" in params and "block_size" in params:
        n = -(-params["trials"] // params["block_size"])
        what = (f"trials={params['trials']} in blocks of block_size={params['block_size']} "
                f"makes {n} blocks")
    elif "blocks" in params:
        n = params["blocks"]
        what = f"blocks={n}"
    else:
        return
    if n > MAX_BLOCKS:
        raise ValueError(f"{what}, more than the {MAX_BLOCKS} a run may plan (each block is a task "
                         "in memory and a row of the store): use fewer trials or larger blocks")


EXPERIMENTS: dict[str, Experiment] = {}


def register(experiment: Experiment) -> Experiment:
    """Add ``experiment`` to the registry (names are unique)."""
    if experiment.name in EXPERIMENTS:
        raise ValueError(f"an experiment named {experiment.name!r} is already registered")
    EXPERIMENTS[experiment.name] = experiment
    return experiment


def get(name: str) -> Experiment:
    """The registered experiment ``name``."""
    if name not in EXPERIMENTS:
        hint = did_you_mean(name, EXPERIMENTS, after=" ")
        raise ValueError(f"unknown experiment {name!r}; {hint}known: "
                         f"{', '.join(sorted(EXPERIMENTS))}")
    return EXPERIMENTS[name]


def names() -> list[str]:
    """Registered experiment names, sorted."""
    return sorted(EXPERIMENTS)
