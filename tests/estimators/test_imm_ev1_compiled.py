"""IMMEV1Filter on the compiled kernel against its numpy oracle (imm_ev1_oracle.py, beside this).

The oracle is the filter as it ran before the kernel: every hypothesis (predecessor, destination,
grid point) predicted and updated by the numpy Kalman core, then selected. The kernel scores
the hypotheses without forming their predictions and predicts and updates the chosen ones only
(Shankar et al., Algorithm 1; :mod:`switchest.engine.imm_ev1`), so the two differ
in operation order only. Tolerance: every float output equals the oracle's to RTOL = 1e-9
relative to the largest entry of the oracle's array (entrywise relative error means nothing for
entries that cancel to ~0); each step is backward stable and these filters are stable, so the
observed agreement is ~1e-14. Modes, outlier flags and which switching times are NaN must agree
exactly; they depend on comparisons of likelihoods that differ between hypotheses by far more
than rounding on these data.
"""

import math
import warnings

import numpy as np
import pytest
from imm_ev1_oracle import OracleIMMEV1Filter
from scipy.stats import chi2

from switchest import SwitchedLinearSystem
from switchest import signals as sg
from switchest.discretize import pairwise_grid, switch_grid
from switchest.engine import raise_for_status
from switchest.engine.imm_ev1 import imm_ev1_run
from switchest.estimators import IMMEV1Filter
from switchest.models import BOOST_INPUT_VOLTAGE, BOOST_SAMPLE_PERIOD, boost_converter
from switchest.simulate import simulate

RTOL = 1e-9
FIELDS = ("x", "P", "mode_prob", "switch_time")
STATE = ("x", "P", "log_weight", "switch_offset")


def three_modes():
    """Three stable modes of three states with different dynamics and inputs, two correlated
    outputs: told apart well enough that the MAP path switches (mode accuracy ~0.6-0.8)."""
    rng = np.random.default_rng(7)
    A = 0.5 * rng.standard_normal((3, 3, 3)) - 0.5 * np.eye(3)
    B = 5.0 * rng.standard_normal((3, 3, 1))
    C = rng.standard_normal((2, 3))
    R = np.array([[0.02, 0.005], [0.005, 0.01]])
    return SwitchedLinearSystem.continuous(A, B, C, Q=0.01 * np.eye(3), R=R)


SYS3 = three_modes()
X3, P3 = np.zeros(3), np.eye(3)
TRANSITION3 = np.array([[0.8, 0.2, 0.0], [0.1, 0.8, 0.1], [0.0, 0.3, 0.7]])  # two impossible


def assert_close(actual, expected, rtol=RTOL):
    """``|actual - expected| <= rtol max|expected|`` entrywise, NaN where the oracle's is NaN."""
    expected = np.asarray(expected)
    nan = np.isnan(expected)
    np.testing.assert_array_equal(np.isnan(actual), nan)
    if nan.all():
        return
    scale = np.abs(expected[~nan]).max()
    np.testing.assert_allclose(np.where(nan, 0.0, actual), np.where(nan, 0.0, expected), rtol=0.0,
                               atol=rtol * scale)


def assert_same_estimate(est, ref):
    for field in FIELDS:
        assert_close(getattr(est, field), getattr(ref, field))
    np.testing.assert_array_equal(est.mode, ref.mode)
    np.testing.assert_array_equal(est.outlier, ref.outlier)


def assert_same_state(state, ref):
    for field in STATE:
        a, e = getattr(state, field), getattr(ref, field)
        finite = np.isfinite(e)  # a log weight of -inf (an impossible path) must stay -inf
        np.testing.assert_array_equal(np.isfinite(a), finite)
        np.testing.assert_array_equal(np.isneginf(a), np.isneginf(e))
        assert_close(np.where(finite, a, np.nan), np.where(finite, e, np.nan))
    np.testing.assert_array_equal(state.predecessor, ref.predecessor)
    np.testing.assert_array_equal(state.outlier, ref.outlier)


@pytest.fixture(scope="module")
def data3():
    """Six trials of the three-mode system with holes, a partial sample and an outlier."""
    t = sg.periodic(0.2, 6.0)
    traj = simulate(SYS3, lambda r: sg.dwell_time(3, t[-1], 0.5, 1.2, rng=r), t, (X3, P3),
                    u=np.ones(1), trials=6, rng=3)
    y = traj.y.copy()
    y[0, 4] = np.nan  # a whole sample missing
    y[1, 6, 0] = np.nan  # one component missing
    y[2, 9, 1] = np.nan
    y[3, 12, 0] = 1e300  # an outlier every hypothesis rejects
    return y, t


