"""Shankar et al. Table I: Kalman filtering with gridded switching times on the boost converter.
=============================================================================================

The setting of Shankar, Yang & Hespanha §III and §V.A: the boost converter
(:func:`switchest.models.boost_converter`, output ``v_0`` sampled every
T = 0.5 ms with R = 5 V^2) switches asynchronously, every 1.2 ms until 0.02 s and
then after gaps drawn uniformly in [0.9, 1.2] ms. The mode at each sample is
known; the instant of each switch inside its interval is not, and is estimated
by the gridded maximum-likelihood rule of eq. (23) with g = 1..5 grid points
(:class:`switchest.estimators.SwitchTimeKalmanFilter`).

Beside the paper's printed RMSE the script reports, on the same data: the grid
filter polished by a bounded search on the exact likelihood (``refine=True``) and
with the switching instant integrated out over the grid (``switch_time="marginal"``),
the clairvoyant filter that knows the true switching instants (the bound), the
IMM filter (switches at the samples, modes unknown) and the IMM-EV1 filter of
Algorithm 1 (modes and switching instants unknown), as printed and with the
switching instant integrated out over the grid instead of maximized, with the
mean absolute switching-time error and the run time of each.

The paper does not state the process noise, the prior or the transient it
discards; this script uses the recipe of the ``shankar-table1`` reproduction
(:class:`switchest.models.shankar.BoostTable1`): process-noise intensity ``I``,
initial states drawn from the prior ``N([0 A, 100 V], diag(25, 25))`` that every
filter starts from, the IMM's switch probability 0.48 per sample, and the RMSE
taken over the samples after the first 10 ms.

Run ``python examples/shankar_table1.py``; the paper's size (100 trials x 10 s,
two million samples) takes most of an hour on two shared cores, nearly all of
it in the refined search. ``python examples/shankar_table1.py TRIALS DURATION``
runs a smaller size (the documentation's gallery: 10 trials x 1 s, seconds).
"""

# %% Setup
from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from rich.console import Console
from rich.table import Table
from threadpoolctl import threadpool_limits

from switchest.experiments.shankar import (
    TABLE1_PAPER,  # Table I as printed: g, i_L (A), v_0 (V)
    table1_estimate,
)
from switchest.metrics import mode_accuracy, rmse, switch_time_error
from switchest.models.shankar import BOOST_SAMPLE_PERIOD, BoostTable1
from switchest.simulate import Trajectory

TRIALS = 100  # Table I: "100 trials"
DURATION = 10.0  # §V.A: "We simulated 10 seconds of operation"
GRIDS = (1, 2, 3, 4, 5)  # Table I: T/g = 0.5, 0.25, 0.167, 0.125, 0.1 ms
SEED = 2019
SETTING = BoostTable1()  # model, prior, switching, IMM transition and transient of Table I


@dataclass(frozen=True)
class Row:
    """One filter on the common data.

    ``rmse`` is ``(i_L, v_0)`` over trials and samples after ``SETTING.transient``;
    ``switch_error`` the mean ``|t_hat - t|`` in seconds over intervals where both
    the truth and the filter have a switch (NaN if none); ``mode_accuracy`` the
    fraction of samples whose estimated mode is the true one (NaN when the modes
    are given); ``paper`` the printed ``(i_L, v_0)`` of Table I for this ``g``.
    """

    filter: str
    g: int | None
    rmse: np.ndarray
    switch_error: float
    mode_accuracy: float
    seconds: float
    paper: tuple[str, str] | None = None


# %% Filters: time each run, score it against the truth
def score(name: str, method: str, g: int | None, traj: Trajectory, true_switch: np.ndarray) -> Row:
    """Run one filter of Table I's recipe (:func:`table1_estimate`) and score it against
    ``traj`` (``true_switch = traj.switch_times()``)."""
    start = time.perf_counter()
    est = table1_estimate(SETTING, method, traj, g=g)
    seconds = time.perf_counter() - start
    first = SETTING.transient
    errors = [] if est.switch_time is None else switch_time_error(est.switch_time, true_switch)
    paper = None
    if name == "switch-time KF" and g in TABLE1_PAPER["g"]:
        i = TABLE1_PAPER["g"].index(g)
        paper = (TABLE1_PAPER["i_L"][i], TABLE1_PAPER["v_0"][i])
    return Row(
        filter=name,
        g=g,
        rmse=rmse(est.x, traj.x, start=first).overall,
        switch_error=float(np.mean(errors)) if len(errors) else float("nan"),
        mode_accuracy=mode_accuracy(est.mode, traj.mode) if est.mode is not None else float("nan"),
        seconds=seconds,
        paper=paper,
    )


def main(*, trials: int = TRIALS, duration: float = DURATION, grids: Sequence[int] = GRIDS,
         seed: int = SEED, refine: bool = True, console: Console | None = None) -> list[Row]:
    """Reproduce Table I and its baselines; print the table and return its rows."""
    console = console or Console(width=150)
    with threadpool_limits(1):  # tiny matrices: threaded BLAS only adds contention
        traj = SETTING.simulate(duration, trials, seed)  # one random switching signal per trial
        true = traj.switch_times()
        jobs = [("clairvoyant", "clairvoyant", None)]
        grid_methods = [("switch-time KF", "grid")]
        grid_methods += [("switch-time KF, refined", "refine")] if refine else []
        grid_methods += [("switch-time KF, tau marginalized", "marginal")]
        jobs += [(name, method, g) for name, method in grid_methods for g in grids]
        jobs.append(("IMM", "imm", None))
        for name, method in (("IMM-EV1 (Alg. 1)", "imm-ev1"),
                             ("IMM-EV1, tau marginalized", "imm-ev1-marginal")):
            jobs += [(name, method, g) for g in grids]
        rows = [score(name, method, g, traj, true) for name, method, g in jobs]
    console.print(render(rows, trials=trials, duration=duration))
    return rows


# %% Table
def render(rows: Sequence[Row], *, trials: int, duration: float) -> Table:
    """Paper beside ours, one line per filter and grid size."""
    table = Table(title=f"Shankar et al. Table I, boost converter: {trials} trials x "
                        f"{duration:g} s (T = {BOOST_SAMPLE_PERIOD * 1e3:g} ms, R = 5 V^2)")
    for head in ("filter", "g", "T/g (ms)", "paper i_L (A)", "paper v_0 (V)", "i_L (A)",
                 "v_0 (V)", "|t_hat - t| (ms)", "mode acc.", "run (s)"):
        table.add_column(head, justify="left" if head == "filter" else "right")

    def number(v, fmt):
        return "-" if v is None or not np.isfinite(v) else format(v, fmt)

    for row, nxt in zip(rows, [*rows[1:], None]):
        table.add_row(
            row.filter,
            "-" if row.g is None else str(row.g),
            "-" if row.g is None else f"{BOOST_SAMPLE_PERIOD * 1e3 / row.g:.3g}",
            "-" if row.paper is None else row.paper[0],  # the paper's printed digits
            "-" if row.paper is None else row.paper[1],
            f"{row.rmse[0]:.3g}",
            f"{row.rmse[1]:.3g}",
            number(row.switch_error * 1e3, ".3f"),
            number(row.mode_accuracy, ".3f"),
            f"{row.seconds:.1f}",
            end_section=nxt is not None and nxt.filter != row.filter,
        )
    return table


if __name__ == "__main__":
    if len(sys.argv) > 2:  # a smaller size: TRIALS DURATION
        main(trials=int(sys.argv[1]), duration=float(sys.argv[2]))
    else:
        main()
