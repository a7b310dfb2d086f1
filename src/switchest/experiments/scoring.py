"""Trial blocks, the variants a task runs on its block, additive error statistics of an
estimate, and the one merge of the blocks' results that every experiment's summary uses."""

from __future__ import annotations

from collections.abc import Callable, Collection, Hashable, Iterable
from typing import NamedTuple

import numpy as np

from ..metrics import switch_time_error

__all__ = ["blocks", "mean_and_se", "merge_blocks", "merge_groups", "rms_and_se", "rmse_and_se",
           "score", "split_variants"]


def blocks(trials: int, block_size: int) -> list[tuple[int, int]]:
    """``(block index, trials in it)`` covering ``trials`` in blocks of ``block_size``; the last
    block holds the remainder when ``block_size`` does not divide ``trials``."""
    full, rest = divmod(trials, block_size)
    return list(enumerate([block_size] * full + ([rest] if rest else [])))


def split_variants(results: list[tuple[dict, dict]]) -> list[tuple[dict, dict]]:
    """One ``(config, result)`` pair per variant of the tasks that ran several on one block.

    A task that simulates its trial block once and runs several variants on it
    (methods, gains, noise levels) lists their settings under ``"variants"`` in its
    configuration and returns ``{"variants": [...]}``, one result per variant in
    that order. Each of its pairs here is the task's configuration without
    ``"variants"``, updated with the variant's settings, and the variant's result;
    tasks without variants pass through unchanged.
    """
    out = []
    for cfg, res in results:
        if "variants" not in cfg:
            out.append((cfg, res))
            continue
        common = {k: v for k, v in cfg.items() if k != "variants"}
        out += [({**common, **variant}, r)
                for variant, r in zip(cfg["variants"], res["variants"], strict=True)]
    return out


def score(est, traj, start: int, defined: np.ndarray | None = None) -> dict:
    """Sums over trials (and over samples from ``start`` on) of squared errors and hits.

    ``sse``/``scale`` per state component, ``sse_per_step (K, n)``, the sum over trials of
    each trial's mean squared error and of its square (``trial_mse``, ``trial_mse_sq``, per
    component: :func:`rmse_and_se`), ``mode_hits``
    where the estimate has modes, and switching-time errors (absolute and in units
    of the sampling interval) where it has switching times. ``defined (trials, K)``
    marks the samples where a method gives an estimate at all (e.g. a detector
    between its windows): the sums and ``count`` then run over those only, and
    ``samples`` counts all of them.
    """
    mask = (np.ones(traj.x.shape[:2], dtype=bool) if defined is None
            else np.asarray(defined, dtype=bool))
    err = np.where(mask[..., None], est.x - traj.x, 0.0)
    kept = mask[:, start:, None]
    out = {"sse": np.sum(err[:, start:] ** 2, axis=(0, 1)).tolist(), "count": int(kept.sum()),
           "scale": np.sum(np.where(kept, traj.x[:, start:], 0.0) ** 2, axis=(0, 1)).tolist(),
           "sse_per_step": np.sum(err**2, axis=0).tolist(), "trials": traj.n_trials}
    per_trial = np.sum(err[:, start:] ** 2, axis=1) / np.maximum(kept.sum(axis=1), 1)
    out["trial_mse"] = np.sum(per_trial, axis=0).tolist()  # for the standard error of the RMSE
    out["trial_mse_sq"] = np.sum(per_trial**2, axis=0).tolist()
    if defined is not None:
        out["samples"] = int(kept.size)
    if est.mode is not None:
        out["mode_hits"] = int(np.sum(kept[..., 0] & (est.mode[:, start:] == traj.mode[:, start:])))
    if est.switch_time is not None:
        truth = traj.switch_times()
        gap = switch_time_error(est.switch_time, truth)
        period = np.r_[np.nan, np.diff(traj.t)]  # the length of the interval each instant falls in
        out["switch_abs_err"] = float(gap.sum())
        relative = switch_time_error(est.switch_time / period, truth / period)
        out["switch_rel_err"] = float(relative.sum())
        out["switch_pairs"] = int(gap.size)
    return out


