"""Shankar et al. Algorithm 1 (IMM-EV1 with gridded switching times) on the vehicle maneuver.
==========================================================================================

The setting of Shankar, Yang & Hespanha §V.B (Figs 3-4): the two-dimensional
vehicle (:func:`switchest.models.vehicle_2d`, positions measured every
T = 0.5 s with R = 0.05 I) starts at rest at the origin in mode 1, switches to
mode 2 at 1.65 s, to mode 3 at 2.75 s and back to mode 1 at 3.9 s (0, 1, 2, 0 in
code), with ``u = 1``; 500 Monte-Carlo trials; g = 1, 2, 5, 10 grid points.

For each g the script runs :class:`switchest.estimators.IMMEV1Filter` as
printed (no transition prior) and in variants: the paper's literal likelihood
``N(y; C x-, R)``, the printed predecessor rule ``max_j b_ij``, a larger
covariance inflation epsilon, the switching time integrated out over the grid
instead of maximized, a sticky transition prior, and the last two together.
Beside them: the clairvoyant Kalman filter (true switching instants), the
switching-time Kalman filter with the true modes at the samples (§III) and the
IMM filter.

Columns: RMSE per state over trials and samples; mode accuracy of the decision
at sample k, of the one-sample-delayed decision (the predecessor that the best
destination at k+1 chose: the mode at k on the best path through k+1) and of
the whole best path traced back from the last sample; the mean absolute error
of the estimated switching instants where the truth and the estimate both have
a switch in an interval, the fraction of true switches with an estimated switch
in their interval, and the estimated switches per trial where there is none.

A second table asks what one measurement says about a switching instant: for
each true switch, starting from the clairvoyant filter's posterior (exact past,
modes known), the log-likelihood ``J_k(tau)`` of the next sample over tau.

The paper states neither process noise nor prior; here: the model's
process-noise intensity ``1e-3 I``, the prior ``N(0, 0.1 I)`` for every filter,
and the sticky prior ``P(stay) = 0.85`` (3 switches in 20 intervals).

Run ``python examples/shankar_imm_ev1.py`` (under a minute at the paper's size).
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

from switchest.discretize import pairwise_grid, switch_grid
from switchest.estimators import (
    IMMEV1Filter,
    IMMFilter,
    ModeKalmanFilter,
    SwitchTimeKalmanFilter,
    kf_predict,
    switch_time_loglik,
)
from switchest.metrics import mode_accuracy, rmse, switch_time_error
from switchest.models import vehicle_2d, vehicle_maneuver
from switchest.simulate import Trajectory, simulate

TRIALS = 500  # Fig. 4: "500 MC trials"
DURATION = 10.0  # §V.B: "a single trajectory over 10 seconds"
GRIDS = (1, 2, 5, 10)  # Figs 3-4
SEED = 2019

X0 = np.zeros(4)  # true initial state and prior mean
P0 = 0.1 * np.eye(4)
STAY = 0.85  # sticky prior: 3 switches in the 20 intervals of the maneuver
STICKY = np.full((3, 3), (1 - STAY) / 2) + (STAY - (1 - STAY) / 2) * np.eye(3)
INFLATION = 1e-2  # the "larger epsilon" variant; Algorithm 1 asks for a small one
FINE_GRID = 200  # grid for the one-measurement likelihood profile

VARIANTS: dict[str, dict] = {
    "IMM-EV1 (Alg. 1)": {},
    "  printed J = N(y; Cx-, R)": {"likelihood": "printed"},
    "  predecessor = argmax_j b_ji": {"predecessor": "likelihood"},
    f"  epsilon = {INFLATION:g}": {"epsilon": INFLATION},
    "  tau marginalized": {"switch_time": "marginal"},
    f"  sticky prior ({STAY:g})": {"transition": STICKY},
    "  sticky + tau marginalized": {"transition": STICKY, "switch_time": "marginal"},
}


@dataclass(frozen=True)
class Row:
    """One filter on the common data (accuracies and switch scores NaN where not defined)."""

    filter: str
    g: int | None
    rmse: np.ndarray  # (4,): x_1, dx_1/dt, x_2, dx_2/dt
    accuracy: float
    accuracy_delayed: float
    accuracy_path: float
    switch_error: float  # seconds
    switch_hits: float
    false_switches: float  # per trial
    seconds: float


@dataclass(frozen=True)
class Decoded:
    """What a filter says: estimate of the state, modes and switching instants ``(N, K)``."""

    x: np.ndarray
    mode: np.ndarray | None = None
    delayed: np.ndarray | None = None
    path: np.ndarray | None = None
    switch_time: np.ndarray | None = None


# %% Data: the maneuver of §V.B, 500 noise realizations
def maneuver_data(*, trials: int, duration: float, seed: int) -> Trajectory:
    """Simulate ``trials`` runs of the maneuver over ``duration`` seconds."""
    man = vehicle_maneuver(t_end=duration)
    return simulate(vehicle_2d(), man.signal, man.t, X0, u=man.u, trials=trials, rng=seed)


# %% Algorithm 1 step by step, to read the delayed decision off the filter state
def run_traced(filt: IMMEV1Filter, traj: Trajectory) -> Decoded:
    """Drive ``filt.init``/``filt.step`` over the data and decode its state at every sample.

    ``mode[k]`` is the destination of largest weight after sample k (what
    ``filt.run`` reports); ``delayed[k]`` the predecessor chosen at k+1 by the
    destination of largest weight there (``mode`` at the last sample);
    ``path`` the best path traced back from the last sample through the
    predecessors.
    """
    y, u, t = traj.y, traj.u, traj.t
    N, K, _ = y.shape
    state = filt.init((N,))
    trace = []
    for k in range(K):
        dt = None if k == 0 else t[k] - t[k - 1]
        state = filt.step(state, y[:, k], u[:, max(k - 1, 0)], dt=dt)  # u held on [t_k-1, t_k)
        trace.append((state.log_weight, state.predecessor, state.x, state.switch_offset))
    log_w, pred, x, offset = (np.stack(a, axis=1) for a in zip(*trace))
    mode = np.argmax(log_w, axis=-1)
    delayed = mode.copy()
    delayed[:, :-1] = _at(pred[:, 1:], mode[:, 1:])
    path = mode.copy()
    for k in range(K - 1, 0, -1):
        path[:, k - 1] = pred[np.arange(N), k, path[:, k]]
    start = np.concatenate([[np.nan], t[:-1]])
    return Decoded(x=_at(x, mode), mode=mode, delayed=delayed, path=path,
                   switch_time=_at(offset, mode) + start)


def _at(a: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``a[n, k, index[n, k], ...]`` for ``a (N, K, L, ...)`` and ``index (N, K)``."""
    index = index.reshape(*index.shape, 1, *([1] * (a.ndim - 3)))
    return np.take_along_axis(a, index, axis=2)[:, :, 0]