@pytest.mark.parametrize("transition", [None, TRANSITION3], ids=["no-transition", "transition"])
@pytest.mark.parametrize("predecessor", ["path", "likelihood"])
@pytest.mark.parametrize("switch_time", ["max", "marginal"])
@pytest.mark.parametrize("likelihood", ["innovation", "printed"])
def test_run_equals_the_oracle(data3, likelihood, switch_time, predecessor, transition):
    y, t = data3
    # a tight gate: some hypotheses reject some samples, every one rejects the outlier
    kw = dict(x0=X3, P0=P3, grid=3, likelihood=likelihood, switch_time=switch_time,
              predecessor=predecessor, gate=float(chi2.ppf(0.999, df=2)))
    est = IMMEV1Filter(SYS3, transition, **kw).run(y, np.ones(1), t)
    ref = OracleIMMEV1Filter(SYS3, transition, **kw).run(y, np.ones(1), t)
    assert_same_estimate(est, ref)
    assert ref.outlier[3, 12] and np.isfinite(ref.switch_time).any()


@pytest.mark.parametrize("switch_time", ["max", "marginal"])
@pytest.mark.parametrize("g", [1, 2, 4])
def test_two_modes_at_irregular_sample_times_equal_the_oracle(g, switch_time):
    system = boost_converter()
    T = BOOST_SAMPLE_PERIOD
    rng = np.random.default_rng(5)
    t = np.cumsum(T * rng.choice([0.5, 1.0, 1.5], size=40))  # three distinct steps, repeated
    traj = simulate(system, lambda r: sg.dwell_time(2, t[-1], 2 * T, 4 * T, rng=r), t,
                    (np.array([0.0, 100.0]), np.diag([25.0, 25.0])), u=[BOOST_INPUT_VOLTAGE],
                    trials=4, rng=2)
    kw = dict(x0=np.array([0.0, 100.0]), P0=np.diag([25.0, 25.0]), grid=g,
              switch_time=switch_time, mode_prob0=[0.7, 0.3])
    est = IMMEV1Filter(system, **kw).run(traj.y, [BOOST_INPUT_VOLTAGE], t)
    ref = OracleIMMEV1Filter(system, **kw).run(traj.y, [BOOST_INPUT_VOLTAGE], t)
    assert_same_estimate(est, ref)


@pytest.mark.parametrize("batch", [(), (1,), (2, 3)])
def test_batch_shapes_equal_the_oracle(data3, batch):
    y, t = data3
    N = int(np.prod(batch, dtype=int))
    y = y[:N].reshape(*batch, *y.shape[1:]) if batch else y[4]
    u = np.linspace(0.5, 1.5, t.size)[:, None]  # (K, l): a time-varying input shared by trials
    kw = dict(x0=X3, P0=P3, grid=2, switch_time="marginal")
    est = IMMEV1Filter(SYS3, TRANSITION3, **kw).run(y, u, t)
    ref = OracleIMMEV1Filter(SYS3, TRANSITION3, **kw).run(y, u, t)
    assert est.x.shape == (*batch, t.size, 3) and est.mode.shape == (*batch, t.size)
    assert_same_estimate(est, ref)


@pytest.mark.parametrize("switch_time", ["max", "marginal"])
def test_step_streams_what_run_reports_and_the_oracle_steps(data3, switch_time):
    y, t = data3
    u = np.ones(1)
    kw = dict(x0=X3, P0=P3, grid=3, switch_time=switch_time, gate=50.0)
    f, oracle = IMMEV1Filter(SYS3, TRANSITION3, **kw), OracleIMMEV1Filter(SYS3, TRANSITION3, **kw)
    est = f.run(y, u, t)
    batch = (2, 3)
    state, ref = f.init(batch), oracle.init((6,))
    for k in range(t.size):
        dt = None if k == 0 else t[k] - t[k - 1]
        state = f.step(state, y[:, k].reshape(*batch, -1), u, dt=dt)
        ref = oracle.step(ref, y[:, k], np.ones((6, 1)), dt=dt)
        flat = type(state)(**{name: getattr(state, name).reshape(6, *getattr(state, name).shape[2:])
                              for name in ("x", "P", "log_weight", "predecessor", "switch_offset",
                                           "outlier")})
        assert_same_state(flat, ref)
        best = np.argmax(flat.log_weight, axis=-1)
        rows = np.arange(6)
        assert_close(flat.x[rows, best], est.x[:, k])
        assert_close(flat.P[rows, best], est.P[:, k])
        offset = flat.switch_offset[rows, best] + (t[k - 1] if k else np.nan)
        assert_close(offset, est.switch_time[:, k])
        np.testing.assert_array_equal(best, est.mode[:, k])
        np.testing.assert_array_equal(flat.outlier, est.outlier[:, k])


