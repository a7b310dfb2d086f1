"""The bake-off: every applicable estimator on the same simulated data (beyond the papers).

Five cases — the boost converter and the vehicle of Shankar et al., a Markov
jump system whose switches fall anywhere between samples, a system with an
unobservable mode, and the FSK phasor of :mod:`switchest.models.lee` with
Gaussian noise — and for each the methods that apply to it, compared on state
RMSE, mode accuracy, switching-time error and run time, all on the same trials
(a task simulates one block of a case once and runs every method on it). Lee
et al.'s minimum-distance detector applies only where their Assumption 1 (joint
observability of every mode pair) holds: of these cases, only the FSK phasor.

No paper prints these numbers: every row is derived. Each RMSE carries its standard error
over the trials (the per-trial mean squared errors of the whole state are summed with
their squares for it).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..analysis import joint_observability, lee_assumptions
from ..estimators.min_distance import match_detections
from ..estimators.registry import get_method
from ..modelfile import ModelSpec
from ..models.catalog import catalog
from ..models.lee import LEE_SCENARIO
from ..plotting import bars
from ..simulate import simulate
from ..switching import Dwell, MarkovContinuous, Schedule
from ..system import SwitchedLinearSystem
from .registry import Experiment, Row, Summary, register
from .scoring import blocks, merge_groups, rmse_and_se, score
from .verdict import Z_95


@dataclass(frozen=True)
class Contender:
    """One bake-off row: a registered method (:func:`~switchest.estimators.get_method`) with
    the options it runs with here.

    ``options`` go to the method's :meth:`~switchest.estimators.Method.build` (its user
    options, or its estimator's constructor's); ``true_instants`` also gives ``run`` the true
    switching instants (the clairvoyant floor); ``smooth`` runs the estimator's fixed-interval
    smoother instead of its filter (given the whole record: offline); ``seeded`` gives it the
    option ``seed``, drawn from the task's generator (the particle filter)."""

    key: str
    method: str
    label: str
    options: tuple[tuple[str, object], ...] = ()
    true_instants: bool = False
    smooth: bool = False
    seeded: bool = False

    def __post_init__(self) -> None:
        get_method(self.method)  # a registered method, or a ValueError naming them


FSK_NOISE_STD = 0.03  # measurement noise of the FSK case, per component
FSK_V_MAX = 3 * FSK_NOISE_STD  # the noise bound the detector is told
# Lee et al.'s detector with the lee-detection design (the FSK phasor is its system): windows
# delta = 0.25 s, Delta = 1 s, gains L_i = A_i + 40 I (so A_i - L_i C = -40 I) and the noise
# bound v_max = 3 sigma of the FSK case
_DETECTOR = (("v_max", FSK_V_MAX), ("delta", LEE_SCENARIO.delta), ("Delta", LEE_SCENARIO.Delta),
             ("u_max", LEE_SCENARIO.u_max), ("observer_gains", LEE_SCENARIO.observer_gains))
_CONTENDERS = (
    Contender("clairvoyant", "kalman", "mode KF, true switch times", true_instants=True),
    Contender("kalman-at-samples", "kalman", "mode KF, switches at samples"),
    Contender("switch-time", "switch-time", "switch-time KF (g = 5)", (("grid", 5),)),
    Contender("switch-time-refined", "switch-time", "switch-time KF refined (g = 2)",
              (("grid", 2), ("refine", True))),
    Contender("switch-time-marginal", "switch-time", "switch-time KF marginalized (g = 5)",
              (("grid", 5), ("switch_time", "marginal"))),
    Contender("imm", "imm", "IMM"),
    Contender("imm-between", "imm-between", "IMM on the switching instants (g = 5)",
              (("grid", 5),)),
    Contender("gpb1", "gpb1", "GPB1"),
    Contender("gpb2", "gpb2", "GPB2"),
    Contender("rbpf", "rbpf", "RBPF (1 000 particles, optimal proposal)",
              (("particles", 1000), ("proposal", "optimal")), seeded=True),
    Contender("imm-smoothed", "imm", "IMM smoothed (offline)", smooth=True),
    Contender("gpb2-smoothed", "gpb2", "GPB2 smoothed (offline)", smooth=True),
    Contender("imm-between-smoothed", "imm-between",
              "IMM on the switching instants smoothed (offline)", (("grid", 5),), smooth=True),
    Contender("imm-ev1", "imm-ev1", "IMM-EV1 (g = 5)", (("grid", 5),)),
    Contender("imm-ev1-mixture", "imm-ev1", "IMM-EV1 marginalized, mixture (g = 5)",
              (("grid", 5), ("switch_time", "marginal"), ("estimate", "mixture"))),
    Contender("min-distance", "min-distance", "min-distance detector (Lee)", _DETECTOR),
)
CONTENDERS = {c.key: c for c in _CONTENDERS}
"""The bake-off's rows by key, in the order they are shown."""
METHODS = tuple(CONTENDERS)
_LABELS = {c.key: c.label for c in _CONTENDERS}


