"""switchest's IMM engine against the issue's yardstick, a plain scalar numba IMM (issue 13).

Three contenders on the vehicle of :mod:`bench_imm` (Shankar et al. §V.B: n = 4, m = 2,
L = 3 modes differing by their input, T = 0.5 s, u = 1, Markov switching at the samples):

* **yardstick** — :func:`yardstick_imm` below: a plain scalar IMM compiled with numba, written
  independently of switchest (textbook equations: mixing with probabilities, Cholesky solves,
  Joseph form; no missing samples, no gating, no irregular times, no equilibration), trials
  outer, time inner; numba is a benchmark-only dependency (the ``bench`` extra);
* **engine** — ``switchest.engine.imm.imm_run``, the C kernel behind ``IMMFilter`` (built at
  install; trials in blocks of 16 across SIMD lanes; log-domain mixing, NaN handling, gating,
  per-step transition table, equilibrated Cholesky), timed through its Python wrapper,
  argument checks included;
* **IMMFilter** — ``switchest.estimators.IMMFilter.run``: the same kernel through the
  estimator (validation, the transition table built from the sample times, the ``Estimate``).
  Before issue 13 this was the numpy core (batched over trials), 5-40x slower.

Shapes (trials x steps): 500 x 200, 100 x 20 000 (the papers' shape), 10 000 x 200. Each shape
is measured interleaved (yardstick, engine, IMMFilter, yardstick, ...) by CPU time
(``time.process_time``) with BLAS and the engine at one thread (``set_threads(1)``: the
yardstick is single-threaded), after an untimed warm-up call (the yardstick's numba compile or
on-disk cache load; nothing of switchest compiles at run time)
(:func:`harness.compare_interleaved`, 3 rounds); the median and the min per trial-step are
reported with the ratios of medians and of mins to the yardstick and the load average. The
issue's target: the engine within 1.5x of the yardstick. A second table gives the cost per
trial-step of the engine and of ``IMMFilter`` at N = 10 and N = 1 000 trials, also
interleaved (target: within 2x). A third measures thread scaling: ``IMMFilter.run`` on
1 000 trials x 2 000 samples at one and at two engine threads, interleaved, by wall time
(CPU time counts every thread) — the issue's target is at least 1.8x on two cores — and
checks that the outputs are identical (bit for bit) whatever the thread count.

``switchest.engine.imm`` is a private interface: should it move, its rows are left out and the
public ``IMMFilter`` is still measured.

Run: ``python benchmarks/bench_engine.py [--quick]`` (``--quick``: shapes 50 x 200,
10 x 2 000 and 500 x 200, 2 rounds; N = 10 vs 500; threads on 100 x 500).
"""

from __future__ import annotations

import math
import os
import time

import numpy as np
from bench_imm import T, vehicle_data
from harness import (
    Contender,
    Section,
    compare_interleaved,
    comparison_header,
    comparison_rows,
    engine_threads,
    format_load,
    format_seconds,
    markdown_table,
    print_sections,
    quick_flag,
    single_threaded,
)
from numba import njit

from switchest.discretize import mode_steps
from switchest.estimators import IMMFilter

try:  # private: the kernel behind IMMFilter; its rows are dropped if its interface moves
    from switchest.engine import raise_for_status
    from switchest.engine.imm import imm_run
    IMPORT_ERROR = ""
except ImportError as exc:  # pragma: no cover - depends on the package's internals
    imm_run = raise_for_status = None
    IMPORT_ERROR = str(exc)

SHAPES = [(500, 200), (100, 20_000), (10_000, 200)]
QUICK_SHAPES = [(50, 200), (10, 2_000), (500, 200)]
QUICK_SCALING_N = (10, 500)
ROUNDS = 3
QUICK_ROUNDS = 2
ESTIMATOR_BUDGET = 60.0  # CPU seconds: a contender sits out further rounds once it used this up
SCALING_N = (10, 1_000)
SCALING_K = 200
SCALING_ROUNDS = 10
QUICK_SCALING_ROUNDS = 3
TARGET_RATIO = 1.5
SCALING_TARGET = 2.0
THREAD_SHAPE = (1_000, 2_000)
QUICK_THREAD_SHAPE = (100, 500)  # still two threads' worth (engine._parallel.MIN_WORK)
THREAD_COUNTS = (1, 2)
THREAD_ROUNDS = 5
QUICK_THREAD_ROUNDS = 2
THREAD_TARGET = 1.8


