"""The C engine's Kalman filters (switchest.engine.kalman) against the numba kernels they
replace (switchest.estimators._compiled.kalman), on many cases.

Every float output must equal numba's to ``1e-12`` of the largest entry of numba's array;
integer and flag outputs, ``status`` and ``repaired`` exactly. The two run the same operations
in the same order (the same grouping of trials, the same fixed-point skips), so the agreement
seen is exact to the bit. The largest relative difference per output is printed at the end
of the module (run with ``-s``). This file goes with the numba code.
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "estimators"))
from test_compiled_kernels import CASES, alone, kalman_args, problem, spd  # noqa: E402

from switchest.discretize import mode_steps  # noqa: E402
from switchest.engine import NOT_FINITE, NOT_POSITIVE_DEFINITE, OK  # noqa: E402
from switchest.engine import kalman as eng  # noqa: E402
from switchest.estimators._compiled import kalman as ref  # noqa: E402
from switchest.models import vehicle_2d  # noqa: E402
from switchest.signals import schedule  # noqa: E402
from switchest.simulate import simulate  # noqa: E402

TOL = 1e-12
WORST: dict[str, float] = {}


@pytest.fixture(autouse=True, scope="module")
def print_worst():
    yield
    print("\nlargest relative difference, engine vs numba:")
    for name, value in sorted(WORST.items()):
        print(f"  {name:12s} {value:.3g}")


def close(name, actual, expected):
    """``|actual - expected| <= 1e-12 max|expected|`` entrywise (NaN where NaN), recorded."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape and actual.dtype == expected.dtype
    np.testing.assert_array_equal(np.isnan(actual), np.isnan(expected))
    finite = np.isfinite(expected)
    np.testing.assert_array_equal(actual[~finite & ~np.isnan(expected)],
                                  expected[~finite & ~np.isnan(expected)])
    if not finite.any():
        return
    scale = np.abs(expected[finite]).max()
    diff = np.abs(actual[finite] - expected[finite]).max()
    rel = diff / scale if scale > 0 else diff
    WORST[name] = max(WORST.get(name, 0.0), rel)
    np.testing.assert_allclose(actual[finite], expected[finite], rtol=0.0, atol=TOL * scale)


def same(out, want, *, complete=True):
    """Every output of two KalmanOutput tuples (the arrays only if the run completed)."""
    assert out.status == want.status
    assert out.repaired == want.repaired
    if math.isinf(want.smallest_eigenvalue):
        assert out.smallest_eigenvalue == want.smallest_eigenvalue
    else:
        close("smallest_eig", out.smallest_eigenvalue, want.smallest_eigenvalue)
    if not complete:
        return
    for name in ("x", "P", "loglik"):
        close(name, getattr(out, name), getattr(want, name))
    np.testing.assert_array_equal(out.flag, want.flag)
    assert out.flag.dtype == want.flag.dtype


def both_run(p, **kw):
    return eng.kalman_run(*kalman_args(p), **kw), ref.kalman_run(*kalman_args(p), **kw)


def odd_problem(seed, n, m, l, L, M, N, K, missing=True):
    """problem() with per-trial x0 kept, and a share of trials tied to trial 0's transitions and
    output matrices (so a block mixes shared groups and lone trials)."""
    p = problem(seed, n, m, l, L, M, N=N, K=K, missing=missing)
    rng = np.random.default_rng(seed + 7)
    tied = rng.random(N) < 0.6
    p["trans"][tied] = p["trans"][0]
    p["mode"][tied] = p["mode"][0]
    return p


# ---------------------------------------------------------------- kalman_run
@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("N, lanes", [(1, 256), (4, 3), (7, 16), (13, 5), (37, 8), (40, 256)])
@pytest.mark.parametrize("gate", [np.inf, 2.0])
def test_random_tables(case, N, lanes, gate):
    p = problem(10 + sum(case) + N, *case, N=N, K=23)
    same(*both_run(p, gate=gate, lanes=lanes))


@pytest.mark.parametrize("n, m, l", [(1, 1, 0), (1, 2, 1), (2, 1, 2), (3, 3, 1), (4, 1, 0),
                                     (4, 3, 2), (2, 4, 0)])
@pytest.mark.parametrize("lanes", [1, 4, 11, 256])
def test_shared_and_lone_trials(n, m, l, lanes):
    p = odd_problem(100 + 7 * n + m + l, n, m, l, 2, 3, N=29, K=37)
    same(*both_run(p, gate=5.0, lanes=lanes))


