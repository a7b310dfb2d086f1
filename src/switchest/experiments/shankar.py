"""Reproductions of Shankar, Yang & Hespanha (seed 000): Table I, Figs 3-4, Lemma 2.

Every method of an experiment sees the same simulated trials (a task simulates
one block of trials once and runs every method on it), so differences between
methods are not sampling noise between data sets.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..analysis.observability import dwell_time_observability, window_gramian
from ..analysis.switch_time_bounds import switch_matrix_bounds
from ..discretize import interval
from ..estimators import (
    Estimate,
    IMMEV1Filter,
    IMMFilter,
    ModeKalmanFilter,
    SwitchTimeKalmanFilter,
)
from ..models import BOOST_SAMPLE_PERIOD, boost_converter, vehicle_2d, vehicle_maneuver
from ..models.shankar import BoostTable1
from ..plotting import curves, estimate_figure, measured_states
from ..simulate import Trajectory, simulate
from ..system import SwitchedLinearSystem
from .registry import Experiment, Row, Summary, register
from .scoring import (
    blocks,
    merge_blocks,
    merge_groups,
    rms_and_se,
    rmse_and_se,
    score,
    split_variants,
)
from .verdict import FALLS, Z_95, Explanation, Fit, Reason, fall_with_error

# Shankar et al. Table I (100 trials, T = 0.5 ms): RMSE for g = 1..5, as printed (the digits
# are the claim: "9.40" claims two decimals)
TABLE1_PAPER = {
    "g": [1, 2, 3, 4, 5],
    "i_L": ["13.5", "10.7", "9.40", "9.17", "9.09"],
    "v_0": ["2.74", "2.15", "2.00", "1.96", "1.89"],
}


def _table1_printed() -> np.ndarray:
    """Table I's printed RMSE as numbers, ``(g, [i_L, v_0])``."""
    return np.array([TABLE1_PAPER["i_L"], TABLE1_PAPER["v_0"]], dtype=float).T


def table1_item(state: str, g: int) -> str:
    """The printed item of Table I for ``state`` (``"i_L"`` or ``"v_0"``) at grid ``g``."""
    return f"Table I: RMSE {state}, g = {g}"


TABLE1_UNSTATED = Explanation(
    Reason.UNSTATED,
    "§V.A states neither the process noise, the initial covariance nor Algorithm 1's "
    "inflation ε, and gives the switching schedule only as a range; the "
    "shankar-table1-readings section shows how far each moves the ten values, and its "
    "closest reading's values (fitted, below each item)")
TABLE1_METHODS = ("clairvoyant", "grid", "refine", "marginal", "imm", "imm-ev1", "imm-ev1-marginal")
VEHICLE_P0 = 0.01 * np.eye(4)
VEHICLE_TRANSITION = np.array([[0.9, 0.05, 0.05], [0.05, 0.9, 0.05], [0.05, 0.05, 0.9]])


# ------------------------------------------------------------------ Table I
def _table1_tasks(p: dict) -> list[dict]:
    """One task per trial block: the block is simulated once and every method runs on it."""
    methods = [{"method": "grid", "g": g} for g in p["grids"]]
    methods += [{"method": "refine", "g": g} for g in p["refine_grids"]]
    methods += [{"method": "marginal", "g": g} for g in p["marginal_grids"]]
    methods += [{"method": "clairvoyant"}, {"method": "imm"}]
    methods += [{"method": "imm-ev1", "g": g} for g in p["ev1_grids"]]
    common = {"duration": p["duration"], "process_noise": p["process_noise"], "start": p["start"]}
    return [{"block": b, "trials": n, **common, "variants": methods}
            for b, n in blocks(p["trials"], p["block_size"])]


def table1_estimate(setting: BoostTable1, method: str, traj: Trajectory, *, g: int | None = None,
                    system: SwitchedLinearSystem | None = None) -> Estimate:
    """One method of Table I's comparison on trajectories of ``setting`` (Shankar et al. §V.A).

    ``method``: ``"clairvoyant"`` (the mode Kalman filter told the true switching times),
    ``"grid"`` (the switch-time Kalman filter of eq. (23) on ``g`` grid points, modes at the
    samples given), ``"refine"`` (its grid maximum polished on the exact likelihood),
    ``"marginal"`` (the switching time integrated out over the grid), ``"imm"`` (modes
    unknown, switches at the samples), ``"imm-ev1"`` (Algorithm 1: modes and switching times
    unknown) and ``"imm-ev1-marginal"`` (its switching time integrated out). Every filter
    starts from the setting's prior; ``system`` (default ``setting.system()``) saves
    rebuilding it for each method.
    """
    system = setting.system() if system is None else system
    (x0, P0), u, t = setting.prior, setting.input, traj.t
    if method == "clairvoyant":
        return ModeKalmanFilter(system, x0, P0).run(traj.y, u, t, modes=traj.mode,
                                                    segments=traj.segments())
    if method in ("grid", "refine", "marginal"):
        return SwitchTimeKalmanFilter(
            system, x0, P0, grid=g, refine=method == "refine",
            switch_time="marginal" if method == "marginal" else "max",
        ).run(traj.y, u, t, modes=traj.mode)
    if method == "imm":
        return IMMFilter(system, np.array(setting.transition), x0, P0).run(traj.y, u, t)
    if method == "imm-ev1":
        return IMMEV1Filter(system, x0=x0, P0=P0, grid=g).run(traj.y, u, t)
    if method == "imm-ev1-marginal":
        return IMMEV1Filter(system, x0=x0, P0=P0, grid=g, switch_time="marginal").run(traj.y, u, t)
    raise ValueError(f"method must be one of {', '.join(TABLE1_METHODS)}, got {method!r}")


