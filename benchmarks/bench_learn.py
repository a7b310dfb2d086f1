"""How the error of switchest.learn.fit falls with the data size, against its standard errors.

Two discrete-time Markov jump systems (n = 2 states, m = 1 output, per-mode A, C, Q, R and an
asymmetric transition matrix): a 3-mode one, and a 2-mode one whose modes the data tell apart
better (an oscillating and a damped mode, each measuring another state). Each is simulated for
K samples at several seeds and fitted (transition, Q, R) from a poor start: twice the true Q,
half the true R and a uniform stay (0.8). For each K the table gives, per parameter group, the
RMS error of the fitted entries against the truth over the entries and the seeds, the RMS of
the reported standard errors, and the RMS of the z-scores error / standard error (about 1 when
the standard errors are right). A maximum-likelihood estimate's error falls as 1 / sqrt(K):
the "slope" column is the log-log slope of the RMS error against K over the whole sweep (least
squares; -0.5 expected).

Known modes (a mode column: an exact E-step, Anderson & Goodman 1957 for the transition
matrix, Shumway & Stoffer 1982 for Q, R) are the first table. The others fit with the modes
unknown: Kim's smoother on the chain of mode pairs as E-step (approximate; EM stops at the first
step that would lower its likelihood), then the direct ascent of the same likelihood
(switchest.learn.ascent). Their columns count the likelihood drops of the trace (none
expected), the entries without a standard error (on the boundary, e.g. a transition
probability or a variance at zero, or all of them where the information of the others is not
positive definite: a maximum the data do not pin down),
and the mean log-likelihood of the fit above that of the true parameters (at a regular
maximum-likelihood estimate twice it is chi-square with as many degrees of freedom as free
parameters, so about half their number on average). The 3-mode system is also fitted from the
truth, which separates what the data say from the local optima of the poor start.

Run: ``python benchmarks/bench_learn.py [--quick]``.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np
from harness import Section, markdown_table, print_sections, quick_flag, single_threaded

from switchest.estimators import IMMFilter
from switchest.learn import fit
from switchest.learn.data import record
from switchest.learn.expectation import log_likelihood
from switchest.simulate import simulate
from switchest.switching import MarkovAtSamples
from switchest.system import SwitchedLinearSystem

GROUPS = ("transition", "Q", "R")
TOL = 1e-7  # relative change of the log-likelihood at which EM stops
TEST_TRIALS, TEST_STEPS, TEST_SEED = 40, 300, 77  # the IMM with fitted vs true parameters


@dataclass(frozen=True)
class JumpSystem:
    """A discrete-time Markov jump system (dt = 1) and its transition matrix."""

    name: str
    A: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    transition: np.ndarray

    def system(self, scale_Q: float = 1.0, scale_R: float = 1.0) -> SwitchedLinearSystem:
        """The system with its noise covariances scaled (the poor start: 2, 0.5)."""
        return SwitchedLinearSystem.discrete(self.A, None, self.C, scale_Q * self.Q,
                                             scale_R * self.R, dt=1.0)

    def start_transition(self) -> np.ndarray:
        L = self.transition.shape[0]
        return np.full((L, L), 0.2 / (L - 1)) + (0.8 - 0.2 / (L - 1)) * np.eye(L)

    def free_entries(self, name: str) -> tuple[np.ndarray, ...]:
        """Indices of the fitted entries of a group: every transition entry, the upper
        triangles of Q's and R's blocks (the truth's diagonal Q, R: every component noisy)."""
        L = self.transition.shape[0]
        if name == "transition":
            return np.nonzero(np.ones((L, L), bool))
        n = getattr(self, name).shape[1]
        return np.nonzero(np.broadcast_to(np.triu(np.ones((n, n), bool)), (L, n, n)))


THREE = JumpSystem(
    "a 3-mode Markov jump system",
    A=np.array([[[0.9, 0.1], [0.0, 0.8]], [[0.5, -0.3], [0.2, 0.7]], [[1.0, 0.0], [0.1, 0.6]]]),
    C=np.array([[[1.0, 0.0]], [[1.0, 1.0]], [[0.0, 1.0]]]),
    Q=np.array([np.diag([0.1, 0.05]), np.diag([0.3, 0.1]), np.diag([0.05, 0.2])]),
    R=np.array([[[0.2]], [[0.5]], [[0.1]]]),
    transition=np.array([[0.9, 0.07, 0.03], [0.1, 0.8, 0.1], [0.05, 0.15, 0.8]]))
TWO = JumpSystem(
    "a 2-mode Markov jump system",
    A=np.array([[[0.95, 0.2], [-0.2, 0.95]], [[0.5, 0.0], [0.3, 0.4]]]),
    C=np.array([[[1.0, 0.0]], [[0.0, 1.0]]]),
    Q=np.array([np.diag([0.05, 0.05]), np.diag([0.2, 0.1])]),
    R=np.array([[[0.05]], [[0.1]]]),
    transition=np.array([[0.95, 0.05], [0.1, 0.9]]))

PLANS = {
    "default": {"K": (500, 2000, 8000), "seeds": 5, "max_iter": 150,
                "unknown_K": (500, 2000, 8000), "unknown_seeds": 2, "unknown_iter": 200,
                "two_K": (1000, 4000), "two_seeds": 3},
    "quick": {"K": (500, 2000), "seeds": 2, "max_iter": 60,
              "unknown_K": (500,), "unknown_seeds": 1, "unknown_iter": 10,
              "two_K": (1000,), "two_seeds": 1},
}


def one_fit(model: JumpSystem, K: int, seed: int, *, known: bool, max_iter: int,
            from_truth: bool = False) -> dict:
    """Simulate K samples at ``seed``, fit them from the poor start (or, ``from_truth``, from
    the true parameters); errors and standard errors per group, and the fit's trace."""
    t = np.arange(float(K))
    traj = simulate(model.system(), MarkovAtSamples(model.transition, initial=0), t,
                    (np.zeros(2), np.eye(2)), rng=seed)
    modes = traj.mode[0] if known else None
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        res = fit(model.system() if from_truth else model.system(2.0, 0.5), traj.y[0], t=t,
                  transition=model.transition if from_truth else model.start_transition(),
                  x0=np.zeros(2), P0=np.eye(2), modes=modes, max_iter=max_iter, tol=TOL)
    seconds = time.perf_counter() - start
    falls = np.diff(res.loglik) < -1e-9 * np.abs(res.loglik[1:])
    em = res.iterations if res.ascent_from is None else res.ascent_from
    true_loglik = log_likelihood(model.system(), model.transition, np.zeros(2), np.eye(2),
                                 record(model.system(), traj.y[0], None, t, modes))
    out = {"seconds": seconds, "iterations": (em, res.iterations - em), "drops": int(falls.sum()),
           "gain": res.loglik[-1] - true_loglik, "warnings": len(caught)}
    out["state"] = imm_excess(model, res.system, res.transition)
    truth = {"transition": model.transition, "Q": model.Q, "R": model.R}
    fitted = {"transition": res.transition, "Q": res.system.Q, "R": res.system.R}
    for name in GROUPS:
        idx = model.free_entries(name)
        out[name] = (fitted[name][idx] - truth[name][idx], res.se[name][idx])
    return out


def imm_excess(model: JumpSystem, system: SwitchedLinearSystem, transition: np.ndarray
               ) -> tuple[float, float, float, float]:
    """The IMM's state error with the fitted parameters less that with the true ones, on one
    fresh test batch (paired trials): the mean over trials of the difference of their mean
    squared errors and its standard error; the mean squared error with the true ones and its
    standard error (over the trials: the sampling error of the MSE itself)."""
    test = simulate(model.system(), MarkovAtSamples(model.transition, initial=0),
                    np.arange(float(TEST_STEPS)), (np.zeros(2), np.eye(2)), trials=TEST_TRIALS,
                    rng=TEST_SEED)

    def mse(sys_, pi):
        est = IMMFilter(sys_, pi, np.zeros(2), np.eye(2)).run(test.y)
        return np.sum((est.x - test.x) ** 2, axis=-1).mean(axis=1)

    true = mse(model.system(), model.transition)
    diff = mse(system, transition) - true
    root = np.sqrt(diff.size)
    return (float(diff.mean()), float(diff.std(ddof=1) / root), float(true.mean()),
            float(true.std(ddof=1) / root))


def rms(values) -> float:
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values ** 2))) if values.size else float("nan")