@njit(cache=True)
def yardstick_imm(y, u, F, G, Qd, C, R, transition, x0, P0, mu0, x_out, P_out, mu_out):
    """A plain scalar IMM (Blom & Bar-Shalom, 1988): one trial at a time, one step at a time.

    Mode ``j`` predicts with ``F[j]``, ``G[j]``, ``Qd[j]`` and is updated with ``C[j]``,
    ``R[j]``; ``transition[i, j]`` = P(j next | i now). Sample 0 is update only. Writes the
    combined mean and covariance and the mode probabilities of every trial and sample.
    """
    N, K, m = y.shape
    L, n, _ = F.shape
    n_in = u.shape[2]
    x, P = np.empty((L, n)), np.empty((L, n, n))
    xm, Pm = np.empty((L, n)), np.empty((L, n, n))
    mu, c, w, loglik = np.empty(L), np.empty(L), np.empty((L, L)), np.empty(L)
    e, S, Lc = np.empty(m), np.empty((m, m)), np.empty((m, m))
    PCt, Kg, KR = np.empty((n, m)), np.empty((n, m)), np.empty((n, m))
    A, T1, T2, xp = np.empty((n, n)), np.empty((n, n)), np.empty((n, n)), np.empty(n)
    v = np.empty(m)
    for i in range(N):
        for j in range(L):
            mu[j] = mu0[j]
            for r in range(n):
                x[j, r] = x0[r]
                for s in range(n):
                    P[j, r, s] = P0[r, s]
        for k in range(K):
            if k > 0:
                for j in range(L):  # mixing
                    c[j] = 0.0
                    for q in range(L):
                        c[j] += transition[q, j] * mu[q]
                    for q in range(L):
                        w[q, j] = transition[q, j] * mu[q] / c[j]
                for j in range(L):
                    for r in range(n):
                        acc = 0.0
                        for q in range(L):
                            acc += w[q, j] * x[q, r]
                        xm[j, r] = acc
                    for r in range(n):
                        for s in range(n):
                            acc = 0.0
                            for q in range(L):
                                acc += w[q, j] * (P[q, r, s] + (x[q, r] - xm[j, r])
                                                  * (x[q, s] - xm[j, s]))
                            Pm[j, r, s] = acc
                for j in range(L):  # predict: x = F x + G u, P = F P F' + Qd
                    for r in range(n):
                        acc = 0.0
                        for s in range(n):
                            acc += F[j, r, s] * xm[j, s]
                        for s in range(n_in):
                            acc += G[j, r, s] * u[i, k - 1, s]
                        x[j, r] = acc
                    for r in range(n):
                        for s in range(n):
                            acc = 0.0
                            for q in range(n):
                                acc += F[j, r, q] * Pm[j, q, s]
                            T1[r, s] = acc
                    for r in range(n):
                        for s in range(n):
                            acc = Qd[j, r, s]
                            for q in range(n):
                                acc += T1[r, q] * F[j, s, q]
                            T2[r, s] = acc
                    for r in range(n):
                        for s in range(n):
                            P[j, r, s] = 0.5 * (T2[r, s] + T2[s, r])
            else:
                for j in range(L):
                    c[j] = mu[j]
            for j in range(L):  # update each mode
                for a in range(m):
                    acc = y[i, k, a]
                    for r in range(n):
                        acc -= C[j, a, r] * x[j, r]
                    e[a] = acc
                for r in range(n):
                    for a in range(m):
                        acc = 0.0
                        for s in range(n):
                            acc += P[j, r, s] * C[j, a, s]
                        PCt[r, a] = acc
                for a in range(m):
                    for b in range(m):
                        acc = R[j, a, b]
                        for r in range(n):
                            acc += C[j, a, r] * PCt[r, b]
                        S[a, b] = acc
                for a in range(m):  # Cholesky S = Lc Lc'
                    for b in range(a + 1):
                        acc = S[a, b]
                        for q in range(b):
                            acc -= Lc[a, q] * Lc[b, q]
                        Lc[a, b] = math.sqrt(acc) if a == b else acc / Lc[b, b]
                logdet, nis = 0.0, 0.0
                for a in range(m):  # v = Lc^-1 e
                    acc = e[a]
                    for b in range(a):
                        acc -= Lc[a, b] * v[b]
                    v[a] = acc / Lc[a, a]
                    nis += v[a] * v[a]
                    logdet += 2.0 * math.log(Lc[a, a])
                loglik[j] = -0.5 * (nis + logdet + m * math.log(2.0 * math.pi))
                for r in range(n):  # K = P C' S^-1, row by row
                    for a in range(m):
                        acc = PCt[r, a]
                        for b in range(a):
                            acc -= Lc[a, b] * Kg[r, b]
                        Kg[r, a] = acc / Lc[a, a]
                    for a in range(m - 1, -1, -1):
                        acc = Kg[r, a]
                        for b in range(a + 1, m):
                            acc -= Lc[b, a] * Kg[r, b]
                        Kg[r, a] = acc / Lc[a, a]
                for r in range(n):  # x = x + K e
                    acc = 0.0
                    for a in range(m):
                        acc += Kg[r, a] * e[a]
                    xp[r] = x[j, r] + acc
                for r in range(n):  # Joseph form
                    x[j, r] = xp[r]
                    for s in range(n):
                        acc = 1.0 if r == s else 0.0
                        for a in range(m):
                            acc -= Kg[r, a] * C[j, a, s]
                        A[r, s] = acc
                    for b in range(m):
                        acc = 0.0
                        for a in range(m):
                            acc += Kg[r, a] * R[j, a, b]
                        KR[r, b] = acc
                for r in range(n):
                    for s in range(n):
                        acc = 0.0
                        for q in range(n):
                            acc += A[r, q] * P[j, q, s]
                        T1[r, s] = acc
                for r in range(n):
                    for s in range(n):
                        acc = 0.0
                        for q in range(n):
                            acc += T1[r, q] * A[s, q]
                        for a in range(m):
                            acc += KR[r, a] * Kg[s, a]
                        T2[r, s] = acc
                for r in range(n):
                    for s in range(n):
                        P[j, r, s] = 0.5 * (T2[r, s] + T2[s, r])
            top = -math.inf  # mu_j proportional to c_j Lambda_j
            for j in range(L):
                top = max(top, loglik[j])
            total = 0.0
            for j in range(L):
                mu[j] = c[j] * math.exp(loglik[j] - top)
                total += mu[j]
            for j in range(L):
                mu[j] /= total
            for r in range(n):  # combined output
                acc = 0.0
                for j in range(L):
                    acc += mu[j] * x[j, r]
                x_out[i, k, r] = acc
            for r in range(n):
                for s in range(n):
                    acc = 0.0
                    for j in range(L):
                        acc += mu[j] * (P[j, r, s] + (x[j, r] - x_out[i, k, r])
                                        * (x[j, s] - x_out[i, k, s]))
                    P_out[i, k, r, s] = acc
            for j in range(L):
                mu_out[i, k, j] = mu[j]


