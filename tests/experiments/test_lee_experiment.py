"""Lee, Ping & Shim reproduction (lee-detection), run quick: Theorems 1-2 where the assumptions
hold.

The paper prints no numbers; what it states are guarantees, checked here on the
stored per-task results at the noise level where its Assumptions 1-3 hold
(v_max = 0.1 on the demonstration system): every switch declared within Delta,
no false declaration, the true mode after every window without a switch, the
observer error below v_max E_hat. The same run at noise beyond the bound shows
failures, so the counting can fail.
"""

import numpy as np
import pytest
from summary_rows import assert_every_printed_item_judged, find_row

from switchest.analysis.min_distance_design import lee_assumptions
from switchest.experiments.scoring import mean_and_se
from switchest.experiments.verdict import Verdict, printed_condition
from switchest.models.lee import LEE_SCENARIO as S
from switchest.simulate import simulate

NAME = "lee-detection"
NAMES = (NAME,)  # run by the `runs` fixture of conftest.py


@pytest.fixture(scope="module")
def run(runs):
    """``(params, results, summary)`` of the quick run."""
    return runs[NAME]


def _at(results, noise, told):
    found = [r for c, r in results if c["noise"] == noise and c["told"] == told]
    assert found, (noise, told)
    return found


def _rows(summary, prefix):
    return [r for r in summary.rows if r.quantity.startswith(prefix)]


def test_the_assumptions_hold_at_the_assumed_noise_only():
    x_min = S.x_min(S.horizon)
    kw = {"u_max": S.u_max, "x_min": x_min, "delta": S.delta, "Delta": S.Delta,
          "observer_gains": S.observer_gains, "min_dwell": S.min_dwell}
    assert lee_assumptions(S.system(), v_max=S.v_max, **kw).holds
    assert not lee_assumptions(S.system(), v_max=0.3, **kw).holds


def test_theorem_2_and_lemma_1_at_the_assumed_noise(run):
    params, results, _ = run
    blocks = _at(results, S.v_max, S.v_max)
    assert len(blocks) == params["trials"] // params["block_size"]
    n = sum(r["n_switches"] for r in blocks)
    censored = sum(r["censored"] for r in blocks)
    assert n >= 4 * params["trials"]  # about five switches per 10 s trial
    assert sum(r["late"] for r in blocks) == 0 and sum(r["missed"] for r in blocks) == 0
    assert sum(r["false"] for r in blocks) == 0
    assert sum(r["on_time"] for r in blocks) == n - censored
    delays = np.concatenate([r["delays"] for r in blocks])
    assert delays.size == n - censored and np.all((delays >= 0) & (delays <= S.Delta))
    for r in blocks:  # the hypotheses the guarantee rests on, as realized
        assert r["v_seen"] <= S.v_max and r["x_min_seen"] >= S.x_min(params["duration"])
        assert r["dwell_seen"] > S.delta + S.Delta and r["first_switch_seen"] > S.delta


def test_theorem_1_and_the_observer_bound_at_the_assumed_noise(run):
    _, results, _ = run
    for r in _at(results, S.v_max, S.v_max):
        assert r["windows_clean"] > 0 and r["windows_correct"] == r["windows_clean"]
        assert r["observer_samples"] > 0 and r["observer_ratio"] <= 1.0


def test_beyond_the_bound_failures_are_counted(run):
    """Noise 3x the bound the detector was told raises false declarations; at v = 0.8 told the
    truth, switches are missed: the bookkeeping reports failures when they happen."""
    _, results, _ = run
    over = _at(results, 0.3, S.v_max)
    assert sum(r["false"] for r in over) > 0
    high = _at(results, 0.8, 0.8)
    assert sum(r["missed"] + r["late"] for r in high) > 0


