"""The report: verdicts at the printed precision, provenance, the summary per paper, Monte Carlo
uncertainty; rendered from small stores and checked on the HTML."""

import csv
import html
import re
from dataclasses import replace
from decimal import Decimal

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from switchest.experiments import (
    EXPERIMENTS,
    Experiment,
    Row,
    Store,
    Summary,
    get,
    run_experiment,
    write_report,
)
from switchest.experiments.items import PaperItems, items_of, tally
from switchest.experiments.report import ROW_COLUMNS
from switchest.experiments.verdict import (
    FALLS,
    Explanation,
    Fit,
    Reason,
    Verdict,
    fall_with_error,
    judge,
    printed_number,
)


# ------------------------------------------------------------------------------ verdicts
@given(st.integers(-10**6, 10**6), st.integers(0, 6), st.floats(-0.49, 0.49))
def test_a_value_that_rounds_to_the_printed_digits_is_reproduced(mantissa, decimals, offset):
    printed = Decimal(mantissa).scaleb(-decimals)
    unit = 10.0 ** -decimals
    assert judge(str(printed), float(printed) + offset * unit) is Verdict.REPRODUCED


@given(st.integers(-10**6, 10**6), st.integers(0, 6), st.floats(0.51, 50.0), st.booleans())
def test_a_value_beyond_half_a_printed_unit_differs(mantissa, decimals, offset, below):
    printed = Decimal(mantissa).scaleb(-decimals)
    unit = 10.0 ** -decimals
    value = float(printed) + (-offset if below else offset) * unit
    assert judge(str(printed), value) is Verdict.DIFFERS
    assert judge(str(printed), value,
                 explanation=Explanation(Reason.MISPRINT, "a digit dropped")) is Verdict.EXPLAINED


def test_printed_digits_come_from_the_paper_not_from_the_float():
    assert printed_number(0.9904) == Decimal("0.9904")  # the shortest decimal of the float
    assert printed_number("0.150").as_tuple().exponent == -3  # trailing zeros claim digits
    assert judge("0.150", 0.1506) is Verdict.DIFFERS and judge(0.15, 0.1506) is Verdict.REPRODUCED
    assert judge(0.9904, 1.038) is Verdict.DIFFERS  # 5 % off: no longer green
    assert judge(187.0468, 187.0455) is Verdict.DIFFERS  # a miss in the fourth decimal shows


def test_monte_carlo_values_are_judged_by_their_interval():
    assert judge(2.24, 2.30, se=0.04) is Verdict.WITHIN_ERROR  # 1.5 SE away
    assert judge(2.24, 2.40, se=0.04) is Verdict.DIFFERS  # 4 SE away
    assert judge("< 4", 4.5, se=0.3) is Verdict.WITHIN_ERROR
    assert judge("< 4", 4.5) is Verdict.DIFFERS


def test_words_and_conditions():
    assert judge("feasible", "Feasible") is Verdict.REPRODUCED
    assert judge("feasible", "infeasible") is Verdict.DIFFERS
    assert judge("≤ 1", 0.36) is Verdict.REPRODUCED
    assert judge("> 1 (diverges)", 0.9) is Verdict.DIFFERS
    assert judge("verified", 0.5) is Verdict.DIFFERS  # a number is not the printed word
    assert judge(None, 3.0) is Verdict.DERIVED and judge(None, "agree") is Verdict.DERIVED
    with pytest.raises(TypeError, match="printed value"):
        judge([1.0], 1.0)


def test_numbers_in_a_text_are_judged_by_their_digits_not_as_words():
    assert judge("0.26∠1.33", "0.2610∠1.3353") is Verdict.DIFFERS  # 1.3353 rounds to 1.34
    assert judge("0.25∠1.25", "0.2530∠1.2490") is Verdict.REPRODUCED
    assert judge("[[0.2763, -0.0137]]", "[[0.27634, -0.01368]]") is Verdict.REPRODUCED
    assert judge("[[0.2763, -0.0137]]", "[[0.2763, -0.0137], [1, 2]]") is Verdict.DIFFERS


# ------------------------------------------------------------------------------ reasons, fits
def test_a_difference_with_only_run_details_is_not_explained():
    row = Row("RMSE", 3.7, "2.74", "V", "0.01 s per trial; switch-time error 0.125 ms", se=0.01,
              trials=100)
    assert row.verdict is Verdict.DIFFERS
    explained = Row("RMSE", 3.7, "2.74", "V", explanation=Explanation(Reason.UNSTATED, "no Q"))
    assert explained.verdict is Verdict.EXPLAINED


