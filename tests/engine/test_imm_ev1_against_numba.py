"""The C engine's IMM-EV1 (switchest.engine.imm_ev1) against the numba kernel it replaces
(switchest.estimators._compiled.imm_ev1), on many cases.

Both run the same equations in the same order, so every float output must agree to
ATOL = 1e-12 relative to the largest entry of the numba array (NaN where numba's is NaN, the
same infinities); integer and flag outputs (mode, outlier, predecessor, status, repaired)
exactly. Cases: 1..3 modes, n = 1..4 states, m = 1..3 outputs, l = 0..2 inputs, g = 1..4 grid
points, one or two interval lengths; every combination of printed / marginal / by_path; no
gate and a tight gate; missing components and whole samples (NaN); outliers every hypothesis
rejects; impossible transitions (log pi = -inf); lane blocks of 1, 3, 5, 16 trials with trial
counts that are not a multiple of the block; step against run and step with and without
prediction; repaired covariances; the failure statuses; zero trials and zero samples.

The file is deleted with the numba code (the engine's own tests take over); the largest
relative difference seen is printed with ``-s``.
"""

import math

import numpy as np
import pytest

from switchest.engine import imm_ev1 as eng
from switchest.estimators._compiled import imm_ev1 as ref

ATOL = 1e-12
WORST: dict[str, float] = {}
FLOATS = ("x", "P", "mode_prob", "switch_offset")
EXACT = ("mode", "outlier", "status", "repaired")


def close(name, actual, expected):
    """``|actual - expected| <= ATOL max|expected|`` over the finite entries; NaN and the
    infinities where ``expected`` has them. Records the largest relative difference."""
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    assert actual.shape == expected.shape, name
    finite = np.isfinite(expected)
    np.testing.assert_array_equal(np.isnan(actual), np.isnan(expected), err_msg=name)
    np.testing.assert_array_equal(actual[~finite & ~np.isnan(expected)],
                                  expected[~finite & ~np.isnan(expected)], err_msg=name)
    if not finite.any():
        return
    scale = np.abs(expected[finite]).max()
    diff = np.abs(actual[finite] - expected[finite]).max()
    rel = diff / scale if scale > 0 else diff
    WORST[name] = max(WORST.get(name, 0.0), float(rel))
    assert diff <= ATOL * scale, f"{name}: {rel:.3g} relative to its largest entry"


def same_output(out, expected, prefix=""):
    for name in FLOATS:
        close(prefix + name, getattr(out, name), getattr(expected, name))
    for name in EXACT:
        np.testing.assert_array_equal(getattr(out, name), getattr(expected, name), err_msg=name)
    assert out.outlier.dtype == np.bool_ and out.mode.dtype == np.int64
    if expected.repaired:
        close(prefix + "smallest_eigenvalue", out.smallest_eigenvalue,
              expected.smallest_eigenvalue)
    else:
        assert out.smallest_eigenvalue == expected.smallest_eigenvalue == math.inf


def same_state(state, expected, prefix=""):
    for name, a, e in zip(("x_last", "P_last", "log_w_last", "chosen_last", "offset_last"),
                          state, expected, strict=True):
        assert a.shape == e.shape and a.dtype == e.dtype, name
        if a.dtype == np.int64:
            np.testing.assert_array_equal(a, e, err_msg=name)
        else:
            close(prefix + name, a, e)


def spd(rng, shape, n, floor=0.1):
    V = rng.standard_normal((*shape, n, n))
    return V @ np.swapaxes(V, -1, -2) / n + floor * np.eye(n)


