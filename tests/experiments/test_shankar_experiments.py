"""Shankar et al. reproductions: Lemma 1's counter-example and the Table I readings section."""

import numpy as np
from summary_rows import assert_every_printed_item_judged

from switchest.experiments import Store, get, run_experiment
from switchest.experiments.verdict import FALLS, Reason, Verdict


def _summary(name, tmp_path, **overrides):
    exp = get(name)
    params = exp.params(quick=True, **overrides)
    results = run_experiment(exp, params, store=Store(tmp_path / "s.sqlite"), workers=1)
    return exp.summarize(params, results, tmp_path / "figures")


def test_lemma1_printed_claim_fails_and_the_corrected_one_holds(tmp_path):
    rows = _summary("shankar-lemma1", tmp_path).rows
    printed = next(r for r in rows if "printed window" in r.quantity)
    assert printed.verdict is Verdict.EXPLAINED and printed.measured < 1e-3 * 0.2887
    assert printed.explanation.reason is Reason.PAPER_ERROR
    corrected = next(r for r in rows if r.quantity.startswith("corrected statement"))
    assert corrected.verdict is Verdict.DERIVED and "holds" in corrected.details


def test_table1_readings_judge_the_closest_reading_against_the_printed_table(tmp_path):
    summary = _summary("shankar-table1-readings", tmp_path, process_noises=[1.0, 10000.0],
                       inflations=[0.0, 1.0])
    readings = [r for r in summary.rows if r.quantity.startswith("reading:")]
    assert len(readings) == 2 * 2 * 2 * 2  # schedules x process noises x inflations x likelihoods
    deviations = [r.measured for r in readings]
    assert all(r.verdict is Verdict.DERIVED for r in readings) and deviations == sorted(deviations)
    judged = [r for r in summary.rows if r.quantity.startswith("closest reading")]
    assert len(judged) == 10 and all(r.paper is not None and r.se > 0 for r in judged)
    assert {r.paper for r in judged} >= {"9.40", "2.00"}  # the printed digits, zeros kept
    # a reading chosen to be closest is a fitted reading of Table I's items, never reproduced
    assert all(r.fit is not None and r.reading and r.item.startswith("Table I: RMSE")
               for r in judged)
    assert all(r.verdict in (Verdict.FITTED, Verdict.DIFFERS) for r in judged)
    best = summary.notes[0]
    assert best.startswith("Closest to the printed table:")
    assert np.all([r.trials == 4 for r in judged]) and summary.figures[0].exists()
    effects = [note for note in summary.notes if "moves the ten values by up to" in note]
    assert [e.split(":")[0] for e in effects] == ["schedule", "process noise", "inflation",
                                                   "likelihood"]


def test_table1_readings_without_a_zero_inflation(tmp_path):
    """The setting effects compare readings with each other, not with an epsilon = 0 one."""
    summary = _summary("shankar-table1-readings", tmp_path, process_noises=[1.0],
                       schedules=["constant"], inflations=[1.0, 3.0], likelihoods=["innovation"])
    effect = next(note for note in summary.notes if note.startswith("inflation:"))
    assert "changing it from 1 moves the ten values by up to" in effect


NAMES = ("shankar-table1", "shankar-table1-readings", "shankar-vehicle", "shankar-lemma1",
         "shankar-lemma2")  # run by the `runs` fixture of conftest.py


def test_table1_items_carry_a_reason_and_the_trend_claims_are_items(runs):
    summary = runs["shankar-table1"][2]
    printed = [r for r in summary.rows if r.paper is not None and r.item.startswith("Table I: RMSE")
               and "falls" not in r.item]
    assert len(printed) == 10
    assert all(r.explanation.reason is Reason.UNSTATED for r in printed)
    assert all(r.verdict is not Verdict.EXPLAINED or r.explanation for r in printed)
    trends = [r for r in summary.rows if r.item and r.item.endswith("falls as g grows")]
    assert [r.paper for r in trends] == [FALLS, FALLS] and all(r.trials for r in trends)
    vehicle = [r for r in runs["shankar-vehicle"][2].rows if r.paper is not None]
    assert len(vehicle) == 2 and len({r.item for r in vehicle}) == 1


def test_every_printed_item_of_the_paper_is_judged_or_declared_not_computed(runs):
    assert_every_printed_item_judged("Shankar", [summary for _, _, summary in runs.values()])
