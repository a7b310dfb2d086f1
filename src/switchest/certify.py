"""Everything switchest can certify about a model file, in one report.

Each check returns a :class:`Check`: its verdict (True, False, or None where it
is inconclusive or does not apply), a margin where one is defined, a one-line
detail and the paper it comes from. ``switchest check --model M.toml`` prints
them; :func:`certify` returns them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .analysis import (
    combined_observability,
    critical_interval,
    cqlf,
    dwell_time_observability,
    impulsive_observer_search,
    joint_observability,
    jsr_bounds,
    mismatch_dynamics,
    mode_observability,
    ms_stable_iid,
    stable_mismatch_region,
)
from .discretize import mode_steps
from .modelfile import ModelSpec

__all__ = ["Check", "certify", "CHECKS"]


@dataclass(frozen=True)
class Check:
    """One certificate: ``verdict`` True/False, or None when inconclusive or not applicable."""

    name: str
    paper: str
    verdict: bool | None
    detail: str
    margin: float | None = None


def _period(spec: ModelSpec) -> float | None:
    if not spec.system.is_continuous:
        return spec.system.dt
    return spec.sampling.get("period", spec.sampling.get("tau_max"))


def _sampled_modes(spec: ModelSpec) -> np.ndarray | None:
    """The one-step transition matrices at the sampling period (A itself in discrete time)."""
    T = _period(spec)
    if T is None:
        return None
    return mode_steps(spec.system, T).F if spec.system.is_continuous else spec.system.A


def _modes_observable(spec: ModelSpec) -> Check:
    r = mode_observability(spec.system)
    bad = [i for i, ok in enumerate(r.observable) if not ok]
    detail = "every mode observable" if r.holds else (
        f"mode(s) {bad} unobservable (observable dimensions {list(map(int, r.n_observable))})")
    return Check("each mode observable", "Lee §II; Shankar Assumption 1; Wang §3.1", bool(r.holds), detail,
                 float(np.min(r.margin)))


def _joint(spec: ModelSpec) -> Check:
    if not spec.system.is_continuous or spec.system.n_modes < 2:
        return Check("joint observability of mode pairs", "Lee Assumption 1", None,
                     "applies to continuous-time systems with two or more modes")
    r = joint_observability(spec.system)
    detail = "rank [O_i O_j] = 2n for every pair" if r.holds else f"fails for pairs {list(r.failing_pairs)}"
    return Check("joint observability of mode pairs", "Lee Assumption 1", bool(r.holds), detail)


def _combined(spec: ModelSpec) -> Check:
    r = combined_observability(spec.system)
    return Check("combined observability W_S", "Wang Assumption 2", bool(r.holds),
                 f"rank W_S = {r.rank} of n = {spec.system.n_states}")


def _cqlf(spec: ModelSpec) -> Check:
    r = cqlf(spec.system.A, domain=spec.system.domain)
    detail = ("common quadratic Lyapunov function found: stable under arbitrary switching" if r.feasible
              else f"no CQLF ({r.solver_status}); not a proof of instability, see the JSR bounds")
    return Check(f"CQLF of the mode matrices ({spec.system.domain})", "Zhang eq. (13) / Lemma 3",
                 bool(r.feasible), detail, r.margin if r.feasible else None)


def _jsr(spec: ModelSpec) -> Check:
    F = _sampled_modes(spec)
    if F is None:
        return Check("joint spectral radius of the sampled modes", "beyond the papers", None,
                     "needs a sampling period")
    r = jsr_bounds(F)
    verdict = True if r.upper < 1 else (False if r.lower >= 1 else None)
    return Check("joint spectral radius of the sampled modes", "beyond the papers", verdict,
                 f"JSR in [{r.lower:.4g}, {r.upper:.4g}] (switching at the samples)", 1 - r.upper)


def _lemma1(spec: ModelSpec) -> Check:
    sw = spec.switching
    T = spec.sampling.get("period")
    tau_d = sw.get("min_dwell") if sw.get("kind") == "dwell" else (
        float(np.min(np.diff(sw["times"]))) if sw.get("kind") == "schedule" and len(sw["times"]) > 1 else None)
    if not spec.system.is_continuous or T is None or tau_d is None or not spec.system.has_measurement_noise:
        return Check("uniform observability under a dwell time", "Shankar Lemma 1", None,
                     "needs periodic sampling, a dwell-time switching model and measurement noise R")
    r = dwell_time_observability(spec.system, T, tau_d)
    detail = (f"tau_d = {tau_d:g} s vs h_bar T; printed lemma: {r.holds} (h = {r.h}, rho = {r.rho:.3g}); "
              f"corrected lemma: {r.holds_corrected} (h = {r.h_corrected}, rho = {r.rho_corrected:.3g})")
    return Check("uniform observability under a dwell time", "Shankar Lemma 1 (corrected)",
                 bool(r.holds_corrected), detail)


def _ms_iid(spec: ModelSpec) -> Check:
    F = _sampled_modes(spec)
    if spec.switching.get("kind") != "iid" or F is None:
        return Check("mean-square stability under i.i.d. modes", "Wang §2 / eq. (16)", None,
                     "applies to i.i.d. switching at the samples")
    r = ms_stable_iid(F, spec.switching["p"])
    return Check("mean-square stability under i.i.d. modes (open loop)", "Wang §2", bool(r.stable),
                 f"spectral radius of E[F kron F] = {r.radius:.4g}", 1 - r.radius)


def _filter_cqlf(spec: ModelSpec) -> Check:
    sys = spec.system
    if sys.is_continuous or not sys.has_measurement_noise:
        return Check("CQLF of the filter error matrices Lambda_i", "Zhang Lemma 3 / Theorem 2", None,
                     "applies to discrete-time systems with measurement noise")
    r = cqlf(mismatch_dynamics(sys).Lambda, domain="discrete")
    detail = ("the mode-based Kalman filter's bias is stable under any matched mode sequence" if r.feasible
              else f"no CQLF for the Lambda_i ({r.solver_status})")
    return Check("CQLF of the filter error matrices Lambda_i", "Zhang Lemma 3 / Theorem 2", bool(r.feasible),
                 detail, r.margin if r.feasible else None)


def _mismatch(spec: ModelSpec) -> Check:
    sys = spec.system
    if sys.is_continuous or not sys.has_measurement_noise or sys.n_modes < 2:
        return Check("tolerable mode mismatches", "Zhang Algorithm 2", None,
                     "applies to discrete-time systems with measurement noise and two or more modes")
    mask = stable_mismatch_region(sys)
    allowed = [(int(i), int(q)) for i, q in zip(*np.nonzero(mask)) if i != q]
    return Check("tolerable mode mismatches", "Zhang Algorithm 2", True,
                 f"filter mode i may be used in true mode q for (i, q) in {allowed or 'none'} (0-based)")


def _impulsive(spec: ModelSpec) -> Check:
    sw, smp = spec.switching, spec.sampling
    if not spec.system.is_continuous or "tau_min" not in smp and "period" not in smp:
        return Check("impulsive observer under aperiodic sampling", "Etienne Theorem 8", None,
                     "needs a continuous-time system and sampling bounds")
    dwell = sw.get("tau_a") if sw.get("kind") == "average-dwell" else sw.get("min_dwell")
    if dwell is None:
        return Check("impulsive observer under aperiodic sampling", "Etienne Theorem 8", None,
                     "needs an (average) dwell-time switching model")
    lo, hi = smp.get("tau_min", smp.get("period")), smp.get("tau_max", smp.get("period"))
    r = impulsive_observer_search(spec.system, lo, hi, dwell)
    best = r.best
    detail = (f"gains found with guaranteed decay rate beta = {best.beta:.4g} for sampling in [{lo:g}, {hi:g}], "
              f"dwell {dwell:g} (corrected LMIs; scalars searched)" if best.feasible
              else "no certificate with a positive rate (the LMIs are sufficient conditions only)")
    return Check("impulsive observer under aperiodic sampling", "Etienne Theorem 8 (corrected)",
                 bool(best.feasible), detail, best.beta if best.feasible else None)


def _wang_critical_interval(spec: ModelSpec) -> Check:
    """Critical switching interval of Wang et al. Theorem 3 for i.i.d. modes, and the sampling period against it.

    Reports eq. (20) as the paper computes it (``q_max h(T) = 1``; §6's ``T_max = 0.7365``,
    printed truncated, hence shown truncated to four decimals with the full value beside it),
    the exact MS threshold for fast sub-observers and, with several sub-states, Example 2's
    per-sub-state thresholds. The verdict compares the sampling period with the exact
    threshold: eq. (20) is not a proven bound (for Example 1 it gives 0.0279, below the
    paper's own T = 0.03, which is MS convergent); the detail compares it with both.
    """
    name, paper = "critical switching interval T_max (i.i.d. modes)", "Wang Theorem 3, eq. (20); Example 2"
    system, switching = spec.system, spec.switching
    if not system.is_continuous or switching.get("kind") != "iid":
        return Check(name, paper, None, "applies to continuous-time systems with i.i.d. modes at the switching instants")
    if system.n_inputs or np.any(system.Q != 0):
        return Check(name, paper, None, "applies to Wang et al.'s model (1): no input and no process noise")
    try:
        ci = critical_interval(system, switching["p"])
    except ValueError as exc:  # e.g. Assumption 2(b): the modes' observable subspaces do not span the state
        return Check(name, paper, None, f"not applicable: {exc}")
    truncated = np.floor(ci.theorem3 * 1e4) / 1e4
    eq20 = f"eq. (20) T_max = {truncated:.4f} ({ci.theorem3:.6f}, q_max = {ci.q_max:.4g})"
    exact = f"exact MS threshold {ci.fast_observer:.4f}"
    per = "" if ci.per_block.size < 2 else "; per sub-state " + ", ".join(f"{v:.4f}" for v in ci.per_block)
    T = spec.sampling.get("period")
    if T is None:
        return Check(name, paper, None, f"{eq20}; {exact}{per}; no sampling period to compare")
    verdict = bool(T < ci.fast_observer)
    detail = (f"T = {T:g} {'<' if T < ci.theorem3 else '>='} {eq20}; T {'<' if verdict else '>='} {exact} "
              f"(fast sub-observers are MS convergent below it){per}")
    return Check(name, paper, verdict, detail, float(1.0 - T / ci.fast_observer))


CHECKS: list[Callable[[ModelSpec], Check]] = [
    _modes_observable, _joint, _combined, _cqlf, _jsr, _lemma1, _ms_iid, _filter_cqlf, _mismatch, _impulsive,
    _wang_critical_interval,
]


def certify(spec: ModelSpec) -> list[Check]:
    """Run every check on the model; a check that fails to run says why instead of stopping the rest."""
    out = []
    for check in CHECKS:
        try:
            out.append(check(spec))
        except (ValueError, np.linalg.LinAlgError) as exc:
            name = check.__name__.strip("_").replace("_", " ")
            out.append(Check(name, "", None, f"could not be evaluated: {exc}"))
    return out
