"""Property-based fuzz of the public entry points (issue 19): malformed input never escapes.

For every entry point a valid call is built, then one argument is replaced by a malformed
version of itself (wrong kind, rank, size, NaN, infinity, mask, ...). The only outcomes
allowed are ``ValueError``/``TypeError`` whose message names the argument, or a valid result
(finite where the input was finite and moderate). Never an internal exception type
(IndexError, LinAlgError, AttributeError, ZeroDivisionError, a bare numpy broadcasting
message) and never a hang. Examples are derandomized so that every run checks the same cases.
"""

import re

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from switchest import SwitchedLinearSystem, metrics
from switchest import signals as sg
from switchest.analysis import estimation_error_bounds, kalman_decomposition, switch_matrix_bounds
from switchest.discretize import interval, mode_steps, pairwise_grid, segment_transitions
from switchest.estimators import (
    IMMFilter,
    ImpulsiveObserver,
    MinimumDistanceDetector,
    ModeKalmanFilter,
    RSLSObserver,
    SwitchTimeKalmanFilter,
)
from switchest.models.lee import LEE_SCENARIO
from switchest.models.wang import wang_scalar_pair
from switchest.simulate import simulate

FUZZ = settings(max_examples=40, deadline=None, derandomize=True)

A = np.array([[[-0.4, 1.0], [-1.0, -0.3]], [[-0.1, 0.0], [0.5, -1.2]]])
B = np.array([[0.0], [1.0]])
C = np.array([[1.0, 0.2]])
Q, R = 0.05 * np.eye(2), np.array([[0.1]])
SYS = SwitchedLinearSystem.continuous(A, B, C, Q=Q, R=R)
X0, P0 = np.array([0.5, -0.5]), np.eye(2)
T = sg.periodic(0.25, 1.5)
SIGNAL = sg.schedule([0.6, 1.1], [0, 1, 0])
TRAJ = simulate(SYS, SIGNAL, T, X0, u=np.ones(1), trials=2, rng=3)
SEGMENTS = TRAJ.segments()
TRANSITION = np.array([[0.9, 0.1], [0.3, 0.7]])


# ---------------------------------------------------------------- malformed versions of a value
def _one(arr, value, index):
    out = np.array(arr, dtype=float)
    if out.size:
        out.flat[index % out.size] = value
    return out


def _masked(arr, index):
    arr = np.asarray(arr, dtype=float)
    mask = np.zeros(arr.shape, dtype=bool)
    if arr.size:
        mask.flat[index % arr.size] = True
    return np.ma.masked_array(arr, mask=mask)


# kind: the value is not a real array at all -> the message must name the argument itself
KIND = {
    "None": lambda a, i: None,
    "string": lambda a, i: "abc",
    "strings": lambda a, i: np.full(np.shape(a), "x"),
    "complex": lambda a, i: np.asarray(a, dtype=float) + 1j,
    "bool": lambda a, i: np.asarray(a, dtype=float) > 0,
    "datetime": lambda a, i: np.zeros(np.shape(a), dtype="datetime64[s]"),
    "object": lambda a, i: np.array([None, *np.ravel(a)[1:]], dtype=object),
    "dict": lambda a, i: {"value": a},
    "ragged": lambda a, i: [[1.0, 2.0], [3.0]],
}
# value: a real array with a bad entry -> named argument, or a valid result
VALUE = {
    "nan": lambda a, i: _one(a, np.nan, i),
    "inf": lambda a, i: _one(a, np.inf, i),
    "masked": _masked,
    "negative": lambda a, i: -np.abs(np.asarray(a, dtype=float)) - 1.0,
    "huge": lambda a, i: _one(a, 1e300, i),
    "zero": lambda a, i: np.zeros(np.shape(a)),
}
# shape: -> the argument, or the one it must agree with, is named
SHAPE = {
    "scalar": lambda a, i: 1.0,
    "empty": lambda a, i: np.zeros(0),
    "extra_axis": lambda a, i: np.asarray(a)[None],
    "drop_axis": lambda a, i: np.asarray(a)[i % max(np.shape(a)[0], 1)] if np.ndim(a) else a,
    "zero_axis": lambda a, i: np.asarray(a)[:0] if np.ndim(a) else np.zeros(0),
    "zero_last": lambda a, i: np.asarray(a)[..., :0] if np.ndim(a) else np.zeros(0),
    "longer": lambda a, i: np.concatenate([np.atleast_1d(a), np.atleast_1d(a)[..., :1]], axis=-1),
    "transposed": lambda a, i: np.swapaxes(a, 0, -1) if np.ndim(a) > 1 else np.flip(a),
}
MUTATIONS = {**KIND, **VALUE, **SHAPE}
# replacements for scalar parameters (rates, periods, counts, options)
SCALARS = {
    "None": None, "string": "1.0", "complex": 1 + 1j, "bool": True, "nan": float("nan"),
    "inf": float("inf"), "negative": -1.0, "zero": 0.0, "huge": 1e300, "tiny": 1e-300,
    "array": np.array([1.0, 2.0]), "list": [1.0],
}