def test_one_sample_is_an_update_only():
    y = np.array([[[0.3, -0.2]], [[np.nan, 0.1]]])
    kw = dict(x0=X3, P0=P3, grid=4)
    est = IMMEV1Filter(SYS3, **kw).run(y, t=[0.0])
    ref = OracleIMMEV1Filter(SYS3, **kw).run(y, t=[0.0])
    assert_same_estimate(est, ref)
    assert np.isnan(est.switch_time).all()


def kernel_arguments(data3, lanes):
    """:func:`imm_ev1_run` on the three-mode data with two distinct sampling steps."""
    y, t = data3
    t = t.copy()
    t[5:] += 0.05  # one longer interval
    steps, which = np.unique(np.diff(t), return_inverse=True)
    grids = [pairwise_grid(SYS3, h, 3) for h in steps]
    F, G, Qd = (np.concatenate([getattr(gr, a).reshape(-1, *getattr(gr, a).shape[-2:])
                                for gr in grids]) for a in ("F", "G", "Qd"))
    tau = np.stack([switch_grid(h, 3) for h in steps])
    table = np.concatenate([[0], which])
    u = np.ones((y.shape[0], t.size, 1))
    return imm_ev1_run(y, u, F, G, Qd, table, tau, SYS3.C, SYS3.R, np.log(TRANSITION3 + 1e-300),
                       X3, P3, np.log(np.full(3, 1 / 3)), epsilon=1e-6, gate=30.0, lanes=lanes)


def test_the_block_of_lanes_does_not_change_the_results(data3):
    ref = kernel_arguments(data3, 16)
    raise_for_status(ref.status)
    for lanes in (1, 4):
        out = kernel_arguments(data3, lanes)
        for field in ("x", "P", "mode_prob", "switch_offset"):
            assert_close(getattr(out, field), getattr(ref, field), rtol=1e-14)
        np.testing.assert_array_equal(out.mode, ref.mode)
        np.testing.assert_array_equal(out.outlier, ref.outlier)