def _table1_run(cfg: dict, rng: np.random.Generator) -> dict:
    setting = BoostTable1(process_noise=cfg["process_noise"])
    system, traj = setting.system(), setting.simulate(cfg["duration"], cfg["trials"], rng)
    v0 = traj.x[:, cfg["start"]:, 1]  # the range of v_0 the scenario reaches, after the transient
    return {"variants": [{**_table1_method(setting, m, system, traj, cfg["start"]),
                          "v0_min": float(v0.min()), "v0_max": float(v0.max())}
                         for m in cfg["variants"]]}


def _table1_method(setting: BoostTable1, m: dict, system, traj, start: int) -> dict:
    """One method on the block's trajectories: its scores and its run time (``elapsed``, s)."""
    begin = time.perf_counter()
    est = table1_estimate(setting, m["method"], traj, g=m.get("g"), system=system)
    out = score(est, traj, start)
    out.pop("sse_per_step")
    return {**out, "elapsed": time.perf_counter() - begin}


def _label(cfg: dict) -> str:
    m = cfg["method"]
    return {"grid": f"switch-time KF, g = {cfg.get('g')}", "refine": f"refined, g = {cfg.get('g')}",
            "marginal": f"switch time marginalized, g = {cfg.get('g')}",
            "clairvoyant": "clairvoyant (true switch times)", "imm": "IMM (modes unknown)",
            "imm-ev1": f"IMM-EV1 (modes unknown), g = {cfg.get('g')}"}[m]


def _by_method(results: list[tuple[dict, dict]]) -> dict[str, tuple[dict, dict]]:
    """Method label -> (a configuration of it, its statistics summed over the blocks)."""
    return merge_groups(results, _label, minimum=("v0_min",), maximum=("v0_max",))


def _table1_summary(p: dict, results, out: Path) -> Summary:
    rows, ours, errors = [], {}, {}
    methods = _by_method(results)
    for label, (cfg, tot) in methods.items():
        rmse, se = rmse_and_se(tot)
        ours[label], errors[label] = rmse, se
        paper_i = paper_v = None
        if cfg["method"] == "grid" and cfg["g"] in TABLE1_PAPER["g"]:
            k = TABLE1_PAPER["g"].index(cfg["g"])
            paper_i, paper_v = TABLE1_PAPER["i_L"][k], TABLE1_PAPER["v_0"][k]
        extra = [f"{tot['elapsed'] / tot['trials']:.2g} s per trial"]
        if "switch_pairs" in tot and tot["switch_pairs"]:
            extra.append("switch-time error "
                         f"{1e3 * tot['switch_abs_err'] / tot['switch_pairs']:.3f} ms")
        if "mode_hits" in tot:
            extra.append(f"mode accuracy {tot['mode_hits'] / tot['count']:.3f}")
        n, why = tot["trials"], None if paper_i is None else TABLE1_UNSTATED
        item = {} if paper_i is None else {"i_L": table1_item("i_L", cfg["g"]),
                                           "v_0": table1_item("v_0", cfg["g"])}
        rows.append(Row(f"RMSE i_L, {label}", float(rmse[0]), paper_i, "A", "; ".join(extra),
                        se=float(se[0]), trials=n, item=item.get("i_L"), explanation=why))
        rows.append(Row(f"RMSE v_0, {label}", float(rmse[1]), paper_v, "V", "; ".join(extra),
                        se=float(se[1]), trials=n, item=item.get("v_0"), explanation=why))
    grid_g = [g for g in p["grids"]]
    grid_rmse = np.array([ours[f"switch-time KF, g = {g}"] for g in grid_g])
    grid_se = np.array([errors[f"switch-time KF, g = {g}"] for g in grid_g])
    rows += [_table1_trend(state, unit, grid_g, grid_rmse[:, c], grid_se[:, c], p["trials"])
             for c, (state, unit) in enumerate((("i_L", "A"), ("v_0", "V")))]
    series = {"ours (grid maximum, eq. (23))": grid_rmse}
    if p["marginal_grids"] == grid_g:
        series["ours (switch time marginalized)"] = np.array(
            [ours[f"switch time marginalized, g = {g}"] for g in grid_g])
    bands = {"ours (grid maximum, eq. (23))": Z_95 * np.array(
        [errors[f"switch-time KF, g = {g}"] for g in grid_g])}
    fig = curves(out / "shankar-table1.png", BOOST_SAMPLE_PERIOD * 1e3 / np.array(grid_g), series,
                 bands=bands, xlabel="T / g (ms)", ylabel=["RMSE i_L (A)", "RMSE v_0 (V)"],
                 title="Shankar Table I: switch-time KF RMSE vs grid resolution",
                 paper={"Table I": (BOOST_SAMPLE_PERIOD * 1e3 / np.array(TABLE1_PAPER["g"]),
                                    _table1_printed())})
    setup = (f"Boost converter (Shankar §V.A), T = 0.5 ms, R = 5 V², {p['trials']} trials x "
             f"{p['duration']} s, switches every 1.2 ms then random in [0.9, 1.2] ms from 0.02 s; "
             "modes at the samples known, switching times estimated on the grid of eq. (23). "
             f"Process noise intensity {p['process_noise']} (unstated in the paper); RMSE from "
             f"sample {p['start']} on.")
    notes = [
        "The paper does not state the process noise, the initial covariance or any covariance "
        "inflation, so the digits cannot be matched; its claim about the table (§V.A: \"more "
        "precision in the switching time interval leads to more accuracy\") is judged as an item "
        "of its own for each state, beyond sampling error. How far the unstated choices move the "
        "table: the shankar-table1-readings section.",
        *_table1_findings(p, methods, ours, errors),
        "One 5 V² sample of v_0 says little about when a switch happened inside 0.5 ms, so the "
        "estimated switching times are far from the grid resolution; refine=True polishes the grid "
        "maximum of the exact likelihood (beyond the paper).",
        "Beyond the paper, switch_time='marginal' keeps every grid instant, updates each with the "
        "sample and merges them with their posterior weights instead of keeping the maximizer: a "
        "single sample cannot locate the switch, but it can weigh the candidates, and the merged "
        "estimate improves steadily with g at about the cost of the grid maximum.",
        "The IMM and IMM-EV1 rows do not know the modes; the clairvoyant row knows the switching "
        "times exactly (the best any method here can do).",
    ]
    return Summary("shankar-table1", "Shankar et al. Table I — gridded switching-time estimation",
                   setup, rows, notes, [fig])


