"""The Monte Carlo of Wang et al.'s model and its comparison with exact moments (both experiments).

Both reproductions simulate the paper's model exactly — continuous state, modes i.i.d. at
the instants kT, the Ito output ``dy = C x dt + Xi dw`` integrated on a fine grid
(``simulate(..., output="integrated")``) — and run
:class:`~switchest.estimators.RSLSObserver` on it. The true state starts at ``x(0) = 0``,
so it stays 0 (no process noise) and the estimate is the error: the error dynamics
(Theorem 1) do not depend on ``x``, and a growing ``x`` would only cost floating-point
digits. The Monte Carlo mean squared error is compared with the exact second-moment
recursion and the steady state of eq. (21)
(:func:`~switchest.analysis.error_moments.state_error_moments`,
:func:`~switchest.analysis.subsystem_observers.steady_state`). A task simulates one trial
block of a model once and runs every gain on it, so that two gains can be compared
pairwise.

The squared errors of Examples 1-4 are heavy-tailed (open-loop runs multiply the error by
``e^{a_1 T}`` each step; its fourth moment grows without bound), so a sample standard error
understates the spread of a Monte Carlo mean. Each comparison therefore has two checks: the
unconditional one, with the standard error from the exact fourth moments where they are
known (the scalar examples), and one given the simulated modes, where the error is Gaussian
with Theorem 1's mean and covariance and each run's window sum has an exact conditional mean
and variance (:func:`~switchest.analysis.error_moments.window_sums_given_modes`).
"""

from __future__ import annotations

import numpy as np

from ...analysis.error_moments import state_error_moments, window_sums_given_modes
from ...analysis.subsystem_observers import error_dynamics, ms_convergence, steady_state
from ...estimators.rsls import RSLSObserver
from ...signals import iid_at_samples
from ...simulate import simulate
from ..registry import Row
from ..scoring import merge_blocks

Z_MAX = 4.0  # |MC - exact| / SE beyond which a comparison disagrees (P ~ 6e-5 per comparison)


def simulate_model(system, p, T: float, intervals: int, substeps: int, trials: int, rng):
    """``trials`` runs of Wang et al.'s model (1) from ``x(0) = 0`` over ``intervals`` switching
    intervals, the output integrated on ``substeps`` fine steps per interval."""
    t = T * np.arange(intervals + 1)
    return simulate(system, lambda r: iid_at_samples(p, t, rng=r), t, np.zeros(system.n_states),
                    trials=trials, rng=rng, fine_dt=T / substeps, output="integrated")


def observer_errors(system, gains, T: float, e0, traj) -> np.ndarray:
    """``x_hat_k - x_k`` at the switching instants ``(N, K + 1, n)`` of the observer started at
    ``x(0) + e0 = e0`` with that error known exactly (``P0 = 0``)."""
    n = system.n_states
    return RSLSObserver(system, gains, T, np.asarray(e0, float),
                        np.zeros((n, n))).sample_errors(traj)


def moment_stats(sq: np.ndarray, start: int) -> dict:
    """Additive sums over the trials of ``sq (N, K + 1, c)``: per step, and of each trial's average
    from ``start``."""
    window = sq[:, start:].mean(axis=1)
    return {"sum": sq.sum(axis=0).tolist(), "sq": (sq**2).sum(axis=0).tolist(),
            "win_sum": window.sum(axis=0).tolist(), "win_sq": (window**2).sum(axis=0).tolist()}


def given_modes_stats(system, gains, T: float, e0, modes: np.ndarray, err: np.ndarray,
                      start: int, selectors: np.ndarray) -> dict:
    """The runs' window sums against Theorem 1 given their modes (:func:`window_sums_given_modes`),
    as additive sums over the runs: ``dev = sum (S - E[S | alpha])``, ``var = sum Var(S | alpha)``
    (so ``dev / sqrt(var)`` has mean 0 and variance 1) and ``var2 = sum Var^2`` (the effective
    number of runs is ``var^2 / var2``)."""
    given = window_sums_given_modes(error_dynamics(system, gains, T), e0, modes, start, selectors)
    observed = np.einsum("dc,nkc->nd", np.asarray(selectors, float), err[:, start:] ** 2)
    return {"dev": (observed - given.mean).sum(axis=0).tolist(),
            "var": given.var.sum(axis=0).tolist(), "var2": (given.var**2).sum(axis=0).tolist()}


def block_total(results, **match) -> tuple[dict, dict, dict]:
    """(config, ``stats`` summed over blocks, result of block 0) of the tasks whose config matches
    ``match``."""
    chosen = sorted(((c, r) for c, r in results if all(c[k] == v for k, v in match.items())),
                    key=lambda cr: cr[0]["block"])
    return chosen[0][0], merge_blocks(r["stats"] for _, r in chosen), chosen[0][1]


def exact_moments(system, gains, T: float, p, e0, steps: int):
    """What a Monte Carlo of one design is compared with: the exact ``E[(x_hat_k - x_k)_c^2]``
    ``(steps + 1, n)`` from a deterministic error ``e0``, the diagonal of the steady state of eq.
    (21) (None when the error system is not MS stable) and the MS tests."""
    dyn = error_dynamics(system, gains, T)
    ms = ms_convergence(dyn, p)
    steady = np.diag(steady_state(dyn, p).V_x) if ms.holds else None
    return state_error_moments(dyn, p, e0, steps), steady, ms


def verdict_rows(zs: list[float], zgs: list[float], se_note: str) -> list[Row]:
    """Our consistency checks of an experiment's Monte Carlo (the paper prints none, so the rows
    are derived): the largest ``|MC - exact| / SE`` of its unconditional comparisons (``zs``, with
    the standard errors ``se_note`` describes) and the largest ``|z|`` given the simulated modes
    (``zgs``), each against :data:`Z_MAX`."""
    def verdict(z: float) -> str:
        return f"below {Z_MAX:g}: the simulation agrees" if z < Z_MAX else \
            f"above {Z_MAX:g}: the simulation disagrees"

    return [
        Row(f"our check, Monte Carlo vs exact moments: largest |MC − exact| / SE ({len(zs)} "
            "comparisons)", float(max(zs)), None, "", f"{verdict(max(zs))}; {se_note}"),
        Row(f"our check, Monte Carlo given the simulated modes: largest |z| ({len(zgs)} "
            "comparisons)", float(max(zgs)), None, "",
            f"{verdict(max(zgs))}; window sums against Theorem 1's conditional mean and variance: "
            "mean 0, variance 1"),
    ]


def positive(a: np.ndarray) -> np.ndarray:
    """NaN where ``a <= 0`` (e.g. an exactly known zero initial error), so a log axis skips the
    point."""
    return np.where(np.asarray(a) > 0, a, np.nan)


def z_score(mc: float, se: float, exact: float) -> float:
    """``|mc - exact| / se`` for the report (0 or inf where ``se`` is 0)."""
    return abs(mc - exact) / se if se > 0 else (0.0 if mc == exact else np.inf)
