"""Everything switchest can certify about a model file, in one report.

Each check returns a :class:`Check`: its verdict (True, False, or None where it
is inconclusive or does not apply), a margin where one is defined, a one-line
detail, the paper it comes from and the estimation methods whose guarantee it is a
condition of. ``switchest check --model M.toml`` prints them; :func:`certify` returns
them, :func:`method_verdicts` what they say of each method.

Every margin has one sign: positive when the condition holds, zero or negative when it
fails (how far it is from the threshold, in the check's own quantity: :math:`1 - \\mathrm{JSR}`, the
noise bound allowed minus the one given, a PBH singular value, a decay rate).

Every check finishes in bounded time and memory: a check whose estimated size is
beyond its budget (an LMI of many states, the :math:`n^2 \\times n^2` second-moment matrices
on a grid) is skipped with a note saying what it needs and the limit, and the JSR
of a large model is bounded in the spectral norm with fewer products. Verdicts
compare a computed number with a threshold beyond that number's rounding.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ._checks import memory_limit
from ._threads import one_blas_thread
from .analysis import (
    combined_observability,
    cqlf,
    critical_interval,
    decay_observer_gains,
    dwell_time_observability,
    impulsive_observer_search,
    joint_observability,
    jsr_bounds,
    lee_assumptions,
    lee_windows,
    mismatch_dynamics,
    mode_observability,
    ms_stable_iid,
    stable_mismatch_region,
)
from .analysis._lmi import lmi_nbytes
from .analysis.subsystem_observers import critical_interval_nbytes
from .discretize import mode_steps
from .estimators.registry import METHOD_NAMES
from .modelfile import ModelSpec
from .switching import IID, AverageDwell, Dwell, Schedule

__all__ = ["Check", "certify", "CHECKS", "method_verdicts"]


@dataclass(frozen=True)
class Check:
    """One certificate: ``verdict`` True/False, or None when inconclusive or not applicable.

    ``margin`` (where one is defined) is positive when the condition holds and at most zero
    when it fails; ``methods`` names the registered estimation methods
    (:data:`~switchest.estimators.registry.METHOD_NAMES`) whose guarantee needs it.
    """

    name: str
    paper: str
    verdict: bool | None
    detail: str
    margin: float | None = None
    methods: tuple[str, ...] = ()


#: Memory one check may plan for its largest solve (or its Kronecker matrices): 1 GiB, a
#: CQLF of about 50 states with two modes, solved in a minute or two (its time grows like
#: n^6); never more than :func:`switchest._checks.memory_limit`.
_BUDGET = 2**30
#: Work for the JSR's products, in flops (~25 n^3 per product: a product, its eigenvalues
#: and singular values): 20000 products up to n = 20, 25 at n = 200.
_JSR_FLOPS = 5e9
_JSR_BISECTIONS = 16  # CQLF solves of the ellipsoid bisection (rtol 1e-4 from a 2x bracket)
#: Relative accuracy of :func:`critical_interval`'s thresholds (Brent's method to 1e-13,
#: absolute and relative); a period closer than ten times that is not compared.
_CROSSING_RTOL = 1e-12


def _limit() -> float:
    return min(memory_limit(), _BUDGET)


def _skip(need: float, what: str) -> str | None:
    """The note of a check too large to run (None when it fits the budget)."""
    if need <= _limit():
        return None
    return f"skipped: {what} needs ~{_gib(need)}; limit {_gib(_limit())}"


def _gib(nbytes: float) -> str:
    gib = nbytes / 2**30
    return f"{gib:.0f} GiB" if gib >= 100 else f"{gib:.3g} GiB"


def _cqlf_skip(spec: ModelSpec, what: str) -> str | None:
    n, L = spec.system.n_states, spec.system.n_modes
    return _skip(lmi_nbytes(n, L + 1), f"an n = {n} {what}")


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
    # the PBH margin of each mode's observable part; an unobservable mode is at zero
    # distance from unobservability (its PBH singular value is zero to the test's tolerance)
    margin = float(np.min(r.margin)) if r.holds else 0.0
    return Check("each mode observable", "Lee §II; Shankar Assumption 1; Wang §3.1", bool(r.holds),
                 detail, margin)


def _joint(spec: ModelSpec) -> Check:
    if not spec.system.is_continuous or spec.system.n_modes < 2:
        return Check("joint observability of mode pairs", "Lee Assumption 1", None,
                     "applies to continuous-time systems with two or more modes")
    r = joint_observability(spec.system)
    detail = ("rank [O_i O_j] = 2n for every pair" if r.holds
              else f"fails for pairs {list(r.failing_pairs)}")
    return Check("joint observability of mode pairs", "Lee Assumption 1", bool(r.holds), detail)


def _lee(spec: ModelSpec) -> Check:
    """Lee, Ping & Shim Assumption 1, conditions (3)-(4), Assumption 3 for the ``[noise]`` bounds.

    Reads from the noise table ``v_max`` (eq. (2); without it the check does not apply),
    ``x_min`` (a lower bound on :math:`|x(t)|`, at which (3)-(4) are evaluated), ``u_max``
    (needed when the system has inputs) and the detector design where given: the
    windows ``delta``, ``Delta`` (otherwise the smallest multiples of the sampling
    period satisfying (3) and (4), :func:`~switchest.analysis.lee_windows`) and
    ``observer_decay`` (gains of
    :func:`~switchest.analysis.min_distance_design.decay_observer_gains`; otherwise
    :func:`~switchest.analysis.min_distance_design.default_observer_gains`). Assumption 3 is
    checked against the switching model's dwell time (:func:`_lee_dwell`). The margin is
    :math:`\\mathrm{v\\_max\\_allowed} - \\mathrm{v\\_max}`: positive exactly when (3) and (4)
    hold.
    """
    name = "Lee's assumptions for the given noise bounds"
    paper = "Lee Assumptions 1-3, conditions (3)-(4)"
    system, noise = spec.system, spec.noise
    if not system.is_continuous or system.n_modes < 2 or "v_max" not in noise:
        return Check(name, paper, None, "applies to continuous-time systems with two or more modes "
                                        "and a noise bound noise.v_max")
    needed = ["x_min"] + (["u_max"] if system.n_inputs else [])
    missing = [k for k in needed if k not in noise]
    if missing:
        return Check(name, paper, None, f"needs noise.{missing[0]} besides noise.v_max")
    modes = mode_observability(system)
    if not modes.holds:
        unobservable = [i for i, ok in enumerate(modes.observable) if not ok]
        return Check(name, paper, False, f"mode(s) {unobservable} unobservable: Lee §II needs "
                                         "every mode observable")
    bounds = {"u_max": noise.get("u_max", 0.0), "v_max": noise["v_max"], "x_min": noise["x_min"]}
    decay = noise.get("observer_decay")
    gains = None if decay is None else decay_observer_gains(system, decay)
    dwell, dwell_verdict, dwell_note = _lee_dwell(spec)
    if "delta" in noise and "Delta" in noise:
        delta, Delta, windows = noise["delta"], noise["Delta"], "given"
    else:
        t_max = dwell.get("min_dwell", 10.0)
        w = lee_windows(system, **bounds, observer_gains=gains, t_max=t_max,
                        step=spec.sampling.get("period"))
        if not w.holds:
            failing = "(3)" if w.delta is None else f"(4) (with delta = {w.delta:g} s)"
            return Check(name, paper, False, f"no window up to {t_max:g} s satisfies {failing} at "
                                             f"v_max = {bounds['v_max']:g}, "
                                             f"x_min = {bounds['x_min']:g}")
        delta, Delta, windows = w.delta, w.Delta, "the smallest satisfying (3)-(4)"
    a = lee_assumptions(system, **bounds, delta=delta, Delta=Delta, observer_gains=gains, **dwell)
    k = a.constants
    a3 = a.assumption3
    if a3 is not None:
        dwell_verdict = a3.holds
        dwell_note = f"dwell {a3.lhs:g} s {'>' if a3.holds else '<='} delta + Delta = {a3.rhs:g} s"
    conditions = "hold" if a.condition3.holds and a.condition4.holds else (
        "fail: " + ", ".join(c for c, r in (("(3)", a.condition3), ("(4)", a.condition4))
                             if not r.holds))
    detail = (f"Assumption 1 {'holds' if a.assumption1.holds else 'FAILS'} "
              f"(PBH margin {a.assumption1.margin:.3g}); "
              f"(3)-(4) {conditions} at v_max = {bounds['v_max']:g}, "
              f"noise bound allowed {a.v_max_allowed:.4g} "
              f"(u_max = {bounds['u_max']:g}, x_min = {bounds['x_min']:g}; "
              f"delta = {delta:g} s, Delta = {Delta:g} s "
              f"{windows}; observer decay {k.lambda_hat:.4g}, E_hat(delta) = {k.E_hat:.4g}); "
              f"Assumption 3: {dwell_note}")
    verdict = (a.assumption1.holds and a.condition3.holds and a.condition4.holds
               and dwell_verdict is not False)
    margin = a.v_max_allowed - bounds["v_max"]
    # the noise-bound margin is that of (3)-(4); when Assumption 1 or 3 fails instead, it
    # does not measure the failure (the detail says which)
    return Check(name, paper, bool(verdict), detail, margin if (margin > 0) == verdict else None)


def _lee_dwell(spec: ModelSpec) -> tuple[dict, bool | None, str]:
    """What bounds the dwell time for Lee Assumption 3.

    Returns keywords for ``lee_assumptions``, the verdict and a note.

    A dwell model gives ``min_dwell``, a schedule its signal; switching at the samples
    (``iid``, ``markov``) dwells at least one sampling interval; continuous-time Markov
    and average-dwell models have no minimum dwell, so Assumption 3 fails.
    """
    sw = spec.switching
    if isinstance(sw, Dwell):
        return {"min_dwell": sw.min_dwell}, None, ""
    if isinstance(sw, Schedule):
        return {"signal": sw.signal}, None, ""
    shortest = spec.sampling.get("period", spec.sampling.get("tau_min"))
    if sw is not None and sw.at_samples and shortest is not None:
        return {"min_dwell": shortest}, None, ""
    if sw is None:
        return {}, None, "not checked (no switching model)"
    return {}, False, f"fails ({sw.kind} switching has no minimum dwell time)"


def _combined(spec: ModelSpec) -> Check:
    r = combined_observability(spec.system)
    return Check("combined observability W_S", "Wang Assumption 2", bool(r.holds),
                 f"rank W_S = {r.rank} of n = {spec.system.n_states}")


def _cqlf(spec: ModelSpec) -> Check:
    name = f"CQLF of the mode matrices ({spec.system.domain})"
    skipped = _cqlf_skip(spec, "CQLF")
    if skipped:
        return Check(name, "Zhang eq. (13) / Lemma 3", None, skipped)
    r = cqlf(spec.system.A, domain=spec.system.domain)
    detail = ("common quadratic Lyapunov function found: stable under arbitrary switching"
              if r.holds
              else f"no CQLF ({r.solver_status}); not a proof of instability, see the JSR bounds")
    return Check(name, "Zhang eq. (13) / Lemma 3", bool(r.holds), detail,
                 r.margin if r.holds else None)


def _jsr(spec: ModelSpec) -> Check:
    """JSR bounds; for a large model in the spectral norm (no CQLF bisection), fewer products.

    The bounds are rounded outward (:func:`~switchest.analysis.jsr_bounds`), so comparing
    them with 1 is robust to rounding.
    """
    F = _sampled_modes(spec)
    if F is None:
        return Check("joint spectral radius of the sampled modes", "beyond the papers", None,
                     "needs a sampling period")
    n, L = spec.system.n_states, spec.system.n_modes
    quadratic = _JSR_BISECTIONS * lmi_nbytes(n, L + 1) <= _limit()  # the CQLF norm, if it fits
    budget = int(min(20000, max(L, _JSR_FLOPS / (25.0 * n**3))))
    r = jsr_bounds(F, quadratic=quadratic, max_products=budget)
    verdict = True if r.upper < 1 else (False if r.lower >= 1 else None)
    how = "" if quadratic else (f"; spectral norm, {r.n_products} products: the CQLF bisection "
                                f"of an n = {n} model is beyond the LMI budget")
    return Check("joint spectral radius of the sampled modes", "beyond the papers", verdict,
                 f"JSR in [{r.lower:.4g}, {r.upper:.4g}] (switching at the samples{how})",
                 1 - r.upper)


def _lemma1(spec: ModelSpec) -> Check:
    T = spec.sampling.get("period")
    tau_d = None if spec.switching is None else spec.switching.dwell_time
    if (not spec.system.is_continuous or T is None or tau_d is None
            or not spec.system.has_measurement_noise):
        return Check("uniform observability under a dwell time", "Shankar Lemma 1", None,
                     "needs periodic sampling, a dwell-time switching model and measurement "
                     "noise R")
    r = dwell_time_observability(spec.system, T, tau_d)
    detail = (f"tau_d = {tau_d:g} s vs h_bar T; "
              f"printed lemma: {r.holds} (h = {r.h}, rho = {r.rho:.3g}); "
              f"corrected lemma: {r.holds} (h = {r.h_corrected}, rho = {r.rho_corrected:.3g})")
    return Check("uniform observability under a dwell time", "Shankar Lemma 1 (corrected)",
                 bool(r.holds), detail)


def _ms_iid(spec: ModelSpec) -> Check:
    F = _sampled_modes(spec)
    if not isinstance(spec.switching, IID) or F is None:
        return Check("mean-square stability under i.i.d. modes", "Wang §2 / eq. (16)", None,
                     "applies to i.i.d. switching at the samples")
    r = ms_stable_iid(F, spec.switching.p)
    return Check("mean-square stability under i.i.d. modes (open loop)", "Wang §2", bool(r.holds),
                 f"spectral radius of E[F kron F] = {r.radius:.4g}", 1 - r.radius)


def _filter_cqlf(spec: ModelSpec) -> Check:
    sys = spec.system
    if sys.is_continuous or not sys.has_measurement_noise:
        return Check("CQLF of the filter error matrices Lambda_i", "Zhang Lemma 3 / Theorem 2",
                     None, "applies to discrete-time systems with measurement noise")
    skipped = _cqlf_skip(spec, "CQLF of the Lambda_i")
    if skipped:
        return Check("CQLF of the filter error matrices Lambda_i", "Zhang Lemma 3 / Theorem 2",
                     None, skipped)
    r = cqlf(mismatch_dynamics(sys).Lambda, domain="discrete")
    detail = ("the mode-based Kalman filter's bias is stable under any matched mode sequence"
              if r.holds else f"no CQLF for the Lambda_i ({r.solver_status})")
    return Check("CQLF of the filter error matrices Lambda_i", "Zhang Lemma 3 / Theorem 2",
                 bool(r.holds), detail, r.margin if r.holds else None)


def _mismatch(spec: ModelSpec) -> Check:
    sys = spec.system
    if sys.is_continuous or not sys.has_measurement_noise or sys.n_modes < 2:
        return Check("tolerable mode mismatches", "Zhang Algorithm 2", None,
                     "applies to discrete-time systems with measurement noise and two or more "
                     "modes")
    skipped = _cqlf_skip(spec, "CQLF of the A_i (Algorithm 2, step 1)")
    if skipped:
        return Check("tolerable mode mismatches", "Zhang Algorithm 2", None, skipped)
    mask = stable_mismatch_region(sys)
    allowed = [(int(i), int(q)) for i, q in zip(*np.nonzero(mask)) if i != q]
    return Check("tolerable mode mismatches", "Zhang Algorithm 2", True,
                 f"filter mode i may be used in true mode q for (i, q) in {allowed or 'none'} "
                 "(0-based)")


def _impulsive(spec: ModelSpec) -> Check:
    sw, smp = spec.switching, spec.sampling
    if not spec.system.is_continuous or "tau_min" not in smp and "period" not in smp:
        return Check("impulsive observer under aperiodic sampling", "Etienne Theorem 8", None,
                     "needs a continuous-time system and sampling bounds")
    dwell = (sw.tau_a if isinstance(sw, AverageDwell)
             else sw.min_dwell if isinstance(sw, Dwell) else None)
    if dwell is None:
        return Check("impulsive observer under aperiodic sampling", "Etienne Theorem 8", None,
                     "needs an (average) dwell-time switching model")
    lo, hi = smp.get("tau_min", smp.get("period")), smp.get("tau_max", smp.get("period"))
    n, L = spec.system.n_states, spec.system.n_modes
    # blocks of up to 2n (the jump LMIs (7)), about two per mode
    skipped = _skip(lmi_nbytes(2 * n, 2 * L + 1), f"an n = {n} impulsive-observer LMI (Theorem 8)")
    if skipped:
        return Check("impulsive observer under aperiodic sampling", "Etienne Theorem 8", None,
                     skipped)
    r = impulsive_observer_search(spec.system, lo, hi, dwell)
    best = r.best
    detail = (f"gains found with guaranteed decay rate beta = {best.beta:.4g} "
              f"for sampling in [{lo:g}, {hi:g}], "
              f"dwell {dwell:g} (corrected LMIs; scalars searched)" if best.holds
              else "no certificate with a positive rate (the LMIs are sufficient conditions only)")
    return Check("impulsive observer under aperiodic sampling", "Etienne Theorem 8 (corrected)",
                 bool(best.holds), detail, best.beta if best.holds else None)


def _wang_critical_interval(spec: ModelSpec) -> Check:
    """Critical switching interval (Wang et al. Theorem 3, i.i.d. modes) vs the sampling period.

    Reports eq. (20) as the paper computes it (:math:`q_{\\max} h(T) = 1`; §6's
    :math:`T_{\\max} = 0.7365`, printed truncated, hence shown truncated to four decimals with
    the full value beside it),
    the exact MS threshold for fast sub-observers and, with several sub-states, Example 2's
    per-sub-state thresholds. The verdict compares the sampling period with the exact
    threshold: eq. (20) is not a proven bound (for Example 1 it gives 0.0279, below the
    paper's own :math:`T = 0.03`, which is MS convergent); the detail compares it with both.
    """
    name = "critical switching interval T_max (i.i.d. modes)"
    paper = "Wang Theorem 3, eq. (20); Example 2"
    system, switching = spec.system, spec.switching
    if not system.is_continuous or not isinstance(switching, IID):
        return Check(name, paper, None, "applies to continuous-time systems with i.i.d. modes at "
                                        "the switching instants")
    if system.n_inputs or np.any(system.Q != 0):
        return Check(name, paper, None, "applies to Wang et al.'s model (1): no input and no "
                                        "process noise")
    skipped = _skip(critical_interval_nbytes(system),
                    f"the critical interval of an n = {system.n_states} model (its n^2 x n^2 "
                    "second-moment matrices on a grid of T)")
    if skipped:
        return Check(name, paper, None, skipped)
    try:
        ci = critical_interval(system, switching.p)
    except ValueError as exc:
        # e.g. Assumption 2(b): the modes' observable subspaces do not span the state
        return Check(name, paper, None, f"not applicable: {exc}")
    truncated = np.floor(ci.printed_t_max * 1e4) / 1e4
    eq20 = f"eq. (20) T_max = {truncated:.4f} ({ci.printed_t_max:.6f}, q_max = {ci.q_max:.4g})"
    exact = f"exact MS threshold {ci.fast_observer:.4f}"
    per = ("" if ci.per_block.size < 2
           else "; per sub-state " + ", ".join(f"{v:.4f}" for v in ci.per_block))
    T = spec.sampling.get("period")
    if T is None:
        return Check(name, paper, None, f"{eq20}; {exact}{per}; no sampling period to compare")
    if abs(T - ci.fast_observer) <= _CROSSING_RTOL * ci.fast_observer:
        return Check(name, paper, None,
                     f"T = {T:g} equals the {exact} to its accuracy; {eq20}{per}",
                     float(1.0 - T / ci.fast_observer))
    verdict = bool(T < ci.fast_observer)
    detail = (f"T = {T:g} {'<' if T < ci.printed_t_max else '>='} {eq20}; "
              f"T {'<' if verdict else '>='} {exact} "
              f"(fast sub-observers are MS convergent below it){per}")
    return Check(name, paper, verdict, detail, float(1.0 - T / ci.fast_observer))


CHECKS: list[Callable[[ModelSpec], Check]] = [
    _modes_observable, _joint, _lee, _combined, _cqlf, _jsr, _lemma1, _ms_iid, _filter_cqlf,
    _mismatch, _impulsive, _wang_critical_interval,
]

#: The methods whose guarantee each check is a condition of (those of the paper the method
#: implements, :mod:`switchest.estimators.registry`); checks of the system alone (the CQLF
#: and JSR of the modes, open-loop mean-square stability) name none.
_METHODS: dict[Callable[[ModelSpec], Check], tuple[str, ...]] = {
    # Lee §II; not switch-time: Shankar's own boost converter has an unobservable mode, and
    # its guarantee is Lemma 1's observability over a dwell time
    _modes_observable: ("min-distance",),
    _joint: ("min-distance",),  # Lee Assumption 1
    _lee: ("min-distance",),  # Lee Assumptions 1-3, (3)-(4)
    _combined: ("rsls",),  # Wang Assumption 2
    _lemma1: ("switch-time",),  # Shankar Lemma 1
    _filter_cqlf: ("kalman",),  # Zhang Theorem 2: the mode-based filter's bias
    _impulsive: ("impulsive",),  # Etienne Theorem 8
    _wang_critical_interval: ("rsls",),  # Wang Theorem 3
}


def certify(spec: ModelSpec) -> list[Check]:
    """Run every check on the model; a check that fails to run says why, the rest go on.

    BLAS runs on one thread (as in the experiment runner): the checks' matrices are small
    or their work sequential, and threads on a busy machine were measured to slow them
    tenfold.
    """
    out = []
    with one_blas_thread():
        for check in CHECKS:
            methods = _METHODS.get(check, ())
            try:
                out.append(replace(check(spec), methods=methods))
            except (ValueError, np.linalg.LinAlgError) as exc:
                name = check.__name__.strip("_").replace("_", " ")
                out.append(Check(name, "", None, f"could not be evaluated: {exc}",
                                 methods=methods))
    return out


def method_verdicts(checks: Sequence[Check]) -> dict[str, bool | None]:
    """What ``checks`` (:func:`certify`'s) say of each method whose conditions they include.

    Returns
    -------
    dict
        For each registered method that some check names (:attr:`Check.methods`), in the
        registry's order: True when every one of its conditions holds, False when one fails,
        None otherwise (one inconclusive or not applicable, none failing). Methods that no
        check names are left out: nothing here certifies them.
    """
    out: dict[str, bool | None] = {}
    for name in METHOD_NAMES:
        verdicts = [c.verdict for c in checks if name in c.methods]
        if verdicts:
            out[name] = (False if False in verdicts
                         else True if all(v is True for v in verdicts) else None)
    return out
