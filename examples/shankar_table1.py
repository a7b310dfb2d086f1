"""Shankar et al. Table I: Kalman filtering with gridded switching times on the boost converter.

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
discards; here: process-noise intensity ``I`` (the model's default), the true
initial state ``[0 A, 100 V]`` with prior covariance ``diag(100, 100)``, and the
RMSE taken over the samples after the first 5 ms.

Run ``python examples/shankar_table1.py``; the paper's size (100 trials x 10 s,
two million samples) takes most of an hour on two shared cores, nearly all of
it in the refined search.
"""

# %% Setup
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np
from rich.console import Console
from rich.table import Table
from threadpoolctl import threadpool_limits

from switchest.estimators import (
    Estimate,
    IMMEV1Filter,
    IMMFilter,
    ModeKalmanFilter,
    SwitchTimeKalmanFilter,
)
from switchest.experiments.shankar import TABLE1_PAPER  # Table I as printed: g, i_L (A), v_0 (V)
from switchest.metrics import mode_accuracy, rmse, switch_time_error
from switchest.models import (
    BOOST_INPUT_VOLTAGE,
    BOOST_SAMPLE_PERIOD,
    boost_converter,
    boost_switching,
)
from switchest.signals import periodic
from switchest.simulate import Trajectory, simulate

TRIALS = 100  # Table I: "100 trials"
DURATION = 10.0  # §V.A: "We simulated 10 seconds of operation"
GRIDS = (1, 2, 3, 4, 5)  # Table I: T/g = 0.5, 0.25, 0.167, 0.125, 0.1 ms
SEED = 2019

X0 = np.array([0.0, 100.0])  # true initial state and prior mean: i_L = 0 A, v_0 = 100 V
P0 = np.diag([100.0, 100.0])
DISCARD = 5e-3  # seconds of initial transient left out of the RMSE

# The IMM assumes switches at the samples with probability T / (mean gap) per interval.
MEAN_GAP = (0.9e-3 + 1.2e-3) / 2
P_SWITCH = BOOST_SAMPLE_PERIOD / MEAN_GAP
IMM_TRANSITION = np.array([[1 - P_SWITCH, P_SWITCH], [P_SWITCH, 1 - P_SWITCH]])


@dataclass(frozen=True)
class Row:
    """One filter on the common data.

    ``rmse`` is ``(i_L, v_0)`` over trials and samples after :data:`DISCARD`;
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
    paper: tuple[float, float] | None = None


# %% Data: the switching scenario of §V.A, one random signal per trial
def boost_data(*, trials: int, duration: float, seed: int) -> Trajectory:
    """Simulate ``trials`` runs of the boost converter over ``duration`` seconds."""
    system = boost_converter()
    t = periodic(BOOST_SAMPLE_PERIOD, duration)
    return simulate(system, lambda rng: boost_switching(rng, t_end=duration), t, X0,
                    u=np.array([BOOST_INPUT_VOLTAGE]), trials=trials, rng=seed)


# %% Filters: time each run, score it against the truth
def score(name: str, g: int | None, run: Callable[[], Estimate], traj: Trajectory,
          true_switch: np.ndarray) -> Row:
    """Run one filter and score it against ``traj`` (``true_switch = traj.switch_times()``)."""
    start = time.perf_counter()
    est = run()
    seconds = time.perf_counter() - start
    first = round(DISCARD / BOOST_SAMPLE_PERIOD)
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
        traj = boost_data(trials=trials, duration=duration, seed=seed)
        system, t, y, u = boost_converter(), traj.t, traj.y, np.array([BOOST_INPUT_VOLTAGE])
        true = traj.switch_times()

        def clairvoyant():
            return ModeKalmanFilter(system, X0, P0).run(y, u, t, modes=traj.mode,
                                                        segments=traj.segments())

        def grid_filter(g, polish, how="max"):
            return SwitchTimeKalmanFilter(system, X0, P0, grid=g, refine=polish, switch_time=how).run(
                y, u, t, modes=traj.mode)

        def imm():
            return IMMFilter(system, IMM_TRANSITION, X0, P0).run(y, u, t)

        def imm_ev1(g, how):
            return IMMEV1Filter(system, x0=X0, P0=P0, grid=g, switch_time=how).run(y, u, t)

        jobs = [("clairvoyant", None, clairvoyant)]
        for polish in (False, True) if refine else (False,):
            name = "switch-time KF, refined" if polish else "switch-time KF"
            jobs += [(name, g, partial(grid_filter, g, polish)) for g in grids]
        jobs += [("switch-time KF, tau marginalized", g, partial(grid_filter, g, False, "marginal")) for g in grids]
        jobs.append(("IMM", None, imm))
        for name, how in (("IMM-EV1 (Alg. 1)", "max"), ("IMM-EV1, tau marginalized", "marginal")):
            jobs += [(name, g, partial(imm_ev1, g, how)) for g in grids]
        rows = [score(name, g, run, traj, true) for name, g, run in jobs]
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
            number(row.paper and row.paper[0], "#.3g"),  # the paper's printed digits
            number(row.paper and row.paper[1], "#.3g"),
            f"{row.rmse[0]:.3g}",
            f"{row.rmse[1]:.3g}",
            number(row.switch_error * 1e3, ".3f"),
            number(row.mode_accuracy, ".3f"),
            f"{row.seconds:.1f}",
            end_section=nxt is not None and nxt.filter != row.filter,
        )
    return table


if __name__ == "__main__":
    main()
