"""Trial blocks, the variants a task runs on its block, and additive error statistics of an
estimate, so that trial blocks combine by summation."""

from __future__ import annotations

import numpy as np

from ..metrics import switch_time_error

__all__ = ["blocks", "split_variants", "score", "combine"]


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

    ``sse``/``scale`` per state component, ``sse_per_step (K, n)``, ``mode_hits``
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


def combine(results: list[dict]) -> dict:
    """Sum the statistics of several blocks (lists element-wise)."""
    total: dict = {}
    for r in results:
        for k, v in r.items():
            if isinstance(v, list):
                total[k] = total[k] + np.asarray(v, float) if k in total else np.asarray(v, float)
            elif isinstance(v, (int, float)):
                total[k] = total.get(k, 0) + v
    return total
