"""The C engine's switch-time Kalman filter (switchest.engine.switch_time) against the numba
kernel it replaces (switchest.estimators._compiled.switch_time), on many cases.

Every float output must equal numba's to ``1e-12`` of the largest entry of numba's array (NaN
where numba's is NaN); flags, ``status`` and ``repaired`` exactly. The cases run the kernel's
tables as the estimator builds them (``switchest.estimators.switch_time._tables``) for the
boost converter, a three-mode system and random systems of n = 1..4 states: grids g = 1..5,
the grid maximum, Brent's refinement (with its edge step), the marginal merge, the printed
likelihood, gates and outliers, missing samples and components, irregular steps, streaming
steps (``predict_first``), single samples, zero trials or samples, failures and repairs, and
lane blocks of several sizes (the binding called directly) with trial counts that are not a
multiple of the block. The largest relative difference per output is printed at the end of
the module (run with ``-s``). This file goes with the numba code.
"""

import math

import numpy as np
import pytest
from switchest.engine._switch_time import switch_time_filter as c_filter

from switchest import signals as sg
from switchest.engine import NOT_FINITE, NOT_POSITIVE_DEFINITE, OK
from switchest.engine import switch_time as eng
from switchest.estimators._compiled import switch_time as ref
from switchest.estimators.switch_time import _tables
from switchest.models import (
    BOOST_INPUT_VOLTAGE,
    BOOST_SAMPLE_PERIOD,
    boost_converter,
    boost_switching,
)
from switchest.simulate import simulate
from switchest.system import SwitchedLinearSystem

TOL = 1e-12
WORST: dict[str, float] = {}


@pytest.fixture(autouse=True, scope="module")
def print_worst():
    yield
    print("\nlargest relative difference, engine vs numba (switch_time):")
    for name, value in sorted(WORST.items()):
        print(f"  {name:12s} {value:.3g}")


