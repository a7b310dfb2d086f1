"""IMMFilter (batched over trials) against FilterPy's IMMEstimator (looped over trials).

Setting (issue 3, item 7): the vehicle of Shankar et al. §V.B
(:func:`switchest.models.vehicle_2d`: n = 4, m = 2, L = 3 modes differing by their
input, Q = 1e-3 I intensity, R = 0.05 I), T = 0.5 s, u = 1, modes switching at the
samples as a Markov chain with 0.9 on the diagonal and 0.05 off it; 500 trials x 200
samples. Both filters run the same discrete model: FilterPy's per-mode
``KalmanFilter`` gets ``F``, ``B = G``, ``Q = Qd`` of
:func:`switchest.discretize.mode_steps` and ``H = C``, ``R``.

Order of operations, lined up exactly:

* sample 0: update only (switchest's ``run`` does no prediction at the first
  sample). FilterPy's first ``update`` weights the likelihoods by
  ``cbar = mu0 @ M``, computed in its constructor; we set ``cbar = mu0`` first, so
  both start from the same prior mode probabilities (for the uniform ``mu0`` and
  this doubly-stochastic ``M`` the two are equal anyway).
* sample k >= 1: FilterPy's ``IMMEstimator.predict(u)`` mixes the mode-matched
  posteriors and then predicts each filter; ``update(z)`` updates them and the mode
  probabilities. That is switchest's ``step``: mix, predict over T with the input
  held since the previous sample (``u[k-1]``), update.

How it is timed (issue 13): the contenders run interleaved, round by round —
IMMFilter on all 500 trials, FilterPy on the first 20 trials, and for scale a bare
numpy and a FilterPy single-mode Kalman loop (1 trial x 2 000 steps) — by CPU time
(``time.process_time``) with BLAS and switchest's engine at one thread, each warmed up first
(:func:`harness.compare_interleaved`). FilterPy loops over trials, so its cost per
trial-step does not depend on how many it filters; a subset keeps each round near
two seconds. Reported per trial-step: the median and the min over the rounds, the
ratios of medians and of mins to IMMFilter (issue 13's target: FilterPy / IMMFilter
at least 500) with the 1-minute load average; the largest differences of the
combined state, covariance and mode probabilities over the trials FilterPy
filtered; and a cProfile table of ``IMMFilter.run``.

Run: ``python benchmarks/bench_imm.py [--quick]`` (``--quick``: FilterPy on 5
trials per round, 3 rounds instead of 5).
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats

import numpy as np
from filterpy.kalman import IMMEstimator, KalmanFilter
from harness import (
    Contender,
    Section,
    compare_interleaved,
    comparison_header,
    comparison_rows,
    format_load,
    format_seconds,
    markdown_table,
    print_sections,
    single_threaded,
)

from switchest.discretize import mode_steps
from switchest.estimators import IMMFilter
from switchest.models import vehicle_2d
from switchest.signals import markov_at_samples
from switchest.simulate import simulate

T = 0.5
TRIALS = 500
STEPS = 200
FILTERPY_TRIALS = 20  # FilterPy filters this many trials per round (~2 s at 0.5 ms per step)
QUICK_FILTERPY_TRIALS = 5
ROUNDS = 5
QUICK_ROUNDS = 3
CONTEXT_STEPS = 2000
SEED = 20240603
TARGET_SPEEDUP = 500.0  # issue 13: IMMFilter.run at least 500x FilterPy per trial-step


def transition_matrix(L: int = 3, stay: float = 0.9) -> np.ndarray:
    """``stay`` on the diagonal, the rest spread evenly off it (rows sum to 1)."""
    off = (1.0 - stay) / (L - 1)
    return np.full((L, L), off) + (stay - off) * np.eye(L)


def vehicle_data(trials: int, steps: int, seed: int = SEED):
    """The system, transition, prior and a simulated batch ``Trajectory``."""
    system = vehicle_2d(measurement_variance=0.05, process_noise=1e-3)
    transition = transition_matrix()
    x0, P0 = np.zeros(4), np.eye(4)
    t = T * np.arange(steps)
    traj = simulate(
        system,
        lambda rng: markov_at_samples(transition, t, rng=rng),
        t,
        (x0, P0),  # the true initial state is drawn from the filters' prior
        np.ones(1),
        trials=trials,
        rng=seed,
    )
    return system, transition, x0, P0, traj


def filterpy_run(system, transition, x0, P0, y, u):
    """FilterPy's IMMEstimator over each trial in turn; returns ``x, P, mu`` like switchest's."""
    steps = mode_steps(system, T)
    L, n = system.n_modes, system.n_states
    N, K, m = y.shape
    xs, Ps, mus = np.empty((N, K, n)), np.empty((N, K, n, n)), np.empty((N, K, L))
    mu0 = np.full(L, 1.0 / L)
    for i in range(N):
        filters = []
        for j in range(L):
            kf = KalmanFilter(dim_x=n, dim_z=m, dim_u=system.n_inputs)
            kf.F, kf.B, kf.Q = steps.F[j].copy(), steps.G[j].copy(), steps.Qd[j].copy()
            kf.H, kf.R = system.C[j].copy(), system.R[j].copy()
            kf.x, kf.P = x0.copy(), P0.copy()
            filters.append(kf)
        imm = IMMEstimator(filters, mu0, transition)
        imm.cbar = imm.mu.copy()  # the first update uses the prior itself, as switchest does
        for k in range(K):
            if k:
                imm.predict(u[i, k - 1])  # mix, then predict with the input held since t_{k-1}
            imm.update(y[i, k])
            xs[i, k], Ps[i, k], mus[i, k] = imm.x, imm.P, imm.mu
    return xs, Ps, mus


def bare_kalman_steps(system, y, u):
    """A textbook single-trial Kalman filter (one mode) in plain numpy, for context."""
    steps = mode_steps(system, T)
    F, G, Qd, C, R = steps.F[1], steps.G[1], steps.Qd[1], system.C[1], system.R[1]
    x, P = np.zeros(4), np.eye(4)
    eye = np.eye(4)
    for k in range(y.shape[0]):
        x = F @ x + G @ u[k]
        P = F @ P @ F.T + Qd
        S = C @ P @ C.T + R
        K = np.linalg.solve(S, C @ P).T
        x = x + K @ (y[k] - C @ x)
        IKC = eye - K @ C
        P = IKC @ P @ IKC.T + K @ R @ K.T
    return x, P


def filterpy_kalman_steps(system, y, u):
    """FilterPy's single KalmanFilter (one mode), predict + update per sample, for context."""
    steps = mode_steps(system, T)
    kf = KalmanFilter(dim_x=4, dim_z=2, dim_u=1)
    kf.F, kf.B, kf.Q = steps.F[1].copy(), steps.G[1].copy(), steps.Qd[1].copy()
    kf.H, kf.R = system.C[1].copy(), system.R[1].copy()
    kf.x, kf.P = np.zeros(4), np.eye(4)
    for k in range(y.shape[0]):
        kf.predict(u[k])
        kf.update(y[k])
    return kf.x


