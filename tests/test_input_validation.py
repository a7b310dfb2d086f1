"""Each class of malformed input found by the fuzz of issue 19 gets a clear error, named argument.

Classes: arrays of the wrong kind (complex, boolean, dates, objects) anywhere a real array is
expected; a system without outputs; masked arrays; non-finite or out-of-interval switch
offsets; requests that cannot finish or fit (switch counts, trial counts, grid sizes); and
the valid extremes next to them that must keep working (a dwell time of 1e-15 s).
"""

import time
from pathlib import Path

import numpy as np
import pytest

from switchest import SwitchedLinearSystem, _checks, metrics
from switchest import signals as sg
from switchest.analysis import is_observable
from switchest.discretize import interval, pairwise_grid, segment_transitions
from switchest.estimators import (
    IMMFilter,
    ModeKalmanFilter,
    SwitchTimeKalmanFilter,
    impulsive_update,
    switch_time_loglik,
)
from switchest.simulate import simulate

A = np.array([[[-0.4, 1.0], [-1.0, -0.3]], [[-0.1, 0.0], [0.5, -1.2]]])
B = np.array([[0.0], [1.0]])
C = np.array([[1.0, 0.2]])
SYS = SwitchedLinearSystem.continuous(A, B, C, Q=0.05 * np.eye(2), R=[[0.1]])
X0, P0 = np.array([0.5, -0.5]), np.eye(2)
T = sg.periodic(0.25, 1.5)  # 7 samples
SIGNAL = sg.schedule([0.6, 1.1], [0, 1, 0])  # both switches inside sample intervals
# a refusal happens before any work: far below the minutes the refused request would take
UP_FRONT_SECONDS = 5.0


@pytest.fixture
def memory_4gib(monkeypatch):
    """Memory refusals independent of the machine: the limit is fixed at 4 GiB."""
    monkeypatch.setattr(_checks, "memory_limit", lambda: 4 * 2**30)


def trajectory(trials=2):
    return simulate(SYS, SIGNAL, T, X0, u=np.ones(1), trials=trials, rng=3)


# ---------------------------------------------------------------- wrong kinds of array
WRONG_KINDS = {
    "complex": lambda a: np.asarray(a, dtype=float) + 1j,
    "bool": lambda a: np.asarray(a, dtype=float) != 0,
    "datetime": lambda a: np.zeros(np.shape(a), dtype="datetime64[s]"),
    "object": lambda a: np.full(np.shape(a), None, dtype=object),
}
DTYPE_TEXT = {"complex": "complex128", "bool": "bool", "datetime": "datetime64", "object": "object"}


@pytest.mark.parametrize("kind", WRONG_KINDS)
@pytest.mark.parametrize("name", ["A", "B", "C", "Q", "R"])
def test_system_matrices_of_the_wrong_kind_are_refused(name, kind):
    args = dict(A=A, B=B, C=C, Q=0.05 * np.eye(2), R=[[0.1]])
    args[name] = WRONG_KINDS[kind](args[name])
    message = rf"^{name} must be a real numeric array.*{DTYPE_TEXT[kind]}"
    with pytest.raises(TypeError, match=message):
        SwitchedLinearSystem.continuous(**args)


@pytest.mark.parametrize("kind", WRONG_KINDS)
def test_real_arrays_everywhere_else_refuse_the_wrong_kind(kind):
    bad = WRONG_KINDS[kind]
    traj = trajectory()
    P = np.array([[0.9, 0.1], [0.3, 0.7]])
    calls = {
        "x0": lambda: ModeKalmanFilter(SYS, bad(X0), P0),
        "P0": lambda: ModeKalmanFilter(SYS, X0, bad(P0)),
        "y": lambda: ModeKalmanFilter(SYS, X0, P0).run(bad(traj.y), traj.u, T, modes=traj.mode),
        "u": lambda: ModeKalmanFilter(SYS, X0, P0).run(traj.y, bad(traj.u), T, modes=traj.mode),
        "t": lambda: ModeKalmanFilter(SYS, X0, P0).run(traj.y, traj.u, bad(T), modes=traj.mode),
        "transition": lambda: IMMFilter(SYS, bad(P), X0, P0),
        "offsets": lambda: interval(SYS, 0.25, [0, 1], bad([0.1])),
        "estimate": lambda: metrics.rmse(bad(traj.x), traj.x),
    }
    for name, call in calls.items():
        with pytest.raises(TypeError, match=rf"^{name} must be .*(real|numeric)"):
            call()