def close(name, actual, expected):
    """``|actual - expected| <= 1e-12 max|expected|`` entrywise (NaN where NaN), recorded."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape and actual.dtype == expected.dtype
    np.testing.assert_array_equal(np.isnan(actual), np.isnan(expected))
    finite = np.isfinite(expected)
    odd = ~finite & ~np.isnan(expected)
    np.testing.assert_array_equal(actual[odd], expected[odd])
    if not finite.any():
        return
    scale = np.abs(expected[finite]).max()
    diff = np.abs(actual[finite] - expected[finite]).max()
    rel = diff / scale if scale > 0 else diff
    WORST[name] = max(WORST.get(name, 0.0), rel)
    np.testing.assert_allclose(actual[finite], expected[finite], rtol=0.0, atol=TOL * scale)


def same(out, want, *, complete=True):
    """Every output of two SwitchTimeOutput tuples (the arrays only if the run completed)."""
    assert out.status == want.status
    assert out.repaired == want.repaired
    if math.isinf(want.smallest_eigenvalue):
        assert out.smallest_eigenvalue == want.smallest_eigenvalue
    else:
        close("smallest_eig", out.smallest_eigenvalue, want.smallest_eigenvalue)
    if not complete:
        return
    for name in ("x", "P", "loglik", "offset"):
        close(name, getattr(out, name), getattr(want, name))
    np.testing.assert_array_equal(out.flag, want.flag)
    assert out.flag.dtype == want.flag.dtype


# ---------------------------------------------------------------- cases
def random_system(seed, n, m, l, L):
    """A stable continuous-time system of L modes with their own dynamics, inputs, outputs."""
    rng = np.random.default_rng(seed)
    A = [-1.0 * np.eye(n) + 0.5 * rng.standard_normal((n, n)) for _ in range(L)]
    B = rng.standard_normal((L, n, l))
    C = rng.standard_normal((L, m, n)) + np.eye(m, n)
    R = []
    for _ in range(L):
        X = rng.standard_normal((m, m))
        R.append(0.05 * X @ X.T + 0.1 * np.eye(m))
    return SwitchedLinearSystem.continuous(A, B, C, Q=0.1 * np.eye(n), R=np.array(R))


def three_mode_system():
    """The three-mode system of tests/estimators/test_switch_time_compiled.py."""
    A = [[[-0.5, 1.0, 0.0], [-1.0, -0.2, 0.3], [0.0, 0.0, -0.8]],
         [[-1.5, 0.0, 0.5], [0.2, -0.4, 0.0], [0.0, 1.0, -0.3]],
         [[0.1, -1.0, 0.0], [1.0, -0.1, 0.0], [0.5, 0.0, -2.0]]]
    B = [[[1.0, 0.0], [0.0, 0.5], [0.0, 0.0]], [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
         [[0.5, 0.5], [0.0, 0.0], [1.0, 0.0]]]
    C = [[[1.0, 0.0, 0.0], [0.0, 1.0, 0.5]], [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]],
         [[1.0, 1.0, 0.0], [0.0, 0.3, 1.0]]]
    R = [[[0.1, 0.02], [0.02, 0.2]], [[0.3, 0.0], [0.0, 0.1]], [[0.2, -0.05], [-0.05, 0.15]]]
    return SwitchedLinearSystem.continuous(A, B, C, Q=0.05 * np.eye(3), R=R)


def times(seed, K, pool):
    """K sample times whose steps are drawn from ``pool`` (D = len(pool) distinct steps)."""
    rng = np.random.default_rng(seed)
    return np.concatenate([[0.0], np.cumsum(rng.choice(pool, K - 1))])


def simulated(system, t, N, seed, *, rate=1.0, x0=None, P0=None):
    """Simulated y, u (N, K, l) and modes of N trials with Markov switching at ``rate``."""
    n, l, L = system.n_states, system.n_inputs, system.n_modes
    rng = np.random.default_rng(seed)
    rates = np.full((L, L), rate / (L - 1))
    np.fill_diagonal(rates, -rate)
    u = rng.standard_normal((N, t.size, l))
    x0 = np.zeros(n) if x0 is None else x0
    P0 = np.eye(n) if P0 is None else P0
    traj = simulate(system, lambda r: sg.markov_continuous(rates, t[-1], rng=r), t, (x0, P0),
                    u=u, trials=N, rng=seed + 1)
    return traj.y.copy(), u, traj.mode


def with_holes(y, seed, p=0.1):
    """NaN in whole samples and in single components."""
    rng = np.random.default_rng(seed)
    y = y.copy()
    y[rng.random(y.shape[:2]) < p] = np.nan
    y[rng.random(y.shape) < p] = np.nan
    return y


def kernel_case(system, t, y, u, modes, x0, P0, *, g, refine, inflation=0.0, no_inputs=False):
    """``(args, kwargs)`` of switch_time_run as the estimator's run builds them."""
    N, K = modes.shape
    modes = np.ascontiguousarray(modes, dtype=np.int64)
    prev = np.concatenate([modes[:, :1], modes[:, :-1]], axis=1)
    held = np.concatenate([u[:, :1], u[:, :-1]], axis=1)
    steps, which = np.unique(np.diff(t), return_inverse=True)
    which = np.concatenate([[0], which]).astype(np.int64)
    F, G, Qd, grid_tau, levels, outputs = _tables(system, tuple(steps.tolist()), g, refine,
                                                  inflation)
    if no_inputs:  # l = 0 (the estimator's _tables needs an input to reshape its G)
        held, G = held[:, :, :0].copy(), G[:, :, :0].copy()
        outputs = (outputs[0], outputs[1][:, :, :0].copy(), outputs[2])
    x0 = np.broadcast_to(x0, (N, system.n_states)).copy()
    P0 = np.broadcast_to(P0, (N, system.n_states, system.n_states)).copy()
    args = [y, held, which, modes, prev, system.C.copy(), system.R.copy(), F, G, Qd, steps,
            grid_tau, x0, P0]
    return args, dict(levels=levels, outputs=outputs)


def options(how, g):
    """Keyword options of switch_time_run for a named way of estimating the instant."""
    table = {
        "max": dict(),
        "refine": dict(iterations=30),
        "refine8": dict(iterations=8),
        "marginal": dict(marginal=True),
        "printed": dict(printed=True),
        "printed_refine": dict(printed=True, iterations=30),
        "printed_gate": dict(printed=True, gate=9.0),
        "printed_gate_refine": dict(printed=True, gate=9.0, iterations=30),
        "gate": dict(gate=9.0),
        "gate_refine": dict(gate=4.0, iterations=30),
        "marginal_gate": dict(marginal=True, gate=4.0),
        "tolerance": dict(iterations=40, tolerance=1e-7),
        "loose": dict(iterations=40, tolerance=0.3),
    }
    base = dict(predict_first=False, marginal=False, printed=False)
    base.update(table[how])
    return base