def test_a_reason_needs_evidence_from_the_vocabulary():
    with pytest.raises(ValueError, match="evidence"):
        Explanation(Reason.MISPRINT, " ")
    with pytest.raises(TypeError, match="Reason"):
        Explanation("misprint", "the digits")
    with pytest.raises(TypeError, match="explanation must be an Explanation"):
        judge("1.0", 2.0, explanation="a misprint")


@given(st.floats(-1e3, 1e3), st.floats(0.0, 1e-3))
def test_a_fitted_reading_is_never_counted_as_reproduced(value, offset):
    fit = Fit("eta = 1.04", unique=True)
    printed = f"{value:.2f}"
    verdict = judge(printed, float(printed) + offset, fit=fit)
    assert verdict is Verdict.FITTED
    item = items_of("P", [("e", Row("x", float(printed) + offset, printed, fit=fit))])
    counts = tally("P", item).counts
    assert counts[Verdict.FITTED] == 1 and counts[Verdict.REPRODUCED] == 0


def test_items_count_printed_values_not_rows():
    """A printed value judged by a table row and a sub-row (another reading) counts once; a
    claim checked at two settings holds only where it holds at both."""
    rows = [("a", Row("T_max", 0.7366, "0.7365", item="T_max",
                      explanation=Explanation(Reason.ROUNDING, "truncated"))),
            ("b", Row("T_max, exact", 0.7365, "0.7365", item="T_max", reading="exact")),
            ("a", Row("bound at v = 0.05", 0.6, "≤ 1", item="bound")),
            ("a", Row("bound at v = 0.1", 1.2, "≤ 1", item="bound")),
            ("a", Row("derived", 3.0))]
    items = items_of("P", rows)
    assert [i.key for i in items] == ["T_max", "bound"]
    assert [i.verdict for i in items] == [Verdict.EXPLAINED, Verdict.DIFFERS]
    t = tally("P", items)
    assert t.printed == 2 and t.consistent and [i.key for i in t.unexplained] == ["bound"]
    assert t.sentence().startswith("0 of 2 printed items reproduced")


def test_the_declared_count_meets_the_judged_and_the_not_computed_items():
    from switchest.experiments import items as items_module

    items_module.PAPERS["Q"] = PaperItems(3, {"Fig. 9": "a plot without numbers"})
    try:
        t = tally("Q", items_of("Q", [("a", Row("x", 1.0, "1.0"))]))
        assert t.counts[Verdict.NOT_COMPUTED] == 1 and not t.consistent  # 1 + 1 != 3
    finally:
        del items_module.PAPERS["Q"]


def test_trend_claims_hold_only_beyond_sampling_error():
    assert fall_with_error([2.39, 2.30, 2.24], [0.01, 0.01, 0.01], [1, 2, 3]) == FALLS
    rises = fall_with_error([8.50, 8.36, 8.66], [0.01, 0.01, 0.01], [1, 3, 5])
    assert rises.startswith("rises from g = 3 to 5")
    flat = fall_with_error([1.0, 0.99], [0.05, 0.05], [1, 2])
    assert flat.startswith("no fall beyond sampling error")
    with pytest.raises(ValueError, match="same length"):
        fall_with_error([1.0], [0.1], [1])


def test_every_reason_round_trips_through_rows_csv(tmp_path, toy_experiment):
    rows = [Row(f"row {k}", 2.0, "1.0", explanation=Explanation(reason, f"evidence {k}"))
            for k, reason in enumerate(Reason)]
    rows.append(Row("fitted", 1.0, "1.0", fit=Fit("q = 3", unique=False, evidence="scan")))
    summary = Summary("toy-mc", "toy", "setup", rows)
    experiment = replace(toy_experiment, summarize=lambda p, r, o: summary)
    EXPERIMENTS["toy-mc"] = experiment
    store = Store(tmp_path / "r.sqlite")
    run_experiment(experiment, experiment.params(), store=store)
    write_report(store, tmp_path)
    with (tmp_path / "rows.csv").open(encoding="utf-8") as f:
        read = list(csv.DictReader(f))
    assert tuple(read[0]) == ROW_COLUMNS
    assert [Reason(r["reason"]) for r in read[:-1]] == list(Reason)
    assert [r["evidence"] for r in read[:-1]] == [f"evidence {k}" for k in range(len(Reason))]
    assert read[-1]["verdict"] == Verdict.FITTED.value and read[-1]["fit unique"] == "False"
    here = "test_report:test_every_reason_round_trips_through_rows_csv"
    assert all(r["computed by"].endswith(here) for r in read)


