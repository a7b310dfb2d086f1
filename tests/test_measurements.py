"""The measurement table: what write_measurements writes, read_measurements reads back exactly."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from switchest import SwitchedLinearSystem, tabular
from switchest.default_designs import impulsive_gains, rsls_gains, transition_for
from switchest.measurements import mode_signal, read_measurements, write_measurements
from switchest.modelfile import ModelSpec, load_model
from switchest.simulate import simulate

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "models"
LEE = load_model(EXAMPLES / "lee-fsk.toml")  # 2 outputs, 1 input, 2 modes


def spec_for(outputs: int, inputs: int, modes: int) -> ModelSpec:
    """A model with the given numbers of outputs, inputs and modes (one state more than outputs)."""
    n = outputs + 1
    A = np.stack([-(i + 1.0) * np.eye(n) for i in range(modes)])
    B = np.ones((n, inputs)) if inputs else None
    return ModelSpec(SwitchedLinearSystem.continuous(A, B, np.eye(outputs, n)))


def lee_trajectory(trials: int = 2):
    t = LEE.sample_times(0.05)
    traj = simulate(LEE.system, lambda r: LEE.signal(r, t), t, LEE.initial, u=np.array([0.01]),
                    trials=trials, rng=4)
    return t, traj


def test_tabular_still_offers_the_names_that_moved():
    assert tabular.read_measurements is read_measurements
    assert tabular.mode_signal is mode_signal
    assert tabular.transition_for is transition_for
    assert tabular.rsls_gains is rsls_gains
    assert tabular.impulsive_gains is impulsive_gains


def test_one_trial_of_a_trajectory_round_trips_through_a_csv_file(tmp_path):
    t, traj = lee_trajectory()
    y = traj.y.copy()
    y[1, [0, 3, 7], 1] = np.nan  # missing samples
    path = tmp_path / "d.csv"
    written = write_measurements(path, t, y, u=traj.u, x=traj.x, modes=traj.mode, trial=1)
    assert list(written.columns) == ["t", "u", "y0", "y1", "mode", "x0", "x1"]
    assert path.read_text().splitlines()[1].split(",")[3] == ""  # y1 at row 0: an empty cell
    back = read_measurements(path, LEE)
    np.testing.assert_array_equal(back["t"], t)
    np.testing.assert_array_equal(back["y"], y[1])  # NaN where missing, every other bit equal
    np.testing.assert_array_equal(back["u"], traj.u[1])
    np.testing.assert_array_equal(back["mode"], traj.mode[1])
    pd.testing.assert_frame_equal(pd.read_csv(path), written, check_dtype=False)
    np.testing.assert_array_equal(pd.read_csv(path)[["x0", "x1"]].to_numpy(), traj.x[1])


def test_without_a_path_the_table_is_only_built_and_reads_as_a_dataframe():
    t = np.array([0.0, 0.5, 1.25])
    table = write_measurements(None, t, [[1.0], [np.nan], [3.0]])
    assert list(table.columns) == ["t", "y"]
    back = read_measurements(table, spec_for(1, 0, 1))
    np.testing.assert_array_equal(back["y"][:, 0], [1.0, np.nan, 3.0])
    assert back["u"].shape == (3, 0)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(1, 3), st.integers(0, 2), st.integers(1, 3), st.integers(1, 8),
       st.integers(0, 2**32 - 1), st.floats(0.0, 0.5))
def test_any_table_round_trips_exactly(tmp_path_factory, m, l, L, K, seed, missing):
    """Times, inputs, outputs (NaN = missing) and modes come back bit for bit, whatever the
    numbers of columns; one output or input is named ``y`` / ``u`` alone."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.exponential(size=K)) - rng.normal()
    y = rng.normal(size=(K, m)) * 10.0 ** rng.integers(-12, 12, size=(K, m))
    y[rng.random((K, m)) < missing] = np.nan
    u = rng.normal(size=(K, l))
    modes = rng.integers(L, size=K)
    path = tmp_path_factory.mktemp("rt") / "d.csv"
    table = write_measurements(path, t, y, u=u, modes=modes)
    assert ("y" in table) == (m == 1) and ("u" in table) == (l == 1)
    back = read_measurements(path, spec_for(m, l, L))
    for name, sent in {"t": t, "y": y, "u": u, "mode": modes}.items():
        np.testing.assert_array_equal(back[name], sent, err_msg=name)