def refines(how):
    return "refine" in how or how in ("tolerance", "loose")


def both(args, kwargs):
    return (eng.switch_time_run(*args, **kwargs), ref.switch_time_run(*args, **kwargs))


HOWS = ["max", "refine", "refine8", "marginal", "printed", "printed_refine", "printed_gate",
        "printed_gate_refine", "gate", "gate_refine", "marginal_gate", "tolerance", "loose"]


def boost_data(N, K, seed=3, t=None):
    system = boost_converter()
    t = np.arange(K) * BOOST_SAMPLE_PERIOD if t is None else t
    traj = simulate(system, lambda r: boost_switching(r, t_end=t[-1]), t,
                    (np.array([0.0, 100.0]), np.diag([25.0, 25.0])),
                    u=np.array([BOOST_INPUT_VOLTAGE]), trials=N, rng=seed)
    u = np.broadcast_to(np.array([BOOST_INPUT_VOLTAGE]), (N, t.size, 1)).copy()
    return system, t, traj.y.copy(), u, traj.mode, np.array([0.0, 100.0]), np.diag([25.0, 25.0])


# ---------------------------------------------------------------- tests
@pytest.mark.parametrize("how", HOWS)
@pytest.mark.parametrize("g", [1, 2, 3, 5])
def test_boost_converter(how, g):
    system, t, y, u, modes, x0, P0 = boost_data(N=37, K=150)
    args, kw = kernel_case(system, t, y, u, modes, x0, P0, g=g, refine=refines(how))
    out, want = both(args, {**kw, **options(how, g)})
    assert want.status == OK and np.isfinite(want.offset).sum() > 100
    same(out, want)


@pytest.mark.parametrize("how", HOWS)
@pytest.mark.parametrize("g", [1, 3, 5])
def test_three_modes_with_missing_samples_and_components(how, g):
    system = three_mode_system()
    t = times(4, 60, [0.25, 0.3])
    y, u, modes = simulated(system, t, 21, seed=11, rate=0.8)
    y = with_holes(y, 5)
    args, kw = kernel_case(system, t, y, u, modes, np.zeros(3), np.eye(3), g=g,
                           refine=refines(how))
    out, want = both(args, {**kw, **options(how, g)})
    assert want.status == OK and np.isfinite(want.offset).sum() > 50
    same(out, want)


SIZES = [(1, 1, 1, 2), (2, 1, 1, 2), (2, 2, 2, 3), (3, 2, 1, 3), (3, 3, 2, 2), (4, 1, 2, 2),
         (4, 3, 1, 4), (2, 1, 0, 2), (3, 2, 0, 3)]


@pytest.mark.parametrize("how", ["max", "refine", "marginal", "printed_gate_refine",
                                 "gate_refine", "marginal_gate"])
@pytest.mark.parametrize("g", [1, 3, 5])
@pytest.mark.parametrize("size", SIZES, ids=str)
def test_random_systems(size, g, how):
    n, m, l, L = size
    seed = 100 * n + 10 * m + l + L
    system = random_system(seed, n, m, max(l, 1), L)
    t = times(seed, 40, [0.2, 0.35, 0.5])
    y, u, modes = simulated(system, t, 19, seed=seed + 2, rate=1.5)
    y = with_holes(y, seed + 3)
    y[:, 11] += 50.0  # an outlier, gated where there is a gate
    rng = np.random.default_rng(seed + 4)
    x0 = rng.standard_normal(n)
    X = rng.standard_normal((n, n))
    P0 = X @ X.T + 0.5 * np.eye(n)
    args, kw = kernel_case(system, t, y, u, modes, x0, P0, g=g, refine=refines(how),
                           no_inputs=l == 0)
    out, want = both(args, {**kw, **options(how, g)})
    assert want.status == OK
    same(out, want)


@pytest.mark.parametrize("how", ["max", "refine", "marginal", "printed"])
def test_inflation(how):
    system = three_mode_system()
    t = times(9, 40, [0.25])
    y, u, modes = simulated(system, t, 9, seed=13)
    args, kw = kernel_case(system, t, with_holes(y, 2), u, modes, np.zeros(3), np.eye(3), g=3,
                           refine=False, inflation=0.05)
    opts = options(how, 3)
    opts.pop("iterations", None)
    out, want = both(args, {**kw, **opts})
    same(out, want)