def sweep(model: JumpSystem, sizes, seeds: int, *, known: bool, max_iter: int,
          from_truth: bool = False) -> Section:
    """One table over the data sizes: errors, standard errors, z-scores and the slopes."""
    results = {K: [one_fit(model, K, 1000 + s, known=known, max_iter=max_iter,
                           from_truth=from_truth) for s in range(seeds)] for K in sizes}
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
            em, up = (np.mean([r["iterations"][a] for r in runs]) for a in (0, 1))
            row = [K, name, f"{errors[name][i]:.4f}", f"{rms(se):.4f}", f"{rms(err / se):.2f}",
                   f"{slopes[name]:.2f}" if i == 0 else "",
                   f"{em:.0f}" if known else f"{em:.0f} + {up:.0f}",
                   f"{sum(r['drops'] for r in runs)}"]
            if not known:
                row.append(f"{int(np.sum(~np.isfinite(se)))} of {se.size}")
            state = np.array([r["state"] for r in runs])  # (seeds, 4): imm_excess's
            se = np.sqrt(np.sum(state[:, [1, 3]] ** 2, axis=0)) / len(runs)  # of the means
            state = (f"{state[:, 0].mean():+.4f} ± {se[0]:.4f} (of {state[:, 2].mean():.3f} "
                     f"± {se[1]:.3f})" if name == "transition" else "")
            rows.append((*row, f"{np.mean([r['gain'] for r in runs]):.2f}", state,
                         f"{np.mean([r['seconds'] for r in runs]):.2f}"))
    head = ["K", "parameter", "RMS error", "RMS std. error", "RMS z", "slope vs K"]
    if known:
        head += ["iterations (mean)", "loglik drops"]
    else:
        head += ["iterations (EM + ascent, mean)", "loglik drops", "no std. error"]
    table = markdown_table([*head, "loglik - truth's (mean)", "IMM state MSE, fitted - true",
                            "fit (s, mean)"], rows)
    label = "known modes (exact E-step)" if known else "UNKNOWN modes (Kim's E-step, then ascent)"
    label += ", started at the truth" if from_truth else ""
    notes = (f"{seeds} seeds per K, at most {max_iter} EM iterations, tol {TOL:g}; z = (fitted - "
             "true) / reported standard error, RMS over the entries and seeds with one (1 when "
             "the standard errors are right); slope: least-squares log-log slope of the RMS "
             "error over all K (-0.5 for the 1/sqrt(K) rate).",
             f"IMM state MSE: the IMM with the fitted parameters against the IMM with the true "
             f"ones on one test batch ({TEST_TRIALS} trials x {TEST_STEPS} samples), the mean "
             "excess squared error of the state over the seeds ± its standard error (paired "
             "trials: far below the MSE's own), and (of ...) the MSE with the true parameters "
             "± its sampling error over the trials; the excess is what the parameters' "
             "estimation error costs, and falls with K.")
    if not known:
        notes += ("unknown modes: Kim's smoother on the chain of mode pairs as E-step (not "
                  "exact; EM stops at the first step that would lower its likelihood), then "
                  "direct ascent of that E-step's likelihood (at most as many "
                  "iterations again); standard errors from its observed information, jointly "
                  "for the transition, Q and R; 'no std. error': entries on the boundary "
                  "(held fixed, named in a warning), or all where the information of the others "
                  "was not positive definite.",)
    return Section(f"EM on {model.name}: {label}", table, notes)


def run(*, quick: bool = False) -> list[Section]:
    """The known-modes sweep, two unknown-modes ones on the 3-mode system (from the poor
    start, and from the truth) and one on the better separated 2-mode system."""
    plan = PLANS["quick" if quick else "default"]
    unknown = {"known": False, "max_iter": plan["unknown_iter"]}
    return [sweep(THREE, plan["K"], plan["seeds"], known=True, max_iter=plan["max_iter"]),
            sweep(THREE, plan["unknown_K"], plan["unknown_seeds"], **unknown),
            sweep(THREE, plan["unknown_K"], plan["unknown_seeds"], from_truth=True, **unknown),
            sweep(TWO, plan["two_K"], plan["two_seeds"], known=False, max_iter=40)]


def main(argv=None) -> None:
    quick = quick_flag(__doc__.splitlines()[0], argv)
    with single_threaded() as blas:
        print(f"BLAS and engine at one thread: {blas['single_threaded']}")
        print_sections(run(quick=quick))


if __name__ == "__main__":
    main()