def test_blocks_share_their_data_across_noise_levels(run):
    """The levels of one block see the same states and signals whatever their noise level."""
    _, results, _ = run
    by_block = {}
    for cfg, r in results:
        by_block.setdefault(cfg["block"],
                            set()).add((r["x_min_seen"], r["dwell_seen"], r["first_switch_seen"]))
    assert all(len(v) == 1 for v in by_block.values())


def test_summary_shows_the_guarantees_beside_ours(run):
    _, _, summary = run
    within = find_row(summary, f"v = {S.v_max:g}: switches declared within Δ")
    assert within.measured == 1.0 and "Theorem 2" in within.paper
    assert printed_condition(within.paper) == ("≥", 1.0)
    false = find_row(summary, f"v = {S.v_max:g}: false declarations")
    assert false.measured == 0.0 and printed_condition(false.paper) == ("≤", 0.0)
    assert "Lemma 1" in false.paper
    # the guarantees hold for every switch, window and trial: reproduced, with no sampling
    # allowance (a single failure would refute them)
    guarantees = _rows(summary, f"v = {S.v_max:g}:")
    assert len(guarantees) == 4
    assert all(r.verdict is Verdict.REPRODUCED and r.se is None for r in guarantees)
    assert not any(n.startswith("GUARANTEE VIOLATED") for n in summary.notes)
    # no guarantee is claimed where the assumptions fail
    assert all(r.paper is None for r in _rows(summary, "v = 0.8:"))
    allowed = find_row(summary, "largest noise bound").measured
    assert S.v_max < allowed < 0.3
    assert len(summary.figures) == 3 and all(f.exists() for f in summary.figures)


def test_monte_carlo_rows_carry_standard_errors(run):
    """Beyond the assumptions the counts are Monte Carlo estimates: binomial over the uncensored
    switches for the fraction declared on time, over the trials for false declarations (from the
    per-trial sums of squares, checked against a recount)."""
    _, results, summary = run
    blocks = _at(results, 0.8, 0.8)
    on_time = sum(r["on_time"] for r in blocks)
    n = sum(r["n_switches"] - r["censored"] for r in blocks)
    within = find_row(summary, "v = 0.8: switches declared within Δ")
    p = on_time / n
    assert within.trials == n and within.se == pytest.approx(np.sqrt(p * (1 - p) / n))
    false = find_row(summary, "v = 0.8: false declarations")
    trials = sum(r["trials"] for r in blocks)
    _, se = mean_and_se(sum(r["false"] for r in blocks), sum(r["false_sq"] for r in blocks),
                        trials)
    assert false.trials == trials and false.se == pytest.approx(se) and false.se > 0
    for r in blocks:  # the sum of squares is of per-trial counts that add up to the total
        assert r["false"] <= r["false_sq"] <= r["false"] ** 2


def test_the_window_note_gives_the_margin_the_printed_start_would_eat(run):
    _, _, summary = run
    note = next(n for n in summary.notes if "energy s of (24)" in n)
    assert f"up to {S.v_max**2 * S.delta:.3g}" in note


def test_interpolation_gap_covers_the_gap_to_the_smooth_output():
    """Oracle: the exact path on a 16x finer grid never leaves the linear interpolant of the
    detector's grid by more than :meth:`LeeScenario.interpolation_gap`."""
    h, duration = 0.0025, 4.0
    t = h * np.arange(round(duration / h) + 1)
    rng = np.random.default_rng(3)
    u = S.input(t, 3, rng)
    traj = simulate(S.system(), S.signal, t, np.array(S.x0), u, trials=3, rng=rng, fine_dt=h / 16)
    lin = np.stack([np.stack([np.interp(traj.t_fine, t, traj.x[n, :, j]) for j in range(2)],
                             axis=-1)
                    for n in range(3)])
    gap = np.max(np.linalg.norm(traj.x_fine - lin, axis=-1))
    bound = S.interpolation_gap(h, duration)
    assert 0.2 * bound < gap <= bound


def test_every_printed_item_of_the_paper_is_judged(runs):
    assert_every_printed_item_judged("Lee", [summary for _, _, summary in runs.values()])
