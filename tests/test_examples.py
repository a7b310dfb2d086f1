"""Every example of the gallery runs end to end, smaller than in the documentation, and shows
what its text claims.

Each script is run as ``python examples/NAME.py ARGS`` would run it (``runpy`` with
``__name__ == "__main__"``), from a temporary folder (it writes its figures under
``figures/``); the assertions check its results against what follows from the setup alone:
the paper's printed numbers, invariants of the methods, the figures it says it draws.
"""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest

from switchest.experiments.shankar import TABLE1_PAPER

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

# the arguments each example's test runs it with (smaller than the gallery's)
ARGV = {
    "bakeoff": [],
    "boost_converter": ["0.03"],
    "check_certificates": [],
    "etienne_observer": [],
    "fit_round_trip": ["4"],
    "lee_detection": ["4"],
    "rbpf_particles": ["5"],
    "shankar_imm_ev1": ["5"],
    "shankar_table1": ["2", "0.05"],
    "smoother_exact": ["8"],
    "wang_ieee5bus": ["20", "3"],
    "zhang_bias": [],
}


@pytest.fixture
def run(tmp_path, monkeypatch):
    """``run(name)``: the globals of ``examples/<name>.py`` after running it with ``ARGV``."""
    monkeypatch.chdir(tmp_path)

    def _run(name: str) -> dict:
        monkeypatch.setattr(sys, "argv", [f"{name}.py", *ARGV[name]])
        try:
            return runpy.run_path(str(EXAMPLES / f"{name}.py"), run_name="__main__")
        finally:
            plt.close("all")

    return _run


def figures(*names: str) -> None:
    for name in names:
        assert Path("figures", name).stat().st_size > 1000, name


def test_every_example_is_tested():
    assert {p.stem for p in EXAMPLES.glob("*.py")} == set(ARGV)


def test_boost_converter_switch_time_filter_beats_the_mixtures_on_the_current(run):
    g = run("boost_converter")
    errors = g["errors"]
    assert set(errors) == {"switch-time KF, g = 5", "switch-time KF, g = 5, merged", "IMM", "GPB2"}
    for name in ("switch-time KF, g = 5", "switch-time KF, g = 5, merged"):
        assert errors[name][0] < min(errors["IMM"][0], errors["GPB2"][0]), name
    figures("boost-trial.png", "boost-rmse.png")


def test_smoother_and_filter_agree_where_they_must(run):
    g = run("smoother_exact")
    p = g["probabilities"]
    for name, values in p.items():
        assert values.shape == (8,) and np.all((values >= 0) & (values <= 1)), name
    # at the last sample the smoother conditions on what the filter does
    assert p["exact smoother"][-1] == pytest.approx(p["exact filter"][-1], abs=1e-9)
    # before the first merge the IMM filter is exact
    assert p["IMM filter"][0] == pytest.approx(p["exact filter"][0], abs=1e-9)
    figures("smoother-exact.png")


def test_rbpf_error_falls_with_its_particles(run):
    g = run("rbpf_particles")
    assert g["rbpf"].shape == g["counts"].shape and np.all(np.isfinite(g["rbpf"]))
    assert g["rbpf"][-1] < g["rbpf"][0]
    figures("rbpf-particles.png")


def test_table1_is_computed_beside_the_printed_values(run):
    g = run("shankar_table1")
    np.testing.assert_array_equal(g["grids"], [1, 2, 3, 4, 5])
    np.testing.assert_allclose(g["paper"][0], [13.5, 2.74])  # Table I, g = 1
    np.testing.assert_allclose(g["paper"][:, 1], np.array(TABLE1_PAPER["v_0"], dtype=float))
    assert g["paper"].shape == g["grid_rmse"].shape == (5, 2)
    assert np.all(g["clairvoyant"] < 0.1 * g["grid_rmse"].min(axis=0))
    figures("table1.png")


def test_imm_ev1_switching_instants_lie_in_their_interval(run):
    g = run("shankar_imm_ev1")
    assert g["errors"].size > 0 and np.all((g["errors"] >= 0) & (g["errors"] <= 0.5))
    figures("imm-ev1-trial.png")


@pytest.mark.parametrize("name, experiment, drawn", [
    ("lee_detection", "lee-detection", 3),
    ("etienne_observer", "etienne-sync", 3),
    ("zhang_bias", "zhang-example1", 4),
    ("bakeoff", "bakeoff", 1),
])
def test_reproduction_examples_print_rows_and_draw_the_reports_figures(run, name, experiment,
                                                                        drawn):
    g = run(name)
    summary = g["summary"]
    assert summary.experiment == experiment and summary.rows
    assert len(summary.figures) == drawn
    figures(*(f.name for f in summary.figures))


def test_zhang_bias_stays_below_the_printed_tolerance(run):
    rows = run("zhang_bias")["summary"].rows
    fig6 = [r for r in rows if r.quantity.startswith("Fig. 6") and "(9)" in r.quantity]
    assert fig6 and all(r.paper == "≤ 0.3" and r.measured < 0.3 for r in fig6)


def test_fit_lands_within_a_few_standard_errors(run):
    g = run("fit_round_trip")
    assert g["fitted"].shape == g["se"].shape == (6,)
    assert np.all(g["se"] > 0) and np.all(np.abs(g["z"]) < 5)
    figures("fit.png")


def test_check_margins_have_the_verdicts_sign(run):
    checks = run("check_certificates")["checks"]
    assert len(checks) >= 10
    for c in checks:
        if c.margin is not None and c.verdict is not None:
            assert (c.margin > 0) == c.verdict, c.name


def test_wang_critical_interval_and_ms_error(run):
    g = run("wang_ieee5bus")
    assert g["ci"].printed_t_max == pytest.approx(0.7365, abs=1e-4)  # printed T_max, §6
    for name, radius in g["radius"].items():  # converges at T_max, not beyond the fast limit
        below = g["periods"] <= g["ci"].printed_t_max
        assert np.all(radius[below] < 1), name
    assert g["results"]["first"]["exact"].shape == (4,)
    figures("wang-critical-interval.png", "wang-ieee5bus.png")