def hot_spots(imm: IMMFilter, traj, steps: int = 10, top: int = 10) -> Section:
    """Where ``IMMFilter.run`` spends its time (cProfile, all trials, a few steps)."""
    profiler = cProfile.Profile()
    profiler.runcall(imm.run, traj.y[:, :steps], traj.u[:, :steps], traj.t[:steps])
    stats = pstats.Stats(profiler)
    total = stats.total_tt
    rows = []
    # by cumulative time
    entries = sorted(stats.stats.items(), key=lambda kv: kv[1][3], reverse=True)
    for (filename, line, func), (_, ncalls, tottime, cumtime, _) in entries:
        if filename == "~" or "cProfile" in filename:  # built-ins and the profiler itself
            continue
        where = filename.split("site-packages/")[-1].split("src/")[-1]
        rows.append((f"`{func}` ({where}:{line})", ncalls, format_seconds(tottime),
                     format_seconds(cumtime), f"{cumtime / total:.0%}"))
        if len(rows) == top:
            break
    table = markdown_table(["function", "calls", "own time", "cumulative", "share"], rows)
    return Section(
        (f"Where IMMFilter.run spends its time (cProfile, {traj.y.shape[0]} trials x "
         f"{steps} steps)"),
        table,
        (f"total profiled time {format_seconds(total)} (profiling overhead included).",),
    )