def score(name: str, g: int | None, run: Callable[[], Decoded], traj: Trajectory) -> Row:
    """Run one filter and summarize it as a :class:`Row`."""
    begin = time.perf_counter()
    dec = run()
    seconds = time.perf_counter() - begin
    nan = float("nan")

    def accuracy(modes):
        return nan if modes is None else mode_accuracy(modes, traj.mode)

    error, hits, false = nan, nan, nan
    if dec.switch_time is not None:
        true = traj.switch_times()
        errors = switch_time_error(dec.switch_time, true)
        error = float(errors.mean()) if errors.size else nan
        hits = errors.size / np.isfinite(true).sum()
        false = np.sum(np.isfinite(dec.switch_time) & np.isnan(true)) / traj.n_trials
    return Row(name, g, rmse(dec.x, traj.x).overall, accuracy(dec.mode), accuracy(dec.delayed),
               accuracy(dec.path), error, hits, float(false), seconds)


def main(*, trials: int = TRIALS, duration: float = DURATION, grids: Sequence[int] = GRIDS,
         seed: int = SEED, console: Console | None = None) -> tuple[list[Row], list[dict]]:
    """Run every filter on the maneuver; print both tables and return their rows."""
    console = console or Console(width=170)
    with threadpool_limits(1):  # tiny matrices: threaded BLAS only adds contention
        traj = maneuver_data(trials=trials, duration=duration, seed=seed)
        system, y, u, t = vehicle_2d(), traj.y, traj.u, traj.t

        def clairvoyant():
            est = ModeKalmanFilter(system, X0, P0).run(y, u, t, modes=traj.mode,
                                                       segments=traj.segments())
            return Decoded(x=est.x)

        def imm():
            return _decoded(IMMFilter(system, STICKY, X0, P0).run(y, u, t))

        def known_modes(g):
            return _decoded(SwitchTimeKalmanFilter(system, X0, P0, grid=g).run(
                y, u, t, modes=traj.mode))

        def imm_ev1(g, options):
            return run_traced(IMMEV1Filter(system, x0=X0, P0=P0, grid=g, **options), traj)

        jobs = [("clairvoyant (true switch times)", None, clairvoyant),
                (f"IMM (P(stay) = {STAY:g})", None, imm)]
        jobs += [("switch-time KF (modes known)", g, partial(known_modes, g)) for g in grids]
        for name, options in VARIANTS.items():
            jobs += [(name, g, partial(imm_ev1, g, options)) for g in grids]
        rows = [score(name, g, run, traj) for name, g, run in jobs]
        info = switch_information(traj, grids)
    modes, counts = np.unique(traj.mode, return_counts=True)
    table = render(rows, trials=trials, duration=duration)
    table.caption = (f"A constant guess of the most frequent mode ({modes[np.argmax(counts)] + 1} "
                     f"in the paper's numbering) scores mode accuracy "
                     f"{counts.max() / traj.mode.size:.3f}.")
    console.print(table)
    console.print(render_information(info, grids))
    return rows, info