@pytest.mark.parametrize("lanes", [1, 3, 9, 256])
def test_groups_part_ways(lanes):
    # one group at the start; missing components, a gate and an outlier split it; per-trial
    # copies of the tables (equal by value) keep it together
    p = problem(31, 3, 2, 1, 2, 3, N=9, missing=False)
    N, K, _ = p["y"].shape
    p["trans"][:], p["mode"][:] = p["trans"][0], p["mode"][0]
    p["y"][2, 5:, 0] = np.nan
    p["y"][4, 10] = np.nan
    p["y"][6, 12, 1] = 1e300
    p["y"][7, np.random.default_rng(31).random(K) < 0.3, 1] = np.nan
    same(*both_run(p, gate=6.0, lanes=lanes))
    M, L = p["F"].shape[0], p["C"].shape[0]
    copies = dict(p, F=np.tile(p["F"], (N, 1, 1)), G=np.tile(p["G"], (N, 1, 1)),
                  Qd=np.tile(p["Qd"], (N, 1, 1)), trans=p["trans"] + M * np.arange(N)[:, None],
                  C=np.tile(p["C"], (N, 1, 1)), R=np.tile(p["R"], (N, 1, 1)),
                  mode=p["mode"] + L * np.arange(N)[:, None])
    same(*both_run(copies, gate=6.0, lanes=lanes))
    # distinct initial covariances: groups by P_init (kalman_step's path)
    x0 = np.random.default_rng(1).standard_normal((N, 3))
    P0 = np.repeat(p["P0"][None], N, axis=0)
    P0[3] *= 2.0
    P0[5:7] *= 3.0
    for predict_first in (False, True):
        for k in (0, 1):
            t, md = p["trans"][:, k], p["mode"][:, k]
            args = (x0, P0, p["y"][:, k], p["u"][:, 0], p["F"][t], p["G"][t], p["Qd"][t],
                    p["C"][md], p["R"][md])
            same(eng.kalman_step(*args, predict_first=predict_first, gate=6.0),
                 ref.kalman_step(*args, predict_first=predict_first, gate=6.0))


@pytest.mark.parametrize("lanes", [2, 5, 256])
def test_fixed_point_skips(lanes):
    # the vehicle in one mode: the covariances settle to a fixed point to the last bit (after
    # about 120 samples) and the covariance equations are skipped; events after it break the
    # skip (test_mode_kalman_compiled's case, with more events)
    system = vehicle_2d(measurement_variance=0.05, process_noise=1e-3)
    T, K, N = 0.5, 480, 5
    t = T * np.arange(K)
    traj = simulate(system, schedule([], [1]), t, (np.zeros(4), np.eye(4)), u=np.ones(1),
                    trials=N, rng=np.random.default_rng(11))
    y = traj.y.copy()
    y[0, 160, 0] = np.nan  # one trial parts from the others' covariance
    y[:, 320] += 1e3  # every trial gates it
    y[2:4, 250:260] = np.nan  # two trials miss a stretch
    modes = np.broadcast_to(np.where(np.arange(K) < 400, 1, 0), (N, K)).copy()
    modes[4, 440:] = 2  # and then another mode for one trial
    steps = mode_steps(system, T)
    trans = np.concatenate([modes[:, :1], modes[:, :-1]], axis=1)
    p = dict(y=y, u=np.ones((N, K, 1)), F=steps.F, G=steps.G, Qd=steps.Qd, trans=trans,
             C=system.C, R=system.R, mode=modes, x0=np.zeros(4), P0=np.eye(4))
    out, want = both_run(p, gate=25.0, lanes=lanes)
    same(out, want)
    np.testing.assert_array_equal(out.P[:, 159], out.P[:, 158])  # settled


def test_repairs_of_an_indefinite_prior():
    # P0 indefinite: S = C P0 C' + R fails its factorization, P0 is repaired (eigenvalues
    # raised to n eps max|eig|) and the filter goes on, well conditioned: the same numbers to
    # rounding (linalg.c's Jacobi eigensolver against numba's LAPACK eigh), the same report
    p = problem(44, 2, 1, 1, 1, 1, N=7, missing=False)
    p["P0"] = np.diag([-1.0, 1.0])
    p["C"] = np.array([[[1.0, 0.0]]])
    p["R"] = np.array([[[0.5]]])
    for lanes in (1, 3, 256):
        out, want = both_run(p, lanes=lanes)
        assert want.repaired == 7 and want.status == OK
        same(out, want)
    q = dict(p, y=p["y"].copy())
    q["y"][2:4, 0] = np.nan  # those trials are not repaired at sample 0 (nothing observed)
    q["y"][5, :3] = np.nan
    for lanes in (1, 4):
        same(*both_run(q, lanes=lanes))