def test_complex_scalars_and_boolean_seeds_are_refused():
    with pytest.raises(TypeError, match="dt must be a real scalar, got complex"):
        SwitchedLinearSystem.discrete(A, dt=0.1 + 0j)
    with pytest.raises(TypeError, match="rng must be .* got bool"):
        sg.dwell_time(2, 5.0, 0.5, 1.0, rng=True)
    with pytest.raises(TypeError, match="steady_state must be True or False, got str"):
        ModeKalmanFilter(SYS, X0, P0, steady_state="no")


def test_object_arrays_of_plain_numbers_still_work():
    # e.g. a list mixing Python ints and floats, or Python ints beyond int64
    sys = SwitchedLinearSystem.continuous(np.array([[-1, 0.5], [0, -2]], dtype=object))
    assert sys.A.dtype == np.float64 and sys.A[0, 0, 1] == 0.5


# ---------------------------------------------------------------- no outputs
def test_a_system_without_outputs_is_refused():
    with pytest.raises(ValueError, match=r"C must have at least one row \(m >= 1 outputs\)"):
        SwitchedLinearSystem.continuous(A, C=np.zeros((0, 2)))
    with pytest.raises(ValueError, match=r"C must have shape \(m, 2\) with m >= 1"):
        is_observable(A[0], np.zeros((0, 2)))


# ---------------------------------------------------------------- masked arrays
def test_masked_measurements_are_missing_samples():
    traj = trajectory()
    mask = np.zeros(traj.y.shape, dtype=bool)
    mask[0, 2] = mask[1, 4] = True
    filt = ModeKalmanFilter(SYS, X0, P0)
    masked = filt.run(np.ma.masked_array(traj.y, mask=mask), traj.u, T, modes=traj.mode)
    nan = filt.run(np.where(mask, np.nan, traj.y), traj.u, T, modes=traj.mode)
    full = filt.run(traj.y, traj.u, T, modes=traj.mode)
    # both runs see identical arrays; 1e-12 only absorbs a BLAS reordering of a few ulps
    np.testing.assert_allclose(masked.x, nan.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(masked.P, nan.P, rtol=1e-12, atol=1e-12)
    # and the mask was not ignored: the masked sample skipped its update, so P grew there
    assert masked.P[0, 2, 0, 0] > 1.5 * full.P[0, 2, 0, 0]


def test_a_masked_input_or_system_matrix_is_an_error():
    traj = trajectory()
    u = np.ma.masked_array(traj.u, mask=np.zeros(traj.u.shape, dtype=bool))
    u.mask[0, 1, 0] = True
    with pytest.raises(ValueError, match="u must not have masked entries, got 1 masked"):
        ModeKalmanFilter(SYS, X0, P0).run(traj.y, u, T, modes=traj.mode)
    with pytest.raises(ValueError, match="modes must not have masked entries"):
        ModeKalmanFilter(SYS, X0, P0).run(traj.y, traj.u, T,
                                          modes=np.ma.masked_array(traj.mode, mask=traj.mode > 0))
    with pytest.raises(ValueError, match="A must not have masked entries"):
        SwitchedLinearSystem.continuous(np.ma.masked_array(A, mask=A == 1.0))


# ---------------------------------------------------------------- switch offsets
def test_non_finite_or_outside_offsets_are_refused_in_the_clairvoyant_filter():
    traj = trajectory()
    seg_m, seg_o = traj.segments()
    filt = ModeKalmanFilter(SYS, X0, P0)
    nan = seg_o.copy()
    nan[0, 0, 0] = np.nan  # an interval WITHOUT a switch: its offset used to be ignored
    assert seg_m[0, 0, 0] == seg_m[0, 0, 1]
    with pytest.raises(ValueError, match=r"segments\[1\] \(offsets\) must be finite, got nan"):
        filt.run(traj.y, traj.u, T, modes=traj.mode, segments=(seg_m, nan))
    late = seg_o.copy()
    late[1, 0, 0] = 0.3  # beyond the interval's length 0.25
    with pytest.raises(ValueError, match=r"must lie within \[0, t\[k\] - t\[k-1\]\]"):
        filt.run(traj.y, traj.u, T, modes=traj.mode, segments=(seg_m, late))
    with pytest.raises(ValueError, match=r"segments\[0\] \(modes\) must be in 0..1, got 0..2"):
        filt.run(traj.y, traj.u, T, modes=traj.mode, segments=(np.where(seg_m, 2, 0), seg_o))


def test_non_finite_or_outside_offsets_are_refused_by_discretize():
    with pytest.raises(ValueError, match="offsets must be finite, got nan"):
        interval(SYS, 0.5, [0, 1], [np.nan])
    with pytest.raises(ValueError, match=r"offsets must lie within \[0, T\], got 0.7..0.7"):
        interval(SYS, 0.5, [0, 1], [0.7])
    no_switch = np.array([[0, 0], [0, 1]])
    with pytest.raises(ValueError, match="offsets must be finite, got nan"):
        segment_transitions(SYS, 0.5, no_switch, [[np.nan], [0.2]])
    with pytest.raises(ValueError, match=r"offsets must lie within \[0, T\], got -1..0.2"):
        segment_transitions(SYS, 0.5, no_switch, [[-1.0], [0.2]])
    with pytest.raises(ValueError, match=r"T \(2,\), modes \(3,\) .* must broadcast"):
        interval(SYS, [0.5, 0.5], [[0, 1]] * 3, [[0.1]] * 3)


def test_signals_refuse_non_finite_instants():
    with pytest.raises(ValueError, match="times must be finite"):
        sg.schedule([np.nan], [0, 0])  # a repeated mode used to drop (and hide) the NaN
    with pytest.raises(ValueError, match="t must not hold NaN"):
        SIGNAL.at([0.1, np.nan])
    with pytest.raises(ValueError, match="at must be finite"):
        SIGNAL.then(SIGNAL, at=np.nan)
    with pytest.raises(ValueError, match=r"t must be finite, got inf at index \(1,\)"):
        sg.sample_segments([SIGNAL], [0.0, np.inf])


# ---------------------------------------------------------------- requests that cannot finish
@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: sg.markov_continuous([[-1e9, 1e9], [1e9, -1e9]], 10.0, rng=0),
         r"max\(-rates\[i, i\]\) \* \(t_end - t_start\) = 1e\+10 expected switches"),
        (lambda: sg.dwell_time(2, 10.0, 1e-15, 1e-15, rng=0),
         r"\(t_end - t_start\) / \(\(min_dwell \+ max_dwell\) / 2\) = 1e\+16"),
        (lambda: sg.average_dwell_time(2, 10.0, 1e-12, 2.0, rng=0),
         r"rate \* \(t_end - t_start\) = 2e\+13 expected switch attempts"),
        (lambda: sg.periodic(1e-15, 10.0), r"\(t_end - t_start\) / T = 1e\+16 expected sample"),
        (lambda: sg.aperiodic(1e-15, 1e-15, 10.0, rng=0), r"= 1e\+16 expected sample times"),
    ],
    ids=["markov-rate", "dwell", "average-dwell", "periodic", "aperiodic"],
)
def test_signal_generators_refuse_more_than_max_events_up_front(call, match):
    start = time.perf_counter()
    with pytest.raises(ValueError, match=match + r".*MAX_EVENTS = 1e\+07"):
        call()
    assert time.perf_counter() - start < UP_FRONT_SECONDS