@pytest.mark.parametrize("lanes", [1, 2, 5, 16, 17, 40])
@pytest.mark.parametrize("how", ["max", "refine", "marginal", "printed_gate"])
def test_lane_blocks_of_several_sizes(lanes, how):
    # the binding called with the numba kernel's arguments, every block size
    system, t, y, u, modes, x0, P0 = boost_data(N=43, K=60, seed=8)
    y = with_holes(y, 4)
    args, kw = kernel_case(system, t, y, u, modes, x0, P0, g=3, refine=refines(how))
    opts = options(how, 3)
    y, u, which, mode, prev, C, R, F, G, Qd, steps, grid_tau, x0, P0 = args
    n_coarse, n_switch = kw["levels"]
    N, K, n = y.shape[0], y.shape[1], x0.shape[1]
    results = []
    for kernel in (c_filter, ref.switch_time_filter):
        x, P = np.empty((N, K, n)), np.empty((N, K, n, n))
        ll, off = np.empty((N, K)), np.empty((N, K))
        flag, report = np.empty((N, K), dtype=np.uint8), np.empty(2)
        status = kernel(y, u, which, mode, prev, C, R, F, G, Qd, steps, grid_tau, n_coarse,
                        n_switch, x0, P0, False, opts["marginal"], opts["printed"],
                        float(opts.get("gate", math.inf)), opts.get("iterations", 0),
                        opts.get("tolerance", ref.REFINE_TOLERANCE), kw["outputs"], lanes,
                        x, P, ll, off, flag, report)
        results.append(eng.SwitchTimeOutput(x, P, ll, off, flag, int(status), int(report[0]),
                                            float(report[1])))
    same(*results)
    # and every block size gives the numbers of the wrapper's (LANES = 16)
    whole = eng.switch_time_run(*args, **kw, **opts)
    for name in ("x", "P", "loglik", "offset"):
        np.testing.assert_array_equal(getattr(results[0], name), getattr(whole, name))


@pytest.mark.parametrize("how", ["max", "refine", "marginal", "printed_gate_refine"])
def test_streaming_steps_and_single_samples(how):
    # predict_first: a step of the streaming API (K = 1) and stretches of a run (K > 1)
    system = three_mode_system()
    t = times(21, 30, [0.25, 0.4])
    y, u, modes = simulated(system, t, 11, seed=22)
    y = with_holes(y, 23)
    args, kw = kernel_case(system, t, y, u, modes, np.zeros(3), np.eye(3), g=3,
                           refine=refines(how))
    opts = {**options(how, 3), "predict_first": True}
    y, u, which, mode, prev, *tables, x0, P0 = args
    run = eng.switch_time_run(*args, **kw, **options(how, 3))
    for k0, k1 in ((1, 2), (5, 6), (1, 30), (7, 19)):
        start_x, start_P = run.x[:, k0 - 1].copy(), run.P[:, k0 - 1].copy()
        part = [y[:, k0:k1].copy(), u[:, k0:k1].copy(), which[k0:k1].copy(),
                mode[:, k0:k1].copy(), prev[:, k0:k1].copy(), *tables, start_x, start_P]
        out, want = both(part, {**kw, **opts})
        same(out, want)
        np.testing.assert_allclose(out.x, run.x[:, k0:k1], rtol=1e-12, atol=1e-14)


def test_a_single_update_and_empty_batches():
    system, t, y, u, modes, x0, P0 = boost_data(N=5, K=20)
    args, kw = kernel_case(system, t, y, u, modes, x0, P0, g=3, refine=True)
    y, u, which, mode, prev, *tables, x0, P0 = args
    common = dict(predict_first=False, marginal=False, printed=False, iterations=30)
    # one sample, update only
    same(*both([y[:, :1].copy(), u[:, :1].copy(), which[:1].copy(), mode[:, :1].copy(),
                prev[:, :1].copy(), *tables, x0, P0], {**kw, **common}))
    # no trials
    empty = [y[:0].copy(), u[:0].copy(), which, mode[:0].copy(), prev[:0].copy(), *tables,
             x0[:0].copy(), P0[:0].copy()]
    out, want = both(empty, {**kw, **common})
    same(out, want)
    assert out.x.shape == (0, 20, 2)
    # no samples
    none = [y[:, :0].copy(), u[:, :0].copy(), which[:0].copy(), mode[:, :0].copy(),
            prev[:, :0].copy(), *tables, x0, P0]
    same(*both(none, {**kw, **common}))
    # no steps (D = 0): the first sample only, nothing predicted
    F, G, Qd = (np.zeros((0,) + a.shape[1:]) for a in tables[2:5])
    grid = np.zeros((0, 3))
    no_steps = [y[:, :1].copy(), u[:, :1].copy(), which[:1].copy(), mode[:, :1].copy(),
                prev[:, :1].copy(), tables[0], tables[1], F, G, Qd, np.zeros(0), grid, x0, P0]
    same(*both(no_steps, dict(predict_first=False, marginal=False, printed=False)))


