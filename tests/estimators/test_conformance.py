"""One conformance suite over every registered estimator (the protocol of
``docs/estimators/index.rst``): the abstract protocol and its conventions, batched equals
looped, streaming ``step`` equals ``run``, no state kept between runs, a single-mode model
reduces to the Kalman filter, NaN skips the update, bad shapes are refused, results are
reproducible.

The protocol tests run over :data:`switchest.estimators.METHOD_NAMES` directly; the tests on
data run over :data:`CASES`, at least one configuration per registered method (a method
registered without one fails :func:`test_every_registered_method_has_a_case`).
"""

import inspect
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import pytest

from switchest import SwitchedLinearSystem
from switchest import signals as sg
from switchest.analysis import steady_state_gain
from switchest.discretize import mode_steps
from switchest.estimators import (
    METHOD_NAMES,
    BetweenSamplesIMMFilter,
    Estimate,
    Estimator,
    GPB1Filter,
    GPB2Filter,
    IMMEV1Filter,
    IMMFilter,
    ImpulsiveObserver,
    MinimumDistanceDetector,
    ModeKalmanFilter,
    RBPFilter,
    RSLSObserver,
    SwitchTimeKalmanFilter,
    get_method,
)
from switchest.models.wang import wang_scalar_pair
from switchest.simulate import simulate

A = np.array([[[-0.4, 1.0], [-1.0, -0.3]], [[-0.1, 0.0], [0.5, -1.2]]])
B = np.array([[[0.0], [1.0]], [[1.0], [0.0]]])
C = np.array([[1.0, 0.2]])
SYS = SwitchedLinearSystem.continuous(A, B, C, Q=0.05 * np.eye(2), R=[[0.1]])
X0, P0 = np.array([0.5, -0.5]), np.eye(2)
TRANSITION = np.array([[0.8, 0.2], [0.35, 0.65]])
G_IMPULSIVE = np.array([[[0.5], [0.2]], [[0.4], [0.3]]])  # any gains: conformance, not accuracy

# Wang et al.'s scalar pair (no input, no process noise), observed through its integrated output
WANG = wang_scalar_pair(2.0, 4.0, 0.01)
WANG_T = 0.03
WANG_GAINS = np.array([[[40.0], [0.0]], [[0.0], [15.0]]])


# ---------------------------------------------------------------------- scenarios
@dataclass(frozen=True)
class Scenario:
    """Records of N trials: ``y (N, K, m)``, ``u (N, K, l)`` (None: the model has no input),
    ``t (K,)``, the modes at the samples ``(N, K)`` and the switching signals (N)."""

    t: np.ndarray
    y: np.ndarray
    u: np.ndarray | None
    modes: np.ndarray
    signals: list

    def trial(self, n: int) -> "Scenario":
        """Trial ``n`` alone, without a batch axis."""
        u = None if self.u is None else self.u[n]
        return Scenario(self.t, self.y[n], u, self.modes[n], self.signals[n])

    def head(self, k: int) -> "Scenario":
        """The first ``k`` samples."""
        u = None if self.u is None else self.u[:, :k]
        return Scenario(self.t[:k], self.y[:, :k], u, self.modes[:, :k], self.signals)


def switched(dt: float, trials: int = 3, seed: int = 0, t_end: float = 4.0) -> Scenario:
    """SYS sampled every ``dt`` under dwell-time switching, with an input that varies by sample
    (so that a filter holding the wrong sample's input is caught)."""
    t = sg.periodic(dt, t_end)
    u = 1.0 + 0.5 * np.sin(3.0 * t)[:, None]
    traj = simulate(SYS, lambda r: sg.dwell_time(2, t_end, 0.6, 1.2, rng=r), t, (X0, P0),
                    u=u, trials=trials, rng=seed)
    return Scenario(t, traj.y, np.broadcast_to(u, (trials, *u.shape)), traj.mode,
                    list(traj.signals))


def integrated(dt: float, trials: int = 3, seed: int = 0) -> Scenario:
    """Wang et al.'s model: i.i.d. modes every ``WANG_T``, the integrated output every ``dt``."""
    t = WANG_T * np.arange(13)
    traj = simulate(WANG, lambda r: sg.iid_at_samples([0.2, 0.8], t, rng=r), t,
                    np.array([1.0, 1.0]), trials=trials, rng=seed, fine_dt=dt,
                    output="integrated")
    return Scenario(traj.t_fine, traj.y_fine, None, traj.mode_fine, list(traj.signals))