def _contenders(system, transition, x0, P0, y, u, t, fp_trials):
    """IMMFilter on all trials, FilterPy on ``fp_trials`` of them, and two one-mode Kalman
    loops for scale; each a :class:`harness.Contender` with its trial-steps as units."""
    trials, steps = y.shape[:2]
    imm = IMMFilter(system, transition, x0, P0, timing="interval")  # FilterPy's timing
    ctx_y = np.tile(y[0], (CONTEXT_STEPS // steps + 1, 1))[:CONTEXT_STEPS]
    ctx_u = np.ones((CONTEXT_STEPS, 1))
    fp_y, fp_u = y[:fp_trials], u[:fp_trials]
    return imm, [
        Contender("IMMFilter", lambda: imm.run(y, u, t), units=trials * steps),
        Contender("FilterPy IMM", lambda: filterpy_run(system, transition, x0, P0, fp_y, fp_u),
                  units=fp_trials * steps,
                  warmup=lambda: filterpy_run(system, transition, x0, P0, fp_y[:1, :5],
                                              fp_u[:1, :5])),
        Contender("numpy KF", lambda: bare_kalman_steps(system, ctx_y, ctx_u),
                  units=CONTEXT_STEPS),
        Contender("FilterPy KF", lambda: filterpy_kalman_steps(system, ctx_y, ctx_u),
                  units=CONTEXT_STEPS),
    ]


def run(*, quick: bool = False, trials: int = TRIALS, steps: int = STEPS) -> list[Section]:
    """Time the IMMs interleaved on the same data and check that they agree."""
    system, transition, x0, P0, traj = vehicle_data(trials, steps)
    y, u, t = traj.y, traj.u, traj.t
    fp_trials = min(QUICK_FILTERPY_TRIALS if quick else FILTERPY_TRIALS, trials)
    rounds = QUICK_ROUNDS if quick else ROUNDS
    imm, contenders = _contenders(system, transition, x0, P0, y, u, t, fp_trials)
    cmp = compare_interleaved(contenders, rounds=rounds)
    est = cmp.results["IMMFilter"]
    fx, fP, fmu = cmp.results["FilterPy IMM"]

    speed_med, speed_min = cmp.ratio("FilterPy IMM", "IMMFilter")
    dx = np.abs(est.x[:fp_trials] - fx).max()
    dP = np.abs(est.P[:fp_trials] - fP).max()
    dmu = np.abs(est.mode_prob[:fp_trials] - fmu).max()
    identical = max(dx, dP, dmu) <= 1e-9

    labels = {
        "IMMFilter": f"switchest `IMMFilter.run`, all {trials} trials at once",
        "FilterPy IMM": f"FilterPy `IMMEstimator`, loop over the first {fp_trials} trials",
        "numpy KF": f"bare numpy Kalman step (1 trial x {CONTEXT_STEPS}, 1 mode)",
        "FilterPy KF": f"FilterPy `KalmanFilter` step (1 trial x {CONTEXT_STEPS}, 1 mode)",
    }
    sizes = {"IMMFilter": f"{trials} x {steps}", "FilterPy IMM": f"{fp_trials} x {steps}",
             "numpy KF": f"1 x {CONTEXT_STEPS}", "FilterPy KF": f"1 x {CONTEXT_STEPS}"}
    rows = [[labels[name], sizes[name], *row[1:]]
            for name, row in zip(cmp.names, comparison_rows(cmp, "IMMFilter"))]
    table = markdown_table(["implementation", "trials x steps per call",
                            *comparison_header("trial-step", "IMMFilter")], rows)
    verdict = "meets" if min(speed_med, speed_min) >= TARGET_SPEEDUP else "does NOT meet"
    notes = [
        (f"FilterPy per trial-step / IMMFilter per trial-step: **{speed_med:.0f}x** (medians), "
         f"{speed_min:.0f}x (mins) — {verdict} issue 13's target of {TARGET_SPEEDUP:.0f}x; "
         f"1-minute load average {format_load(cmp)} on {os.cpu_count()} CPUs."),
        (f"{rounds} interleaved rounds (IMMFilter, FilterPy, numpy KF, FilterPy KF, IMMFilter, "
         "...) by CPU time (`time.process_time`), each contender warmed up first; FilterPy "
         f"is slow, so each of its rounds filters only the first {fp_trials} of the "
         f"{trials} trials and the comparison is per trial-step (FilterPy's cost does "
         "not depend on the number of trials: it loops over them)."),
        (f"at FilterPy's median per trial-step, all {trials} x {steps} would take "
         f"{format_seconds(cmp.median('FilterPy IMM') * trials * steps)} of CPU."),
    ]
    check = markdown_table(
        ["quantity", "max abs difference", "scale (max abs value)"],
        [("combined state x", f"{dx:.2e}", f"{np.abs(fx).max():.3g}"),
         ("combined covariance P", f"{dP:.2e}", f"{np.abs(fP).max():.3g}"),
         ("mode probabilities", f"{dmu:.2e}", "1")],
    )
    check_notes = (
        (f"compared over the {fp_trials} trials x {steps} samples FilterPy filtered, every "
         f"sample; {'identical to 1e-9' if identical else 'NOT identical to 1e-9'}."),
        ("true mode recovered by the most probable IMM mode on "
         f"{np.mean(est.mode == traj.mode):.1%} of the samples (all trials)."),
    )
    return [
        Section(f"IMM: switchest IMMFilter vs FilterPy IMMEstimator (vehicle, L = 3, T = {T} s), "
                "interleaved CPU time", table, tuple(notes)),
        Section("IMM: equality check (switchest - FilterPy)", check, check_notes),
        hot_spots(imm, traj),
    ]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help=f"FilterPy on {QUICK_FILTERPY_TRIALS} trials, {QUICK_ROUNDS} rounds")
    args = parser.parse_args(argv)
    with single_threaded() as blas:
        print(f"BLAS and engine at one thread: {blas['single_threaded']}")
        print_sections(run(quick=args.quick))


if __name__ == "__main__":
    main()