class Contenders:
    """The three contenders on one simulated batch, each a call returning ``(x, P, mode_prob)``."""

    def __init__(self, trials: int, steps: int):
        system, transition, x0, P0, traj = vehicle_data(trials, steps)
        self.y, self.u, self.t = traj.y, traj.u, traj.t
        self.trials, self.steps = trials, steps
        steps_ = mode_steps(system, T)
        L = system.n_modes
        self.tables = (steps_.F, steps_.G, steps_.Qd)
        self.C, self.R = system.C, system.R
        self.transition, self.x0, self.P0 = transition, x0, P0
        self.mu0 = np.full(L, 1.0 / L)
        self.trans = np.tile(np.arange(L), (steps, 1))  # mode j always uses entry j (periodic)
        # the yardstick is Bar-Shalom's IMM (mix, then predict): the same timing
        self.imm = IMMFilter(system, transition, x0, P0, timing="interval")

    def yardstick(self):
        N, K, (L, n, _) = self.trials, self.steps, self.tables[0].shape
        x, P, mu = np.empty((N, K, n)), np.empty((N, K, n, n)), np.empty((N, K, L))
        yardstick_imm(self.y, self.u, *self.tables, self.C, self.R, self.transition, self.x0,
                      self.P0, self.mu0, x, P, mu)
        return x, P, mu

    def engine(self):
        out = imm_run(self.y, self.u, *self.tables, self.trans, self.C, self.R,
                      np.log(self.transition), self.x0, self.P0, np.log(self.mu0),
                      timing="interval")
        raise_for_status(out.status)
        return out.x, out.P, out.mode_prob

    def estimator(self):
        est = self.imm.run(self.y, self.u, self.t)
        return est.x, est.P, est.mode_prob