def test_repairs_beyond_1_over_eps():
    # P0 = 1e300 I with m < n: the covariance is repaired at almost every sample and the
    # results are determined only to rounding (the condition number is beyond 1/eps): the
    # eigensolvers' rounding decides whether a later eigenvalue falls below the level, so the
    # repair count and the means need not agree with numba's; P agrees at the 1e-12 of its
    # largest entry (1e300), and the engine reports a group's repair once per trial
    p = problem(43, 3, 1, 1, 1, 1, N=6, missing=False)
    p["P0"] = 1e300 * np.eye(3)
    out, want = both_run(p)
    assert out.status == want.status == OK
    assert out.repaired > 4 and abs(out.repaired - want.repaired) <= 0.2 * want.repaired
    close("P (1e300)", out.P, want.P)
    assert np.all(np.isfinite(out.x)) and np.all(np.isfinite(out.P))
    runs = [eng.kalman_run(*kalman_args(alone(p, i))) for i in range(6)]
    assert out.repaired == sum(r.repaired for r in runs)
    np.testing.assert_array_equal(out.P, np.concatenate([r.P for r in runs]))


def test_diffuse_prior_takes_the_information_form():
    # a diffuse prior and a nearly noise-free measurement: Joseph's form loses its digits
    p = problem(61, 3, 2, 1, 2, 2, N=7, missing=True)
    p["P0"] = 1e12 * np.eye(3)
    p["R"] = 1e-8 * p["R"]
    out, want = both_run(p, lanes=3)
    assert want.repaired == 0
    same(out, want)


def test_failures_are_the_same_status():
    p = problem(12, 2, 2, 0, 1, 1, N=5, missing=False)
    singular = dict(p, R=np.zeros_like(p["R"]), P0=np.zeros((2, 2)))
    out, want = both_run(singular)
    assert want.status == NOT_POSITIVE_DEFINITE
    same(out, want, complete=False)
    overflow = dict(p, P0=np.full((2, 2), np.inf))
    out, want = both_run(overflow)
    assert want.status == NOT_FINITE
    same(out, want, complete=False)
    nan = dict(p, P0=np.full((2, 2), np.nan))
    out, want = both_run(nan)
    same(out, want, complete=False)


def test_odd_values():
    p = problem(71, 2, 2, 1, 2, 2, N=8, K=20)
    p["y"][1, 4, 0] = np.inf
    p["y"][3, 6, 1] = -1e300
    p["y"][5, :, :] = np.nan  # a trial that never observes anything
    p["u"][6, 3, 0] = 1e200
    same(*both_run(p, lanes=3))
    same(*both_run(p, gate=1e-300, lanes=8))


def test_streaming_step_against_numba():
    p = problem(13, 3, 2, 1, 2, 4, N=11)
    N, K, _ = p["y"].shape
    x, P = np.tile(p["x0"], (N, 1)), np.tile(p["P0"], (N, 1, 1))
    xr, Pr = x, P
    for k in range(K):
        t, md = p["trans"][:, k], p["mode"][:, k]
        rest = (p["y"][:, k], p["u"][:, max(k - 1, 0)], p["F"][t], p["G"][t], p["Qd"][t],
                p["C"][md], p["R"][md])
        out = eng.kalman_step(x, P, *rest, predict_first=k > 0, gate=6.0)
        want = ref.kalman_step(xr, Pr, *rest, predict_first=k > 0, gate=6.0)
        same(out, want)
        x, P, xr, Pr = out.x, out.P, want.x, want.P


def test_zero_sizes():
    p = problem(3, 2, 2, 0, 1, 1, N=3, K=6)
    for q in (dict(p, **{key: p[key][:, :0] for key in ("y", "u", "trans", "mode")}),):
        same(*both_run(q))
    # no trials: numba's kernel refuses (range() with step 0); the engine returns empty outputs
    empty = dict(p, **{key: p[key][:0] for key in ("y", "u", "trans", "mode")})
    out = eng.kalman_run(*kalman_args(empty))
    assert out.status == OK and out.x.shape == (0, 6, 2) and out.P.shape == (0, 6, 2, 2)
    assert out.repaired == 0 and math.isinf(out.smallest_eigenvalue)
    step = eng.kalman_step(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros((0, 2)),
                           np.zeros((0, 0)), np.zeros((0, 2, 2)), np.zeros((0, 2, 0)),
                           np.zeros((0, 2, 2)), np.zeros((0, 2, 2)), np.zeros((0, 2, 2)),
                           predict_first=True)
    assert step.status == OK and step.x.shape == (0, 2)


