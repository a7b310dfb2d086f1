"""Wang et al. §6 (Figs 8-9): the IEEE 5-bus system with packet losses, experiment
``wang-ieee5bus``.

The critical interval of eq. (20), two pole-placement designs (their gains, the eigenvalues
of ``sum p_i Lambda(i)'Lambda(i)``, the MS tests and the steady state) and the Monte Carlo of
their mean-square error (:mod:`.monte_carlo`), over all runs and over the runs without a
blind interval.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...analysis.error_moments import moment_fixed_point
from ...analysis.subsystem_observers import (
    critical_interval,
    error_dynamics,
    ms_convergence,
    place_gains,
    pole_placement_gain,
    steady_state,
    subsystem_structure,
)
from ...discretize import mode_steps
from ...estimators.rsls import fine_step_error_system
from ...models import (
    IEEE_5BUS_A,
    IEEE_5BUS_INITIAL_ERROR,
    IEEE_5BUS_POLES,
    IEEE_5BUS_POLES_AGGRESSIVE,
    IEEE_5BUS_SAMPLE_PERIOD,
    ieee_5bus,
    ieee_5bus_mode_probabilities,
)
from ...plotting import curves
from ..registry import Experiment, Row, Summary, register
from ..scoring import blocks, mean_and_se, split_variants
from .monte_carlo import (
    block_total,
    exact_moments,
    given_modes_stats,
    moment_stats,
    observer_errors,
    positive,
    simulate_model,
    verdict_rows,
    z_score,
)
from .paper import BUS_PAPER

BUS_POLES = {"first": IEEE_5BUS_POLES, "aggressive": IEEE_5BUS_POLES_AGGRESSIVE}
# Angles theta_j of the output directions g_j = (cos theta_j, sin theta_j) of a mode-1 (two-output)
# gain that places the printed poles (in printed order) and reproduces the printed eigenvalues of
# sum_i p_i Lambda(i)'Lambda(i). Not printed: fitted by least squares,
# tests/data/wang_ieee5bus.json.
BUS_MODE1_DIRECTIONS = {
    "first": (-1.7318899, 3.30243474, 0.44398433, 0.38295169),
    "aggressive": (-0.42207729, 2.71638582, 2.75201056, -0.39804537),
}
STATE_LABELS = ("δ1", "ω1", "δ2", "ω2")


def bus_gains(design: str, *, printed_eigenvalues: bool = False) -> np.ndarray:
    """Pole-placement gains of modes 1-3 (mode 4 is blind); optionally mode 1's gain of the printed
    eigenvalues."""
    system = ieee_5bus()
    poles = np.asarray(BUS_POLES[design], float)
    gains = place_gains(subsystem_structure(system), [poles] * 3 + [None])
    if printed_eigenvalues:
        theta = np.asarray(BUS_MODE1_DIRECTIONS[design])
        gains[0] = pole_placement_gain(IEEE_5BUS_A, system.C[0], poles,
                                       np.stack([np.cos(theta), np.sin(theta)], axis=1))
    return gains


def _bus_tasks(p: dict) -> list[dict]:
    """One task per trial block: the block is simulated once and both designs run on it."""
    return [{"block": b, "trials": n, "intervals": p["intervals"], "substeps": p["substeps"],
             "window": p["window"], "variants": [{"design": d} for d in BUS_POLES]}
            for b, n in blocks(p["trials"], p["block_size"])]


def _bus_run(cfg: dict, rng: np.random.Generator) -> dict:
    system, prob, T = ieee_5bus(), ieee_5bus_mode_probabilities(), IEEE_5BUS_SAMPLE_PERIOD
    traj = simulate_model(system, prob, T, cfg["intervals"], cfg["substeps"], cfg["trials"], rng)
    return {"variants": [_bus_design_run(v["design"], traj, cfg["window"])
                         for v in cfg["variants"]]}


def _bus_design_run(design: str, traj, window: int) -> dict:
    """The moments of one pole-placement design's observer on the block's trajectories."""
    system, T = ieee_5bus(), IEEE_5BUS_SAMPLE_PERIOD
    gains = bus_gains(design)
    err = observer_errors(system, gains, T, IEEE_5BUS_INITIAL_ERROR, traj)
    sq = err**2
    total = sq.sum(axis=-1, keepdims=True)
    modes = traj.mode[:, :-1]  # the mode of each interval [kT, (k+1)T)
    clear = ~np.any(modes == 3, axis=1)  # runs without a blind interval (both packets lost)
    return {"stats": {
        "trials": traj.n_trials,
        "component": moment_stats(sq, window),
        "total": moment_stats(total, window),
        "clear": {**moment_stats(total[clear], window), "trials": int(clear.sum())},
        "mode_counts": np.bincount(modes.ravel(), minlength=4).tolist(),
        "given_modes": given_modes_stats(system, gains, T,
                                         np.asarray(IEEE_5BUS_INITIAL_ERROR, float), modes, err,
                                         window, np.ones((1, 4))),
    }}


def _bus_design(design: str, p: dict) -> tuple[list[Row], dict]:
    """Rows of one pole-placement design (gains, eigenvalues of sum p_i Lambda'Lambda, MS tests,
    steady state) and its exact moments for the Monte Carlo comparison."""
    system, prob, T = ieee_5bus(), ieee_5bus_mode_probabilities(), IEEE_5BUS_SAMPLE_PERIOD
    paper, e0 = BUS_PAPER, np.asarray(IEEE_5BUS_INITIAL_ERROR, float)
    gains = bus_gains(design)
    tag = "poles " + ", ".join(f"{v:g}" for v in BUS_POLES[design])
    rows = [Row(f"{design} design ({tag}): δ1-only mode (paper's mode 2) gain entry {j + 1}",
                float(v), paper["gain"][design][j], "",
                "the printed 'L_1' is the gain of mode 2 (δ1 only: single output, unique)"
                if j == 0 else "")
            for j, v in enumerate(gains[1, :, 0])]
    ms = ms_convergence(error_dynamics(system, gains, T), prob)
    fitted = bus_gains(design, printed_eigenvalues=True)
    printed = ms_convergence(error_dynamics(system, fitted, T), prob)
    rows += [Row(f"{design}: eigenvalue {j + 1} of Σ p_i Λ(i)'Λ(i), scipy place_poles gain",
                 float(ms.moment_eigenvalues[j]), paper["moment_eig"][design][j], "",
                 "mode 1 has two outputs: its placing gain is not unique" if j == 0 else "")
             for j in range(4)]
    rows += [Row(f"{design}: eigenvalue {j + 1}, mode-1 gain with fitted eigenvector directions",
                 float(printed.moment_eigenvalues[j]), paper["moment_eig"][design][j], "",
                 "same poles, other free parameters (BUS_MODE1_DIRECTIONS)" if j == 0 else "")
             for j in range(4)]
    exact, steady, _ = exact_moments(system, gains, T, prob, e0, p["intervals"])
    # i.i.d. modes given that mode 4 never occurs
    clear_p = np.append(prob[:3], 0.0) / prob[:3].sum()
    exact_clear, steady_clear, _ = exact_moments(system, gains, T, clear_p, e0, p["intervals"])
    fine = np.diag(moment_fixed_point(*fine_step_error_system(system, gains, T, p["substeps"]),
                                      prob))
    rows += [
        Row(f"{design}: Theorem 2's γ = E‖Λ_k‖²", ms.gamma, None, "", "sufficient test"),
        Row(f"{design}: λ_max(E[Λ'Λ]) (the paper's test)", ms.moment_bound, None, "",
            "sufficient; above 1 for the scipy gain of the first design" if design == "first"
            else "sufficient"),
        Row(f"{design}: exact MS spectral radius ρ(E[Λ⊗Λ])", ms.radius, None, "",
            "< 1: MS convergent"),
        Row(f"{design}: steady-state MS error tr V_x (eq. (21) corrected)", float(steady.sum()),
            None, "",
            "with the fitted mode-1 gain: "
            f"{steady_state(error_dynamics(system, fitted, T), prob).mu_x:.4g}; given no blind "
            f"interval: {steady_clear.sum():.4g}"),
        Row(f"{design}: simulated observer ({p['substeps']} fine steps per T), steady state / (21) "
            "− 1",
            float(fine.sum() / steady.sum() - 1.0), None, "",
            "exact for the discretization the Monte Carlo runs"),
    ]
    return rows, {"gains": gains, "moments": exact, "steady": steady, "moments_clear": exact_clear}


def _bus_monte_carlo(design: str, exact: dict, results, out: Path):
    """Rows, figure (Fig. 8 or 9), |z| values and total MS curves of one design's Monte Carlo."""
    cfg, tot, _ = block_total(results, design=design)
    N, w, K = int(tot["trials"]), cfg["window"], cfg["intervals"]
    moments, steady = exact["moments"], exact["steady"]
    mc, se = mean_and_se(tot["total"]["win_sum"][0], tot["total"]["win_sq"][0], N)
    expected = float(moments[w:].sum(axis=1).mean())
    z = z_score(float(mc), float(se), expected)
    Nc = int(tot["clear"]["trials"])
    mcc, sec = mean_and_se(tot["clear"]["win_sum"][0], tot["clear"]["win_sq"][0], Nc)
    expected_c = float(exact["moments_clear"][w:].sum(axis=1).mean())
    zc = z_score(float(mcc), float(sec), expected_c)
    g = tot["given_modes"]
    zg = float(g["dev"][0] / np.sqrt(g["var"][0]))
    rows = [
        Row(f"{design}: MC ‖e_k‖², time average k = {w}..{K}, all {N} runs", float(mc), None, "",
            f"± {float(se):.2g} (SE); exact {expected:.4g}; |MC − exact| = {z:.2f} SE; given the "
            f"simulated modes {zg:+.2f} SD (effective runs {g['var'][0] ** 2 / g['var2'][0]:.0f}); "
            f"intervals per mode {tot['mode_counts'].astype(int).tolist()}"),
        Row(f"{design}: MC ‖e_k‖², time average, {Nc} runs without a blind interval", float(mcc),
            None, "",
            f"± {float(sec):.2g} (SE); exact given no blind interval {expected_c:.4g}; |MC − "
            f"exact| = {zc:.2f} SE"),
    ]
    mean_c, _ = mean_and_se(tot["component"]["sum"], tot["component"]["sq"], N)
    level = np.where(np.arange(K + 1)[:, None] >= w, tot["component"]["win_sum"] / N, np.nan)
    number = "8" if design == "first" else "9"
    fig = curves(out / f"wang-ieee5bus-fig{number}.png", np.arange(K + 1),
                 {f"Monte Carlo ({N} runs)": positive(mean_c),
                  f"Monte Carlo, average over k ≥ {w}": level,
                  "exact second moments": positive(moments),
                  "steady state (21)": np.broadcast_to(steady, moments.shape)},
                 xlabel=f"k (switching intervals, T = {IEEE_5BUS_SAMPLE_PERIOD:g})",
                 ylabel=[f"E(e_{s})²" for s in STATE_LABELS], logy=True,
                 title=f"Wang Fig. {number}: 5-bus, {design} design "
                       f"(poles {', '.join(f'{v:g}' for v in BUS_POLES[design])})")
    total = (mean_and_se(tot["total"]["sum"], tot["total"]["sq"], N)[0][:, 0], moments.sum(axis=1))
    return rows, fig, [z, zc], abs(zg), total