def run_keywords(method: str, sc: Scenario) -> dict:
    """What ``run`` is told of the switching, by the registry's ``switching`` keyword."""
    kind = get_method(method).switching
    return {} if kind is None else {kind: getattr(sc, kind)}


# ---------------------------------------------------------------------- streaming: step keywords
def at_samples(sc: Scenario, k: int) -> dict:
    """The mode believed at sample k and the one over the interval into it."""
    return {"mode": sc.modes[:, k], "prev_mode": sc.modes[:, k - 1] if k else None}


def over_interval(sc: Scenario, k: int) -> dict:
    """The mode active over the interval into sample k (Wang et al.: constant on it)."""
    return {"mode": sc.modes[:, max(k - 1, 0)]}


def signal_segments(sc: Scenario, k: int) -> dict:
    """sigma(t_k) and the segments of sigma over the interval into sample k."""
    mode_at, seg_m, seg_o = sg.sample_segments(sc.signals, sc.t)
    if k == 0:
        return {"mode": mode_at[:, 0]}
    return {"mode": mode_at[:, k], "segment_modes": seg_m[:, k - 1],
            "segment_offsets": seg_o[:, k - 1]}


def no_keywords(sc: Scenario, k: int) -> dict:
    return {}


# ---------------------------------------------------------------------- reading a state
def read_kalman(est, s) -> dict:
    return {"x": s.x, "P": s.P, "loglik": s.loglik}


def read_imm(est, s) -> dict:
    return {"x": s.combined_x, "P": s.combined_P, "mode_prob": np.exp(s.log_prob),
            "loglik": s.loglik}


def read_imm_between(est, s) -> dict:
    """The modes' probabilities: the members' summed over those that end in each mode."""
    prob = np.exp(s.log_prob) @ np.eye(est.system.n_modes)[est.member_modes[:, 1]]
    return {"x": s.combined_x, "P": s.combined_P, "mode_prob": prob, "loglik": s.loglik}


def read_rbpf(est, s) -> dict:
    return {"x": s.combined_x, "P": s.combined_P, "mode_prob": s.mode_prob, "loglik": s.loglik}


def read_imm_ev1(est, s) -> dict:
    """The destination of largest weight (the MAP path), as run reports."""
    best = np.argmax(s.log_weight, axis=-1)
    rows = np.arange(best.size)
    return {"x": s.x[rows, best], "P": s.P[rows, best], "mode_prob": np.exp(s.log_weight),
            "mode": best}


def read_min_distance(est, s) -> dict:
    """The observer (19) and sigma_hat outside the estimation windows, NaN / -1 inside."""
    return {"x": np.where(s.estimating[:, None], np.nan, s.x_hat),
            "mode": np.where(s.estimating, -1, s.mode)}


def read_rsls(est, s) -> dict:
    """``x_hat = Phi z_hat`` and ``P = Phi Sigma_zz Phi'``."""
    st = est.structure
    n_s = st.n_substates
    return {"x": s.s[:, :n_s] @ st.Phi.T, "P": st.Phi @ s.Sigma[:, :n_s, :n_s] @ st.Phi.T}


def read_impulsive(est, s) -> dict:
    return {"x": s.x, "P": s.P, "mode": s.mode}


# ---------------------------------------------------------------------- the cases
@dataclass(frozen=True)
class SteadyState:
    """The steady-state Kalman gain and a-priori covariance of a one-mode system."""

    gain: np.ndarray
    prior: np.ndarray


@dataclass(frozen=True)
class Case:
    """One configuration of a registered method.

    ``make(system)`` builds it; ``scenario(dt, trials, seed)`` gives it data at the sampling
    periods ``periods``; ``stream(scenario, k)`` the keywords of ``step`` at sample k that
    ``run`` derives from its own; ``read(estimator, state)`` the fields of the Estimate that
    ``run`` reports for a state. ``one_mode(system, steady)`` builds the configuration on a
    one-mode system with the prior covariance the Kalman filter it must equal starts from
    (returned with it), or is the reason it has no Kalman equivalent. ``alone(estimator,
    trials, n)`` gives the keywords that run trial ``n`` of a batch of ``trials`` by itself as
    in the batch (the particle filter: the random key the trial had there).
    """

    method: str
    make: Callable[[SwitchedLinearSystem], Estimator]
    scenario: Callable[..., Scenario]
    periods: tuple[float, float]
    stream: Callable[[Scenario, int], dict]
    read: Callable[[Estimator, object], dict]
    one_mode: Callable[[SwitchedLinearSystem, SteadyState], tuple] | str
    alone: Callable[[Estimator, int, int], dict] = lambda est, trials, n: {}


