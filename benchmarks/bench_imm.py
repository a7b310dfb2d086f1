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

Run: ``python benchmarks/bench_imm.py [--quick]``. ``--quick`` times FilterPy on
50 trials and extrapolates per trial-step; the default loops over all 500.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats

import numpy as np
from filterpy.kalman import IMMEstimator, KalmanFilter
from harness import (
    Section,
    best_time,
    format_seconds,
    markdown_table,
    print_sections,
    single_threaded_blas,
)

from switchest.discretize import mode_steps
from switchest.estimators import IMMFilter
from switchest.models import vehicle_2d
from switchest.signals import markov_at_samples
from switchest.simulate import simulate

T = 0.5
TRIALS = 500
STEPS = 200
QUICK_FILTERPY_TRIALS = 50
SEED = 20240603
TARGET_SPEEDUP = 100.0


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
    entries = sorted(stats.stats.items(), key=lambda kv: kv[1][3], reverse=True)  # cumulative time
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
        f"Where IMMFilter.run spends its time (cProfile, {traj.y.shape[0]} trials x {steps} steps)",
        table,
        (f"total profiled time {format_seconds(total)} (profiling overhead included).",),
    )


def run(*, quick: bool = False, trials: int = TRIALS, steps: int = STEPS) -> list[Section]:
    """Time both IMMs on the same data and check that they agree; returns the result sections."""
    system, transition, x0, P0, traj = vehicle_data(trials, steps)
    y, u, t = traj.y, traj.u, traj.t
    imm = IMMFilter(system, transition, x0, P0)
    ours = best_time(lambda: imm.run(y, u, t), repeat=3, budget=30.0)
    est = ours.result

    fp_trials = min(QUICK_FILTERPY_TRIALS, trials) if quick else trials
    theirs = best_time(lambda: filterpy_run(system, transition, x0, P0, y[:fp_trials], u[:fp_trials]),
                       repeat=1)
    fx, fP, fmu = theirs.result

    ours_per = ours.best / (trials * steps)
    theirs_per = theirs.best / (fp_trials * steps)
    speedup = theirs_per / ours_per
    dx = np.abs(est.x[:fp_trials] - fx).max()
    dP = np.abs(est.P[:fp_trials] - fP).max()
    dmu = np.abs(est.mode_prob[:fp_trials] - fmu).max()
    identical = max(dx, dP, dmu) <= 1e-9

    context_steps = 2000
    ctx_y = np.tile(y[0], (context_steps // steps + 1, 1))[:context_steps]
    ctx_u = np.ones((context_steps, 1))
    bare = best_time(lambda: bare_kalman_steps(system, ctx_y, ctx_u), repeat=3)
    fp_kf = best_time(lambda: filterpy_kalman_steps(system, ctx_y, ctx_u), repeat=3)

    rows = [
        ("switchest `IMMFilter.run` (all trials at once)", f"{trials} x {steps}",
         format_seconds(ours.best), format_seconds(ours_per), "1"),
        ("FilterPy `IMMEstimator` (loop over trials)", f"{fp_trials} x {steps}",
         format_seconds(theirs.best), format_seconds(theirs_per), f"{speedup:.3g}"),
        ("bare numpy Kalman step (1 trial, 1 mode)", f"1 x {context_steps}",
         format_seconds(bare.best), format_seconds(bare.best / context_steps),
         f"{bare.best / context_steps / ours_per:.3g}"),
        ("FilterPy `KalmanFilter` step (1 trial, 1 mode)", f"1 x {context_steps}",
         format_seconds(fp_kf.best), format_seconds(fp_kf.best / context_steps),
         f"{fp_kf.best / context_steps / ours_per:.3g}"),
    ]
    timing = markdown_table(["implementation", "trials x steps", "wall time (best)", "per trial-step",
                             "per trial-step / IMMFilter's"], rows)
    verdict = "meets" if speedup >= TARGET_SPEEDUP else "does NOT meet"
    notes = [
        (f"speedup of IMMFilter over FilterPy per trial-step: **{speedup:.1f}x** — {verdict} the "
         f"issue's target of {TARGET_SPEEDUP:.0f}x."),
        (f"IMMFilter timed {ours.repeats}x (all: {', '.join(format_seconds(s) for s in ours.times)}); "
         "FilterPy once."),
    ]
    if fp_trials < trials:
        notes.append(f"--quick: FilterPy timed on the first {fp_trials} trials only; its per trial-step "
                     f"cost is extrapolated to {trials} x {steps}: "
                     f"{format_seconds(theirs_per * trials * steps)}.")
    check = markdown_table(
        ["quantity", "max abs difference", "scale (max abs value)"],
        [("combined state x", f"{dx:.2e}", f"{np.abs(fx).max():.3g}"),
         ("combined covariance P", f"{dP:.2e}", f"{np.abs(fP).max():.3g}"),
         ("mode probabilities", f"{dmu:.2e}", "1")],
    )
    check_notes = (
        (f"compared over {fp_trials} trials x {steps} samples, every sample; "
         f"{'identical to 1e-9' if identical else 'NOT identical to 1e-9'}."),
        ("true mode recovered by the most probable IMM mode on "
         f"{np.mean(est.mode == traj.mode):.1%} of the samples."),
    )
    return [
        Section(f"IMM: switchest IMMFilter vs FilterPy IMMEstimator (vehicle, L = 3, T = {T} s)",
                timing, tuple(notes)),
        Section("IMM: equality check (switchest - FilterPy)", check, check_notes),
        hot_spots(imm, traj),
    ]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help=f"time FilterPy on {QUICK_FILTERPY_TRIALS} trials and extrapolate")
    args = parser.parse_args(argv)
    with single_threaded_blas() as blas:
        print(f"BLAS limited to one thread: {blas['single_threaded']}")
        print_sections(run(quick=args.quick))


if __name__ == "__main__":
    main()