def _table1_trend(state: str, unit: str, g: list[int], rmse, se, trials: int) -> Row:
    """Table I's claim that the RMSE of ``state`` falls as ``g`` grows, judged on ours."""
    values = ", ".join(f"{a:.3f}" for a in rmse)
    return Row(f"Table I's claim: RMSE {state} falls as g grows (g = {g[0]}..{g[-1]})",
               fall_with_error(rmse, se, g), FALLS, "",
               f"ours {values} {unit} (± up to {np.max(se):.2g}) at g = "
               f"{', '.join(map(str, g))}; printed {', '.join(TABLE1_PAPER[state])}",
               trials=trials, item=f"Table I: RMSE {state} falls as g grows")


def _table1_findings(p: dict, methods: dict, ours: dict, errors: dict) -> list[str]:
    """What the numbers of this run say beyond the table, each with its evidence."""
    _, any_total = next(iter(methods.values()))
    v_lo, v_hi = any_total["v0_min"], any_total["v0_max"]
    out = [f"The paper's output voltage stays between 100 and 120 V; this scenario's v_0 ranges "
           f"over {v_lo:.1f}..{v_hi:.1f} V after the transient (all trials): the switching "
           "schedule we read from the text (see the setup) sets it, not the filter."]
    raw = float(np.sqrt(boost_converter(process_noise=p["process_noise"]).R[0, 0, 0]))
    coarse, refined = ours.get("switch-time KF, g = 1"), ours.get("refined, g = 1")
    if coarse is not None and coarse[1] > raw:
        se = errors["switch-time KF, g = 1"][1]
        after = ("" if refined is None else
                 f" Polishing the same grid maximum on the exact likelihood (refined, g = 1) "
                 f"brings it to {refined[1]:.2f} V.")
        out.append(
            f"At g = 1 the switch-time KF's v_0 RMSE ({coarse[1]:.2f} ± {se:.2g} V) is worse than "
            f"the raw measurement's ({raw:.2f} V = sqrt(R)). With one grid point every switch is "
            "placed mid-interval, up to T/2 of the wrong dynamics in each switched interval, "
            "while the filter's covariance (process noise only, no inflation) claims a "
            "prediction better than the measurement: the model error enters the estimate and "
            f"the measurement is not trusted enough to remove it.{after} More process noise or "
            "a covariance inflation trades that bias for noise: shankar-table1-readings.")
    ev1 = sorted((cfg["g"], label) for label, (cfg, _) in methods.items()
                 if cfg["method"] == "imm-ev1")
    if len(ev1) >= 2:
        (g0, a), (g1, b) = ev1[0], ev1[-1]
        out.append(
            f"IMM-EV1 (Algorithm 1, modes unknown): from g = {g0} to g = {g1} its v_0 RMSE goes "
            f"from {ours[a][1]:.2f} to {ours[b][1]:.2f} V while its i_L RMSE goes from "
            f"{ours[a][0]:.1f} to {ours[b][0]:.1f} A (± {max(errors[a][0], errors[b][0]):.2g} A): "
            "a finer grid fits the measured v_0 better and lets the current, which is not "
            "measured, absorb the misplaced switches.")
    return out


register(Experiment(
    name="shankar-table1",
    paper="Shankar",
    title="Table I: Kalman filter RMSE vs switching-time grid (boost converter)",
    # A task simulates a block (20000 samples a trial, most of its ~20 CPU-s) and runs the 16
    # methods on it: blocks of 10 make 10 tasks, 5 per worker on 2 cores. --quick: 2 tasks, one
    # per worker; single trials would spend most of a task in per-call overhead.
    defaults=dict(trials=100, duration=10.0, grids=[1, 2, 3, 4, 5], refine_grids=[1, 2],
                  marginal_grids=[1, 2, 3, 4, 5],
                  ev1_grids=[1, 5], process_noise=BoostTable1.process_noise, block_size=10,
                  start=BoostTable1.transient),
    quick=dict(trials=4, duration=0.25, block_size=2),
    tasks=_table1_tasks,
    run_task=_table1_run,
    summarize=_table1_summary,
))


# ------------------------------------------------------------------ Table I under other readings
READING_SCHEDULES = {
    "random": ((0.9e-3, 1.2e-3), "gaps uniform in [0.9, 1.2] ms"),
    "constant": ((0.9e-3, 0.9e-3), "constant 0.9 ms (Fig. 2 caption)"),
}
READING_CLOSE = 0.06  # "within 6 %" of a printed value
READINGS_DRAWN = 5  # readings in the figure, the closest to the printed table (all in the table)


