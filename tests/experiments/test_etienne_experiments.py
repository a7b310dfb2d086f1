"""Etienne et al. reproductions (Figs 1-2), run quick: the rows against the paper's claims and
against independent recomputations (the printed formulas evaluated by hand, exact matrix
exponentials for the example trial, the bound re-evaluated from the stored per-sample results)."""

import math
from collections import Counter

import numpy as np
import pytest
from scipy.linalg import expm
from summary_rows import assert_every_printed_item_judged, find_row

import switchest.experiments.etienne  # noqa: F401  (registers the Etienne experiments)
from switchest.analysis.impulsive_lmis import impulsive_closed_loop_decay_rate
from switchest.experiments import get
from switchest.experiments.etienne import (
    THEOREM10_ITEM,
    _decay_stats,
    _envelope,
    _group,
    _mean_rate,
)
from switchest.experiments.verdict import Z_95, Reason, Verdict, printed_condition
from switchest.models import ETIENNE_SCENARIO as S
from switchest.models import etienne_academic

PAPER = {
    "provenance": (
        "Etienne et al. (004) §4: scalars of Theorem 8 (alpha 0.2, mu_s 5, mu_c 0.98) and Theorem "
        "10 (delta 0.15, mu_c_bar 5, alpha_bar 3), tau in [0.3, 0.4], s = 7, 'the condition of "
        "Theorem 10 are verified'; Fig. 1 claims the error converges, Fig. 2 that the closed loop "
        "is asymptotically stable. The paper prints neither beta nor (28)'s value: both evaluated "
        "from the printed formulas (11), (31)."
    ),
    "theorem8_beta_eq11": 0.010294,  # (0.2 - ln 5 / 7 - ln 0.98 / 0.4) / 2
    "theorem10_lhs_eq28_printed": 0.16403,
    "tolerance": 1e-5,  # half a unit of the last digit given
    "delta": 0.15,
    "theorem10_verdict": "verified",
}
NAMES = ("etienne-sync", "etienne-async")


def _bound_excess(results, M, beta):
    """max over blocks and samples of (worst ratio) / (M exp(-beta t)), from the stored results."""
    return max(float(np.max(np.exp(np.asarray(r["worst_log"]) + beta * np.asarray(r["t"])) / M))
               for r in results)


def test_defaults_are_the_papers_setup():
    sync, loop = get("etienne-sync"), get("etienne-async")
    for exp in (sync, loop):
        assert exp.params(quick=True)["trials"] < exp.defaults["trials"]
        assert len(exp.tasks(exp.params(quick=True))) <= len(exp.tasks(exp.defaults))
    assert loop.defaults["example_delay"] == PAPER["delta"]
    assert PAPER["delta"] in loop.defaults["delays"]
    with pytest.raises(ValueError, match="has no parameter"):
        sync.params(delta=0.1)


# ---------------------------------------------------------------- Fig. 1
def test_sync_paper_scalars_rows(runs):
    summary = runs["etienne-sync"][2]
    assert find_row(summary, "Theorem 8 at the paper's scalars").measured == "feasible"
    # eq. (11) by hand
    beta = (S.alpha - math.log(S.mu_s) / S.dwell - math.log(S.mu_c) / S.tau_max) / 2
    assert beta == pytest.approx(PAPER["theorem8_beta_eq11"], abs=PAPER["tolerance"])
    row = find_row(summary, "guaranteed rate β of ‖e‖ (eq. 11), paper's scalars")
    assert row.measured == pytest.approx(beta, rel=1e-12)
    assert find_row(summary, "rate condition (9)").measured == pytest.approx(2 * beta, rel=1e-12)
    search = find_row(summary, "scalar search: best guaranteed β").measured
    assert search > 5 * beta  # the paper's scalars are far from the best (quick grid: 8.7x)
    # Fig. 1a: the plant is not stable
    growth = find_row(summary, "plant ‖x(t_K)‖/‖x(0)‖")
    assert growth.measured > 1 and growth.paper is None and growth.se > 0
    plant = find_row(summary, "plant with u = 0")
    assert plant.paper == plant.measured == "not stable" and plant.verdict is Verdict.REPRODUCED