def _decoded(est) -> Decoded:
    return Decoded(x=est.x, mode=est.mode, switch_time=est.switch_time)


# %% What one measurement says about a switching instant
def switch_information(traj: Trajectory, grids: Sequence[int]) -> list[dict]:
    """Likelihood of the sample after each true switch as a function of the switching instant.

    From the clairvoyant filter's posterior at ``t_{k-1}`` (exact past) and with
    the true modes, ``J_k(tau)`` (the innovation likelihood of
    :func:`switchest.estimators.switch_time_loglik`) is evaluated on a fine
    grid and on each grid of ``grids``. Per true switching interval, over
    trials: the median spread ``max - min`` of ``log J``, the posterior standard
    deviation of tau under a uniform prior relative to the prior's ``T/sqrt(12)``,
    and the mean ``|tau_hat - tau|`` of the fine-grid maximum, of the interval's
    midpoint and of each grid's maximum (eq. (23)).
    """
    system, t = vehicle_2d(), traj.t
    clair = ModeKalmanFilter(system, X0, P0).run(traj.y, traj.u, t, modes=traj.mode,
                                                 segments=traj.segments())
    true = traj.switch_times()
    out = []
    for k in np.flatnonzero(np.any(np.isfinite(true), axis=0)):
        n = np.flatnonzero(np.isfinite(true[:, k]))
        T, tau = t[k] - t[k - 1], true[n, k] - t[k - 1]
        fine = _loglik_over_tau(system, clair, traj, n, k, FINE_GRID)
        taus = switch_grid(T, FINE_GRID)
        w = np.exp(fine - fine.max(axis=1, keepdims=True))
        w /= w.sum(axis=1, keepdims=True)
        post_sd = np.sqrt(w @ taus**2 - (w @ taus) ** 2)
        row = {
            "switch": float(np.mean(true[n, k])),
            "offset": float(np.mean(tau)),
            "T": T,
            "loglik_spread": float(np.median(fine.max(axis=1) - fine.min(axis=1))),
            "posterior_sd_ratio": float(np.mean(post_sd) / (T / np.sqrt(12))),
            "ml_error": float(np.mean(np.abs(taus[np.argmax(fine, axis=1)] - tau))),
            "midpoint_error": float(np.mean(np.abs(T / 2 - tau))),
        }
        for g in grids:
            best = np.argmax(_loglik_over_tau(system, clair, traj, n, k, g), axis=1)
            row[f"grid_error_{g}"] = float(np.mean(np.abs(switch_grid(T, g)[best] - tau)))
        out.append(row)
    return out