def _readings_tasks(p: dict) -> list[dict]:
    """One task per (trial block, schedule, process noise): the block is simulated once and
    the switch-time KF runs on it with each likelihood at each g. Tasks of one block share its
    seed, so every reading sees the same random draws (common random numbers)."""
    variants = [{"likelihood": lk, "inflation": eps, "g": g} for lk in p["likelihoods"]
                for eps in p["inflations"] for g in TABLE1_PAPER["g"]]
    return [{"block": b, "trials": n, "duration": p["duration"], "start": p["start"],
             "schedule": schedule, "process_noise": q, "variants": variants}
            for b, n in blocks(p["trials"], p["block_size"])
            for schedule in p["schedules"] for q in p["process_noises"]]


def _readings_run(cfg: dict, rng: np.random.Generator) -> dict:
    (low, high), _ = READING_SCHEDULES[cfg["schedule"]]
    setting = BoostTable1(process_noise=cfg["process_noise"], min_dwell=low, max_dwell=high)
    system, traj = setting.system(), setting.simulate(cfg["duration"], cfg["trials"], rng)
    (x0, P0), u = setting.prior, setting.input
    out = []
    for variant in cfg["variants"]:
        est = SwitchTimeKalmanFilter(system, x0, P0, grid=variant["g"],
                                     likelihood=variant["likelihood"],
                                     inflation=variant["inflation"]).run(
            traj.y, u, traj.t, modes=traj.mode)
        scores = score(est, traj, cfg["start"])
        scores.pop("sse_per_step")
        out.append(scores)
    return {"variants": out}


_FACTORS = ("schedule", "process_noise", "inflation", "likelihood")
"""What a reading chooses: the settings the paper leaves open."""


def _reading_key(cfg: dict) -> tuple:
    return tuple(cfg[f] for f in _FACTORS)


def _reading_label(key: tuple) -> str:
    schedule, q, eps, likelihood = key
    return (f"{READING_SCHEDULES[schedule][1]}; q = {q:g}; epsilon = {eps:g}; {likelihood} "
            "likelihood")


def _readings_summary(p: dict, results, out: Path) -> Summary:
    """Each reading's table against the printed one (ranked by its largest deviation), what
    each open setting does to the table, the closest reading's ten values as fitted readings
    of Table I's items, and a figure of the closest readings."""
    groups = merge_groups(results, lambda c: (_reading_key(c), c["g"]))
    printed = _table1_printed()
    tables: dict[tuple, tuple[np.ndarray, np.ndarray, int]] = {}
    for key in dict.fromkeys(k[0] for k in groups):
        stats = [rmse_and_se(groups[(key, g)][1]) for g in TABLE1_PAPER["g"]]
        tables[key] = (np.array([r for r, _ in stats]), np.array([e for _, e in stats]),
                       groups[(key, 1)][1]["trials"])
    deviation = {key: np.abs(rmse / printed - 1) for key, (rmse, _, _) in tables.items()}
    ranked = sorted(tables, key=lambda k: (deviation[k].max(), deviation[k].mean()))
    rows = []
    for key in ranked:
        d, n = deviation[key], tables[key][2]
        rows.append(Row(f"reading: {_reading_label(key)}", float(d.max()), None,
                        "largest |ours/printed − 1|",
                        f"mean {d.mean():.1%}; {int(np.sum(d <= READING_CLOSE))} of 10 within "
                        f"{READING_CLOSE:.0%}; {n} trials"))
    best = ranked[0]
    rmse, se, n = tables[best]
    close_too = [k for k in ranked[1:] if deviation[k].max() <= deviation[best].max() * 1.1]
    fit = Fit(_reading_label(best), unique=not close_too,
              evidence=(f"the closest of {len(tables)} readings scanned by largest deviation "
                        f"({deviation[best].max():.1%})"
                        + (f"; {len(close_too)} other(s) within 10 % of that deviation"
                           if close_too else "; the next is more than 10 % farther")))
    for k, g in enumerate(TABLE1_PAPER["g"]):
        for c, (name, unit) in enumerate((("i_L", "A"), ("v_0", "V"))):
            rows.append(Row(f"closest reading, RMSE {name}, g = {g}", float(rmse[k, c]),
                            TABLE1_PAPER[name][k], unit, se=float(se[k, c]), trials=n,
                            item=table1_item(name, g), reading="closest reading", fit=fit))
    x = BOOST_SAMPLE_PERIOD * 1e3 / np.array(TABLE1_PAPER["g"])
    shown = ranked[:READINGS_DRAWN]  # a legend of every reading would cover the axes
    fig = curves(out / "shankar-table1-readings.png", x,
                 {_reading_label(k): tables[k][0] for k in shown},
                 bands={_reading_label(best): Z_95 * tables[best][1]}, xlabel="T / g (ms)",
                 ylabel=["RMSE i_L (A)", "RMSE v_0 (V)"],
                 title=f"Shankar Table I: the {len(shown)} readings closest to the printed "
                       f"table (of {len(tables)})",
                 paper={"Table I": (x, printed)})
    setup = (f"The switch-time KF of Table I (grid maximum of eq. (23), modes at the samples "
             f"known) on {p['trials']} trials x {p['duration']} s of the boost converter, under "
             f"each combination of the readings the paper leaves open: the switching schedule "
             f"after 0.02 s ({', '.join(READING_SCHEDULES[s][1] for s in p['schedules'])}), the "
             f"process-noise intensity q ({', '.join(f'{q:g}' for q in p['process_noises'])}; "
             "unstated), Algorithm 1's covariance inflation epsilon I added to every P_k|k-1 "
             f"(§IV; epsilon = {', '.join(f'{e:g}' for e in p['inflations'])}: \"some small "
             "epsilon\", unstated) and the likelihood J_k of eq. (23) (the innovation likelihood "
             "N(y; C x-, C P- C' + R), or the printed p(y | x = x-), covariance R alone). Every "
             "reading sees the same random draws. Readings are ranked by their largest deviation "
             "from the ten printed values.")
    d = deviation[best]
    notes = [
        f"Closest to the printed table: {_reading_label(best)}: all ten values within "
        f"{d.max():.1%} ({int(np.sum(d <= READING_CLOSE))} within {READING_CLOSE:.0%}, mean "
        f"{d.mean():.1%}); its values are shown under each Table I item as a fitted reading. A "
        "reading that matches some digits says the paper's unstated choices matter at that "
        "precision; it does not identify them.",
        *_setting_effects(tables, deviation, best),
        "Inflation and process noise act alike on the prediction (epsilon I against Qd, about "
        "q T I over T = 0.5 ms: q = 1, ours, adds about 5e-4 to the covariance each sample, "
        "q = 10^4 about 5), but epsilon I is the same for both states while Qd follows the "
        "converter's dynamics, and only Qd enters the simulated data.",
    ]
    return Summary("shankar-table1-readings",
                   "Shankar et al. Table I — sensitivity to the unstated setup", setup, rows,
                   notes, [fig])