def compare_shape(trials: int, steps: int, rounds: int) -> tuple[list, list[str], dict]:
    """Interleaved rounds of the contenders at one shape; a table row per contender."""
    bench = Contenders(trials, steps)
    contenders = [Contender("yardstick", bench.yardstick, units=trials * steps)]
    if imm_run is not None:
        contenders.append(Contender("engine", bench.engine, units=trials * steps))
    contenders.append(Contender("IMMFilter", bench.estimator, units=trials * steps))
    cmp = compare_interleaved(contenders, rounds=rounds, budget=ESTIMATOR_BUDGET)
    rows = comparison_rows(cmp, "yardstick", prefix=(f"{trials} x {steps}",))
    ref = cmp.results["yardstick"]

    def deviation(name):  # largest difference relative to the largest value, over x, P, mu
        return max(np.abs(a - b).max() / np.abs(b).max() for a, b in zip(cmp.results[name], ref))

    agree = " and ".join(f"{name} to {deviation(name):.1e}" for name in cmp.names[1:])
    diffs = [
        (f"{trials} x {steps}: {agree} of the largest value, against the yardstick "
         f"(x, P, mode probabilities, every sample; largest |x| {np.abs(ref[0]).max():.2g}, "
         "so y - C x cancels that many digits)")
    ]
    ratios = {name: cmp.ratio(name, "yardstick") for name in cmp.names}
    return rows, diffs, ratios