CASES = {
    "kalman": Case(
        "kalman", lambda s: ModeKalmanFilter(s, X0, P0), switched, (0.25, 0.2), at_samples,
        read_kalman, lambda one, ss: (ModeKalmanFilter(one, X0, P0), P0)),
    "kalman-steady": Case(
        "kalman", lambda s: ModeKalmanFilter(s, X0, P0, steady_state=True), switched,
        (0.25, 0.2), lambda sc, k: {**at_samples(sc, k), "period": sc.t[1] - sc.t[0]},
        read_kalman,
        # started at the Riccati fixed point, the time-varying filter IS the steady-state one
        lambda one, ss: (ModeKalmanFilter(one, X0, P0, steady_state=True), ss.prior)),
    "switch-time": Case(
        "switch-time", lambda s: SwitchTimeKalmanFilter(s, X0, P0, grid=4), switched,
        (0.25, 0.2), at_samples, read_kalman,
        lambda one, ss: (SwitchTimeKalmanFilter(one, X0, P0, grid=4), P0)),
    "switch-time-refine": Case(
        "switch-time", lambda s: SwitchTimeKalmanFilter(s, X0, P0, grid=2, refine=True),
        switched, (0.25, 0.2), at_samples, read_kalman,
        lambda one, ss: (SwitchTimeKalmanFilter(one, X0, P0, grid=2, refine=True), P0)),
    "imm": Case(
        "imm", lambda s: IMMFilter(s, TRANSITION, X0, P0), switched, (0.25, 0.2), no_keywords,
        read_imm, lambda one, ss: (IMMFilter(one, [[1.0]], X0, P0), P0)),
    "imm-between": Case(
        "imm-between", lambda s: BetweenSamplesIMMFilter(s, TRANSITION, X0, P0, grid=3),
        switched, (0.25, 0.2), no_keywords, read_imm_between,
        lambda one, ss: (BetweenSamplesIMMFilter(one, [[1.0]], X0, P0, grid=3), P0)),
    "gpb1": Case(
        "gpb1", lambda s: GPB1Filter(s, TRANSITION, X0, P0), switched, (0.25, 0.2),
        no_keywords, read_imm, lambda one, ss: (GPB1Filter(one, [[1.0]], X0, P0), P0)),
    "gpb2": Case(
        "gpb2", lambda s: GPB2Filter(s, TRANSITION, X0, P0), switched, (0.25, 0.2),
        no_keywords, read_imm, lambda one, ss: (GPB2Filter(one, [[1.0]], X0, P0), P0)),
    "rbpf": Case(
        "rbpf", lambda s: RBPFilter(s, TRANSITION, X0, P0, particles=64, rng=5), switched,
        (0.25, 0.2), no_keywords, read_rbpf,
        lambda one, ss: (RBPFilter(one, [[1.0]], X0, P0, particles=8, rng=5), P0),
        alone=lambda est, trials, n: {"keys": est.trial_keys((trials,))[n]}),
    "imm-ev1": Case(
        "imm-ev1", lambda s: IMMEV1Filter(s, TRANSITION, X0, P0, grid=3), switched,
        (0.25, 0.2), no_keywords, read_imm_ev1,
        lambda one, ss: (IMMEV1Filter(one, x0=X0, P0=P0, grid=3, epsilon=0.0), P0)),
    "min-distance": Case(  # v_max small enough that a switch is declared in the records
        "min-distance", lambda s: MinimumDistanceDetector(s, delta=0.5, Delta=0.5, v_max=0.003),
        switched, (0.05, 0.025), no_keywords, read_min_distance,
        "it estimates the state from windows of the output alone: no prior, no covariance, "
        "no Kalman equivalent"),
    "rsls": Case(
        "rsls", lambda s: RSLSObserver(s, WANG_GAINS, WANG_T, X0, 0.1 * np.eye(2)), integrated,
        (WANG_T / 5, WANG_T / 4), over_interval, read_rsls,
        "a fixed-gain observer of the integrated (Ito) output: with one mode it is a "
        "Luenberger observer, not a Kalman filter"),
    "impulsive": Case(
        "impulsive", lambda s: ImpulsiveObserver(s, G_IMPULSIVE, X0, P0), switched,
        (0.25, 0.2), signal_segments, read_impulsive,
        # with the steady-state Kalman gain, from the Riccati fixed point, the jump (2) is
        # the Kalman update and the error covariance the Kalman one
        lambda one, ss: (ImpulsiveObserver(one, ss.gain[None], X0, ss.prior), ss.prior)),
}