def _level(factor: str, level) -> str:
    if factor == "schedule":
        return READING_SCHEDULES[level][1]
    return level if isinstance(level, str) else f"{level:g}"


def _setting_effects(tables: dict, deviation: dict, best: tuple) -> list[str]:
    """Each open setting's effect as numbers: how far changing it alone (the others as in
    every reading) moves the ten values, and the largest deviation from the printed table
    along it with the others at the closest reading."""
    out = []
    for f, factor in enumerate(_FACTORS):
        levels = list(dict.fromkeys(key[f] for key in tables))
        if len(levels) < 2:
            continue
        moves = [np.abs(tables[key][0] / tables[other][0] - 1).max()
                 for key in tables for other in tables
                 if key[f] == levels[0] and other[f] != levels[0]
                 and all(key[i] == other[i] for i in range(len(_FACTORS)) if i != f)]
        along = []
        for level in levels:
            key = best[:f] + (level,) + best[f + 1:]
            if key in deviation:
                along.append(f"{_level(factor, level)}: {deviation[key].max():.1%}")
        out.append(f"{factor.replace('_', ' ')}: changing it from {_level(factor, levels[0])} "
                   "moves the ten values "
                   f"by up to {max(moves):.1%} (median over readings "
                   f"{np.median(moves):.1%}); the largest deviation from the printed table "
                   f"along it, the other settings at the closest reading: {'; '.join(along)}.")
    return out


register(Experiment(
    name="shankar-table1-readings",
    paper="Shankar",
    title="Table I under each plausible reading (schedule, process noise, likelihood)",
    # 2 blocks x 2 schedules x 3 noises = 12 tasks of a simulation and 50 grid filters each;
    # at 20 trials x 10 s the RMSE's standard error is ~0.2 % of it, far below the differences
    # between readings
    defaults=dict(trials=20, duration=10.0, block_size=10, schedules=["random", "constant"],
                  process_noises=[1.0, 100.0, 10000.0], inflations=[0.0, 0.01, 1.0, 3.0, 10.0],
                  likelihoods=["innovation", "printed"],
                  start=BoostTable1.transient),
    quick=dict(trials=4, duration=0.25, block_size=2),
    tasks=_readings_tasks,
    run_task=_readings_run,
    summarize=_readings_summary,
))


# ------------------------------------------------------------------ vehicle, Figs 3-4
def _vehicle_tasks(p: dict) -> list[dict]:
    """One task per trial block: the block is simulated once and every method runs on it."""
    methods = [{"method": "clairvoyant"}, {"method": "imm"}]
    methods += [{"method": "imm-ev1", "g": g} for g in p["grids"]]
    return [{"block": b, "trials": n, "variants": methods}
            for b, n in blocks(p["trials"], p["block_size"])]


def _vehicle_run(cfg: dict, rng: np.random.Generator) -> dict:
    man = vehicle_maneuver()
    system = vehicle_2d()
    traj = simulate(system, man.signal, man.t, np.zeros(4), u=man.u, trials=cfg["trials"],
                    rng=rng)
    x0 = np.zeros(4)
    results = []
    for m in cfg["variants"]:
        start = time.perf_counter()
        if m["method"] == "clairvoyant":
            est = ModeKalmanFilter(system, x0, VEHICLE_P0).run(
                traj.y, man.u, man.t, modes=traj.mode, segments=traj.segments())
        elif m["method"] == "imm":
            est = IMMFilter(system, VEHICLE_TRANSITION, x0, VEHICLE_P0).run(traj.y, man.u, man.t)
        else:
            est = IMMEV1Filter(system, x0=x0, P0=VEHICLE_P0, grid=m["g"]).run(traj.y, man.u, man.t)
        out = {**score(est, traj, 0), **_position_velocity_errors(est.x - traj.x)}
        if cfg["block"] == 0:  # the first trial, for the figure of Fig. 3
            out["example"] = {
                "truth": traj.x[0].tolist(), "x": est.x[0].tolist(), "y": traj.y[0].tolist(),
                "std": np.sqrt(np.diagonal(est.P[0], axis1=-2, axis2=-1)).tolist(),
                "mode": traj.mode[0].tolist(),
                "mode_prob": None if est.mode_prob is None else est.mode_prob[0].tolist(),
                "switch_time": ([] if est.switch_time is None else
                                est.switch_time[0][np.isfinite(est.switch_time[0])].tolist())}
        results.append({**out, "elapsed": time.perf_counter() - start})
    return {"variants": results}