@pytest.mark.parametrize(("change", "error", "match"), [
    ({"path": 3}, TypeError, "path must be None or the path of a CSV file, got int"),
    ({"trial": 1.0}, TypeError, "trial must be an int, got float"),
    ({"t": [0.0, 0.0, 1.0]}, ValueError, r"t must be strictly increasing, got t\[1\] = 0"),
    ({"t": [0.0, np.inf, 1.0]}, ValueError, "t must be finite"),
    ({"t": []}, ValueError, "t must hold at least one sample time"),
    ({"y": [[1.0], [2.0]]}, ValueError, r"y has 2 samples \(shape \(2, 1\)\), t has 3"),
    ({"y": [1.0, 2.0, 3.0]}, ValueError, r"y must have shape \(K, m\) or \(N, K, m\)"),
    ({"y": np.zeros((3, 0))}, ValueError, "y must have at least one output column"),
    ({"y": [[1.0], [np.inf], [3.0]]}, ValueError, "y must be finite, got inf at index"),
    ({"y": [["a"], ["b"], ["c"]]}, TypeError, "y must be a real numeric array"),
    ({"u": [[1.0], [np.nan], [3.0]]}, ValueError, "u must be finite, got nan"),
    ({"x": [[1.0], [np.nan], [3.0]]}, ValueError, "x must be finite, got nan"),
    ({"modes": [0, -1, 1]}, ValueError, "modes must be 0-based mode indices, got -1 at sample 1"),
    ({"modes": [0, 0.5, 1]}, ValueError, "modes must hold integers"),
    ({"modes": [0, 1]}, ValueError, r"modes has 2 samples \(shape \(2,\)\), t has 3"),
    ({"y": np.ones((2, 3, 1))}, ValueError, "y has a leading trials axis .* pass trial="),
    ({"y": np.ones((2, 3, 1)), "trial": 2}, ValueError, r"trial must be in 0..1 \(y holds 2"),
    ({"trial": 0}, ValueError, "trial=0 chooses among the trials .* none has one"),
])
def test_bad_arguments_are_refused_by_name(tmp_path, change, error, match):
    args = {"path": tmp_path / "d.csv", "t": [0.0, 1.0, 2.0], "y": [[1.0], [2.0], [3.0]]}
    args.update(change)
    with pytest.raises(error, match=match):
        write_measurements(args.pop("path"), args.pop("t"), args.pop("y"), **args)
    assert not (tmp_path / "d.csv").exists()  # nothing half-written


def test_arrays_without_a_trials_axis_go_with_the_chosen_trial():
    """A Trajectory's y with one shared (K, l) input: the input is written as given."""
    t, traj = lee_trajectory()
    shared = np.full((t.size, 1), 0.01)
    table = write_measurements(None, t, traj.y, u=shared, trial=0)
    np.testing.assert_array_equal(table["u"], shared[:, 0])
    np.testing.assert_array_equal(table[["y0", "y1"]].to_numpy(), traj.y[0])


# ------------------------------------------------------------------ simulate_measurements, trials
def test_simulated_trials_read_back_one_at_a_time():
    from switchest.measurements import simulate_measurements

    table = simulate_measurements(LEE, duration=0.05, trials=3, u=[0.5], rng=4)
    assert list(table.columns[:2]) == ["trial", "t"] and set(table["trial"]) == {0, 1, 2}
    with pytest.raises(ValueError, match=r"holds 3 trials \(0\.\.2\): choose one"):
        read_measurements(table, LEE)
    again = simulate_measurements(LEE, duration=0.05, trials=3, u=[0.5], rng=4)
    pd.testing.assert_frame_equal(table, again)  # one seed, one table
    runs = [read_measurements(table, LEE, trial=i) for i in range(3)]
    np.testing.assert_array_equal(runs[0]["t"], runs[2]["t"])  # the trials share their times
    boost = load_model(EXAMPLES / "shankar-boost.toml")  # a model with noise: each trial its own
    noisy = simulate_measurements(boost, duration=0.01, trials=2, u=[100.0], rng=4)
    first, second = (read_measurements(noisy, boost, trial=i)["y"] for i in range(2))
    assert not np.array_equal(first, second)
    assert np.all(runs[1]["u"] == 0.5) and runs[1]["mode"].min() >= 0
    with pytest.raises(ValueError, match=r"trial=5: .* holds trials 0\.\.2"):
        read_measurements(table, LEE, trial=5)
    with pytest.raises(TypeError, match="trial must be an int"):
        read_measurements(table, LEE, trial=1.0)
    single = simulate_measurements(LEE, duration=0.05, rng=4)
    assert "trial" not in single.columns
    with pytest.raises(ValueError, match="has no 'trial' column"):
        read_measurements(single, LEE, trial=0)


def test_simulate_measurements_refuses_bad_input():
    from switchest.measurements import simulate_measurements

    with pytest.raises(ValueError, match="u must hold the model's 1 input"):
        simulate_measurements(LEE, duration=0.05, u=[1.0, 2.0])
    with pytest.raises(ValueError, match="trials must be a positive int"):
        simulate_measurements(LEE, duration=0.05, trials=0)
    with pytest.raises(ValueError, match=r"no \[switching\] table"):
        simulate_measurements(spec_for(1, 0, 2), duration=1.0)
