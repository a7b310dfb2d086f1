"""How the error of switchest.learn.fit falls with the data size, against its standard errors.

A 3-mode discrete-time Markov jump system (n = 2 states, m = 1 output; per-mode A, C, Q, R and an
asymmetric transition matrix) is simulated for K samples at several seeds and fitted by EM
(transition, Q, R) from a poor start: twice the true Q, half the true R and a uniform 0.8 stay.
For each K the table gives, per parameter group, the RMS error of the fitted entries against
the truth over the entries and the seeds, the RMS of the reported standard errors, and the RMS
of the z-scores error / standard error (about 1 when the standard errors are right). A
maximum-likelihood estimate's error falls as 1 / sqrt(K): the "slope" column is the log-log
slope of the RMS error against K over the whole sweep (least squares; -0.5 expected).

Known modes (a mode column: an exact E-step, Anderson & Goodman 1957 for the transition
matrix, Shumway & Stoffer 1982 for Q, R) are the main table. A second, clearly labelled
table runs the unknown-modes fit (Kim's smoother on the chain of mode pairs, an approximate
E-step: switchest.learn.expectation), fewer iterations, and counts the iterations where its
log-likelihood decreased; a third runs it from the true parameters, which separates the
E-step's bias (where the fit drifts from the truth) from the local optima of the poor start.

Run: ``python benchmarks/bench_learn.py [--quick]``.
"""

from __future__ import annotations

import time
import warnings

import numpy as np
from harness import Section, markdown_table, print_sections, quick_flag, single_threaded_blas

from switchest.learn import fit
from switchest.simulate import simulate
from switchest.switching import MarkovAtSamples
from switchest.system import SwitchedLinearSystem

A = np.array([[[0.9, 0.1], [0.0, 0.8]], [[0.5, -0.3], [0.2, 0.7]], [[1.0, 0.0], [0.1, 0.6]]])
C = np.array([[[1.0, 0.0]], [[1.0, 1.0]], [[0.0, 1.0]]])
Q = np.array([np.diag([0.1, 0.05]), np.diag([0.3, 0.1]), np.diag([0.05, 0.2])])
R = np.array([[[0.2]], [[0.5]], [[0.1]]])
TRANSITION = np.array([[0.9, 0.07, 0.03], [0.1, 0.8, 0.1], [0.05, 0.15, 0.8]])
START_TRANSITION = np.full((3, 3), 0.1) + 0.7 * np.eye(3)
GROUPS = ("transition", "Q", "R")
TOL = 1e-7  # relative change of the log-likelihood at which EM stops

PLANS = {
    "default": {"K": (500, 2000, 8000), "seeds": 5, "max_iter": 150,
                "unknown_K": (500, 2000), "unknown_seeds": 2, "unknown_iter": 30},
    "quick": {"K": (500, 2000), "seeds": 2, "max_iter": 60,
              "unknown_K": (500,), "unknown_seeds": 1, "unknown_iter": 10},
}


def system(Qs=Q, Rs=R) -> SwitchedLinearSystem:
    """The 3-mode jump system (discrete time, dt = 1) with noise covariances ``Qs``, ``Rs``."""
    return SwitchedLinearSystem.discrete(A, None, C, Qs, Rs, dt=1.0)


def free_entries(name: str) -> tuple[np.ndarray, ...]:
    """Indices of the fitted entries of a group: every transition entry, the upper triangles
    of Q's and R's blocks (the diagonal Q, R of the truth have all components noisy)."""
    if name == "transition":
        return np.nonzero(np.ones((3, 3), bool))
    n = Q.shape[1] if name == "Q" else R.shape[1]
    upper = np.triu(np.ones((n, n), bool))
    return np.nonzero(np.broadcast_to(upper, (3, n, n)))