def _markov_jump() -> ModelSpec:
    """Two lightly damped oscillators of different frequency, one sensor, and a third mode that
    drifts; continuous-time Markov switching (mean dwell 0.8 s) at arbitrary instants."""
    A = np.array([[[0.0, 2.0], [-2.0, -0.2]], [[0.0, 5.0], [-5.0, -0.3]],
                  [[-0.5, 0.0], [0.0, -0.5]]])
    B = np.array([[[0.0], [1.0]], [[0.0], [1.0]], [[1.0], [0.0]]])
    sys = SwitchedLinearSystem.continuous(A, B, [[1.0, 0.0]], Q=0.01 * np.eye(2), R=[[0.01]])
    rates = np.array([[-1.25, 0.75, 0.5], [0.5, -1.25, 0.75], [0.75, 0.5, -1.25]])
    return ModelSpec(sys, sampling={"period": 0.2, "duration": 20.0},
                     switching=MarkovContinuous(rates),
                     initial=(np.zeros(2), np.eye(2)), noise={"u_max": 1.0})


def _unobservable_mode() -> ModelSpec:
    """A damped oscillator whose sensor drops out in mode 1 (C = 0): that mode is unobservable;
    dwell times in [1, 2] s."""
    A = np.array([[0.0, 2.0], [-2.0, -0.3]])
    C = np.array([[[1.0, 0.0]], [[0.0, 0.0]]])
    sys = SwitchedLinearSystem.continuous(np.stack([A, A]), np.array([[0.0], [1.0]]), C,
                                          Q=0.02 * np.eye(2), R=[[0.01]])
    return ModelSpec(sys, sampling={"period": 0.25, "duration": 30.0},
                     switching=Dwell(sys.n_modes, 1.0, 2.0),
                     initial=(np.zeros(2), np.eye(2)), noise={"u_max": 1.0})


def _fsk_phasor(lee: ModelSpec) -> ModelSpec:
    """Lee's FSK phasor (catalog ``lee-fsk``) with Gaussian noise: R = 0.03^2 I, Q = 1e-4 I, T = 10
    ms."""
    s = lee.system
    noisy = SwitchedLinearSystem.continuous(s.A, s.B, s.C, Q=1e-4 * np.eye(s.n_states),
                                            R=FSK_NOISE_STD**2 * np.eye(s.n_outputs))
    return replace(lee, system=noisy, sampling={**lee.sampling, "period": 0.01})


def cases() -> dict[str, tuple[ModelSpec, np.ndarray]]:
    """The bake-off systems and their constant inputs."""
    cat = catalog()
    return {
        "boost converter": (cat["shankar-boost"], np.array([100.0])),
        "vehicle": (cat["shankar-vehicle"], np.array([1.0])),
        "Markov jump": (_markov_jump(), np.array([1.0])),
        "unobservable mode": (_unobservable_mode(), np.array([1.0])),
        "FSK phasor": (_fsk_phasor(cat["lee-fsk"]), np.array([LEE_SCENARIO.u_max])),
    }


def min_distance_inapplicable(spec: ModelSpec) -> str | None:
    """Why Lee et al.'s detector does not apply to a case, or None when it does.

    It needs a continuous-time system whose mode pairs are jointly observable (Lee
    et al. Assumption 1, which implies every mode observable).
    """
    if not spec.system.is_continuous:
        return "continuous-time systems only (Lee et al. eq. (1))"
    joint = joint_observability(spec.system)
    if not joint.holds:
        pairs = ", ".join(f"({i}, {j})" for i, j in joint.failing_pairs)
        return f"Lee Assumption 1 fails: mode pairs {pairs} not jointly observable (0-based)"
    return None