@pytest.mark.parametrize("how", ["max", "refine", "marginal", "printed", "printed_refine"])
def test_gated_outliers_and_overflowing_measurements(how):
    system, t, y, u, modes, x0, P0 = boost_data(N=20, K=80, seed=5)
    switched = np.flatnonzero((modes[:, 1:] != modes[:, :-1]).any(axis=0)) + 1
    y[:, switched[2]] += 1e3  # beyond every hypothesis' gate
    y[:3, switched[3]] = np.nan  # missing where a switch happened: the middle grid instant
    y[:, 7] = 1e300  # overflows the innovation whatever the gate
    args, kw = kernel_case(system, t, y, u, modes, x0, P0, g=3, refine=refines(how))
    for gate in (25.0, math.inf):
        out, want = both(args, {**kw, **options(how, 3), "gate": gate})
        assert want.status == OK
        same(out, want)


def test_failures_stop_the_kernel_with_numbas_status():
    system, t, y, u, modes, x0, P0 = boost_data(N=20, K=40, seed=6)
    args, kw = kernel_case(system, t, y, u, modes, x0, P0, g=3, refine=True)
    common = dict(predict_first=False, marginal=False, printed=False)
    # a covariance of infinities: not finite at the first update
    bad = list(args)
    bad[13] = np.full_like(args[13], np.inf)
    out, want = both(bad, {**kw, **common})
    assert want.status == NOT_FINITE
    same(out, want, complete=False)
    # no measurement noise and the printed likelihood N(y; C x-, R): R = 0 fails at a switch
    # (the grid's hypotheses), after samples without a switch were updated
    bad = list(args)
    bad[6] = np.zeros_like(args[6])
    for how in ("printed", "printed_refine"):
        out, want = both(bad, {**kw, **options(how, 3)})
        assert want.status == NOT_POSITIVE_DEFINITE
        same(out, want, complete=False)
    # and in the marginal merge: every hypothesis from a zero prior with R = 0, Qd = 0
    bad = list(args)
    bad[6] = np.zeros_like(args[6])
    bad[9] = np.zeros_like(args[9])
    bad[13] = np.zeros_like(args[13])
    for how in ("marginal", "max", "refine"):
        out, want = both(bad, {**kw, **options(how, 3)})
        assert want.status != OK
        same(out, want, complete=False)


@pytest.mark.parametrize("how", ["max", "refine", "marginal", "printed_gate_refine",
                                 "gate_refine"])
@pytest.mark.parametrize("g", [1, 3])
def test_indefinite_priors_are_repaired_as_numba_repairs_them(how, g):
    # priors c I - s v v' (indefinite for most trials), every trial switching into its first,
    # predicted sample and then at random: the grid's hypotheses, the refinement's probes (a
    # lane that passes the grid may fail a probe nearer the cell's edges: with g = 1, 400 such
    # trials over one sample took 464 repairs refined, 461 on the grid alone) and the updates
    # repair them (se_repair: a Jacobi eigendecomposition, LAPACK's in numba: the same to
    # rounding, so here the agreement is to rounding, not to the bit)
    system = random_system(31, 2, 1, 1, 2)
    t = times(31, 12, [0.5, 0.3])
    N = 200
    y, u, modes = simulated(system, t, N, seed=32, rate=1.5)
    modes[:, 0] = 1 - modes[:, 1]
    args, kw = kernel_case(system, t, y, u, modes, np.zeros(2), np.eye(2), g=g,
                           refine=refines(how))
    rng = np.random.default_rng(1)
    v = rng.standard_normal((N, 2))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    P0 = (rng.uniform(0.1, 3.0, N)[:, None, None] * np.eye(2)
          - rng.uniform(0.5, 6.0, N)[:, None, None] * v[:, :, None] * v[:, None, :])
    y, u, which, mode, prev, *tables, x0, _ = args
    part = [y[:, 1:].copy(), u[:, 1:].copy(), which[1:].copy(), mode[:, 1:].copy(),
            prev[:, 1:].copy(), *tables, x0[:, :], P0]
    opts = {**options(how, g), "predict_first": True}
    out, want = both(part, {**kw, **opts})
    assert want.status == OK and want.repaired > N
    same(out, want)
    first = [a[:, :1].copy() for a in part[:2]] + [part[2][:1].copy()] + [
        a[:, :1].copy() for a in part[3:5]] + part[5:]
    same(*both(first, {**kw, **opts}))  # the first sample alone