@pytest.mark.parametrize("gains", ["paper's", "searched"])
def test_sync_measured_rate_is_at_least_the_guaranteed_beta(runs, gains):
    _, results, summary = runs["etienne-sync"]
    key = "paper" if gains == "paper's" else "search"
    mine = [r for c, r in results if c["gains"] == key]
    cert = mine[0]["certificate"]
    assert all(r["certificate"] == cert for r in mine)  # deterministic SDP: same in every block
    rate = find_row(summary, f"measured decay rate of ‖e‖, {gains} scalars' gains").measured
    assert rate == min(r["rate_min"] for r in mine)
    assert rate >= cert["beta"] > 0
    # ||e(t_k+)|| <= M exp(-beta t_k) ||e(0+)|| at every sample of every trial (Theorem 8, N0 = 1)
    excess = _bound_excess(mine, cert["M"], cert["beta"])
    assert excess <= 1
    row = find_row(summary, f"largest ‖e(t_k+)‖/‖e(0+)‖ ÷ M e^(−β t_k), {gains}")
    assert row.measured == pytest.approx(excess)
    # the error is measured far above the round-off of x - x_hat
    assert min(r["roundoff_min"] for r in mine) > 100 * np.finfo(float).eps


def test_sync_example_trial_follows_the_plant_and_error_dynamics(runs):
    """Between two samples with no switch (mode i): x(t_{k+1}) = expm(A_i tau) x(t_k), u = 0 (eq.
    (1)), and e(t_{k+1}+) = (I - G_i C_i) expm(A_i tau) e(t_k+) (eq. (4))."""
    _, results, _ = runs["etienne-sync"]
    res = next(r for c, r in results if c["gains"] == "paper" and c["block"] == 0)
    ex, G = res["example"], np.asarray(res["certificate"]["G"])
    sys = etienne_academic()
    t, x, e, mode = (np.asarray(ex[k]) for k in ("t", "x", "e", "mode"))
    switches = np.asarray(ex["switches"])
    # x(0) and e(0-) = x(0) - 0, then e(0+)
    assert t[0] == t[1] == 0.0 and np.array_equal(x[0], x[1])
    np.testing.assert_allclose(e[1], (np.eye(2) - G[mode[1]] @ sys.C[mode[1]]) @ e[0], atol=1e-12)
    checked = 0
    for k in range(1, t.size - 1):
        if np.any((switches > t[k]) & (switches <= t[k + 1])):
            continue
        i = mode[k]
        assert mode[k + 1] == i
        F = expm(sys.A[i] * (t[k + 1] - t[k]))
        np.testing.assert_allclose(x[k + 1], F @ x[k], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(e[k + 1], (np.eye(2) - G[i] @ sys.C[i]) @ F @ e[k], rtol=1e-7,
                                   atol=1e-12)
        checked += 1
    assert checked > 40


# ---------------------------------------------------------------- Fig. 2
def test_async_theorem10_verdict_printed_vs_corrected(runs):
    _, results, summary = runs["etienne-async"]
    verdict = find_row(summary, "Theorem 10's conditions at the paper's scalars")
    assert verdict.paper == PAPER["theorem10_verdict"] and verdict.measured == "not verified"
    assert verdict.verdict is Verdict.EXPLAINED and "(28) = +0.1640" in verdict.details
    assert verdict.explanation.reason is Reason.PAPER_ERROR and verdict.item == THEOREM10_ITEM
    corrected = find_row(summary, "LMIs (24)-(27) corrected")
    assert corrected.measured == "infeasible" and corrected.paper is None
    # (26) as printed (block Q0 J): feasible at the §4 scalars, which reproduces the paper's claim
    # about the LMIs, but the Q found does not bound the jumps J' Q0 J < mu Q(tau)
    printed_lmis = next(r for c, r in results if c["kind"] == "verdict")["printed_lmis"]
    assert printed_lmis["feasible"] and printed_lmis["jump_growth"] > 1
    row = find_row(summary, "LMIs (24)-(27) as printed")
    assert row.measured == "feasible" and row.verdict is Verdict.REPRODUCED
    assert f"{printed_lmis['jump_growth']:.3g}×" in row.details
    assert row.item == THEOREM10_ITEM and row.reading  # a reading of the verdict, not counted
    # (31) as printed, by hand: 2 beta = alpha (1 - r) - alpha_bar r - ln mu_s / s
    #                                  - ln mu_c (1 - r) / tau_max
    #                                  - delta ln mu_c_bar / (tau_min s), r = delta / s
    r = S.delta / S.dwell
    two_beta = (S.alpha * (1 - r) - S.alpha_bar * r - math.log(S.mu_s) / S.dwell
                - math.log(S.mu_c) * (1 - r) / S.tau_max
                - S.delta * math.log(S.mu_c_bar) / (S.tau_min * S.dwell))
    assert -two_beta == pytest.approx(PAPER["theorem10_lhs_eq28_printed"], abs=PAPER["tolerance"])
    printed = find_row(summary, "(28) as printed")
    assert printed.measured == pytest.approx(-two_beta, rel=1e-12) and printed.measured > 0
    assert printed_condition(printed.paper) == ("<", 0.0)
    assert printed.verdict is Verdict.EXPLAINED and f"sum {-two_beta:+.4f}" in printed.details
    corrected = find_row(summary, "corrected rate β").measured
    assert corrected == pytest.approx(impulsive_closed_loop_decay_rate(
        S.alpha, S.alpha_bar, S.mu_s, S.mu_c, S.mu_c_bar, S.tau_min, S.tau_max, S.dwell, S.delta))
    assert corrected < two_beta / 2 < 0


def test_async_largest_certified_delay(runs):
    params, results, summary = runs["etienne-async"]
    row = find_row(summary, "largest δ certified")
    # §4 claims Theorem 10 verified at delta = 0.15: the largest certified delay is at least that
    assert printed_condition(row.paper) == ("≥", PAPER["delta"])
    assert row.verdict is Verdict.EXPLAINED
    assert 0.05 < row.measured < PAPER["delta"]  # certified, but well short of the paper's delay
    search = max((r for c, r in results if c["kind"] == "search"), key=lambda r: r["best"]["delta"])
    best = search["best"]
    assert best["delta"] == row.measured

    def rate(delta):
        return impulsive_closed_loop_decay_rate(best["alpha"], best["alpha_bar"], search["mu_s"],
                                                search["mu_c"], search["mu_c"],
                              S.tau_min, S.tau_max, S.dwell, delta)

    # where (28) turns
    assert rate(best["delta"] * (1 - 1e-6)) > 0 >= rate(best["delta"] * (1 + 1e-6))
    assert rate(PAPER["delta"]) < 0
    # below it the corrected Theorem 10 certifies, and the simulated closed loop obeys the bound
    certs = search["certificates"]
    assert set(certs) == {str(d) for d in params["delays"] if d < best["delta"]} and certs
    for d, cert in certs.items():
        assert cert["feasible"] and cert["beta"] == pytest.approx(rate(float(d)))
        sims = [r for c, r in results if c["kind"] == "simulate" and c["delay"] == float(d)]
        assert _bound_excess(sims, cert["M"], cert["beta"]) <= 1


def test_async_closed_loop_converges_at_the_papers_delay(runs):
    params, results, summary = runs["etienne-async"]
    row = find_row(summary, f"measured decay rate of ‖z‖, z = (x, e), δ = {PAPER['delta']:g} ")
    assert row.paper is None
    sims = [r for c, r in results if c["kind"] == "simulate" and c["delay"] == PAPER["delta"]]
    # every trial decays, though not certified
    assert row.measured == min(r["rate_min"] for r in sims) > 0
    stable = find_row(summary, f"closed loop at δ = {PAPER['delta']:g}")
    assert stable.paper == stable.measured == "asymptotically stable"
    assert stable.verdict is Verdict.REPRODUCED
    assert sum(r["trials"] for r in sims) == params["trials"]
    # samples corrected with the wrong mode: one per switch at most here (ceil(0.15/0.3)), more than
    # (31)'s 0.5
    window = find_row(summary, "most samples in one mismatch window")
    assert window.measured == math.ceil(PAPER["delta"] / S.tau_min) == 1
    assert window.paper is None and f"δ/τ_min = {PAPER['delta'] / S.tau_min:.3g}" in window.details
    assert sum(r["wrong_samples"] for r in sims) == sum(r["window_samples"] for r in sims) > 0
    # longer delays slow the decay
    rates = [find_row(summary, f"measured decay rate of ‖z‖, z = (x, e), δ = {d:g} ").measured
             for d in sorted(params["delays"])]
    assert rates[0] > rates[-1]


# ---------------------------------------------------------------- the report's verdicts
def test_rows_compare_printed_claims_only(runs):
    """Every printed claim of Fig. 1 is reproduced; of Fig. 2, the LMIs as printed and the
    stability are, Theorem 10's verdict, (28) and the certified delay differ with their reason.
    Numbers the paper does not print (beta, M, gains, rates) are derived."""
    sync, loop = runs["etienne-sync"][2], runs["etienne-async"][2]
    counted = [r for r in sync.rows if r.paper is not None]
    assert len(counted) == 5 and all(r.verdict is Verdict.REPRODUCED for r in counted)
    verdicts = Counter(r.verdict for r in loop.rows if r.paper is not None)
    assert verdicts == {Verdict.REPRODUCED: 2, Verdict.EXPLAINED: 3}
    for summary in (sync, loop):
        for row in summary.rows:  # printed words and conditions
            assert row.paper is None or isinstance(row.paper, str), row.quantity
        assert not any(n.startswith("NOT REPRODUCED") for n in summary.notes)
    for name in ("guaranteed rate β", "overshoot M", "scalar search"):
        assert find_row(sync, name).paper is None


def test_monte_carlo_means_carry_standard_errors():
    """The mean rate and the geometric-mean band from the additive block sums equal numpy's over
    the pooled trials (two blocks, different sample times)."""
    rng = np.random.default_rng(5)
    blocks = []
    for n, t in ((7, np.array([0.0, 0.3, 0.65, 1.0])), (5, np.array([0.0, 0.35, 0.7, 1.05]))):
        norm = np.exp(np.cumsum(rng.normal(-0.3, 0.2, (n, t.size)), axis=1))
        blocks.append((norm, t, _decay_stats(norm, t)))
    total = _group([({"k": 0}, b[2]) for b in blocks], "k")[0]
    rates = np.concatenate([-np.log(nm[:, -1] / nm[:, 0]) / (t[-1] - t[0]) for nm, t, _ in blocks])
    mean, se = _mean_rate(total)
    assert mean == pytest.approx(rates.mean()) and se == pytest.approx(
        rates.std(ddof=1) / math.sqrt(rates.size))
    grid = np.array([0.0, 0.5, 1.0])
    logs = np.concatenate([np.log(nm / nm[:, :1])[:, np.searchsorted(t, grid, side="right") - 1]
                           for nm, t, _ in blocks])
    worst, geometric, band = _envelope(total, grid)
    np.testing.assert_allclose(worst, np.exp(logs.max(axis=0)))
    np.testing.assert_allclose(geometric, np.exp(logs.mean(axis=0)))
    np.testing.assert_allclose(band, Z_95 * logs.std(axis=0, ddof=1) / math.sqrt(12) * geometric)


def test_every_printed_item_of_the_paper_is_judged_or_declared_not_computed(runs):
    assert_every_printed_item_judged("Etienne", [summary for _, _, summary in runs.values()])