# ------------------------------------------------------------------------------ the page
def _toy_summary(params, results, out):
    mean = float(np.mean([r["value"] for _, r in results]))
    return Summary("toy-mc", "A toy Monte Carlo", "four blocks of one number", [
        Row("Monte Carlo mean", mean, "2.000", se=0.01, trials=400),
        Row("derived quantity", 1.5),
    ])


@pytest.fixture
def toy_experiment():
    toy = Experiment(
        name="toy-mc", paper="Toy", title="A toy Monte Carlo", defaults={"blocks": 4},
        quick={"blocks": 2}, tasks=lambda p: [{"block": b} for b in range(p["blocks"])],
        run_task=lambda cfg, rng: {"value": 2.0 + 0.001 * cfg["block"]},
        summarize=_toy_summary)
    EXPERIMENTS[toy.name] = toy
    yield toy
    del EXPERIMENTS[toy.name]


def _row(page: str, quantity: str) -> str:
    match = re.search(r"<tr class=\"(\w+)\"><td>" + re.escape(html.escape(quantity)) +
                      r"</td>(.*?)</tr>", page)
    assert match, f"no row {quantity!r} in the report"
    return match.group(1) + " " + match.group(2)


def test_report_shows_provenance_summary_verdicts_and_uncertainty(tmp_path, toy_experiment):
    store = Store(tmp_path / "r.sqlite")
    zhang = get("zhang-smartgrid")
    run_experiment(zhang, zhang.params(quick=True), store=store)
    run_experiment(toy_experiment, toy_experiment.params(), store=store, seed=7)
    page = write_report(store, tmp_path, command="switchest report --store r.sqlite",
                        wall_seconds=12.0).read_text()

    with (tmp_path / "rows.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    mean = next(r for r in rows if r["quantity"] == "Monte Carlo mean")
    assert (mean["printed"], mean["ours"], mean["se"], mean["trials"], mean["verdict"]) == (
        "2.000", "2.0015", "0.01", "400", "within sampling error")
    assert mean["computed by"].endswith("test_report:_toy_summary") and mean["seed"] == "7"

    provenance = page[:page.index("id='summary'")]
    for fact in ("commit", "switchest report --store r.sqlite", "machine", "date", "12 s",
                 "load average"):
        assert fact in provenance
    assert "1 full, 1 quick" in provenance and "0, 7" in provenance  # modes and seeds

    # a value reproduced to its printed digits, and a misprint (the printed -0.0088 is ten
    # times ours: a slipped decimal) that differs with its explanation
    reproduced = _row(page, "‖Λ_2‖")
    assert reproduced.startswith("ok ") and ">0.8837<" in reproduced and "reproduced" in reproduced
    misprint = _row(page, "T_2,3[2,2] = (Λ_i − Γ_i,q)[2,2] (Algorithm 2)")
    assert misprint.startswith("known ") and ">-0.0088<" in misprint
    assert "differs, explained" in misprint
    assert "<summary>misprint in the paper</summary>" in misprint

    # a Monte Carlo row: mean ± standard error and the trial count, judged by its interval
    mc = _row(page, "Monte Carlo mean")
    assert "2.00150 ± 0.010" in mc and "n = 400" in mc and "within sampling error" in mc
    assert _row(page, "derived quantity").startswith("derived ")

    # the summary counts printed items per paper (N, then each verdict, then the derived rows)
    summary = page[page.index("<table class='summary'>"):]
    summary = summary[:summary.index("</table>")]
    toy = re.search(r"<tr><td>Toy</td>(.*?)</tr>", summary).group(1)
    cells = re.findall(r"<td class='num'>(\d*)</td>", toy)
    assert cells == ["1", "", "1", "", "", "", "", "1"]  # N = 1: within error; 1 derived row
    zhang_row = re.search(r"<tr><td>Zhang</td>(.*?)</tr>", summary).group(1)
    zhang_cells = [int(c or 0) for c in re.findall(r"<td class='num'>(\d*)</td>", zhang_row)]
    assert sum(zhang_cells[1:7]) < zhang_cells[0]  # example 1 did not run: not all judged
    assert "not in this report" in zhang_row
    assert zhang_cells[1] >= 10 and '<a href="#zhang-smartgrid">' in zhang_row
    assert "quick" in zhang_row


def test_summary_lines_show_the_paper_beside_ours():
    summary = Summary("x", "t", "s", [Row("RMSE of v_0", 2.71828, "2.74", "V"),
                                      Row("a quantity the paper does not print", 0.5, None, ""),
                                      Row("verdict", "feasible", "feasible", "")])
    lines = summary.lines(width=12)
    assert lines[0] == "RMSE of v_0  paper      2.74  ours 2.718 V"
    assert lines[1] == "a quantity t paper         -  ours 0.5"
    assert lines[2].endswith("paper  feasible  ours feasible")