def _tasks(p: dict) -> list[dict]:
    """One task per (trial block, case): the block is simulated once and every method that
    applies to the case runs on it."""
    out = []
    all_cases = cases()
    for b, n in blocks(p["trials"], p["block_size"]):
        for case in p["cases"]:
            applies = min_distance_inapplicable(all_cases[case][0]) is None
            methods = [{"method": m} for m in METHODS if m != "min-distance" or applies]
            out.append({"case": case, "block": b, "trials": n, "duration": p["durations"][case],
                        "variants": methods})
    return out


def _run(cfg: dict, rng: np.random.Generator) -> dict:
    spec, u = cases()[cfg["case"]]
    t = spec.sample_times(min(cfg["duration"], spec.sampling["duration"]))
    traj = simulate(spec.system, lambda r: spec.signal(r, t), t, spec.initial, u=u,
                    trials=cfg["trials"], rng=rng)
    return {"variants": [_method(m["method"], spec, traj, u, rng) for m in cfg["variants"]]}


def _method(m: str, spec: ModelSpec, traj, u: np.ndarray, rng: np.random.Generator) -> dict:
    """Method ``m`` on a block's trajectories: its scores, and its run time (``elapsed``, s)."""
    contender, t = CONTENDERS[m], traj.t
    entry = get_method(contender.method)
    start = time.perf_counter()
    options = dict(contender.options)
    if contender.seeded:
        options["seed"] = int(rng.integers(2**63))
    stay = _stay(spec)
    if stay is not None and entry.transition == "required":
        options["stay"] = stay
    estimator = entry.build(spec, t, **options)
    est = entry.run(estimator, traj.y, u, t, modes=traj.mode, signals=traj.signals,
                    segments=traj.segments() if contender.true_instants else None,
                    smooth=contender.smooth)
    elapsed = time.perf_counter() - start
    first = max(1, t.size // 20)
    if m != "min-distance":
        out = score(est, traj, start=first)
        out.update(_state_trial_mse(est, traj, first))
    else:
        # no estimate before its first window ends, nor from a declaration to the end of the next
        defined = est.mode >= 0
        out = score(replace(est, switch_time=None), traj, start=first, defined=defined)
        out.update(_state_trial_mse(est, traj, first, defined))
        out.update(_detections(est, traj, estimator.Delta))
    out.pop("sse_per_step")
    return {**out, "elapsed": elapsed}


def _state_trial_mse(est, traj, start: int, defined: np.ndarray | None = None) -> dict:
    """Sums over trials of each trial's mean squared error of the whole state and of its square,
    scored as :func:`~switchest.experiments.scoring.score` scores (from ``start``, where
    ``defined``): the standard error of the row's RMSE, which pools the components (``score``'s
    per-component sums lack the cross terms)."""
    mask = (np.ones(traj.x.shape[:2], dtype=bool) if defined is None
            else np.asarray(defined, dtype=bool))[:, start:]
    err = np.where(mask, np.sum((est.x - traj.x)[:, start:] ** 2, axis=-1), 0.0)
    per_trial = err.sum(axis=1) / np.maximum(mask.sum(axis=1), 1)
    return {"state_trial_mse": float(per_trial.sum()),
            "state_trial_mse_sq": float(np.sum(per_trial**2))}


def _rmse(tot: dict) -> tuple[float, float | None]:
    """The row's RMSE (all state components pooled) and its standard error
    (:func:`~switchest.experiments.scoring.rmse_and_se`; None for results stored without the
    per-trial sums, or from one trial)."""
    pooled = {"sse": [np.sum(tot["sse"])], "count": tot["count"], "trials": tot["trials"]}
    if "state_trial_mse" in tot:
        pooled |= {"trial_mse": [tot["state_trial_mse"]],
                   "trial_mse_sq": [tot["state_trial_mse_sq"]]}
    rmse, se = rmse_and_se(pooled)
    return float(rmse[0]), None if not np.isfinite(se[0]) else float(se[0])


def _detections(est, traj, Delta: float) -> dict:
    """Declared switches matched to the true ones as in Lee et al. Theorem 2
    (:func:`~switchest.estimators.min_distance.match_detections`): ``delay_T`` sums the
    delays of the declared ones in sampling periods; ``switches``, ``censored``
    (undeclared, less than ``Delta`` before the end), ``on_time`` and ``false`` count."""
    m = match_detections(est.switch_time, traj.signals, Delta=Delta, t_end=traj.t[-1])
    delays = m.delay[np.isfinite(m.delay)]
    return {"delay_T": float(np.sum(delays / np.diff(traj.t).mean())), "declared": int(delays.size),
            "on_time": m.on_time, "switches": m.n_switches, "censored": m.censored,
            "false": m.false}


def _stay(spec: ModelSpec) -> float | None:
    """A schedule implies no transition matrix; for the vehicle use its long dwell (0.9 per
    sample), in the methods that require one (IMM-EV1 keeps its own default: switches are
    rare)."""
    return 0.9 if isinstance(spec.switching, Schedule) else None


def _summary(p: dict, results, out: Path) -> Summary:
    totals = {key: tot for key, (_, tot)
              in merge_groups(results, lambda c: (c["case"], c["method"])).items()}
    all_cases = cases()
    rows, rel, rel_err = [], {m: [] for m in METHODS}, {m: [] for m in METHODS}
    for case in p["cases"]:
        for m in METHODS:
            tot = totals.get((case, m))
            if tot is None:
                rel[m].append(np.nan)
                rel_err[m].append(np.nan)
                reason = (min_distance_inapplicable(all_cases[case][0]) if m == "min-distance"
                          else None)
                if reason:
                    rows.append(Row(f"{case}: {_LABELS[m]}", "n/a", None, "RMSE", reason))
                continue
            rmse, se = _rmse(tot)
            rel[m].append(np.sqrt(tot["sse"].sum() / tot["scale"].sum()))
            # the RMS of the true state as a constant: 1.96 SE of the RMSE, relative
            rel_err[m].append(np.nan if se is None
                              else Z_95 * se / np.sqrt(tot["scale"].sum() / tot["count"]))
            parts = [f"relative RMSE {rel[m][-1]:.3g}",
                     f"{tot['elapsed'] / tot['trials'] * 1e3:.1f} ms per trial"]
            if "mode_hits" in tot:
                parts.append(f"mode accuracy {tot['mode_hits'] / tot['count']:.3f}")
            if tot.get("switch_pairs"):
                parts.append("switch-time error "
                             f"{tot['switch_rel_err'] / tot['switch_pairs']:.3f} T")
            if "samples" in tot:
                parts += _detector_parts(tot)
            rows.append(Row(f"{case}: {_LABELS[m]}", rmse, None, "RMSE", "; ".join(parts), se=se,
                            trials=tot["trials"]))
    fig = bars(out / "bakeoff.png", list(p["cases"]), {_LABELS[m]: v for m, v in rel.items()},
               errors={_LABELS[m]: v for m, v in rel_err.items()},
               ylabel="RMSE / RMS of the state (± 1.96 SE)", logy=True,
               title="Bake-off: every estimator on the same data")
    setup = (f"{p['trials']} trials per case; each method on the same simulated trials. Methods "
             "that know the modes at the samples (mode KF, switch-time KF) are given them; IMM, "
             "IMM-EV1 and the min-distance detector estimate them. Relative RMSE = RMSE over the "
             "RMS of the true state (the first 5 % of samples dropped). FSK phasor: Lee's system "
             "(catalog lee-fsk), R = 0.03² I, Q = 1e-4 I, T = 10 ms, dwell times uniform in [1.3, "
             f"2.5] s, u = {LEE_SCENARIO.u_max:g}; the min-distance detector with δ = "
             f"{LEE_SCENARIO.delta:g} s, Δ = {LEE_SCENARIO.Delta:g} s, L_i = A_i + "
             f"{LEE_SCENARIO.observer_decay:g} I and v_max = 3σ = {FSK_V_MAX:g}.")
    notes = [
        "No paper has this table. The clairvoyant mode KF knows every switching instant: the "
        "floor. Switching-time error is in units of the sampling period.",
        "RMSE ± its standard error over the trials (from the spread of the trials' own mean "
        "squared errors, delta method; n = trials). All methods run on the same trials, so the "
        "difference between two of them varies less than their separate errors suggest.",
        "The unobservable-mode case hides the state while its sensor is off; filters that track "
        "the mode keep predicting through it, IMM-type filters must also infer the mode from the "
        "silence.",
        *_fsk_notes(p),
        "The smoothed rows are offline (each estimate uses the whole record): the two-filter "
        "smoother (backward information messages, switchest.estimators.two_filter) on the "
        "filter's mode-matched posteriors. The IMM on the switching instants runs on the chain "
        "of (mode before, mode after, instant on a grid of 5 per interval), the exact model of "
        "a switch between two samples, where the IMM and GPB switch at the samples: its "
        "smoother's model of the switches is the data's. Kim's (1994) smoother, its former "
        "default, diverges on the boost converter: with the switch closed the inductor current "
        "is unobserved and e^{A T} shrinks it by 0.14 per sample, so its backward step "
        "(J ~ F^-1 there) multiplies the mismatch between the merged pairs at every sample.",
    ]
    return Summary("bakeoff", "Bake-off — every estimator on the same data", setup, rows, notes,
                   [fig])


def _detector_parts(tot: dict) -> list[str]:
    """The min-distance row's extras: where it was scored, and Theorem 2's detection counts."""
    delay = f", mean delay {tot['delay_T'] / tot['declared']:.1f} T" if tot["declared"] else ""
    return [(f"scored only on the {tot['count'] / tot['samples']:.1%} of samples where it has an "
             "estimate (none before its first window ends, nor from a declaration to the end of "
             "the next window)"),
            (f"{tot['on_time']} of {tot['switches'] - tot['censored']} switches declared within "
             f"Δ{delay}, {tot['false']} false declarations")]


def _fsk_notes(p: dict) -> list[str]:
    """Lee et al.'s conditions at the FSK case's noise bound, and why they are not a guarantee
    here."""
    if "FSK phasor" not in p["cases"]:
        return []
    s = LEE_SCENARIO
    spec = cases()["FSK phasor"][0]
    a = lee_assumptions(spec.system, u_max=s.u_max, v_max=FSK_V_MAX, x_min=spec.noise["x_min"],
                        delta=s.delta,
                        Delta=s.Delta, observer_gains=s.observer_gains,
                        min_dwell=spec.switching.min_dwell)
    return [(f"FSK phasor: Lee et al.'s Assumptions 1-3 {'hold' if a.holds else 'fail'} for |v| ≤ "
             f"{FSK_V_MAX:g} "
            f"(noise bound allowed {a.v_max_allowed:.4g}), but the Gaussian noise exceeds 3σ at "
            f"about {np.exp(-4.5):.1%} of the samples, the process noise Q is outside their model "
            "and the linear interpolation of the output between samples adds to the noise: "
            "Theorems 1-2 are not guaranteed, the detector's rows are empirical. Its mode accuracy "
            "counts the samples between a switch and its declaration (the detection delay) as "
            "wrong. No other case satisfies Assumption 1: n/a.")]


register(Experiment(
    name="bakeoff",
    paper="beyond the papers",
    title="Every applicable estimator on five systems: RMSE, mode accuracy, switch times, run time",
    # A task is one case's block through every method: tasks are short and a fixed ~0.2 s each,
    # so blocks of 20 (10 tasks, 5 per worker on 2 cores; --quick: one block, 5 tasks).
    defaults=dict(trials=40, block_size=20, cases=list(cases()),
                  durations={"boost converter": 0.1, "vehicle": 10.0, "Markov jump": 20.0,
                             "unobservable mode": 30.0, "FSK phasor": 10.0}),
    quick=dict(trials=8, block_size=8,
               durations={"boost converter": 0.03, "vehicle": 10.0, "Markov jump": 8.0,
                          "unobservable mode": 10.0, "FSK phasor": 10.0}),
    tasks=_tasks,
    run_task=_run,
    summarize=_summary,
))