def _position_velocity_errors(err: np.ndarray) -> dict:
    """Sums over trials, for the standard errors of Fig. 4: each trial's squared position and
    velocity errors ``(e_1^2 + e_2^2) / 2`` per step (and their squares), and its mean over the
    run (and its square)."""
    sq = np.stack([(err[..., 0] ** 2 + err[..., 2] ** 2) / 2,
                   (err[..., 1] ** 2 + err[..., 3] ** 2) / 2], axis=-1)  # (N, K, 2)
    run = sq.mean(axis=1)
    return {"pv_step": sq.sum(axis=0).tolist(), "pv_step_sq": (sq**2).sum(axis=0).tolist(),
            "pv_run": run.sum(axis=0).tolist(), "pv_run_sq": (run**2).sum(axis=0).tolist()}


def _vehicle_summary(p: dict, results, out: Path) -> Summary:
    man = vehicle_maneuver()
    rows, pos_vel, bands, examples, ev1_rmse = [], {}, {}, {}, {}
    for label, (cfg, tot) in _by_method(results).items():
        n = tot["trials"]
        pos_vel[label], se_step = rms_and_se(tot["pv_step"], tot["pv_step_sq"], n)
        bands[label] = Z_95 * se_step
        overall, se = rms_and_se(tot["pv_run"], tot["pv_run_sq"], n)
        extra = []
        if "mode_hits" in tot:
            extra.append(f"mode accuracy {tot['mode_hits'] / tot['count']:.3f}")
        if tot.get("switch_pairs"):
            extra.append(f"switch-time error {tot['switch_abs_err'] / tot['switch_pairs']:.3f} s")
        rows.append(Row(f"RMSE position, {label}", float(overall[0]), None, "m",
                        "; ".join(extra), se=float(se[0]), trials=n))
        rows.append(Row(f"RMSE velocity, {label}", float(overall[1]), None, "m/s",
                        se=float(se[1]), trials=n))
        if cfg["method"] == "imm-ev1":
            ev1_rmse[cfg["g"]] = (overall, se, n)
    if len(ev1_rmse) >= 2:  # the conclusions' claim on Fig. 4
        grids = sorted(ev1_rmse)
        for c, name in enumerate(("position", "velocity")):
            values = [ev1_rmse[g][0][c] for g in grids]
            ses = [ev1_rmse[g][1][c] for g in grids]
            rows.append(Row(
                f"§VI's claim on Fig. 4: IMM-EV1's {name} RMSE falls as g grows "
                f"(g = {', '.join(map(str, grids))})", fall_with_error(values, ses, grids), FALLS,
                "", f"ours {', '.join(f'{v:.4f}' for v in values)} "
                    f"(± up to {max(ses):.2g}); {values[-1] / values[0] - 1:+.1%} from g = "
                    f"{grids[0]} to {grids[-1]}", trials=ev1_rmse[grids[0]][2],
                item="Fig. 4: the vehicle's RMSE falls as g grows"))
    for cfg, res in split_variants(results):
        if "example" in res:
            examples[_label(cfg)] = res["example"]
    switches = list(man.signal.times)
    figs = [
        curves(out / "shankar-vehicle-rmse.png", man.t, pos_vel, bands=bands, xlabel="t (s)",
               ylabel=["position RMSE (m)", "velocity RMSE (m/s)"], markers=switches,
               marker_label="switching times",
               title=f"Shankar Fig. 4: vehicle RMSE over {p['trials']} trials"),
    ]
    ev1 = [label for label in examples if "IMM-EV1" in label]
    if ev1:  # the finest grid's estimate of the first trial, as the paper's Fig. 3
        ex = examples[ev1[-1]]
        figs.append(estimate_figure(
            out / "shankar-vehicle-trial.png", man.t, np.asarray(ex["x"]),
            std=np.asarray(ex["std"]), truth=np.asarray(ex["truth"]),
            measured=measured_states(vehicle_2d().C, np.asarray(ex["y"])),
            mode_prob=None if ex["mode_prob"] is None else np.asarray(ex["mode_prob"]),
            true_mode=np.asarray(ex["mode"]), switch_times=ex["switch_time"],
            names=["position x1", "velocity dx1/dt", "position x2", "velocity dx2/dt"],
            units=["m", "m/s", "m", "m/s"],
            title=f"Shankar Fig. 3: one trial, {ev1[-1]}"))
    setup = ("Vehicle (Shankar §V.B): double integrators, 3 modes differing by their input, T = "
             "0.5 s, R = 0.05 I, Q = 1e-3 I (unstated in the paper), u = 1, switches at 1.65, "
             f"2.75, 3.9 s; {p['trials']} trials; IMM with transition 0.9 on the diagonal; P0 = "
             "0.01 I.")
    notes = [
        "The paper prints no numbers for Fig. 4 (curves only); our rows are the measured RMSEs, "
        "and the conclusions' claim on them (accuracy improves with the precision of the switching "
        "times) is judged as an item, beyond sampling error.",
        "Where IMM-EV1 does not improve with g: the mode enters a position sample only through one "
        "interval's acceleration, so a hypothesis 'switch at tau' fits one new sample as well as "
        "'no switch' (velocity is not measured), and each destination keeps only its best "
        "predecessor; more grid points give more ways to fit the noise. See the mode accuracy per "
        "g.",
    ]
    return Summary("shankar-vehicle", "Shankar et al. Figs 3-4 — vehicle maneuver tracking", setup,
                   rows, notes, figs)