def test_an_indefinite_covariance_is_repaired_as_by_the_oracle():
    """A state covariance beyond 1/eps and indefinite: the likelihood of a hypothesis cannot be
    factored, so its prediction is formed, repaired to its rounding level (with the package's
    warning) and factored again, as the numpy core does."""
    A = np.array([np.diag([-0.4, -0.3]), np.diag([-0.2, -0.6])])  # diagonal: F keeps P's axes
    B = np.array([[[1.0], [0.0]], [[0.0], [1.0]]])
    system = SwitchedLinearSystem.continuous(A, B, [[1.0, 0.0]], Q=0.01 * np.eye(2), R=[[0.1]])
    kw = dict(x0=np.zeros(2), P0=np.eye(2), grid=2, epsilon=0.0)
    f, oracle = IMMEV1Filter(system, **kw), OracleIMMEV1Filter(system, **kw)
    state, ref = f.init((2,)), oracle.init((2,))
    P = np.broadcast_to(np.diag([-1e3, 1e20]), (2, 2, 2, 2)).copy()  # the seen state: negative
    state = type(state)(state.x, P, state.log_weight, state.predecessor, state.switch_offset,
                        state.outlier)
    ref = type(ref)(ref.x, P.copy(), ref.log_weight, ref.predecessor, ref.switch_offset,
                    ref.outlier)
    y, u = np.array([[0.5], [-0.2]]), np.ones((2, 1))
    with pytest.warns(RuntimeWarning, match="singular or indefinite to working precision"):
        state = f.step(state, y, u, dt=0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        ref = oracle.step(ref, y, u, dt=0.1)
    assert_same_state(state, ref)


def test_a_covariance_that_cannot_be_repaired_is_refused():
    system = SwitchedLinearSystem.continuous(np.array([np.eye(1), -np.eye(1)]), C=[[1.0]],
                                             Q=[[1.0]], R=[[1.0]])
    f = IMMEV1Filter(system, x0=[0.0], P0=[[1.0]], grid=2)
    state = f.init((1,))
    state = type(state)(state.x, np.full((1, 2, 1, 1), np.inf), state.log_weight,
                        state.predecessor, state.switch_offset, state.outlier)
    with np.errstate(all="ignore"), pytest.raises(np.linalg.LinAlgError, match="not finite"):
        f.step(state, np.zeros((1, 1)), dt=1.0)


def test_step_refuses_bad_arguments_by_name():
    f = IMMEV1Filter(SYS3, x0=X3, P0=P3, grid=2)
    state = f.init((4,))
    with pytest.raises(ValueError, match=r"y must have shape \(4, 2\)"):
        f.step(state, np.zeros((4, 3)), dt=0.1)
    with pytest.raises(ValueError, match="dt must be a finite positive number"):
        f.step(state, np.zeros((4, 2)), dt=-0.1)
    with pytest.raises(TypeError, match="dt must be a real scalar"):
        f.step(state, np.zeros((4, 2)), dt="0.1")


def test_the_kernel_refuses_tables_that_do_not_match(data3):
    y, t = data3
    grid = pairwise_grid(SYS3, 0.2, 3)
    F, G, Qd = (getattr(grid, a).reshape(9 * 3, *getattr(grid, a).shape[-2:])
                for a in ("F", "G", "Qd"))
    u = np.ones((y.shape[0], t.size, 1))
    args = (SYS3.C, SYS3.R, np.zeros((3, 3)), X3, P3, np.log(np.full(3, 1 / 3)))
    tau = switch_grid(0.2, 3)[None]
    with pytest.raises(ValueError, match="F, G, Qd must hold D L L g = 1 x 3 x 3 x 2"):
        imm_ev1_run(y, u, F, G, Qd, np.zeros(t.size, int), tau[:, :2], *args, epsilon=0.0)
    with pytest.raises(ValueError, match="table must index 0..0"):
        imm_ev1_run(y, u, F, G, Qd, np.ones(t.size, int), tau, *args, epsilon=0.0)
    with pytest.raises(ValueError, match="epsilon must be a finite non-negative number"):
        imm_ev1_run(y, u, F, G, Qd, np.zeros(t.size, int), tau, *args, epsilon=-1.0)
    with pytest.raises(ValueError, match="gate must be a positive number or inf"):
        imm_ev1_run(y, u, F, G, Qd, np.zeros(t.size, int), tau, *args, epsilon=0.0,
                    gate=math.nan)


@pytest.mark.parametrize("switch_time", ["max", "marginal"])
def test_the_mixture_estimate_is_the_moments_of_the_destinations(data3, switch_time):
    """``estimate="mixture"`` reports, at every sample, the moments of the mixture of the
    destinations' posteriors weighed by their normalized path weights, computed here from the
    stepped state; the mode, mode probabilities and switching instants stay the MAP path's."""
    y, t = data3
    u = np.ones(1)
    kw = dict(x0=X3, P0=P3, grid=3, switch_time=switch_time, gate=50.0)
    mixed = IMMEV1Filter(SYS3, TRANSITION3, estimate="mixture", **kw)
    est, paper = mixed.run(y, u, t), IMMEV1Filter(SYS3, TRANSITION3, **kw).run(y, u, t)
    state = mixed.init((6,))
    for k in range(t.size):
        state = mixed.step(state, y[:, k], u, dt=None if k == 0 else t[k] - t[k - 1])
        w = np.exp(state.log_weight - state.log_weight.max(axis=-1, keepdims=True))
        w /= w.sum(axis=-1, keepdims=True)
        x = np.einsum("nl,nli->ni", w, state.x)
        d = state.x - x[:, None]
        P = np.einsum("nl,nlij->nij", w, state.P + d[..., :, None] * d[..., None, :])
        assert_close(est.x[:, k], x)
        assert_close(est.P[:, k], P)
    for field in ("mode_prob", "switch_time"):
        assert_close(getattr(est, field), getattr(paper, field))
    np.testing.assert_array_equal(est.mode, paper.mode)
    with pytest.raises(ValueError, match="estimate must be 'map' or 'mixture'"):
        IMMEV1Filter(SYS3, TRANSITION3, estimate="mean", **kw)


def test_the_merged_mixture_is_consistent_on_the_boost_converter():
    """On Table I's boost converter (20 trials x 0.1 s, g = 5) the paper's IMM-EV1 reports the
    MAP destination's covariance, its NEES (2 states) in the hundreds of thousands; the
    destinations' mixture over merged instants brings its median near that of chi2(2), 1.39,
    and the RMSE down. Tolerance: the median of 3600 NEES values, a few samples correlated,
    within 0.5 of 1.39 leaves the approximations room."""
    from switchest.models.shankar import BoostTable1

    setting = BoostTable1()
    traj = setting.simulate(0.1, 20, np.random.default_rng(1))
    (x0, P0), u = setting.prior, setting.input
    nees, rmse = {}, {}
    for name, kw in (("paper", {}), ("mixture", dict(switch_time="marginal", estimate="mixture"))):
        est = IMMEV1Filter(setting.system(), x0=x0, P0=P0, grid=5, **kw).run(traj.y, u, traj.t)
        e = (est.x - traj.x)[:, 20:]
        nees[name] = np.einsum("...i,...ij,...j->...", e, np.linalg.inv(est.P[:, 20:]), e)
        rmse[name] = np.sqrt(np.mean(e ** 2, axis=(0, 1)))
    assert np.median(nees["paper"]) > 1e4
    assert abs(np.median(nees["mixture"]) - chi2.median(2)) < 0.5
    assert np.all(rmse["mixture"] < rmse["paper"])