def one_fit(K: int, seed: int, *, known: bool, max_iter: int, from_truth: bool = False) -> dict:
    """Simulate K samples at ``seed``, fit them from the poor start (or, ``from_truth``, from
    the true parameters); errors and standard errors per group."""
    t = np.arange(float(K))
    traj = simulate(system(), MarkovAtSamples(TRANSITION, initial=0), t,
                    (np.zeros(2), np.eye(2)), rng=seed)
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        res = fit(system() if from_truth else system(2 * Q, 0.5 * R), traj.y[0], t=t,
                  transition=TRANSITION if from_truth else START_TRANSITION,
                  x0=np.zeros(2), P0=np.eye(2), modes=traj.mode[0] if known else None,
                  max_iter=max_iter, tol=TOL)
    out = {"seconds": time.perf_counter() - start, "iterations": res.iterations,
           "drops": int(np.sum(np.diff(res.loglik) < -1e-9 * np.abs(res.loglik[1:]))),
           "warnings": len(caught)}
    truth = {"transition": TRANSITION, "Q": Q, "R": R}
    fitted = {"transition": res.transition, "Q": res.system.Q, "R": res.system.R}
    for name in GROUPS:
        idx = free_entries(name)
        out[name] = (fitted[name][idx] - truth[name][idx], res.se[name][idx])
    return out


def rms(values) -> float:
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values ** 2))) if values.size else float("nan")


def sweep(sizes, seeds: int, *, known: bool, max_iter: int, from_truth: bool = False) -> Section:
    """One table over the data sizes: errors, standard errors, z-scores and the slopes."""
    results = {K: [one_fit(K, 1000 + s, known=known, max_iter=max_iter, from_truth=from_truth)
                   for s in range(seeds)] for K in sizes}
    errors = {name: [rms(np.concatenate([r[name][0] for r in results[K]])) for K in sizes]
              for name in GROUPS}
    slopes = {name: (np.polyfit(np.log(sizes), np.log(errors[name]), 1)[0]
                     if len(sizes) > 1 else float("nan")) for name in GROUPS}
    rows = []
    for i, K in enumerate(sizes):
        runs = results[K]
        for name in GROUPS:
            err = np.concatenate([r[name][0] for r in runs])
            se = np.concatenate([r[name][1] for r in runs])
            rows.append((K, name, f"{errors[name][i]:.4f}", f"{rms(se):.4f}",
                         f"{rms(err / se):.2f}", f"{slopes[name]:.2f}" if i == 0 else "",
                         f"{np.mean([r['iterations'] for r in runs]):.0f}",
                         f"{sum(r['drops'] for r in runs)}",
                         f"{np.mean([r['seconds'] for r in runs]):.2f}"))
    table = markdown_table(
        ["K", "parameter", "RMS error", "RMS std. error", "RMS z", "slope vs K",
         "iterations (mean)", "loglik drops", "fit (s, mean)"], rows)
    label = "known modes (exact E-step)" if known else "UNKNOWN modes (approximate E-step)"
    label += ", started at the truth" if from_truth else ""
    notes = (f"{seeds} seeds per K, at most {max_iter} EM iterations, tol {TOL:g}; z = (fitted - "
             "true) / reported standard error, RMS over the entries and seeds (1 when the "
             "standard errors are right); slope: least-squares log-log slope of the RMS error "
             "over all K (-0.5 for the 1/sqrt(K) rate).",)
    if not known:
        notes += ("unknown modes: Kim's smoother on the chain of mode pairs as E-step, not exact; "
                  "its standard errors treat the expected counts as observed and use that "
                  "filter's likelihood, and 'loglik drops' counts iterations where the "
                  "likelihood decreased.",)
    return Section(f"EM on a 3-mode Markov jump system: {label}", table, notes)


def run(*, quick: bool = False) -> list[Section]:
    """The known-modes sweep and two unknown-modes ones: from the poor start, and from the
    truth (where the approximate E-step's own bias shows, apart from EM's local optima)."""
    plan = PLANS["quick" if quick else "default"]
    unknown = {"known": False, "max_iter": plan["unknown_iter"]}
    return [sweep(plan["K"], plan["seeds"], known=True, max_iter=plan["max_iter"]),
            sweep(plan["unknown_K"], plan["unknown_seeds"], **unknown),
            sweep(plan["unknown_K"], plan["unknown_seeds"], from_truth=True, **unknown)]


def main(argv=None) -> None:
    quick = quick_flag(__doc__.splitlines()[0], argv)
    with single_threaded_blas() as blas:
        print(f"BLAS limited to one thread: {blas['single_threaded']}")
        print_sections(run(quick=quick))


if __name__ == "__main__":
    main()