register(Experiment(
    name="shankar-vehicle",
    paper="Shankar",
    title="Figs 3-4: IMM-EV1 on the vehicle maneuver, RMSE vs g",
    # 21 samples a trial: the whole run is a second of CPU, so the blocks are as large as 2 tasks
    # per worker on 2 cores allow (4 of 125; --quick: 2 of 20, one per worker).
    defaults=dict(trials=500, grids=[1, 2, 5, 10], block_size=125),
    quick=dict(trials=40, block_size=20),
    tasks=_vehicle_tasks,
    run_task=_vehicle_run,
    summarize=_vehicle_summary,
))


# ------------------------------------------------------------------ Lemma 1
LEMMA1_COUNTEREXAMPLE = {
    "A": [[[-3.0, 0.0], [0.0, -0.1]], [[-0.1, 0.0], [0.0, -3.0]]],
    "C": [[1.0, 1.0]],
    "T": 1.0,
    "tau_d": 2.0,
}
"""A two-mode system (constructed, not from the paper) on which Lemma 1's printed constants
fail: each mode is uniformly observable with h_i = 1, and tau_d = 2 T > h_bar T."""


def _lemma1_tasks(p: dict) -> list[dict]:
    return [{"block": 0, "phases": p["phases"], "signals": p["signals"]}]


def _lemma1_run(cfg: dict, rng: np.random.Generator) -> dict:
    ex = LEMMA1_COUNTEREXAMPLE
    sys = SwitchedLinearSystem.continuous(np.array(ex["A"]), C=np.array(ex["C"]))
    T, tau_d = ex["T"], ex["tau_d"]
    lemma = dwell_time_observability(sys, T, tau_d)
    # as printed: a window of h + 1 samples with a switch inside it (tau_d > h_bar T allows one)
    printed = min(
        float(np.linalg.eigvalsh(window_gramian(sys, T, lemma.h, [s, s + 10.0], [0, 1, 0]))[0])
        for s in np.linspace(0.05, 0.95, cfg["phases"]) * T)
    # corrected: window 2 h_bar, random alternating signals with every stay >= (h_bar + 1) T
    lowest = np.inf
    for _ in range(cfg["signals"]):
        gaps = (max(lemma.h_modes) + 1) * T + rng.exponential(T, size=4)
        times = rng.uniform(-gaps[0], 0.0) + np.cumsum(gaps)
        first = int(rng.integers(2))
        modes = [(first + q) % 2 for q in range(times.size + 1)]
        gram = window_gramian(sys, T, lemma.h_corrected, times, modes)
        lowest = min(lowest, float(np.linalg.eigvalsh(gram)[0]))
    return {"rho": lemma.rho, "h": lemma.h, "rho_corrected": lemma.rho_corrected,
            "h_corrected": lemma.h_corrected, "printed_lemma_holds": lemma.printed_lemma_holds,
            "holds": lemma.holds, "printed_min": printed, "corrected_min": lowest}


def _lemma1_summary(p: dict, results, out: Path) -> Summary:
    r = results[0][1]
    rows = [
        Row("Lemma 1's hypotheses (each mode uniformly observable, tau_d > h_bar T)",
            "hold" if r["printed_lemma_holds"] else "fail", None, "",
            f"h_bar = 1, tau_d = {LEMMA1_COUNTEREXAMPLE['tau_d']:g} T"),
        Row(f"smallest eigenvalue of the window Gramian, h = {r['h']} (printed window), a switch "
            f"inside it (worst of {p['phases']} phases)", r["printed_min"],
            f"≥ {r['rho']:.4g} (Lemma 1: rho_1 = min rho_1^i)", "", item="Lemma 1",
            explanation=Explanation(
                Reason.PAPER_ERROR,
                "this counterexample satisfies the hypotheses and its window Gramian is "
                "singular: the window need not hold h_j + 1 samples of one mode, and the samples "
                "of mode j start from Phi x, not x, so rho_j must be scaled by sigma_min(Phi)^2 "
                "(switchest.analysis.dwell_time_observability); the corrected statement below "
                "holds")),
        Row(f"corrected statement (tau_d >= (h_bar + 1) T, window 2 h_bar = {r['h_corrected']}): "
            f"smallest Gramian eigenvalue over {p['signals']} random admissible signals",
            r["corrected_min"], None, "",
            f"the proven bound rho_corrected = {r['rho_corrected']:.4g} "
            f"{'holds' if r['corrected_min'] >= r['rho_corrected'] * (1 - 1e-9) else 'FAILS'}"),
    ]
    setup = ("A constructed two-mode system (not the paper's): A_1 = diag(-3, -0.1), "
             "A_2 = diag(-0.1, -3), C = [1 1], T = 1, tau_d = 2. Each sampled mode is uniformly "
             "observable with h_i = 1; Lemma 1 then claims every window of 2 h_bar - 1 = 1 "
             "interval has a Gramian >= min rho_1^i I. Window Gramians are computed exactly, "
             "composing matrix exponentials across the switches (window_gramian).")
    return Summary("shankar-lemma1", "Shankar et al. Lemma 1 — observability under a dwell time",
                   setup, rows, [], [])


register(Experiment(
    name="shankar-lemma1",
    paper="Shankar",
    title="Lemma 1: the printed window and constant fail; the corrected statement holds",
    defaults=dict(phases=19, signals=200),
    quick=dict(signals=50),
    tasks=_lemma1_tasks,
    run_task=_lemma1_run,
    summarize=_lemma1_summary,
))


