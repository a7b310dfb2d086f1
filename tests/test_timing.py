"""One timing convention end to end (issue 35): the system carries it, the model file writes
and reads it, ``simulate`` draws in it and records it, the multiple-model filters default to
it, and a filter of the other timing is named in a TimingWarning (docs/conventions.rst)."""

import warnings

import numpy as np
import pytest

from switchest import SwitchedLinearSystem, simulate
from switchest.estimators import (
    ExactMixtureFilter,
    GPB1Filter,
    GPB2Filter,
    IMMFilter,
    RBPFilter,
    TimingWarning,
)
from switchest.learn import fit
from switchest.modelfile import ModelSpec, load_model, load_system, save_model, save_system
from switchest.signals import SwitchingSignal
from switchest.switching import MarkovAtSamples

FILTERS = [IMMFilter, GPB1Filter, GPB2Filter, RBPFilter, ExactMixtureFilter]
TRANSITION = np.array([[0.8, 0.2], [0.3, 0.7]])


def two_mode_system(timing="sample"):
    """Modes that differ in A and in C: the two timings are different models."""
    A = [[[0.9, 0.1], [0.0, 0.8]], [[0.5, -0.2], [0.3, 0.6]]]
    C = [[[1.0, 0.0]], [[0.0, 1.0]]]
    return SwitchedLinearSystem.discrete(A, None, C, Q=0.1 * np.eye(2), R=[[0.05]], dt=1.0,
                                         timing=timing)


def build(cls, system, **kw):
    extra = {"particles": 64, "rng": 3} if cls is RBPFilter else {}
    return cls(system, TRANSITION, np.zeros(2), np.eye(2), **extra, **kw)


# ---------------------------------------------------------------------- the system
def test_the_system_carries_a_checked_timing_through_its_constructors():
    assert two_mode_system().timing == "sample"  # the default: what simulate draws
    sys = two_mode_system("interval")
    assert sys.timing == "interval"
    assert sys.replace(R=[[0.2]]).timing == "interval"  # a derived system keeps it
    assert sys.replace(timing="sample").timing == "sample"
    assert SwitchedLinearSystem.continuous(-np.eye(2), timing="interval").timing == "interval"
    assert "timing='interval'" in repr(sys)
    with pytest.raises(ValueError, match=r"timing must be one of \('sample', 'interval'\), "
                                         "got 'intervals'"):
        two_mode_system("intervals")
    with pytest.raises(TypeError, match="timing must be one of .* got int"):
        SwitchedLinearSystem.continuous(-np.eye(2), timing=1)


def test_from_statespace_takes_the_timing():
    class StateSpace:  # python-control's attributes, without python-control
        A, B, C, D, dt = -np.eye(2), np.zeros((2, 1)), np.eye(1, 2), np.zeros((1, 1)), 0
    sys = SwitchedLinearSystem.from_statespace([StateSpace(), StateSpace()], timing="interval")
    assert sys.timing == "interval" and sys.is_continuous


# ---------------------------------------------------------------------- the model file
def test_the_model_files_timing_is_the_systems_and_round_trips(tmp_path):
    spec = ModelSpec(two_mode_system("interval"), sampling={"period": 1.0})
    assert spec.timing == "interval"
    back = load_model(save_model(spec, tmp_path / "m.toml"))
    assert back.timing == back.system.timing == "interval"
    assert 'timing = "interval"' in (tmp_path / "m.toml").read_text()
    assert load_system(tmp_path / "m.toml").timing == "interval"
    assert load_system(save_system(two_mode_system(), tmp_path / "s.toml")).timing == "sample"
    assert "timing" not in (tmp_path / "s.toml").read_text()  # the default is not written


# ---------------------------------------------------------------------- simulate
def test_simulate_records_its_timing_and_measures_in_the_mode_of_the_interval_into_a_sample():
    """A switch exactly at t_2: the "sample" timing records and measures the new mode there,
    the "interval" one the mode of the interval into t_2; the states are the same path."""
    signal = SwitchingSignal(times=[2.0], modes=[0, 1])
    t = np.arange(5.0)
    out = {tm: simulate(two_mode_system(tm), signal, t, np.ones(2), trials=2, rng=4)
           for tm in ("sample", "interval")}
    assert out["sample"].timing == "sample" and out["interval"].timing == "interval"
    np.testing.assert_array_equal(out["sample"].mode, [[0, 0, 1, 1, 1]] * 2)
    np.testing.assert_array_equal(out["interval"].mode, [[0, 0, 0, 1, 1]] * 2)
    np.testing.assert_allclose(out["sample"].x, out["interval"].x, rtol=1e-14)
    # y_2 = C(mode) x_2 + v with the same noise draw: the first output in "interval"
    x2, v = out["interval"].x[:, 2], out["interval"].y[:, 2, 0] - out["interval"].x[:, 2, 0]
    np.testing.assert_allclose(out["sample"].y[:, 2, 0], x2[:, 1] + v, rtol=1e-12)