def test_alone_equals_together():
    p = odd_problem(81, 3, 2, 1, 2, 3, N=10, K=30)
    out = eng.kalman_run(*kalman_args(p), gate=4.0, lanes=4)
    runs = [eng.kalman_run(*kalman_args(alone(p, i)), gate=4.0) for i in range(10)]
    for name in ("x", "P", "loglik", "flag"):
        np.testing.assert_array_equal(np.concatenate([getattr(r, name) for r in runs]),
                                      getattr(out, name))


def test_block_aligned_ranges_give_the_same_numbers():
    # the binding on ranges of whole blocks (how the batch would be split over threads) gives
    # every trial the numbers of the whole call
    p = odd_problem(91, 2, 2, 1, 2, 3, N=23, K=40)
    out = eng.kalman_run(*kalman_args(p), gate=5.0, lanes=4)
    N, K, _ = p["y"].shape
    x, P = np.empty((N, K, 2)), np.empty((N, K, 2, 2))
    loglik, flag = np.empty((N, K)), np.empty((N, K), dtype=np.uint8)
    x_init, P_init = np.tile(p["x0"], (N, 1)), np.tile(p["P0"], (N, 1, 1))
    for a, b in [(0, 8), (8, 20), (20, 23)]:
        s = slice(a, b)
        report = np.empty(2)
        status = eng.kalman_filter(p["y"][s], p["u"][s], p["F"], p["G"], p["Qd"],
                                   p["trans"][s].astype(np.int64), p["C"], p["R"],
                                   p["mode"][s].astype(np.int64), x_init[s], P_init[s], False,
                                   5.0, 4, x[s], P[s], loglik[s], flag[s], report)
        assert status == OK
    for name, value in (("x", x), ("P", P), ("loglik", loglik), ("flag", flag)):
        np.testing.assert_array_equal(value, getattr(out, name))


# ---------------------------------------------------------------- fixed gains
def steady_tables(rng, L, n, m):
    gain, P_prior, P_post = rng.standard_normal((L, n, m)), spd(rng, (L,), n), spd(rng, (L,), n)
    whiten = np.tril(rng.standard_normal((L, m, m))) + 2 * np.eye(m)
    return gain, P_prior, P_post, whiten


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("gate", [np.inf, 2.0])
@pytest.mark.parametrize("N, lanes", [(1, 256), (4, 3), (19, 8), (40, 256)])
def test_steady_run(case, gate, N, lanes):
    n, m, l, L, M = case
    p = problem(14 + sum(case) + N, n, m, l, L, M, N=N, K=35)
    gain, P_prior, P_post, whiten = steady_tables(np.random.default_rng(N), L, n, m)
    args = [p[k] for k in ("y", "u", "F", "G", "trans", "C", "mode")]
    args += [gain, P_prior, P_post, whiten, p["x0"]]
    out = eng.kalman_steady_run(*args, gate=gate, lanes=lanes)
    want = ref.kalman_steady_run(*args, gate=gate, lanes=lanes)
    same(out, want)
    np.testing.assert_array_equal(out.P, want.P)


def test_steady_step():
    p = problem(15, 3, 2, 1, 2, 3, N=9)
    gain, P_prior, P_post, whiten = steady_tables(np.random.default_rng(2), 2, 3, 2)
    xs = xr = np.tile(p["x0"], (9, 1))
    for k in range(p["y"].shape[1]):
        t, md = p["trans"][:, k], p["mode"][:, k]
        rest = (p["y"][:, k], p["u"][:, max(k - 1, 0)], p["F"][t], p["G"][t], p["C"][md],
                gain[md], P_prior[md], P_post[md], whiten[md])
        out = eng.kalman_steady_step(xs, *rest, predict_first=k > 0, gate=2.5)
        want = ref.kalman_steady_step(xr, *rest, predict_first=k > 0, gate=2.5)
        same(out, want)
        xs, xr = out.x, want.x


def test_steady_zero_sizes():
    p = problem(16, 2, 1, 1, 1, 1, N=2, K=5)
    gain, P_prior, P_post, whiten = steady_tables(np.random.default_rng(3), 1, 2, 1)
    for N, K in ((2, 0), (0, 5)):
        args = [p[k][:N, :K] for k in ("y", "u")] + [p["F"], p["G"], p["trans"][:N, :K],
                                                     p["C"], p["mode"][:N, :K]]
        args += [gain, P_prior, P_post, whiten, p["x0"]]
        out = eng.kalman_steady_run(*args)
        assert out.status == OK and out.x.shape == (N, K, 2)
        if N:
            same(out, ref.kalman_steady_run(*args))


def test_constants_and_names():
    assert eng.LANES == ref.LANES and eng.CHUNK == ref.CHUNK
    for name in ref.__all__:
        assert hasattr(eng, name)
