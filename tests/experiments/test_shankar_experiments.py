"""Shankar et al. reproductions: Lemma 1's counter-example and the Table I readings section."""

import numpy as np

from switchest.experiments import Store, get, run_experiment
from switchest.experiments.verdict import Verdict


def _summary(name, tmp_path, **overrides):
    exp = get(name)
    params = exp.params(quick=True, **overrides)
    results = run_experiment(exp, params, store=Store(tmp_path / "s.sqlite"), workers=1)
    return exp.summarize(params, results, tmp_path / "figures")


def test_lemma1_printed_claim_fails_and_the_corrected_one_holds(tmp_path):
    rows = _summary("shankar-lemma1", tmp_path).rows
    printed = next(r for r in rows if "printed window" in r.quantity)
    assert printed.verdict is Verdict.EXPLAINED and printed.measured < 1e-3 * 0.2887
    corrected = next(r for r in rows if r.quantity.startswith("corrected statement"))
    assert corrected.verdict is Verdict.DERIVED and "holds" in corrected.note


def test_table1_readings_judge_the_closest_reading_against_the_printed_table(tmp_path):
    summary = _summary("shankar-table1-readings", tmp_path, process_noises=[1.0, 10000.0],
                       inflations=[0.0, 1.0])
    readings = [r for r in summary.rows if r.quantity.startswith("reading:")]
    assert len(readings) == 2 * 2 * 2 * 2  # schedules x process noises x inflations x likelihoods
    assert all(r.verdict is Verdict.DERIVED and 0 <= r.measured <= 10 for r in readings)
    judged = [r for r in summary.rows if r.quantity.startswith("closest reading")]
    assert len(judged) == 10 and all(r.paper is not None and r.se > 0 for r in judged)
    assert {r.paper for r in judged} >= {"9.40", "2.00"}  # the printed digits, zeros kept
    best = summary.notes[0]
    assert best.startswith("Closest to the printed table:")
    assert np.all([r.trials == 4 for r in judged]) and summary.figures[0].exists()
    effect = next(note for note in summary.notes if note.startswith("Algorithm 1's inflation"))
    assert "epsilon = 1: i_L by up to" in effect