def test_simulate_refuses_outputs_that_do_not_fit(memory_4gib):
    start = time.perf_counter()
    # 8 bytes x 1e8 trials x 7 samples x (n + m + l + 1 = 5) = 26.1 GiB
    message = (r"simulate with trials = 100000000, K = 7 samples .* would take about 26.1 GiB, "
               r"more than the limit of 4 GiB")
    with pytest.raises(ValueError, match=message):
        simulate(SYS, SIGNAL, T, X0, trials=10**8, rng=0)
    with pytest.raises(ValueError, match=r"Kf = 1.5e\+15 fine instants"):
        simulate(SYS, SIGNAL, T, X0, trials=1, rng=0, fine_dt=1e-15)
    assert time.perf_counter() - start < UP_FRONT_SECONDS


def test_switch_time_grids_that_do_not_fit_are_refused(memory_4gib):
    start = time.perf_counter()
    with pytest.raises(ValueError, match=r"grid = 10000000 switching instants .* GiB"):
        SwitchTimeKalmanFilter(SYS, X0, P0, grid=10**7)
    with pytest.raises(ValueError, match=r"pairwise_grid with g = 10000000 .* GiB"):
        pairwise_grid(SYS, 0.25, 10**7)
    traj = trajectory()
    filt = SwitchTimeKalmanFilter(SYS, X0, P0, grid=100_000)  # the grid fits, the hypotheses not
    y = np.broadcast_to(traj.y[:1], (1000, *traj.y.shape[1:]))
    with pytest.raises(ValueError, match=r"grid = 100000 switching-time hypotheses for each of "
                                         r"N = 1000 trials"):
        filt.run(y, traj.u[0], T, modes=traj.mode[0])
    assert time.perf_counter() - start < UP_FRONT_SECONDS