def test_a_likelihood_rising_to_the_cells_edge_takes_the_edge_step():
    # the case of test_switch_time_compiled.py: J_k rising to the cell's edges, every number
    # of probes around the edge step
    system = SwitchedLinearSystem.continuous([[[0.0]], [[0.0]]], [[[0.0]], [[1.0]]], [[1.0]],
                                             Q=[[1e-4]], R=[[1e-4]])
    T = 1.0
    N = 4
    t = np.array([0.0, T])
    x = np.array([[2.0], [2.0], [2.0], [2.0]])
    y = np.stack([np.full((N, 1), np.nan), x + np.array([[T], [0.0], [0.3], [0.9]])], axis=1)
    u = np.ones((N, 2, 1))
    modes = np.array([[0, 1]] * N)
    args, kw = kernel_case(system, t, y, u, modes, np.zeros(1), np.eye(1), g=1, refine=True)
    args[12] = x.copy()
    args[13] = np.full((N, 1, 1), 1e-4)
    for probes in range(0, 12):
        opts = dict(predict_first=False, marginal=False, printed=False, iterations=probes)
        same(*both(args, {**kw, **opts}))


def test_outputs_computed_when_not_given_and_the_public_names():
    system, t, y, u, modes, x0, P0 = boost_data(N=7, K=30)
    args, kw = kernel_case(system, t, y, u, modes, x0, P0, g=2, refine=True)
    common = dict(predict_first=False, marginal=False, printed=False, iterations=30)
    given = eng.switch_time_run(*args, **kw, **common)
    computed = eng.switch_time_run(*args, levels=kw["levels"], **common)
    same(computed, given)
    same(computed, ref.switch_time_run(*args, levels=kw["levels"], **common))
    for got, want in zip(eng.coarse_outputs(system.C, *args[7:10], 1, 2, kw["levels"][0]),
                         ref.coarse_outputs(system.C, *args[7:10], 1, 2, kw["levels"][0])):
        np.testing.assert_array_equal(got, want)
    assert eng.REFINE_TOLERANCE == ref.REFINE_TOLERANCE and eng.LANES == 16
    assert eng.SwitchTimeOutput._fields == ref.SwitchTimeOutput._fields
    for name in ("OK", "NOT_FINITE", "NOT_POSITIVE_DEFINITE", "ACCEPTED", "GATED"):
        assert getattr(eng, name) == getattr(ref, name)


def test_the_wrapper_refuses_what_numbas_refuses():
    system = boost_converter()
    y, u = np.zeros((2, 3, 1)), np.zeros((2, 3, 1))
    modes = np.zeros((2, 3), dtype=int)
    F, G, Qd = np.zeros((6, 2, 2)), np.zeros((6, 2, 1)), np.zeros((6, 2, 2))
    args = (y, u, [0, 0, 0], modes, modes, system.C, system.R, F, G, Qd, [BOOST_SAMPLE_PERIOD],
            [[0.5]], np.zeros((2, 2)), np.ones((2, 2, 2)))
    common = dict(predict_first=False, marginal=False, printed=False)
    same(eng.switch_time_run(*args, **common), ref.switch_time_run(*args, **common))
    for bad in (dict(levels=(1, 2)), dict(iterations=3), dict(tolerance=-1.0)):
        with pytest.raises(ValueError) as e_eng:
            eng.switch_time_run(*args, **common, **bad)
        with pytest.raises(ValueError) as e_ref:
            ref.switch_time_run(*args, **common, **bad)
        assert str(e_eng.value) == str(e_ref.value)