def names(text, *candidates):
    """Whether ``text`` names one of ``candidates`` as a word (``y`` but not ``every``)."""
    return any(re.search(rf"(?<![A-Za-z_]){re.escape(c)}(?![A-Za-z_])", text) for c in candidates)


def clear_or_valid(call, argument, mutation, related=(), check=None):
    """Run ``call``: only a ValueError/TypeError naming the argument, or a valid result."""
    try:
        result = call()
    except (ValueError, TypeError) as exc:
        allowed = (argument,) if mutation in KIND else (argument, *related)
        assert names(str(exc), *allowed), (
            f"{argument} <- {mutation}: {type(exc).__name__} does not name it: {exc}"
        )
        return
    if check is not None and mutation not in ("huge", "negative", "tiny"):
        check(result)


def finite_estimate(est):
    assert np.all(np.isfinite(est.x)) and (est.P is None or np.all(np.isfinite(est.P)))


mutation = st.sampled_from(sorted(MUTATIONS))
scalar = st.sampled_from(sorted(SCALARS))
index = st.integers(0, 50)


# ---------------------------------------------------------------- system constructors
@FUZZ
@given(arg=st.sampled_from(["A", "B", "C", "Q", "R", "dt"]), how=mutation, bad=scalar, i=index)
def test_system_constructors(arg, how, bad, i):
    args = dict(A=A, B=B, C=C, Q=Q, R=R)
    if arg == "dt":
        clear_or_valid(lambda: SwitchedLinearSystem.discrete(**args, dt=SCALARS[bad]), "dt", bad)
        return
    args[arg] = MUTATIONS[how](args[arg], i)
    clear_or_valid(lambda: SwitchedLinearSystem.continuous(**args), arg, how, related="ABCQR",
                   check=lambda s: all(np.all(np.isfinite(getattr(s, k))) for k in "ABCQR"))


# ---------------------------------------------------------------- signal generators
GENERATORS = {
    "dwell_time": (sg.dwell_time, dict(n_modes=2, t_end=5.0, min_dwell=0.5, max_dwell=1.0, rng=0)),
    "average_dwell_time": (sg.average_dwell_time, dict(n_modes=2, t_end=5.0, tau_a=0.5, N0=2.0,
                                                       rng=0, rate=3.0)),
    "markov_continuous": (sg.markov_continuous, dict(rates=np.array([[-1.0, 1.0], [2.0, -2.0]]),
                                                     t_end=5.0, rng=0)),
    "markov_at_samples": (sg.markov_at_samples, dict(transition=TRANSITION, t=T, rng=0)),
    "iid_at_samples": (sg.iid_at_samples, dict(p=np.array([0.3, 0.7]), t=T, rng=0)),
    "periodic": (sg.periodic, dict(T=0.1, t_end=1.0)),
    "aperiodic": (sg.aperiodic, dict(tau_min=0.1, tau_max=0.2, t_end=1.0, rng=0)),
    "schedule": (sg.schedule, dict(times=np.array([1.0, 2.0]), modes=np.array([0, 1, 0]))),
    "SwitchingSignal": (sg.SwitchingSignal, dict(times=np.array([1.0, 2.0]),
                                                 modes=np.array([0, 1, 0]))),
}