def system_of(case: Case) -> SwitchedLinearSystem:
    return WANG if case.scenario is integrated else SYS


def data(name: str, trials: int = 3, seed: int = 0, period: int = 0) -> Scenario:
    case = CASES[name]
    return case.scenario(case.periods[period], trials=trials, seed=seed)


def run(name: str, est: Estimator, sc: Scenario, **kw) -> Estimate:
    return est.run(sc.y, sc.u, sc.t, **{**run_keywords(CASES[name].method, sc), **kw})


def fields(est: Estimate) -> dict:
    return {f: getattr(est, f) for f in Estimate.__dataclass_fields__
            if getattr(est, f) is not None}


def defined(name: str, est: Estimate) -> np.ndarray:
    """Samples with an estimate: all but the min-distance detector's windows."""
    if CASES[name].method == "min-distance":
        return est.mode >= 0
    return np.ones(est.x.shape[:-1], dtype=bool)


# ---------------------------------------------------------------------- the protocol
def test_every_registered_method_has_a_case():
    assert {case.method for case in CASES.values()} == set(METHOD_NAMES)


def test_the_protocol_is_abstract():
    assert Estimator.__abstractmethods__ == frozenset({"init", "step", "run"})

    class NoStep(Estimator):
        def init(self, batch_shape=()):
            return None

        def run(self, y, u=None, t=None):
            return Estimate(x=np.zeros((1, 1)))

    with pytest.raises(TypeError, match="abstract method"):
        NoStep()


def positional(sig: inspect.Signature) -> list[str]:
    return [p.name for p in sig.parameters.values()
            if p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD]


@pytest.mark.parametrize("method", METHOD_NAMES)
def test_every_registered_estimator_implements_the_protocol(method):
    cls = get_method(method).estimator
    assert issubclass(cls, Estimator) and not inspect.isabstract(cls)
    init = inspect.signature(cls.init)
    assert positional(init) == ["self", "batch_shape"]
    assert init.parameters["batch_shape"].default == ()
    step = inspect.signature(cls.step)
    assert positional(step) == ["self", "state", "y", "u"] and step.parameters["u"].default is None
    assert step.parameters["dt"].kind is inspect.Parameter.KEYWORD_ONLY
    assert step.parameters["dt"].default is None
    run_sig = inspect.signature(cls.run)
    assert positional(run_sig) == ["self", "y", "u", "t"]
    assert run_sig.parameters["u"].default is None and run_sig.parameters["t"].default is None
    switching = get_method(method).switching  # the one keyword it is told the switching by
    assert switching is None or switching in run_sig.parameters
    assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in run_sig.parameters.values()
               if p.name not in ("self", "y", "u", "t"))


@pytest.mark.parametrize("method", METHOD_NAMES)
def test_every_constructor_follows_the_convention(method):
    """``(system, ..., x0, P0, *, options)``; the min-distance detector has no prior."""
    params = list(inspect.signature(get_method(method).estimator.__init__).parameters.values())
    names = [p.name for p in params]
    assert names[1] == "system"
    if method == "min-distance":  # estimates the state from each window: no x0, P0
        assert "x0" not in names and "P0" not in names
        last = max(i for i, p in enumerate(params) if p.default is inspect.Parameter.empty)
    else:
        last = names.index("P0")
        assert names[last - 1] == "x0"
    assert all(p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD for p in params[: last + 1])
    assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params[last + 1 :])


@pytest.mark.parametrize("name", CASES)
def test_every_case_is_an_estimator(name):
    case = CASES[name]
    est = case.make(system_of(case))
    assert isinstance(est, Estimator) and isinstance(est, get_method(case.method).estimator)