def mean_and_se(total, total_sq, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Monte Carlo mean of ``n`` trials and its standard error, from the merged sum ``total``
    and sum of squares ``total_sq`` (the unbiased sample variance over ``n``)."""
    mean = np.asarray(total, float) / n
    var = np.maximum(np.asarray(total_sq, float) / n - mean**2, 0.0) * n / (n - 1)
    return mean, np.sqrt(var / n)


def rms_and_se(total, total_sq, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Root of a Monte Carlo mean square (merged sum ``total`` and sum of squares
    ``total_sq`` of ``n`` trials' squared errors) and its standard error by the delta method,
    ``SE(sqrt(m)) = SE(m) / (2 sqrt(m))``."""
    mean, se = mean_and_se(total, total_sq, n)
    root = np.sqrt(mean)
    with np.errstate(divide="ignore", invalid="ignore"):
        return root, np.where(root > 0, se / (2 * root), 0.0)


def rmse_and_se(total: dict) -> tuple[np.ndarray, np.ndarray]:
    """RMSE per state component of merged :func:`score` sums, and its standard error.

    The RMSE pools every scored sample, ``sqrt(sse / count)``. Its standard error comes from
    the spread of the trials' own mean squared errors ``m_i`` (independent trials):
    ``SE(mean m) = sd(m_i) / sqrt(N)``, carried to the square root by the delta method,
    ``SE(RMSE) = SE(mean m) / (2 RMSE)``. NaN where fewer than two trials were scored.
    """
    rmse = np.sqrt(np.asarray(total["sse"], float) / total["count"])
    n = total["trials"]
    if n < 2 or "trial_mse" not in total:
        return rmse, np.full_like(rmse, np.nan)
    return rmse, rms_and_se(total["trial_mse"], total["trial_mse_sq"], n)[1]


def merge_blocks(results: Iterable[dict], *, first: Collection[str] = (),
                 per_block: Collection[str] = (), concatenate: Collection[str] = (),
                 minimum: Collection[str] = (), maximum: Collection[str] = ()) -> dict:
    """Merge the results of the trial blocks of one configuration, in the order given.

    By default a number adds, a list adds element-wise (as a float array), a dict merges
    by the same rules, and anything else (text, ``None``) keeps its first value. A key
    listed in ``first`` keeps its first block's value (a certificate, an example trial),
    in ``per_block`` the list of its blocks' values as arrays (series on each block's own
    time grid), in ``concatenate`` the concatenated lists (one entry per event), in
    ``minimum`` / ``maximum`` the extreme over the blocks. A key missing from some blocks
    merges over the blocks that have it.
    """
    rules = _Rules(first, per_block, concatenate, minimum, maximum)
    total: dict = {}
    for result in results:
        _merge_into(total, result, rules)
    return total


def merge_groups(results: Iterable[tuple[dict, dict]], key: Callable[[dict], Hashable],
                 **rules: Collection[str]) -> dict[Hashable, tuple[dict, dict]]:
    """``key(config)`` -> (its first configuration, :func:`merge_blocks` of its results).

    Tasks that ran several variants on one block are split first
    (:func:`split_variants`); groups keep the order of ``results``.
    """
    groups: dict[Hashable, tuple[dict, list]] = {}
    for cfg, res in split_variants(list(results)):
        groups.setdefault(key(cfg), (cfg, []))[1].append(res)
    return {k: (cfg, merge_blocks(v, **rules)) for k, (cfg, v) in groups.items()}


class _Rules(NamedTuple):
    first: Collection[str]
    per_block: Collection[str]
    concatenate: Collection[str]
    minimum: Collection[str]
    maximum: Collection[str]


def _merge_into(total: dict, result: dict, rules: _Rules) -> None:
    """Add one block's ``result`` to ``total`` (the blocks merged so far), in place."""
    for key, value in result.items():
        if key in rules.per_block:
            total.setdefault(key, []).append(np.asarray(value))
        elif key not in total:
            total[key] = _first_value(key, value, rules)
        elif key in rules.concatenate:
            total[key] = total[key] + list(value)
        elif key in rules.minimum:
            total[key] = min(total[key], value)
        elif key in rules.maximum:
            total[key] = max(total[key], value)
        elif key in rules.first:
            continue
        elif isinstance(value, dict):
            _merge_into(total[key], value, rules)
        elif isinstance(value, list):
            total[key] = total[key] + np.asarray(value, float)
        elif isinstance(value, (int, float)):
            total[key] = total[key] + value


def _first_value(key: str, value, rules: _Rules):
    """The merged value of a key after the first block that has it."""
    if key in rules.concatenate:
        return list(value)
    if isinstance(value, dict) and key not in rules.first:
        merged: dict = {}
        _merge_into(merged, value, rules)
        return merged
    if isinstance(value, list) and key not in rules.first:
        return np.asarray(value, float)
    return value