def problem(seed, n, m, l, L, g, D=1, N=7, K=25, missing=True, outliers=True):
    """Random hypothesis tables (M = D L L g entries), a batch simulated along random mode
    paths through them, NaN holes and outliers: the arguments of ``imm_ev1_run``."""
    rng = np.random.default_rng(seed)
    M = D * L * L * g
    V = rng.standard_normal((M, n, n))
    radius = np.abs(np.linalg.eigvals(V)).max(axis=-1)
    F = 0.95 * V / np.maximum(radius, 1.0)[:, None, None]
    G = rng.standard_normal((M, n, l))
    S = rng.standard_normal((M, n, max(n - 1, 1)))
    Qd = 0.2 * S @ np.swapaxes(S, -1, -2)  # rank n - 1: a singular process noise
    C = rng.standard_normal((L, m, n))
    R = spd(rng, (L,), m)
    tau = np.sort(rng.random((D, g)), axis=1) * rng.uniform(0.5, 2.0, (D, 1))
    table = rng.integers(0, D, K)
    u = rng.standard_normal((N, K, l))
    x = rng.standard_normal((N, n))
    mode = rng.integers(0, L, N)
    y = np.empty((N, K, m))
    for k in range(K):
        if k:
            new = np.where(rng.random(N) < 0.3, rng.integers(0, L, N), mode)
            kk = np.where(new == mode, 0, rng.integers(0, g, N))
            e = ((table[k] * L + mode) * L + new) * g + kk
            x = np.einsum("nij,nj->ni", F[e], x) + np.einsum("nij,nj->ni", G[e], u[:, k - 1])
            x += 0.3 * rng.standard_normal((N, n))
            mode = new
        y[:, k] = np.einsum("nij,nj->ni", C[mode], x) + 0.5 * rng.standard_normal((N, m))
    if missing:
        y[rng.random((N, K, m)) < 0.15] = np.nan  # single components
        y[rng.random((N, K)) < 0.08] = np.nan  # whole samples
    if outliers:
        y[rng.random((N, K)) < 0.05, 0] = 1e6  # rejected by a tight gate
        y[0, K // 2, 0] = 1e300  # rejected by every hypothesis
    transition = rng.dirichlet(np.ones(L), size=L) + 2.0 * np.eye(L)
    if L == 3:
        transition[0, 2] = 0.0  # an impossible switch
    transition /= transition.sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore"):
        log_transition = np.log(transition)
    return dict(y=y, u=u, F=F, G=G, Qd=Qd, table=table, tau=tau, C=C, R=R,
                log_transition=log_transition, x0=rng.standard_normal(n),
                P0=spd(rng, (), n, floor=0.5), log_weight0=np.log(rng.dirichlet(np.ones(L))))


ARGS = ("y", "u", "F", "G", "Qd", "table", "tau", "C", "R", "log_transition", "x0", "P0",
        "log_weight0")


def run_both(p, **kw):
    args = [p[a] for a in ARGS]
    expected = ref.imm_ev1_run(*[np.copy(a) for a in args], **kw)
    out = eng.imm_ev1_run(*args, **kw)
    for a, b in zip(args, [p[a] for a in ARGS], strict=True):  # inputs untouched
        assert a is b
    return out, expected


# (n states, m outputs, l inputs, L modes, g grid points, D interval lengths)
SIZES = [(1, 1, 0, 1, 1, 1), (2, 1, 1, 2, 4, 1), (3, 2, 1, 3, 3, 2), (4, 3, 2, 2, 2, 2),
         (2, 2, 0, 3, 1, 1), (4, 1, 1, 3, 2, 1), (1, 2, 2, 2, 3, 2)]
OPTIONS = [dict(printed=p, marginal=mg, by_path=bp)
           for p in (False, True) for mg in (False, True) for bp in (True, False)]


@pytest.mark.parametrize("options", OPTIONS,
                         ids=lambda o: "-".join(k for k, v in o.items() if v) or "default")
@pytest.mark.parametrize("size", SIZES, ids=lambda s: "n{}m{}l{}L{}g{}D{}".format(*s))
def test_run_equals_numba(size, options):
    p = problem(sum(size) * 7 + 1, *size)
    for gate in (math.inf, 9.0):
        out, expected = run_both(p, epsilon=1e-6, gate=gate, **options)
        assert expected.status == 0
        same_output(out, expected)
    if size[3] > 1:
        assert expected.outlier.any() and np.isfinite(expected.switch_offset).any()


@pytest.mark.parametrize("lanes", [1, 3, 5, 16, 64])
@pytest.mark.parametrize("marginal", [False, True])
def test_blocks_of_lanes_and_trial_counts_equal_numba(lanes, marginal):
    p = problem(11, 3, 2, 1, 3, 3, D=2, N=17, K=15)
    out, expected = run_both(p, epsilon=1e-4, gate=12.0, marginal=marginal, lanes=lanes)
    same_output(out, expected)
    base, _ = run_both(p, epsilon=1e-4, gate=12.0, marginal=marginal, lanes=16)
    for name in FLOATS:  # the block does not change the numbers
        np.testing.assert_array_equal(np.isnan(getattr(out, name)),
                                      np.isnan(getattr(base, name)))
        np.testing.assert_allclose(getattr(out, name), getattr(base, name), rtol=0, atol=1e-12
                                   * np.nanmax(np.abs(getattr(base, name))))


@pytest.mark.parametrize("N, K", [(0, 10), (5, 0), (0, 0), (1, 1)])
def test_zero_sizes_equal_numba(N, K):
    p = problem(3, 2, 1, 1, 2, 2, N=max(N, 1), K=max(K, 2), outliers=False)
    p["y"], p["u"], p["table"] = p["y"][:N, :K], p["u"][:N, :K], p["table"][:K]
    p["y"], p["u"] = np.ascontiguousarray(p["y"]), np.ascontiguousarray(p["u"])
    out, expected = run_both(p, epsilon=0.0, marginal=True)
    assert out.x.shape == (N, K, 2) and out.mode_prob.shape == (N, K, 2)
    same_output(out, expected)


def step_args(p, state, k):
    g = p["tau"].shape[1]
    L = p["C"].shape[0]
    M = L * L * g
    d = p["table"][k]
    sl = slice(d * M, (d + 1) * M)
    return (*state, p["y"][:, k], p["u"][:, max(k - 1, 0)], p["F"][sl], p["G"][sl],
            p["Qd"][sl], p["tau"][d], p["C"], p["R"], p["log_transition"])


@pytest.mark.parametrize("options", OPTIONS[::3], ids=lambda o: "-".join(
    k for k, v in o.items() if v) or "default")
def test_step_equals_numba_and_streams_what_run_reports(options):
    p = problem(21, 3, 2, 1, 3, 3, D=2, N=19, K=12)
    kw = dict(epsilon=1e-5, gate=15.0, **options)
    N, L, _n = p["y"].shape[0], p["C"].shape[0], p["x0"].size
    state = (np.tile(p["x0"], (N, L, 1)), np.tile(p["P0"], (N, L, 1, 1)),
             np.tile(p["log_weight0"], (N, 1)), np.tile(np.arange(L), (N, 1)),
             np.full((N, L), np.nan))
    run, _ = run_both(p, **kw)
    ref_state = tuple(a.copy() for a in state)
    for k in range(p["y"].shape[1]):
        before = [a.copy() for a in state]
        out, state = eng.imm_ev1_step(*step_args(p, state, k), predict_first=k > 0, **kw)
        expected, ref_state = ref.imm_ev1_step(*step_args(p, ref_state, k), predict_first=k > 0,
                                               **kw)
        for a, b in zip(before, step_args(p, before, k)[:5], strict=True):
            np.testing.assert_array_equal(a, b)
        same_output(out, expected)
        same_state(state, ref_state)
        for name in FLOATS + ("mode", "outlier"):
            close(f"step-{name}", getattr(out, name)[:, 0], getattr(run, name)[:, k])


def test_a_step_with_prediction_first_equals_numba():
    p = problem(5, 2, 1, 1, 2, 4, N=6, K=3)
    N, L = 6, 2
    rng = np.random.default_rng(0)
    state = (rng.standard_normal((N, L, 2)), spd(rng, (N, L), 2),
             np.log(rng.dirichlet(np.ones(L), size=N)), rng.integers(0, L, (N, L)),
             rng.random((N, L)))
    for options in OPTIONS:
        out, last = eng.imm_ev1_step(*step_args(p, state, 1), predict_first=True, epsilon=1e-3,
                                     **options)
        expected, ref_last = ref.imm_ev1_step(*step_args(p, state, 1), predict_first=True,
                                              epsilon=1e-3, **options)
        same_output(out, expected)
        same_state(last, ref_last)


def repair_case():
    """Two modes with diagonal dynamics, a state covariance beyond 1/eps and indefinite: the
    likelihood pass cannot factor, so the hypotheses are predicted in full and repaired."""
    from switchest import SwitchedLinearSystem
    from switchest.discretize import pairwise_grid, switch_grid

    A = np.array([np.diag([-0.4, -0.3]), np.diag([-0.2, -0.6])])
    Bm = np.array([[[1.0], [0.0]], [[0.0], [1.0]]])
    system = SwitchedLinearSystem.continuous(A, Bm, [[1.0, 0.0]], Q=0.01 * np.eye(2),
                                             R=[[0.1]])
    grid = pairwise_grid(system, 0.1, 2)
    F, G, Qd = (getattr(grid, a).reshape(8, *getattr(grid, a).shape[-2:])
                for a in ("F", "G", "Qd"))
    return system, F, G, Qd, switch_grid(0.1, 2)


@pytest.mark.parametrize("printed", [False, True])
def test_a_repair_equals_numba(printed):
    system, F, G, Qd, tau = repair_case()
    N = 5
    state = (np.zeros((N, 2, 2)), np.broadcast_to(np.diag([-1e3, 1e20]), (N, 2, 2, 2)).copy(),
             np.log(np.full((N, 2), 0.5)), np.tile(np.arange(2), (N, 1)), np.full((N, 2), np.nan))
    state[1][1:3] = np.eye(2)  # some trials well conditioned
    y, u = np.linspace(-0.5, 0.5, N)[:, None], np.ones((N, 1))
    args = (*state, y, u, F, G, Qd, tau, system.C, system.R, np.zeros((2, 2)))
    for marginal in (False, True):
        kw = dict(predict_first=True, epsilon=0.0, printed=printed, marginal=marginal)
        out, last = eng.imm_ev1_step(*args, **kw)
        expected, ref_last = ref.imm_ev1_step(*args, **kw)
        assert expected.repaired > 0
        same_output(out, expected)
        same_state(last, ref_last)


def test_a_repair_in_the_update_without_prediction_equals_numba():
    system, F, G, Qd, tau = repair_case()
    N = 4
    P = np.broadcast_to(np.array([[1.0, 0.0], [0.0, -1e-30]]) * 1e20, (N, 2, 2, 2)).copy()
    state = (np.zeros((N, 2, 2)), P, np.log(np.full((N, 2), 0.5)), np.tile(np.arange(2), (N, 1)),
             np.full((N, 2), np.nan))
    args = (*state, np.full((N, 1), 0.3), np.ones((N, 1)), F, G, Qd, tau, system.C, system.R,
            np.zeros((2, 2)))
    out, last = eng.imm_ev1_step(*args, predict_first=False, epsilon=0.0)
    expected, ref_last = ref.imm_ev1_step(*args, predict_first=False, epsilon=0.0)
    assert expected.repaired > 0
    same_output(out, expected)
    same_state(last, ref_last)


@pytest.mark.parametrize("marginal", [False, True])
def test_a_diffuse_prior_takes_the_information_form_as_in_numba(marginal):
    """A prior of 1e30 on states all observed (m = n): Joseph's form loses its digits in the
    first update (without prediction), lane by lane, and the information form takes over."""
    p = problem(4, 2, 2, 1, 2, 2, N=5, K=6, outliers=False)
    p["P0"] = 1e30 * np.eye(2)
    out, expected = run_both(p, epsilon=0.0, marginal=marginal)
    assert expected.status == 0 and expected.repaired == 0
    same_output(out, expected)


@pytest.mark.parametrize("marginal", [False, True])
def test_repairs_of_a_diffuse_prior_equal_numba_step_by_step(marginal):
    """A prior of 1e30 on three states seen through one output: the posteriors' condition
    numbers pass 1/eps and are repaired at several samples. Each step starts from numba's
    state: a repair's eigendecomposition (cyclic Jacobi in linalg.c, LAPACK in numba) agrees
    only to its rounding level, which this ill-conditioned filter would amplify over the
    following samples."""
    p = problem(4, 3, 1, 1, 2, 2, N=5, K=6, outliers=False)
    p["P0"] = 1e30 * np.eye(3)
    N, L = 5, 2
    state = (np.tile(p["x0"], (N, L, 1)), np.tile(p["P0"], (N, L, 1, 1)),
             np.tile(p["log_weight0"], (N, 1)), np.tile(np.arange(L), (N, 1)),
             np.full((N, L), np.nan))
    repaired = 0
    for k in range(p["y"].shape[1]):
        kw = dict(predict_first=k > 0, epsilon=0.0, marginal=marginal)
        out, last = eng.imm_ev1_step(*step_args(p, state, k), **kw)
        expected, state = ref.imm_ev1_step(*step_args(p, state, k), **kw)
        same_output(out, expected, "jacobi-repair-")
        same_state(last, state, "jacobi-repair-")
        repaired += expected.repaired
    assert repaired > 0


@pytest.mark.parametrize("predict_first", [False, True])
def test_failures_equal_numba(predict_first):
    system, F, G, Qd, tau = repair_case()
    N = 3
    for P in (np.full((N, 2, 2, 2), np.inf), np.zeros((N, 2, 2, 2))):
        state = (np.zeros((N, 2, 2)), P, np.log(np.full((N, 2), 0.5)),
                 np.tile(np.arange(2), (N, 1)), np.full((N, 2), np.nan))
        args = (*state, np.zeros((N, 1)), np.ones((N, 1)), F, G, 0.0 * Qd, tau, system.C,
                np.zeros((2, 1, 1)), np.zeros((2, 2)))  # Qd = R = 0: S = C P C' singular
        with np.errstate(all="ignore"):
            out, _ = eng.imm_ev1_step(*args, predict_first=predict_first, epsilon=0.0)
            expected, _ = ref.imm_ev1_step(*args, predict_first=predict_first, epsilon=0.0)
        assert expected.status != 0
        assert out.status == expected.status
        assert out.repaired == expected.repaired


def test_the_estimator_on_the_boost_converter_equals_numba():
    """The boost converter at irregular sample times (the estimator's setup), both options."""
    from switchest import signals as sg
    from switchest.estimators.imm_ev1 import IMMEV1Filter
    from switchest.models import BOOST_INPUT_VOLTAGE, BOOST_SAMPLE_PERIOD, boost_converter
    from switchest.simulate import simulate

    system = boost_converter()
    T = BOOST_SAMPLE_PERIOD
    rng = np.random.default_rng(5)
    t = np.cumsum(T * rng.choice([0.5, 1.0, 1.5], size=60))
    traj = simulate(system, lambda r: sg.dwell_time(2, t[-1], 2 * T, 4 * T, rng=r), t,
                    (np.array([0.0, 100.0]), np.diag([25.0, 25.0])), u=[BOOST_INPUT_VOLTAGE],
                    trials=21, rng=2)
    for g in (1, 4):
        for switch_time in ("max", "marginal"):
            f = IMMEV1Filter(system, x0=np.array([0.0, 100.0]), P0=np.diag([25.0, 25.0]),
                             grid=g, switch_time=switch_time, mode_prob0=[0.7, 0.3])
            steps, which = np.unique(np.diff(t), return_inverse=True)
            F, G, Qd, tau = f._transitions(steps)
            table = np.concatenate([[0], which])
            u = np.full((21, t.size, 1), BOOST_INPUT_VOLTAGE)
            args = (traj.y, u, F, G, Qd, table, tau, system.C, system.R, f._log_transition,
                    f.x0, f.P0, f._log_p0)
            out = eng.imm_ev1_run(*args, **f._options())
            expected = ref.imm_ev1_run(*args, **f._options())
            same_output(out, expected)


def test_the_arguments_are_checked_as_by_numba():
    p = problem(1, 2, 1, 1, 2, 2)
    args = [p[a] for a in ARGS]
    bad = list(args)
    bad[6] = p["tau"][:, :1]
    for module in (eng, ref):
        with pytest.raises(ValueError, match="F, G, Qd must hold D L L g"):
            module.imm_ev1_run(*bad, epsilon=0.0)
        with pytest.raises(ValueError, match="epsilon must be a finite non-negative number"):
            module.imm_ev1_run(*args, epsilon=-1.0)
        with pytest.raises(ValueError, match="gate must be a positive number or inf"):
            module.imm_ev1_run(*args, epsilon=0.0, gate=math.nan)
        with pytest.raises(ValueError, match="lanes"):
            module.imm_ev1_run(*args, epsilon=0.0, lanes=0)


def test_the_public_names_are_those_of_numba():
    assert set(eng.__all__) == set(ref.__all__)
    assert eng.IMMEV1Output._fields == ref.IMMEV1Output._fields
    assert eng.LANES == 16
    import inspect
    for name in ("imm_ev1_run", "imm_ev1_step"):
        assert (inspect.signature(getattr(eng, name))
                == inspect.signature(getattr(ref, name)))


def test_zz_report_the_largest_difference():
    print("\nimm_ev1 engine vs numba, largest difference relative to the array's largest entry:")
    for name, value in sorted(WORST.items()):
        print(f"  {name}: {value:.3g}")
