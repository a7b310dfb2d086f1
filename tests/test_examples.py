"""The examples run end to end at a small size and print what they claim.

Each example's ``main`` is run with a few trials, a short horizon and two grid
sizes; the assertions check the structure of its rows against the parameters
and values that follow from the setup alone (the paper's printed numbers, the
fixed maneuver schedule, the clairvoyant bound).
"""

from __future__ import annotations

import importlib.util
import io
import sys
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from switchest.estimators import IMMEV1Filter
from switchest.models import BOOST_SAMPLE_PERIOD, vehicle_2d

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
GRIDS = (1, 2)


def load(name: str):
    """Import ``examples/<name>.py`` as a module."""
    spec = importlib.util.spec_from_file_location(f"examples_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses resolve their module while the file executes
    spec.loader.exec_module(module)
    return module


def quiet() -> Console:
    return Console(file=io.StringIO(), width=200)


# ---------------------------------------------------------------- Table I (boost converter)
@pytest.fixture(scope="module")
def table1():
    ex = load("shankar_table1")
    console = quiet()
    rows = ex.main(trials=3, duration=0.02, grids=GRIDS, seed=0, console=console)
    return ex, rows, console.file.getvalue()


def test_table1_defaults_are_the_papers_setup(table1):
    ex, _, _ = table1
    assert (ex.TRIALS, ex.DURATION, ex.GRIDS) == (100, 10.0, (1, 2, 3, 4, 5))
    assert tuple(ex.TABLE1_PAPER["g"]) == ex.GRIDS


def test_table1_rows_cover_every_filter_and_grid(table1):
    _, rows, _ = table1
    found = {(r.filter, r.g) for r in rows}
    grid_filters = ("switch-time KF", "switch-time KF, refined", "switch-time KF, tau marginalized",
                    "IMM-EV1 (Alg. 1)", "IMM-EV1, tau marginalized")
    expected = {("clairvoyant", None), ("IMM", None)}
    expected |= {(f, g) for f in grid_filters for g in GRIDS}
    assert found == expected and len(rows) == len(expected)


def test_table1_prints_the_papers_values_beside_the_grid_filter(table1):
    _, rows, text = table1
    paper = {r.g: r.paper for r in rows if r.filter == "switch-time KF"}
    assert paper == {1: ("13.5", "2.74"), 2: ("10.7", "2.15")}
    assert all(r.paper is None for r in rows if r.filter != "switch-time KF")
    assert "13.5" in text and "2.74" in text and "10.7" in text and "2.15" in text


def test_table1_clairvoyant_filter_is_far_below_the_others(table1):
    _, rows, _ = table1
    clair = next(r for r in rows if r.filter == "clairvoyant").rmse
    for r in rows:
        if r.filter != "clairvoyant":
            assert np.all(clair < 0.1 * r.rmse), (r.filter, r.g, r.rmse)


def test_table1_one_point_grid_puts_every_switch_at_the_midpoint(table1):
    ex, rows, _ = table1
    traj = ex.SETTING.simulate(0.02, 3, 0)  # the data main() ran on
    true = traj.switch_times()
    k = np.nonzero(np.isfinite(true))[1]
    midpoint = traj.t[k - 1] + BOOST_SAMPLE_PERIOD / 2
    midpoint_error = np.mean(np.abs(midpoint - true[np.isfinite(true)]))
    g1 = next(r for r in rows if r.filter == "switch-time KF" and r.g == 1)
    np.testing.assert_allclose(g1.switch_error, midpoint_error, rtol=1e-9)
    for r in rows:
        if r.g is not None:  # every estimate lies inside its interval
            assert 0 < r.switch_error <= BOOST_SAMPLE_PERIOD
        known = r.filter.startswith("switch-time") or r.filter == "clairvoyant"
        assert np.isnan(r.mode_accuracy) == known
        assert known or 0 <= r.mode_accuracy <= 1


# ---------------------------------------------------------------- vehicle maneuver (IMM-EV1)
@pytest.fixture(scope="module")
def vehicle():
    ex = load("shankar_imm_ev1")
    console = quiet()
    rows, info = ex.main(trials=20, duration=5.0, grids=GRIDS, seed=0, console=console)
    return ex, rows, info, console.file.getvalue()


def test_vehicle_defaults_are_the_papers_setup(vehicle):
    ex, _, _, _ = vehicle
    assert (ex.TRIALS, ex.DURATION, ex.GRIDS) == (500, 10.0, (1, 2, 5, 10))
    np.testing.assert_allclose(ex.STICKY.sum(axis=1), 1.0)


def test_vehicle_rows_cover_baselines_and_every_variant(vehicle):
    ex, rows, _, text = vehicle
    found = [(r.filter, r.g) for r in rows]
    per_g = ["switch-time KF (modes known)", *ex.VARIANTS]
    assert found[:2] == [("clairvoyant (true switch times)", None),
                         (f"IMM (P(stay) = {ex.STAY:g})", None)]
    assert found[2:] == [(f, g) for f in per_g for g in GRIDS]
    assert "constant guess of the most frequent mode" in text


def test_vehicle_known_mode_one_point_grid_error_is_the_midpoint_error(vehicle):
    """Switches at 1.65, 2.75, 3.9 s lie 0.15, 0.25, 0.4 s into their 0.5 s intervals (§V.B)."""
    _, rows, info, _ = vehicle
    expected = np.mean(np.abs(0.25 - np.array([0.15, 0.25, 0.4])))
    g1 = next(r for r in rows if r.filter == "switch-time KF (modes known)" and r.g == 1)
    np.testing.assert_allclose(g1.switch_error, expected, rtol=1e-9)
    assert g1.switch_hits == 1.0 and g1.false_switches == 0.0
    np.testing.assert_allclose([r["offset"] for r in info], [0.15, 0.25, 0.4], atol=1e-12)
    np.testing.assert_allclose([r["grid_error_1"] for r in info], [0.1, 0.0, 0.15], atol=1e-12)
    np.testing.assert_allclose([r["midpoint_error"] for r in info], [0.1, 0.0, 0.15], atol=1e-12)


def test_vehicle_clairvoyant_velocity_error_is_below_every_estimator(vehicle):
    _, rows, _, _ = vehicle
    clair = rows[0].rmse
    for r in rows[1:]:
        assert np.all(clair[[1, 3]] < r.rmse[[1, 3]]), (r.filter, r.g, r.rmse)


def test_vehicle_accuracies_are_fractions_and_defined_where_they_should_be(vehicle):
    ex, rows, _, _ = vehicle
    for r in rows:
        accs = np.array([r.accuracy, r.accuracy_delayed, r.accuracy_path])
        if r.filter in ex.VARIANTS:
            assert np.all((accs >= 0) & (accs <= 1))
            assert 0 <= r.switch_hits <= 1 and r.false_switches >= 0
        else:
            assert np.all(np.isnan(accs[1:]))


def test_traced_run_equals_the_filters_own_run_and_decodes_its_predecessors():
    ex = load("shankar_imm_ev1")
    traj = ex.maneuver_data(trials=6, duration=5.0, seed=1)
    filt = IMMEV1Filter(vehicle_2d(), x0=ex.X0, P0=ex.P0, grid=3)  # no prior: paths switch often
    dec = ex.run_traced(filt, traj)
    est = filt.run(traj.y, traj.u, traj.t)
    np.testing.assert_allclose(dec.x, est.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(dec.mode, est.mode)
    np.testing.assert_array_equal(np.isnan(dec.switch_time), np.isnan(est.switch_time))
    np.testing.assert_allclose(dec.switch_time, est.switch_time, rtol=1e-12)
    # oracle: step the filter by hand and read the predecessors off its states
    N, K = traj.mode.shape
    rows = np.arange(N)
    states, state = [], filt.init((N,))
    for k in range(K):
        state = filt.step(state, traj.y[:, k], traj.u[:, max(k - 1, 0)],
                          dt=None if k == 0 else traj.t[k] - traj.t[k - 1])
        states.append(state)
    for k in range(K - 1):
        best_next = np.argmax(states[k + 1].log_weight, axis=1)
        np.testing.assert_array_equal(dec.delayed[:, k], states[k + 1].predecessor[rows, best_next])
        on_path = states[k + 1].predecessor[rows, dec.path[:, k + 1]]
        np.testing.assert_array_equal(dec.path[:, k], on_path)
    np.testing.assert_array_equal(dec.delayed[:, -1], est.mode[:, -1])
    np.testing.assert_array_equal(dec.path[:, -1], est.mode[:, -1])
    assert np.any(dec.delayed != dec.mode) and np.any(dec.path != dec.delayed)