def _loglik_over_tau(system, clair, traj: Trajectory, n: np.ndarray, k: int, g: int) -> np.ndarray:
    """``log J_k(tau_i)`` on the g-point grid of eq. (23) for trials ``n``: ``(n.size, g)``."""
    prev, mode = traj.mode[n, k - 1], traj.mode[n, k]
    tr = pairwise_grid(system, traj.t[k] - traj.t[k - 1], g)
    x, P = kf_predict(clair.x[n, k - 1, None], clair.P[n, k - 1, None], tr.F[prev, mode],
                      tr.G[prev, mode], traj.u[n, k - 1, None], tr.Qd[prev, mode])
    return switch_time_loglik(x, P, traj.y[n, k, None], system.C[mode, None],
                              system.R[mode, None])


# %% Tables
def _num(v: float, fmt: str) -> str:
    return "-" if v is None or not np.isfinite(v) else format(v, fmt)


def render(rows: Sequence[Row], *, trials: int, duration: float) -> Table:
    """One line per filter and grid size."""
    table = Table(title=f"Shankar et al. §V.B vehicle maneuver: {trials} trials x {duration:g} s "
                        f"(T = 0.5 s, R = 0.05 I)")
    heads = ("filter", "g", "x1", "v1", "x2", "v2", "acc k", "acc k|k+1", "acc path",
             "|t_hat - t| (s)", "hits", "false/trial", "run (s)")
    for head in heads:
        table.add_column(head, justify="left" if head == "filter" else "right")
    for row, nxt in zip(rows, [*rows[1:], None]):
        accuracies = (row.accuracy, row.accuracy_delayed, row.accuracy_path, row.switch_error)
        table.add_row(
            row.filter, "-" if row.g is None else str(row.g), *(f"{v:.3f}" for v in row.rmse),
            *(_num(v, ".3f") for v in accuracies),
            _num(row.switch_hits, ".2f"), _num(row.false_switches, ".2f"), f"{row.seconds:.2f}",
            end_section=nxt is not None and nxt.filter != row.filter,
        )
    return table


def render_information(info: Sequence[dict], grids: Sequence[int]) -> Table:
    """The one-measurement likelihood of each true switching instant."""
    table = Table(title="What one measurement says about a switching instant "
                        "(exact past, modes known)")
    heads = ["switch (s)", "offset (s)", "log J spread (nats)", "post. sd / prior sd",
             "|tau_ML - tau| (s)", "|T/2 - tau| (s)", *(f"g={g} |err| (s)" for g in grids)]
    for head in heads:
        table.add_column(head, justify="right")
    for r in info:
        cells = (r["switch"], r["offset"], r["loglik_spread"], r["posterior_sd_ratio"],
                 r["ml_error"], r["midpoint_error"], *(r[f"grid_error_{g}"] for g in grids))
        table.add_row(*(f"{v:.2f}" if name in ("log J spread (nats)", "post. sd / prior sd")
                        else f"{v:.3f}" for name, v in zip(heads, cells)))
    return table


if __name__ == "__main__":
    main()