def _bus_summary(p: dict, results, out: Path) -> Summary:
    results = split_variants(results)
    system, prob, T = ieee_5bus(), ieee_5bus_mode_probabilities(), IEEE_5BUS_SAMPLE_PERIOD
    paper = BUS_PAPER
    e0 = np.asarray(IEEE_5BUS_INITIAL_ERROR, float)
    ci = critical_interval(system, prob)
    ci_stacked = critical_interval(system, prob,
                                   structure=subsystem_structure(system, shared=False))
    eig_A = np.sort(np.linalg.eigvals(IEEE_5BUS_A).real)[::-1]
    rows = [Row(f"eigenvalue {j + 1} of A", float(v), paper["eig_A"][j]) for j,
            v in enumerate(eig_A)]
    rows += [Row(f"p_{i + 1} from ξ_1 = 0.99, ξ_2 = 0.995", float(prob[i]), paper["p"][i], "",
                 "printed rounded (they sum to 1.00005)" if i == 0 else "") for i in range(4)]
    rows += [
        Row("T_max: eq. (20) with q = p_4, h(T) = ‖e^(AT)‖²", ci.printed_t_max, paper["T_max"], "",
            f"{ci.printed_t_max:.6f}: the printed 0.7365 is this truncated (rounding gives "
            "0.7366)"),
        Row("T = 0.95 T_max", 0.95 * ci.printed_t_max, paper["T"]),
        Row("eq. (20) with one sub-state per mode (§3.2 literally)", ci_stacked.printed_t_max,
            None, "",
            f"q_max = {ci_stacked.q_max:g}; that observer's exact threshold is "
            f"{ci_stacked.fast_observer:.4f} < T"),
        Row("exact MS threshold for fast observers, p_4 e^(2 λ_max T) = 1", ci.fast_observer, None,
            "",
            "eq. (20) is sufficient-looking but unproven; this one is exact for infinitely fast "
            "sub-observers"),
        Row("‖e(0)‖", float(np.linalg.norm(e0)), paper["e0_norm"]),
    ]
    exact, figs, zs, zgs, totals = {}, [], [], [], {}
    for design in BUS_POLES:
        design_rows, exact[design] = _bus_design(design, p)
        rows += design_rows
    for design in BUS_POLES:
        mc_rows, fig, z, zg, totals[design] = _bus_monte_carlo(design, exact[design], results, out)
        rows += mc_rows
        figs.append(fig)
        zs += z
        zgs.append(zg)
    K = p["intervals"]
    figs.append(curves(out / "wang-ieee5bus-tradeoff.png", np.arange(K + 1),
                       {**{f"Monte Carlo, {d}": v[0] for d, v in totals.items()},
                        **{f"exact, {d}": v[1] for d, v in totals.items()}},
                       xlabel="k (switching intervals, T = 0.6997)", ylabel="E‖e_k‖²", logy=True,
                       title="Wang §6 trade-off: faster, but a larger error"))
    Ts = np.linspace(0.05, 1.2, 47)
    structure = subsystem_structure(system)
    radius = {d: np.array([ms_convergence(error_dynamics(system, v["gains"], Tk,
                                                         structure=structure), prob).radius
                           for Tk in Ts]) for d, v in exact.items()}
    h = np.array([np.linalg.norm(mode_steps(system, Tk).F[3], 2) ** 2 for Tk in Ts])
    lam = float(np.max(np.linalg.eigvals(IEEE_5BUS_A).real))
    figs.append(curves(out / "wang-ieee5bus-critical.png", Ts,
                       {**{f"ρ(E[Λ⊗Λ]), {d} design": r for d, r in radius.items()},
                        "eq. (20): p_4 ‖e^(AT)‖²": prob[3] * h,
                        "fast-observer limit p_4 e^(2λ_max T)": prob[3] * np.exp(2 * lam * Ts),
                        "1": np.ones_like(Ts)},
                       xlabel="switching interval T", ylabel="mean-square factor per interval",
                       logy=True,
                       markers=[IEEE_5BUS_SAMPLE_PERIOD, ci.printed_t_max, ci.fast_observer],
                       title="5-bus: MS factor vs T (dotted: T, T_max, exact)"))
    rows += verdict_rows(zs, zgs, "sample SE of the runs' time averages")
    setup = (
        "Wang §6: IEEE 5-bus, printed A, sensors δ1 and δ2 with packet delivery ξ = (0.99, 0.995) "
        f"(4 i.i.d. modes), T = {T:g}, Ξ(1) = 0.01 per channel, Ξ(2) = 0.011, Ξ(3) = 0.012. "
        "Observer: one 4-dimensional sub-state shared by the observable modes 1-3 (mode 4 open "
        f"loop), scipy place_poles gains for poles {list(IEEE_5BUS_POLES)} and "
        f"{list(IEEE_5BUS_POLES_AGGRESSIVE)}. {p['trials']} Monte Carlo runs (paper: 400) of "
        f"{p['intervals']} intervals, the Ito output integrated exactly on {p['substeps']} fine "
        f"steps per T; x(0) = 0, e(0) = {list(IEEE_5BUS_INITIAL_ERROR)}; time averages from k = "
        f"{p['window']}."
    )
    notes = [
        ("T_max = 0.7365 is eq. (20) with q = p_4 (the probability that the shared sub-state runs "
         f"open loop) and h(T) = ‖e^(AT)‖², = {ci.printed_t_max:.6f}, truncated in print; "
         "T = 0.6997 is 0.95 T_max. Eq. (20) read with one sub-state per mode (§3.2) gives a "
         "useless bound, and "
         "that observer diverges at the paper's T. Eq. (20) is not a proven bound (Theorem 3's "
         "step (20) has no justification); the exact MS threshold for fast observers is "
         f"{ci.fast_observer:.4f}."),
        ("The printed gain [20.7170, 187.0468, −123.7698, −568.3264]' is mode 2's (δ1 only; the "
         "paper calls it L_1). With one output the placing gain is unique; the printed A is "
         "rounded, which leaves a 4e-3 difference (the unrounded A reproduces every digit: "
         "tests/analysis/test_ms_design.py). The aggressive gain, printed to 0.1, is reproduced."),
        ("The eigenvalues of Σ p_i Λ(i)'Λ(i) depend on mode 1's gain, which is not unique for two "
         "outputs (MATLAB's place and scipy's place_poles choose differently). scipy's gain gives "
         "other eigenvalues (for the first design λ_max > 1: the sufficient test fails although "
         "ρ(E[Λ⊗Λ]) ≈ 0.08); a gain with the same poles and fitted eigenvector directions "
         "reproduces the printed sets. The Monte Carlo uses scipy's gains."),
        ("Eq. (21) as printed (P'VP − V + Ψ = 0 with P'P = E[Λ'Λ]) is not the second-moment "
         "equation of a non-diagonal Λ; the steady state here solves V = Σ p_i (Λ(i) V Λ(i)' + "
         "Γ(i)Γ(i)')."),
        ("The MS error is dominated by rare events: single-sensor intervals (p_2 + p_3 = 1.5%) "
         "carry large gains and noise, and the blind mode (p_4 = 5e-5) contributes about 7% of the "
         "steady state while appearing in well under one of the simulated runs on average. "
         "Single-step means are therefore noisy; the comparison uses each run's time average, for "
         "all runs and for the runs without a blind interval against the exact moments given that "
         "(i.i.d. with p renormalized over modes 1-3)."),
        ("Ξ(1) = 0.01·[1, 1]' is read as 0.01 on each of two independent channels (one Brownian "
         "motion on both would make R singular). The paper's Figs 8-9 print no numbers: the "
         "reproduced claims are convergence to the steady state and the trade-off (faster "
         "convergence, larger persistent error)."),
    ]
    return Summary("wang-ieee5bus",
                   "Wang et al. §6 (Figs 8-9) — IEEE 5-bus with packet losses: T_max, pole "
                   "placement, MS error", setup, rows, notes, figs)


register(Experiment(
    name="wang-ieee5bus",
    paper="Wang",
    title="IEEE 5-bus, Figs 8-9: T_max, two pole-placement designs, Σ p_i Λ'Λ eigenvalues, 400-run "
          "MS error",
    # A task is a block through both designs (~0.7 s fixed, 8 ms a trial): 4 tasks of 100, 2 per
    # worker on 2 cores; --quick: 2, one per worker.
    defaults={"trials": 400, "block_size": 100, "intervals": 30, "substeps": 80, "window": 5},
    quick={"trials": 200},
    tasks=_bus_tasks,
    run_task=_bus_run,
    summarize=_bus_summary,
))