def test_a_tiny_dwell_time_with_a_moderate_rate_works():
    """min_dwell = 1e-15 s used to allocate ceil(t_end / min_dwell) gaps (PiB); it is valid."""
    start = time.perf_counter()
    s = sg.dwell_time(3, 50.0, 1e-15, 1.0, rng=7)
    gaps = np.diff(np.concatenate([[0.0], s.times]))
    assert gaps.min() >= 1e-15 and gaps.max() <= 1.0 and s.times[-1] < 50.0
    # gaps uniform on [0, 1]: mean 1/2, so about 100 switches; 5 standard deviations (sqrt(100/3))
    assert abs(s.n_switches - 100) < 5 * np.sqrt(100 / 3)
    t = sg.aperiodic(1e-15, 0.5, 20.0, rng=8)
    assert t[0] == 0.0 and t[-1] <= 20.0 and np.all(np.diff(t) >= 1e-15)
    assert time.perf_counter() - start < UP_FRONT_SECONDS


def test_markov_chain_stops_in_an_absorbing_mode():
    rates = np.array([[-2.0, 2.0, 0.0], [0.0, 0.0, 0.0], [1.0, 1.0, -2.0]])
    for seed in range(20):
        s = sg.markov_continuous(rates, 100.0, rng=seed, initial_mode=2)
        assert s.modes[-1] == 1 and np.all(s.modes[:-1] != 1)  # mode 1 is entered once, last


def test_average_dwell_time_checker_agrees_with_brute_force():
    rng = np.random.default_rng(11)
    for _ in range(200):
        times = np.cumsum(rng.exponential(0.5, size=rng.integers(0, 12)))
        s = sg.SwitchingSignal(times, np.arange(times.size + 1) % 2)
        tau_a, N0 = rng.uniform(0.2, 2.0), rng.uniform(1.0, 4.0)
        i, j = np.triu_indices(times.size)
        brute = bool(np.all(j - i + 1 <= N0 + (times[j] - times[i]) / tau_a))
        assert sg.satisfies_average_dwell_time(s, tau_a, N0) == brute


# ---------------------------------------------------------------- internal exception types
def test_kernels_name_the_argument_whose_shape_is_wrong():
    x, P, y = np.zeros((3, 2)), np.broadcast_to(np.eye(2), (3, 2, 2)), np.ones((3, 1))
    Cs, G, R = np.ones((3, 1, 2)), np.ones((3, 2, 1)), np.ones((3, 1, 1))
    with pytest.raises(ValueError, match=r"G has n = 3 in its shape \(3, 3, 1\), but x has n = 2"):
        impulsive_update(x, P, y, Cs, np.ones((3, 3, 1)), R)
    with pytest.raises(ValueError, match=r"the batch shapes must broadcast together, got x \(3,\), "
                                         r"P \(3,\), y \(4,\)"):
        impulsive_update(x, P, np.ones((4, 1)), Cs, G, R)
    with pytest.raises(ValueError, match=r"P_pred must have shape \(\.\.\., n, n\), got shape"):
        switch_time_loglik(x, 1.0, y, Cs, R)
    with pytest.raises(ValueError, match="likelihood must be 'innovation' or 'printed'"):
        switch_time_loglik(x, P, y, Cs, R, likelihood=np.zeros(0))


def test_metrics_validate_start():
    est = np.zeros((2, 5, 1))
    with pytest.raises(TypeError, match="start must be an int sample index, got NoneType"):
        metrics.mode_accuracy(np.zeros((2, 5), dtype=int), np.zeros((2, 5), dtype=int), start=None)
    with pytest.raises(TypeError, match="start must be an int sample index, got float"):
        metrics.rmse(est, est, start=1.0)
    with pytest.raises(ValueError, match=r"start must be in 0..4, got 5"):
        metrics.rmse(est, est, start=5)


def test_nan_never_passes_as_a_covariance():
    with pytest.raises(ValueError, match="P0 must be finite"):
        ModeKalmanFilter(SYS, X0, np.full((2, 2), np.nan))
    with pytest.raises(ValueError, match="Q must be finite"):
        _checks.check_symmetric_psd(np.full((2, 2), np.nan), "Q")


def test_messages_name_the_argument_the_user_gave():
    """Issue 35: ``duration=-1`` named ``t_end`` and ``RBPFilter.step(dt=-1)`` named ``T`` (the
    parameters of the functions they call)."""
    from switchest.estimators import IMMFilter, RBPFilter
    from switchest.measurements import simulate_measurements
    from switchest.modelfile import load_model

    spec = load_model(Path(__file__).resolve().parents[1] / "examples/models/shankar-boost.toml")
    with pytest.raises(ValueError, match="^duration"):
        simulate_measurements(spec, duration=-1)
    transition = [[0.9, 0.1], [0.1, 0.9]]
    for f in (RBPFilter(spec.system, transition, np.zeros(2), np.eye(2), particles=4),
              IMMFilter(spec.system, transition, np.zeros(2), np.eye(2))):
        state = f.step(f.init(()), [1.0], [100.0])
        with pytest.raises(ValueError, match="^dt must"):
            f.step(state, [1.0], [100.0], dt=-1.0)