def scaling(trials_list=SCALING_N, steps=SCALING_K, rounds=10) -> Section:
    """Cost per trial-step of the engine's kernel and of IMMFilter at few and many trials."""
    benches = {N: Contenders(N, steps) for N in trials_list}
    big = trials_list[-1]
    contenders = []
    for kind in (("engine", "IMMFilter") if imm_run is not None else ("IMMFilter",)):
        for N, bench in benches.items():
            call = bench.engine if kind == "engine" else bench.estimator
            # the calls at few trials are short: several per timed sample
            contenders.append(Contender(f"{kind}, N = {N}", call, units=N * steps,
                                        number=max(1, big // (10 * N))))
    cmp = compare_interleaved(contenders, rounds=rounds)
    kinds = list(dict.fromkeys(name.split(",")[0] for name in cmp.names))
    rows = []
    for kind in kinds:
        names = [f"{kind}, N = {N}" for N in trials_list]
        rows += comparison_rows(cmp, names[-1], prefix=(kind,), names=names,
                                labels={name: name.split("= ")[1] for name in names})
    verdicts = []
    for kind in kinds:
        med, low = cmp.ratio(f"{kind}, N = {trials_list[0]}", f"{kind}, N = {big}")
        ok = "meets" if max(med, low) <= SCALING_TARGET else "does NOT meet"
        verdicts.append(f"{kind}: N = {trials_list[0]} costs {med:.2f}x (medians), {low:.2f}x "
                        f"(mins) per trial-step of N = {big} — {ok} issue 13's target of "
                        f"{SCALING_TARGET:.0f}x")
    header = ["contender", "N", *comparison_header("trial-step", f"N = {big}")]
    return Section(
        f"IMM: cost per trial-step against the number of trials N ({steps} steps)",
        markdown_table(header, rows),
        (*verdicts,
         (f"{rounds} interleaved rounds by CPU time; at N = {trials_list[0]} each timed "
          "sample is the mean of several calls; wrapper and argument checks included.")),
    )


def thread_scaling(trials: int, steps: int, rounds: int) -> Section:
    """``IMMFilter.run`` at each of :data:`THREAD_COUNTS` engine threads, interleaved; wall time
    speedups to one thread, CPU time beside them, and whether the outputs are identical."""
    bench = Contenders(trials, steps)

    def at(count):
        def call():
            with engine_threads(count):
                return bench.estimator()
        return call

    names = {count: f"{count} thread{'s' if count > 1 else ''}" for count in THREAD_COUNTS}
    cmp = compare_interleaved([Contender(names[c], at(c), units=trials * steps)
                               for c in THREAD_COUNTS], rounds=rounds)
    one = names[THREAD_COUNTS[0]]
    units = trials * steps
    wall_min = {name: min(cmp.wall[name]) / units for name in cmp.names}
    rows, identical = [], {}
    for count, name in names.items():
        identical[name] = all(np.array_equal(a, b)
                              for a, b in zip(cmp.results[name], cmp.results[one]))
        rows.append([count, format_seconds(cmp.wall_median(name)), format_seconds(wall_min[name]),
                     f"{cmp.wall_median(one) / cmp.wall_median(name):.3g}",
                     f"{wall_min[one] / wall_min[name]:.3g}",
                     format_seconds(cmp.median(name)),
                     f"{cmp.median(name) / cmp.median(one):.3g}",
                     "yes" if identical[name] else "**NO**", cmp.calls(name),
                     format_load(cmp)])
    top = names[THREAD_COUNTS[-1]]
    speedup = cmp.wall_median(one) / cmp.wall_median(top)
    best = wall_min[one] / wall_min[top]
    verdict = "meets" if speedup >= THREAD_TARGET else "does NOT meet"
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        usable = os.cpu_count()
    header = ["engine threads", "median wall per trial-step", "min wall",
              f"speedup (medians, to {one})", "speedup (mins)", "median CPU per trial-step",
              f"CPU / {one}", f"x, P, mode_prob identical to {one}", "samples", "load (1 min)"]
    return Section(
        f"IMMFilter.run: engine threads ({trials} trials x {steps} steps, vehicle, L = 3)",
        markdown_table(header, rows),
        (f"{top} against {one}: **{speedup:.2f}x** by wall-time medians, {best:.2f}x by mins — "
         f"{verdict} the issue's target of {THREAD_TARGET}x on two cores; "
         f"{usable} cores usable by this process, 1-minute load {format_load(cmp)} (another "
         "process on a core takes it from the threads: wall time, not CPU time, is what "
         "threads shorten).",
         ("outputs (combined x, P and mode probabilities of every trial and sample, compared "
          f"with `numpy.array_equal`) {'identical' if all(identical.values()) else 'NOT identical'}"
          " whatever the thread count: the trials are split over threads in whole lane blocks."),
         (f"{rounds} interleaved rounds ({', '.join(names.values())}, ...) after an untimed "
          "call of each; `switchest.estimators.set_threads` before each call; BLAS at one "
          "thread. The CPU column counts every thread of the process: its excess over one "
          "thread is the cost of splitting the batch.")),
    )


def run(*, quick: bool = False) -> list[Section]:
    """Warm up the yardstick (numba), then measure every shape; returns the result sections."""
    warm = Contenders(5, 20)
    start = time.process_time()
    warm.yardstick()
    compile_note = (f"warm-up: the yardstick's numba compile (or on-disk cache load) took "
                    f"{time.process_time() - start:.2f} CPU-s; switchest's engine is compiled "
                    "at install, nothing of it compiles at run time")
    rows, notes, ratios = [], [compile_note], {}
    if imm_run is None:
        notes.append("the engine's kernel `switchest.engine.imm.imm_run` could not be "
                     f"imported ({IMPORT_ERROR}): its rows are left out")
    rounds = QUICK_ROUNDS if quick else ROUNDS
    for trials, steps in (QUICK_SHAPES if quick else SHAPES):
        shape_rows, shape_notes, shape_ratios = compare_shape(trials, steps, rounds)
        rows += shape_rows
        notes += shape_notes
        for name, ratio in shape_ratios.items():
            ratios.setdefault(name, []).append(ratio)
    for name in ("engine", "IMMFilter"):
        if name in ratios:
            worst = max(max(pair) for pair in ratios[name])
            verdict = "meets" if worst <= TARGET_RATIO else "does NOT meet"
            notes.append(f"{name} / yardstick at most {worst:.2f} (medians and mins, every "
                         f"shape): {verdict} the target of {TARGET_RATIO}x")
    notes.append(f"{rounds} interleaved rounds per shape by CPU time (`time.process_time`), "
                 f"BLAS and engine at one thread; a contender whose calls used up "
                 f"{ESTIMATOR_BUDGET:.0f} CPU-s sits out the remaining rounds")
    table = markdown_table(["trials x steps", "contender",
                            *comparison_header("trial-step", "yardstick")], rows)
    scale = (scaling(QUICK_SCALING_N, rounds=QUICK_SCALING_ROUNDS) if quick
             else scaling(rounds=SCALING_ROUNDS))
    threads = (thread_scaling(*QUICK_THREAD_SHAPE, QUICK_THREAD_ROUNDS) if quick
               else thread_scaling(*THREAD_SHAPE, THREAD_ROUNDS))
    return [Section("IMM engine: its kernel and IMMFilter vs the plain scalar numba yardstick "
                    f"(vehicle, n = 4, m = 2, L = 3, T = {T} s)", table, tuple(notes)), scale,
            threads]


def main(argv=None) -> None:
    quick = quick_flag(__doc__.splitlines()[0], argv)
    with single_threaded() as blas:
        print(f"BLAS and engine at one thread: {blas['single_threaded']}; "
              f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
        print_sections(run(quick=quick))


if __name__ == "__main__":
    main()