def valid_signal_output(out):
    times = out.times if isinstance(out, sg.SwitchingSignal) else out
    assert np.all(np.isfinite(times)) and np.all(np.diff(times) > 0)


@FUZZ
@given(gen=st.sampled_from(sorted(GENERATORS)), data=st.data(), i=index)
def test_signal_generators(gen, data, i):
    fn, kwargs = GENERATORS[gen]
    arg = data.draw(st.sampled_from(sorted(kwargs)))
    kwargs = dict(kwargs)
    if isinstance(kwargs[arg], np.ndarray):
        how = data.draw(mutation)
        kwargs[arg] = MUTATIONS[how](kwargs[arg], i)
    else:
        how = data.draw(scalar)
        kwargs[arg] = SCALARS[how]
    clear_or_valid(lambda: fn(**kwargs), arg, how, related=tuple(kwargs), check=valid_signal_output)


@FUZZ
@given(arg=st.sampled_from(["signals", "t"]), how=mutation, i=index)
def test_sample_segments(arg, how, i):
    kwargs = dict(signals=[SIGNAL, SIGNAL], t=T)
    kwargs[arg] = MUTATIONS[how](np.array(kwargs[arg], dtype=object if arg == "signals" else float),
                                 i) if arg == "t" else MUTATIONS[how](T, i)
    clear_or_valid(lambda: sg.sample_segments(**kwargs), arg, how, related=("t",))


# ---------------------------------------------------------------- simulate
@FUZZ
@given(arg=st.sampled_from(["t", "x0", "u", "trials", "fine_dt", "output", "signal"]),
       how=mutation, bad=scalar, i=index)
def test_simulate(arg, how, bad, i):
    kwargs = dict(system=SYS, signal=SIGNAL, t=T, x0=X0, u=np.ones((T.size, 1)), trials=2, rng=0)
    if arg in ("t", "x0", "u"):
        kwargs[arg] = MUTATIONS[how](kwargs[arg], i)
    else:
        how = bad
        kwargs[arg] = SCALARS[bad]
    clear_or_valid(lambda: simulate(**kwargs), arg, how, related=("t", "x0", "u", "trials"),
                   check=lambda tr: np.all(np.isfinite(tr.x)))


# ---------------------------------------------------------------- discretize
@FUZZ
@given(arg=st.sampled_from(["T", "modes", "offsets"]), how=mutation, i=index,
       which=st.sampled_from(["interval", "segment_transitions"]))
def test_discretize(arg, how, i, which):
    if which == "interval":
        kwargs = dict(T=np.array([0.5, 0.25]), modes=np.array([[0, 1], [1, 1]]),
                      offsets=np.array([[0.2], [0.25]]))
        fn = interval
    else:
        kwargs = dict(T=np.array(0.5), modes=np.array([[0, 1], [1, 1]]),
                      offsets=np.array([[0.2], [0.5]]))
        fn = segment_transitions
    kwargs[arg] = MUTATIONS[how](kwargs[arg], i)
    clear_or_valid(lambda: fn(SYS, **kwargs), arg, how, related=("T", "modes", "offsets"),
                   check=lambda tr: np.all(np.isfinite(tr.F)) and np.all(np.isfinite(tr.Qd)))


@FUZZ
@given(bad=scalar, which=st.sampled_from(["mode_steps.T", "pairwise_grid.T", "pairwise_grid.g"]))
def test_discretize_scalars(bad, which):
    calls = {
        "mode_steps.T": lambda: mode_steps(SYS, SCALARS[bad]),
        "pairwise_grid.T": lambda: pairwise_grid(SYS, SCALARS[bad], 3),
        "pairwise_grid.g": lambda: pairwise_grid(SYS, 0.5, SCALARS[bad]),
    }
    clear_or_valid(calls[which], which.split(".")[1], bad)