# ------------------------------------------------------------------ Lemma 2
def _lemma2_tasks(p: dict) -> list[dict]:
    return [{"block": b, "cases": p["cases_per_block"]} for b in range(p["blocks"])] + [
        {"block": p["blocks"], "system": "boost"}]


def _lemma2_run(cfg: dict, rng: np.random.Generator) -> dict:
    if cfg.get("system") == "boost":
        sys = boost_converter()
        T = BOOST_SAMPLE_PERIOD
        t_bar = 0.5 * T
        t_hat = np.linspace(0.0, T, 41)
        A_i = np.broadcast_to(sys.A[0], (41, 2, 2))
        A_j = np.broadcast_to(sys.A[1], (41, 2, 2))
        B = np.broadcast_to(sys.B[0], (41, 2, 1))
        true = interval(sys, T, [0, 1], [t_bar])
        est = interval(sys, T, np.broadcast_to([0, 1], (41, 2)), t_hat[:, None])
        actual_F = np.linalg.norm(est.F - true.F, ord=2, axis=(-2, -1))
        actual_G = np.linalg.norm(est.G - true.G, ord=2, axis=(-2, -1))
        b = switch_matrix_bounds(A_i, A_j, B, B, T=T, t_bar=np.full(41, t_bar), t_hat=t_hat)
        return {"t_tilde": (t_hat - t_bar).tolist(), "actual_F": actual_F.tolist(),
                "bound_F": b.F.tolist(), "actual_G": actual_G.tolist(), "bound_G": b.G.tolist()}
    n, N = 3, cfg["cases"]
    A = rng.standard_normal((N, 2, n, n))
    B = rng.standard_normal((N, 2, n, 1))
    T = rng.uniform(0.05, 1.0, N)
    t_bar, t_hat = rng.uniform(0, 1, (2, N)) * T
    worst_F = worst_G = 0.0
    for k in range(N):  # every case is its own system: one exact discretization each
        sys = SwitchedLinearSystem.continuous(A[k], B[k])
        true = interval(sys, T[k], [0, 1], [t_bar[k]])
        est = interval(sys, T[k], [0, 1], [t_hat[k]])
        b = switch_matrix_bounds(A[k, 0], A[k, 1], B[k, 0], B[k, 1], T=T[k], t_bar=t_bar[k],
                                 t_hat=t_hat[k])
        worst_F = max(worst_F, float(np.linalg.norm(est.F - true.F, 2) / b.F))
        worst_G = max(worst_G, float(np.linalg.norm(est.G - true.G, 2) / b.G))
    return {"worst_F": worst_F, "worst_G": worst_G, "cases": N}


def _lemma2_summary(p: dict, results, out: Path) -> Summary:
    drawn = merge_blocks((r for c, r in results if "cases" in c), maximum=("worst_F", "worst_G"))
    boost = next(r for c, r in results if c.get("system") == "boost")
    cases, worst_F, worst_G = drawn["cases"], drawn["worst_F"], drawn["worst_G"]
    tt = np.asarray(boost["t_tilde"]) * 1e3
    fig = curves(out / "shankar-lemma2.png", tt,
                 {"actual ||F~||": np.asarray(boost["actual_F"]),
                  "bound (11)": np.asarray(boost["bound_F"])},
                 xlabel="switching-time error t~ (ms)", ylabel="||F_hat - F||", logy=True,
                 title="Shankar Lemma 2 on the boost converter (t_bar = T/2)")
    mid = len(tt) // 2 + 4
    rows = [
        Row(f"largest actual/bound ratio, eq. (11), over {cases} random cases", worst_F,
            "≤ 1 (Lemma 2)", item="Lemma 2, eq. (11)"),
        Row(f"largest actual/bound ratio, eq. (12), over {cases} random cases", worst_G,
            "≤ 1 (Lemma 2)", item="Lemma 2, eq. (12)"),
        Row("boost converter: bound/actual at |t~| = T/10",
            float(boost["bound_F"][mid] / boost["actual_F"][mid]),
            None, "", "how conservative (11) is on the paper's system"),
    ]
    setup = ("Random 3-state two-mode systems (standard normal A, B), T in [0.05, 1], t_bar and "
             "t_hat uniform in [0, T]; exact F, G by Van Loan; and the boost converter with t_bar "
             "= T/2.")
    notes = [f"The printed bounds (11) and (12) held in every one of the {cases} cases drawn "
             "(largest actual/bound ratios above) and on the boost converter. The proof has typos "
             "(switchest.analysis.switch_time_bounds). Most do not reach the statement, but the "
             "first term of (12) drops the time factor of int_0^t_hat e^(||A(i)|| tau) dtau <= "
             "T e^(||A(i)|| T): (12) as printed is not what the proof shows, nor dimensionally "
             "consistent. It held here because its second term's slack absorbs the missing "
             "factor: evidence that the printed (12) holds on these systems, not a proof."]
    return Summary("shankar-lemma2", "Shankar et al. Lemma 2 — bound vs actual matrix error", setup,
                   rows, notes, [fig])


register(Experiment(
    name="shankar-lemma2",
    paper="Shankar",
    title="Lemma 2: switching-time error bounds vs actual errors",
    # 11 tasks of about a second (the boost converter's the shortest); --quick: 3 of a tenth
    defaults=dict(blocks=10, cases_per_block=1000),
    quick=dict(blocks=2, cases_per_block=100),
    tasks=_lemma2_tasks,
    run_task=_lemma2_run,
    summarize=_lemma2_summary,
))