def test_switches_inside_the_intervals_give_the_same_data_in_both_timings():
    signal = SwitchingSignal(times=[1.3, 2.6], modes=[0, 1, 0])
    sys = {tm: SwitchedLinearSystem.continuous(two_mode_system().A - np.eye(2),
                                               C=two_mode_system().C, Q=0.1 * np.eye(2),
                                               R=[[0.05]], timing=tm)
           for tm in ("sample", "interval")}
    a, b = (simulate(sys[tm], signal, np.arange(5.0), np.ones(2), rng=1) for tm in sys)
    np.testing.assert_array_equal(a.mode, b.mode)
    np.testing.assert_allclose(a.y, b.y, rtol=1e-14)


# ---------------------------------------------------------------------- the filters
@pytest.mark.parametrize("cls", FILTERS, ids=lambda c: c.__name__)
@pytest.mark.parametrize("timing", ["sample", "interval"])
def test_a_filter_defaults_to_its_systems_timing(cls, timing):
    sys = two_mode_system(timing)
    traj = simulate(sys, MarkovAtSamples(TRANSITION), np.arange(8.0), np.zeros(2), trials=3,
                    rng=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TimingWarning)
        default = build(cls, sys)
        est = default.run(traj.y, data_timing=traj.timing)
    assert default.timing == timing
    other = "interval" if timing == "sample" else "sample"
    with pytest.warns(TimingWarning):
        theirs = build(cls, sys, timing=other).run(traj.y)
    np.testing.assert_allclose(est.x, build(cls, sys, timing=timing).run(traj.y).x, rtol=1e-12)
    # the timings are different models here: the default is the system's, not the other
    assert not np.allclose(est.mode_prob, theirs.mode_prob, atol=1e-3)


@pytest.mark.parametrize("cls", FILTERS, ids=lambda c: c.__name__)
def test_an_explicit_other_timing_and_data_of_another_are_named(cls):
    sys = two_mode_system("sample")
    with pytest.warns(TimingWarning, match=f"{cls.__name__} runs in the 'interval' timing, its "
                                           "system in the 'sample' one"):
        build(cls, sys, timing="interval")
    y = np.zeros((4, 1))
    with pytest.warns(TimingWarning, match="the data were drawn in the 'interval' one"):
        build(cls, sys).run(y, data_timing="interval")
    with pytest.raises(ValueError, match="data_timing must be one of"):
        build(cls, sys).run(y, data_timing="before")


def test_the_smoothers_check_the_datas_timing():
    sys = two_mode_system("sample")
    with pytest.warns(TimingWarning, match="drawn in the 'interval' one"):
        IMMFilter(sys, TRANSITION, np.zeros(2), np.eye(2)).smooth(np.zeros((4, 1)),
                                                                 data_timing="interval")
    with pytest.warns(TimingWarning, match="drawn in the 'interval' one"):
        ExactMixtureFilter(sys, TRANSITION, np.zeros(2), np.eye(2)).smooth(
            np.zeros((4, 1)), data_timing="interval")


# ---------------------------------------------------------------------- learning
def test_fit_runs_in_the_sample_timing_without_a_timing_warning_and_refuses_the_other():
    sys = two_mode_system()
    traj = simulate(sys, MarkovAtSamples(TRANSITION), np.arange(30.0), np.zeros(2), trials=2,
                    rng=5)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TimingWarning)  # the pair chain's IMM is interval-timed
        res = fit(sys, traj.y, transition=TRANSITION, x0=np.zeros(2), P0=np.eye(2),
                  estimate=("R",), max_iter=2)
    assert res.system.timing == "sample"
    with pytest.raises(ValueError, match="system.timing must be 'sample' to fit"):
        fit(two_mode_system("interval"), traj.y, transition=TRANSITION, x0=np.zeros(2),
            P0=np.eye(2), estimate=("R",), max_iter=2)


def test_the_kalman_filter_along_given_modes_names_an_interval_timed_system():
    """ModeKalmanFilter predicts an interval in the mode of the sample that starts it: the
    "sample" timing only."""
    from switchest.estimators import ModeKalmanFilter

    with warnings.catch_warnings():
        warnings.simplefilter("error", TimingWarning)
        ModeKalmanFilter(two_mode_system(), np.zeros(2), np.eye(2))
    with pytest.warns(TimingWarning, match="ModeKalmanFilter predicts each interval in the "
                                           "mode of the sample that starts it"):
        ModeKalmanFilter(two_mode_system("interval"), np.zeros(2), np.eye(2))