# ---------------------------------------------------------------- metrics
@FUZZ
@given(arg=st.sampled_from(["estimate", "truth", "estimated", "true", "start"]), how=mutation,
       bad=scalar, i=index)
def test_metrics(arg, how, bad, i):
    x = TRAJ.x
    mode = TRAJ.mode
    if arg in ("estimate", "truth"):
        kwargs = dict(estimate=x, truth=x + 0.1)
        kwargs[arg] = MUTATIONS[how](kwargs[arg], i)
        clear_or_valid(lambda: metrics.rmse(**kwargs), arg, how, related=("estimate", "truth"))
    elif arg in ("estimated", "true"):
        kwargs = dict(estimated=mode, true=mode)
        kwargs[arg] = MUTATIONS[how](kwargs[arg], i)
        clear_or_valid(lambda: metrics.mode_accuracy(**kwargs), arg, how,
                       related=("estimated", "true"))
        clear_or_valid(lambda: metrics.switch_time_error(**kwargs), arg, how,
                       related=("estimated", "true"))
    else:
        clear_or_valid(lambda: metrics.rmse(x, x, start=SCALARS[bad]), "start", bad)


# ---------------------------------------------------------------- estimators
LEE = LEE_SCENARIO
LEE_T = 0.0025 * np.arange(201)
LEE_TRAJ = simulate(LEE.system(), LEE.signal, LEE_T, np.array(LEE.x0), np.zeros((201, 1)),
                    trials=1, rng=0)
WANG = wang_scalar_pair(2.0, 4.0, 0.01)
WANG_GAINS = np.array([[[3.0], [0.0]], [[0.0], [5.0]]])
WANG_T = np.arange(0.0, 1.0001, 0.1)
WANG_TRAJ = simulate(WANG, lambda r: sg.iid_at_samples([0.2, 0.8], WANG_T, rng=r), WANG_T,
                     np.ones(2), trials=2, rng=0, fine_dt=0.05, output="integrated")
G_IMPULSIVE = np.array([[[1.0], [0.0]], [[1.0], [0.5]]])

# name -> (constructor, its keyword arguments, run, the run's keyword arguments)
ESTIMATORS = {
    "mode-kalman": (ModeKalmanFilter, dict(system=SYS, x0=X0, P0=P0),
                    dict(y=TRAJ.y, u=TRAJ.u, t=T, modes=TRAJ.mode, segments=SEGMENTS)),
    "switch-time": (SwitchTimeKalmanFilter, dict(system=SYS, x0=X0, P0=P0, grid=3),
                    dict(y=TRAJ.y, u=TRAJ.u, t=T, modes=TRAJ.mode)),
    "imm": (lambda **kw: IMMFilter(transition=TRANSITION, **kw), dict(system=SYS, x0=X0, P0=P0),
            dict(y=TRAJ.y, u=TRAJ.u, t=T)),
    "impulsive": (ImpulsiveObserver, dict(system=SYS, gains=G_IMPULSIVE, x0=X0, P0=P0),
                  dict(y=TRAJ.y, u=TRAJ.u, t=T, signals=list(TRAJ.signals))),
    "min-distance": (MinimumDistanceDetector,
                     dict(system=LEE.system(), delta=LEE.delta, Delta=LEE.Delta, v_max=LEE.v_max),
                     dict(y=LEE_TRAJ.y, u=LEE_TRAJ.u, t=LEE_T)),
    "rsls": (RSLSObserver, dict(system=WANG, gains=WANG_GAINS, T=0.1, x0=np.ones(2), P0=np.eye(2)),
             dict(y=WANG_TRAJ.y_fine, t=WANG_TRAJ.t_fine, modes=WANG_TRAJ.mode_fine)),
}
RUN_ARGS = sorted({(name, arg) for name, (_, _, run) in ESTIMATORS.items() for arg in run})
INIT_ARGS = sorted({(name, arg) for name, (_, init, _) in ESTIMATORS.items()
                    for arg in init if arg != "system"})


