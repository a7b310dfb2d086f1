"""The report: verdicts at the printed precision, provenance, the summary per paper, Monte Carlo
uncertainty; rendered from small stores and checked on the HTML."""

import html
import re
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
from switchest.experiments.verdict import Verdict, judge, printed_number


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
    assert judge(str(printed), value, note="a misprint") is Verdict.EXPLAINED


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

    rows = (tmp_path / "rows.csv").read_text().splitlines()
    assert rows[0] == "experiment,quantity,paper,ours,se,trials,unit,verdict,note"
    assert any(r.startswith("toy-mc,Monte Carlo mean,2.000,2.0015,0.01,400,,within sampling error")
               for r in rows)

    provenance = page[:page.index("id='summary'")]
    for fact in ("commit", "switchest report --store r.sqlite", "machine", "date", "12 s"):
        assert fact in provenance
    assert "1 full, 1 quick" in provenance and "0, 7" in provenance  # modes and seeds

    # a value reproduced to its printed digits, and a misprint (the printed -0.0088 is ten
    # times ours: a slipped decimal) that differs with its explanation
    reproduced = _row(page, "‖Λ_2‖")
    assert reproduced.startswith("ok ") and ">0.8837<" in reproduced and "reproduced" in reproduced
    misprint = _row(page, "T_2,3[2,2] = (Λ_i − Γ_i,q)[2,2] (Algorithm 2)")
    assert misprint.startswith("known ") and ">-0.0088<" in misprint
    assert "differs, explained" in misprint and "slipped decimal" in misprint

    # a Monte Carlo row: mean ± standard error and the trial count, judged by its interval
    mc = _row(page, "Monte Carlo mean")
    assert "2.00150 ± 0.010" in mc and "n = 400" in mc and "within sampling error" in mc
    assert _row(page, "derived quantity").startswith("derived ")

    # the summary counts only printed values, per paper, and links to the sections
    summary = page[page.index("<table class='summary'>"):]
    summary = summary[:summary.index("</table>")]
    toy = re.search(r"<tr><td>Toy</td>(.*?)</tr>", summary).group(1)
    cells = re.findall(r"<td class='num'>(\d*)</td>", toy)
    assert cells == ["", "1", "", "", "1"]  # within error 1, derived 1
    counts = _verdict_counts(page, "zhang-smartgrid")
    zhang_row = re.search(r"<tr><td>Zhang</td>(.*?)</tr>", summary).group(1)
    zhang_cells = [int(c or 0) for c in re.findall(r"<td class='num'>(\d*)</td>", zhang_row)]
    assert zhang_cells == [counts[v] for v in (Verdict.REPRODUCED, Verdict.WITHIN_ERROR,
                                               Verdict.EXPLAINED, Verdict.DIFFERS,
                                               Verdict.DERIVED)]
    assert zhang_cells[0] >= 10 and '<a href="#zhang-smartgrid">' in zhang_row
    assert "quick" in zhang_row


def _verdict_counts(page: str, experiment: str) -> dict:
    section = page[page.index(f'<h2 id="{experiment}">'):]
    section = section[:section.index("</table>")]
    classes = re.findall(r'<tr class="(\w+)">', section)
    names = {"ok": Verdict.REPRODUCED, "near": Verdict.WITHIN_ERROR, "known": Verdict.EXPLAINED,
             "off": Verdict.DIFFERS, "derived": Verdict.DERIVED}
    return {v: sum(names[c] is v for c in classes) for v in Verdict}