# ---------------------------------------------------------------------- behaviour on data
@pytest.mark.parametrize("name", CASES)
def test_batched_equals_looped(name):
    sc = data(name)
    est = CASES[name].make(system_of(CASES[name]))
    batched = fields(run(name, est, sc))
    for n in range(sc.y.shape[0]):
        single = fields(run(name, est, sc.trial(n), **CASES[name].alone(est, sc.y.shape[0], n)))
        assert single.keys() == batched.keys()
        assert single["x"].shape == sc.y.shape[1:2] + batched["x"].shape[-1:]  # no batch axis
        for f, value in batched.items():
            np.testing.assert_allclose(value[n], single[f], rtol=1e-9, atol=1e-12, err_msg=f)


@pytest.mark.parametrize("name", CASES)
def test_step_streaming_equals_run(name):
    case = CASES[name]
    sc = data(name, trials=2)
    est = case.make(system_of(case))
    whole = fields(run(name, est, sc))
    state = est.init((sc.y.shape[0],))
    streamed = []
    for k in range(sc.t.size):
        dt = None if k == 0 else sc.t[k] - sc.t[k - 1]
        u = None if sc.u is None else sc.u[:, max(k - 1, 0)]  # held over the interval into k
        state = est.step(state, sc.y[:, k], u, dt=dt, **case.stream(sc, k))
        streamed.append(case.read(est, state))
    for f in streamed[0]:
        np.testing.assert_allclose(np.stack([s[f] for s in streamed], axis=1), whole[f],
                                   rtol=1e-9, atol=1e-12, err_msg=f)


@pytest.mark.parametrize("name", CASES)
def test_a_second_run_keeps_nothing_of_the_first(name):
    """A second run at another sampling period equals a fresh estimator's run."""
    case = CASES[name]
    first, second = data(name, period=0), data(name, seed=1, period=1)
    used = case.make(system_of(case))
    run(name, used, first)
    again = fields(run(name, used, second))
    fresh = fields(run(name, case.make(system_of(case)), second))
    assert again.keys() == fresh.keys()
    for f in fresh:  # the same code on the same input: equal to the last bit
        np.testing.assert_array_equal(again[f], fresh[f], err_msg=f)


@pytest.mark.parametrize("name", CASES)
def test_reproducible_and_finite(name):
    case = CASES[name]
    sc = data(name)
    a = fields(run(name, case.make(system_of(case)), sc))
    b = fields(run(name, case.make(system_of(case)), sc))
    for f in a:  # the same code on the same input: equal to the last bit
        np.testing.assert_array_equal(a[f], b[f], err_msg=f)
    ok = defined(name, run(name, case.make(system_of(case)), sc))
    assert ok.any() and np.all(np.isfinite(a["x"][ok]))
    if "P" in a:
        assert np.all(np.isfinite(a["P"][ok]))