BAD_SIGNALS = {
    "None": None,
    "string": "abc",
    "number": 1.0,
    "array": np.zeros(2),
    "one-too-few": [SIGNAL],
    "not-a-signal": [SIGNAL, "x"],
    "empty": [],
    "mode-out-of-range": [sg.schedule([0.6], [0, 2])] * 2,
}


def _mutate_segments(segments, how, i):
    part = i % 2  # modes or offsets
    out = list(segments)
    out[part] = MUTATIONS[how](segments[part], i)
    return tuple(out), ("segments",)


# Finite extremes (1e300) in y or u are the filters' numerical robustness, tested with them
# (an overflowing IMM mixing spread is reported as an overflowed covariance, not a bad argument).
run_mutation = st.sampled_from(sorted(set(MUTATIONS) - {"huge"}))


@FUZZ
@given(target=st.sampled_from(RUN_ARGS), how=run_mutation, i=index)
def test_estimator_runs(target, how, i):
    name, arg = target
    factory, init, run = ESTIMATORS[name]
    est = factory(**init)
    kwargs = dict(run)
    if arg == "segments":
        kwargs[arg], related = _mutate_segments(kwargs[arg], how, i)
    elif arg == "signals":
        how = sorted(BAD_SIGNALS)[i % len(BAD_SIGNALS)]
        kwargs[arg], related = BAD_SIGNALS[how], ()
    else:
        kwargs[arg] = MUTATIONS[how](kwargs[arg], i)
        related = tuple(run)
    # NaN (or a masked entry) in y is a missing sample: the estimate stays finite
    check = finite_estimate if arg == "y" and how in ("nan", "masked") and name != "min-distance" \
        else None
    clear_or_valid(lambda: est.run(**kwargs), arg, how, related=related, check=check)


@FUZZ
@given(target=st.sampled_from(INIT_ARGS), how=mutation, bad=scalar, i=index)
def test_estimator_constructors(target, how, bad, i):
    name, arg = target
    factory, init, _ = ESTIMATORS[name]
    kwargs = dict(init)
    if isinstance(kwargs[arg], np.ndarray):
        kwargs[arg] = MUTATIONS[how](kwargs[arg], i)
    else:
        how = bad
        kwargs[arg] = SCALARS[bad]
    clear_or_valid(lambda: factory(**kwargs), arg, how, related=tuple(init))


# ---------------------------------------------------------------- analysis on plain matrices
@FUZZ
@given(arg=st.sampled_from(["A", "C", "A_i", "B_j", "T", "t_hat", "K", "H", "R"]), how=mutation,
       i=index)
def test_analysis_on_matrices(arg, how, i):
    if arg in ("A", "C"):
        kwargs = dict(A=A[0], C=C)
        kwargs[arg] = MUTATIONS[how](kwargs[arg], i)
        clear_or_valid(lambda: kalman_decomposition(**kwargs), arg, how, related=("A", "C"))
    elif arg in ("A_i", "B_j", "T", "t_hat"):
        kwargs = dict(A_i=A[0], A_j=A[1], B_i=B, B_j=B, T=np.array([0.5, 0.4]),
                      t_bar=np.array([0.1, 0.2]), t_hat=np.array([0.3, 0.2]))
        kwargs[arg] = MUTATIONS[how](kwargs[arg], i)
        clear_or_valid(lambda: switch_matrix_bounds(**kwargs), arg, how, related=tuple(kwargs),
                       check=lambda b: np.all(np.isfinite(b.F)) and np.all(np.isfinite(b.G)))
    else:
        kwargs = dict(K=np.array([[0.5], [0.1]]), H=C, R=R)
        kwargs[arg] = MUTATIONS[how](kwargs[arg], i)
        clear_or_valid(
            lambda: estimation_error_bounds(**kwargs, mean_prediction_error=1.0,
                                            prediction_mse_trace=2.0),
            arg, how, related=("K", "H", "R", "mean_prediction_error", "prediction_mse_trace"),
        )
