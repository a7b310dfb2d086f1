"""Fitting from the files a user has: a measurement CSV of one or several trials and a model
file, and the model file of the fit (what ``switchest fit`` reads and writes).

:func:`read_trials` stacks the trials of a CSV for :func:`~switchest.learn.fit`,
:func:`start_transition` takes the starting transition matrix from the model file's switching
model, and :func:`fitted_model` builds the model file of a :class:`~switchest.learn.FitResult`,
which ``switchest estimate`` and ``switchest check`` read unchanged.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

from ..default_designs import transition_for
from ..measurements import read_measurements
from ..modelfile import ModelSpec
from ..switching import MarkovAtSamples, MarkovContinuous
from .result import FitResult

__all__ = ["fitted_model", "read_trials", "start_transition"]


def _trial_labels(path: Path) -> list[int | None]:
    """The trials of a measurement CSV (its ``trial`` column), ``[None]`` without that column.

    A file pandas cannot read, or a ``trial`` column of no valid label, also gives ``[None]``:
    :func:`~switchest.measurements.read_measurements` then says what is wrong with it.
    """
    try:
        frame = pd.read_csv(path, usecols=lambda c: str(c).strip() == "trial",
                            skipinitialspace=True)
    except (ValueError, OSError):
        return [None]
    if frame.shape[1] != 1:
        return [None]
    labels = pd.to_numeric(frame.iloc[:, 0], errors="coerce").dropna().to_numpy()
    labels = np.unique(labels[(labels >= 0) & (labels == np.round(labels))]).astype(int)
    return [int(v) for v in labels] or [None]


def read_trials(path: Path, spec: ModelSpec, trial: int | None) -> dict:
    """The measurements ``switchest fit`` reads: one trial (``--trial``), or all the trials of
    the CSV stacked, which must share their sample times; ``y (N, K, m)``, ``u (N, K, l)``,
    ``t (K,)``, ``mode (N, K)`` or None, and ``trials`` (N)."""
    labels = [trial] if trial is not None else _trial_labels(path)
    runs = [read_measurements(path, spec, trial=label) for label in labels]
    t = runs[0]["t"]
    for label, run in zip(labels[1:], runs[1:]):
        if not np.array_equal(run["t"], t):
            raise ValueError(f"{path}: trial {label} is sampled at other times than trial "
                             f"{labels[0]}; fit reads several trials only at the same sample "
                             "times: choose one with --trial")
    known = "mode" in runs[0]
    return {"t": t, "y": np.stack([r["y"] for r in runs]), "u": np.stack([r["u"] for r in runs]),
            "mode": np.stack([r["mode"] for r in runs]) if known else None,
            "trials": len(runs)}


def start_transition(spec: ModelSpec, t: np.ndarray) -> np.ndarray | None:
    """The starting transition matrix of ``switchest fit``: the model's switching model's
    (:func:`~switchest.default_designs.transition_for` at the data's median sampling interval),
    or None where it implies none (no switching model, a schedule): then
    :func:`~switchest.learn.fit` starts from the counts of the known modes, or a seeded draw."""
    if spec.switching is None:
        return None
    try:
        return transition_for(spec, float(np.median(np.diff(t))))
    except ValueError:
        return None


def fitted_model(spec: ModelSpec, result: FitResult, estimate: tuple[str, ...],
                 data: Path) -> tuple[ModelSpec, str]:
    """The model file ``switchest fit`` writes, and a note on its switching model.

    The system is the fitted one. The switching model: the model's own when the transition
    matrix was not estimated; a ``markov-continuous`` model of the generator
    ``FitResult.rates`` (``logm`` of the fitted transition over the sampling period) when the
    model's chain is continuous-time and such a generator exists; otherwise a ``markov``
    chain of the fitted per-sample transition matrix, switching at the samples (keeping the
    initial mode distribution of a ``markov`` model); the model's own where the fit put the
    switches between the samples (``FitResult.switch_times``) and the model's switching model is
    not a continuous-time chain."""
    sw = spec.switching
    if "transition" not in estimate and sw is not None:
        switching, note = sw, f"kept the model's switching model ({sw.kind})"
    elif (result.switch_times == "between" and sw is not None
          and not isinstance(sw, MarkovContinuous)):
        switching = sw
        note = (f"kept the model's switching model ({sw.kind}): its switches fall between the "
                "samples, where a per-sample chain of the fitted transition matrix would not "
                "put them")
    elif isinstance(sw, MarkovContinuous) and result.rates is not None:
        switching = MarkovContinuous(result.rates, initial_mode=sw.initial_mode)
        note = "markov-continuous: the generator of the fitted per-sample transition matrix"
    else:
        initial = sw.initial if isinstance(sw, MarkovAtSamples) else None
        switching = MarkovAtSamples(result.transition, initial=initial)
        note = "markov: the fitted per-sample transition matrix"
        if isinstance(sw, MarkovContinuous):
            note += (" (no continuous-time generator has it, or the sampling is aperiodic, so "
                     "the chain switches at the samples)")
        elif sw is not None and sw.kind != "markov":
            note += f" (the model's was {sw.kind})"
    text = f"Fitted by switchest fit ({', '.join(estimate)}) to {data.name}."
    description = f"{spec.description.rstrip().rstrip('.')}. {text}" if spec.description else text
    return dataclasses.replace(spec, system=result.system, switching=switching,
                               description=description), note