@pytest.mark.parametrize("name", CASES)
def test_single_mode_reduces_to_the_kalman_filter(name):
    case = CASES[name]
    if isinstance(case.one_mode, str):
        pytest.skip(f"{case.method}: {case.one_mode}")
    one = SwitchedLinearSystem.continuous(A[:1], B[:1], C, Q=0.05 * np.eye(2), R=[[0.1]])
    t = sg.periodic(0.25, 3.0)
    traj = simulate(one, sg.schedule([], [0]), t, (X0, P0), u=np.ones(1), trials=2, rng=4)
    steps = mode_steps(one, 0.25)
    gain, prior, _ = steady_state_gain(steps.F[0], one.C[0], steps.Qd[0], one.R[0])
    est, start = case.one_mode(one, SteadyState(gain, prior))
    ref = ModeKalmanFilter(one, X0, start).run(traj.y, np.ones(1), t, modes=np.zeros(t.size, int))
    sc = Scenario(t, traj.y, np.ones((2, t.size, 1)), np.zeros((2, t.size), int),
                  [sg.schedule([], [0])] * 2)
    out = run(name, est, sc)
    np.testing.assert_allclose(out.x, ref.x, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(out.P, ref.P, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("name", CASES)
def test_nan_measurement_skips_the_update(name):
    case = CASES[name]
    sc = data(name, trials=2)
    y = sc.y.copy()
    y[:, 5] = np.nan
    est = case.make(system_of(case))
    full = run(name, est, replace(sc, y=y))
    ok = defined(name, full)
    assert np.all(np.isfinite(full.x[ok]))
    assert full.P is None or np.all(np.isfinite(full.P))
    head = run(name, est, sc.head(5))
    np.testing.assert_allclose(full.x[:, :5], head.x, rtol=1e-12)
    if name == "kalman":
        # no update at sample 5: the estimate is the one-step prediction of sample 4's
        steps = mode_steps(SYS, sc.t[1] - sc.t[0])
        m = sc.modes[:, 4]
        x_pred = (np.einsum("nij,nj->ni", steps.F[m], full.x[:, 4])
                  + np.einsum("nij,nj->ni", steps.G[m], sc.u[:, 4]))
        P_pred = steps.F[m] @ full.P[:, 4] @ np.swapaxes(steps.F[m], 1, 2) + steps.Qd[m]
        np.testing.assert_allclose(full.x[:, 5], x_pred, rtol=1e-12)
        np.testing.assert_allclose(full.P[:, 5], P_pred, rtol=1e-12)


#: switching a run is told of that names a mode the system lacks, and the message refusing it
BAD_SWITCHING = {
    "modes": (lambda sc, L: np.full(sc.t.size, L), "modes must be in 0..1"),
    "signals": (lambda sc, L: sg.schedule([], [L]), "signals use a mode beyond"),
}


@pytest.mark.parametrize("name", CASES)
def test_bad_shapes_are_refused(name):
    case = CASES[name]
    sc = data(name, trials=2)
    est = case.make(system_of(case))
    with pytest.raises(ValueError, match=r"y must have shape \(\.\.\., K, m\)"):
        run(name, est, replace(sc, y=np.concatenate([sc.y, sc.y], axis=-1)))
    with pytest.raises(ValueError, match="t must have shape"):
        est.run(sc.y, sc.u, sc.t[:-1], **run_keywords(case.method, sc))
    with pytest.raises(ValueError, match="u must"):  # the wrong l, or any u without inputs
        est.run(sc.y, np.ones(3), sc.t, **run_keywords(case.method, sc))
    with pytest.raises(ValueError, match="infinities"):
        bad = sc.y.copy()
        bad[0, 1, 0] = np.inf
        run(name, est, replace(sc, y=bad))
    kind = get_method(case.method).switching
    if kind is not None:
        wrong, message = BAD_SWITCHING[kind]
        with pytest.raises(ValueError, match=message):
            est.run(sc.y, sc.u, sc.t, **{kind: wrong(sc, system_of(case).n_modes)})


def test_constructors_validate():
    with pytest.raises(ValueError, match="x0 must have shape"):
        ModeKalmanFilter(SYS, np.zeros(3), P0)
    with pytest.raises(ValueError, match="P0 must be symmetric"):
        IMMFilter(SYS, TRANSITION, X0, np.array([[1.0, 2.0], [0.0, 1.0]]))
    rows = r"rows must sum to 1 \(P\[i, j\] = P\(j next \| i now\)\)"
    with pytest.raises(ValueError, match=rows):
        IMMFilter(SYS, TRANSITION.T, X0, P0)
    with pytest.raises(ValueError, match="g must be a positive int"):
        SwitchTimeKalmanFilter(SYS, X0, P0, grid=0)
    with pytest.raises(ValueError, match="predecessor must be"):
        IMMEV1Filter(SYS, x0=X0, P0=P0, predecessor="best")
    with pytest.raises(TypeError, match="SwitchedLinearSystem"):
        ModeKalmanFilter(A, X0, P0)
    disc = SwitchedLinearSystem.discrete(A, dt=0.1)
    with pytest.raises(ValueError, match="continuous-time system"):
        IMMEV1Filter(disc, x0=X0, P0=P0)
    with pytest.raises(TypeError, match=r"IMMEV1Filter needs the prior x0 and P0"):
        IMMEV1Filter(SYS, TRANSITION, X0)


def test_imm_ev1_takes_the_prior_by_position_or_by_keyword():
    sc = data("imm-ev1", trials=1)
    by_position = IMMEV1Filter(SYS, None, X0, P0, grid=3).run(sc.y, sc.u, sc.t)
    by_keyword = IMMEV1Filter(SYS, x0=X0, P0=P0, grid=3).run(sc.y, sc.u, sc.t)
    np.testing.assert_array_equal(by_position.x, by_keyword.x)  # the same filter, same input
