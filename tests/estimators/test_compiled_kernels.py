"""The compiled Kalman and IMM kernels against their numpy oracle (numpy_oracle.py, beside this).

Tolerance: every float output equals the oracle to RTOL = 1e-9 relative to the largest entry
of the oracle's array (entrywise relative error means nothing for entries that cancel to ~0).
The two sides differ only in operation order and factorization (explicit equilibrated Cholesky
loops vs LAPACK); each step is backward stable, so they agree to a few ulps times the
condition number of S (< 1e4 for these systems) per step, and a stable filter does not
amplify that over the <= 30 steps used here: observed agreement is ~1e-15, RTOL is the
issue's contract.
"""

import numpy as np
import pytest
from numpy_oracle import imm_run as oracle_imm_run
from numpy_oracle import imm_trial_step as oracle_imm_trial_step
from numpy_oracle import kalman_run as oracle_kalman_run
from numpy_oracle import kalman_steady_run as oracle_steady_run

from switchest.discretize import interval, mode_steps
from switchest.engine import (
    GATED,
    NOT_FINITE,
    NOT_POSITIVE_DEFINITE,
    OK,
    PARTLY_GATED,
    raise_for_status,
)
from switchest.engine.imm import imm_run, imm_run_per_trial, imm_step
from switchest.engine.kalman import kalman_run, kalman_steady_run, kalman_steady_step, kalman_step
from switchest.estimators import IMMFilter, ModeKalmanFilter
from switchest.system import SwitchedLinearSystem

# These tests run each timing on systems of the default ('sample') timing on purpose, to compare
# the two models on the same data; that a filter names the mismatch is tests/test_timing.py's.
pytestmark = pytest.mark.filterwarnings("ignore::switchest.estimators.TimingWarning")

RTOL = 1e-9
TIMINGS = ("sample", "interval")  # the IMM's interaction after or before the prediction
# (n states, m outputs, l inputs, L modes, M table entries)
CASES = [(1, 1, 0, 1, 1), (2, 3, 1, 2, 3), (4, 2, 2, 3, 4), (3, 1, 1, 3, 2), (4, 3, 0, 2, 5)]


def assert_close(actual, expected, rtol=RTOL):
    """Entrywise ``|actual - expected| <= rtol * max |expected|`` (see the module docstring)."""
    expected = np.asarray(expected)
    np.testing.assert_allclose(actual, expected, rtol=0.0, atol=rtol * np.abs(expected).max())


def spd(rng, shape, n, floor=0.1):
    W = rng.standard_normal((*shape, n, n))
    return W @ np.swapaxes(W, -1, -2) / n + floor * np.eye(n)


def problem(seed, n, m, l, L, M, N=4, K=30, missing=True):
    """Random tables, a simulated batch and NaN holes: a dict of the kernels' arguments."""
    rng = np.random.default_rng(seed)
    W = rng.standard_normal((M, n, n))
    radius = np.abs(np.linalg.eigvals(W)).max(axis=-1)
    F = 0.95 * W / np.maximum(radius, 1.0)[:, None, None]
    G = rng.standard_normal((M, n, l))
    V = rng.standard_normal((M, n, max(n - 1, 1)))
    Qd = 0.2 * V @ np.swapaxes(V, -1, -2)  # rank n - 1: a singular process noise
    C = rng.standard_normal((L, m, n))
    R = spd(rng, (L,), m)
    trans = rng.integers(0, M, (N, K))  # irregular: another table entry per trial and step
    mode = rng.integers(0, L, (N, K))
    u = rng.standard_normal((N, K, l))
    x = rng.standard_normal((N, n))
    y = np.empty((N, K, m))
    for k in range(K):
        if k:
            t = trans[:, k]
            x = np.einsum("nij,nj->ni", F[t], x) + np.einsum("nij,nj->ni", G[t], u[:, k - 1])
            x += 0.3 * rng.standard_normal((N, n))
        y[:, k] = np.einsum("nij,nj->ni", C[mode[:, k]], x) + rng.standard_normal((N, m))
    if missing:
        y[rng.random((N, K, m)) < 0.15] = np.nan  # single components
        y[rng.random((N, K)) < 0.1] = np.nan  # whole samples
    return dict(y=y, u=u, F=F, G=G, Qd=Qd, trans=trans, C=C, R=R, mode=mode,
                x0=rng.standard_normal(n), P0=spd(rng, (), n, floor=0.5))


def imm_problem(seed, n, m, l, L, M, **kw):
    """The arguments of ``imm_run``: per-mode transitions ``(K, L)`` and an asymmetric
    transition matrix with one impossible switch (a ``-inf`` log-probability) when L = 3."""
    p = problem(seed, n, m, l, L, M, **kw)
    rng = np.random.default_rng(seed + 1)
    K = p["y"].shape[1]
    transition = rng.dirichlet(np.ones(L), size=L) + 2.0 * np.eye(L)
    if L == 3:
        transition[0, 2] = 0.0
    transition /= transition.sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore"):
        log_transition = np.log(transition)
    del p["mode"]
    p.update(trans=rng.integers(0, M, (K, L)), log_transition=log_transition,
             log_prob0=np.log(rng.dirichlet(np.ones(L))))
    return p


def kalman_args(p):
    keys = ["y", "u", "F", "G", "Qd", "trans", "C", "R", "mode", "x0", "P0"]
    return [p[key] for key in keys]


def imm_args(p):
    keys = ["y", "u", "F", "G", "Qd", "trans", "C", "R", "log_transition", "x0", "P0",
            "log_prob0"]
    return [p[key] for key in keys]


def assert_imm_equal(out, ref):
    assert out.status == OK
    for name in ("x", "P", "mode_prob", "loglik"):
        assert_close(getattr(out, name), ref[name])
    np.testing.assert_array_equal(out.flag, ref["flag"])
    top2 = np.sort(ref["mode_prob"], axis=-1)[..., -2:] if ref["mode_prob"].shape[-1] > 1 else None
    clear = np.ones(out.mode.shape, bool) if top2 is None else top2[..., 1] - top2[..., 0] > 1e-6
    np.testing.assert_array_equal(out.mode[clear], ref["mode"][clear])  # ties may break either way


# ---------------------------------------------------------------- Kalman
@pytest.mark.parametrize("case", CASES)
def test_kalman_run_matches_the_oracle(case):
    p = problem(10 + sum(case), *case)
    out = kalman_run(*kalman_args(p))
    x, P, loglik, flag = oracle_kalman_run(*kalman_args(p))
    assert out.status == OK
    assert_close(out.x, x)
    assert_close(out.P, P)
    assert_close(out.loglik, loglik)
    np.testing.assert_array_equal(out.flag, flag)
    np.testing.assert_array_equal(out.P, np.swapaxes(out.P, -1, -2))  # mirrored, exactly
    unobserved = np.all(np.isnan(p["y"]), axis=-1)
    assert unobserved.any()
    np.testing.assert_array_equal(out.loglik[unobserved], 0.0)  # written as 0, not computed


def test_kalman_run_with_switches_inside_the_intervals():
    rng = np.random.default_rng(5)
    n, L, N, K = 3, 2, 3, 25
    A = rng.standard_normal((L, n, n)) - 1.5 * np.eye(n)
    system = SwitchedLinearSystem.continuous(A=A, B=rng.standard_normal((L, n, 1)),
                                             C=rng.standard_normal((L, 2, n)),
                                             Q=0.1 * np.eye(n), R=0.2 * np.eye(2))
    t = np.cumsum(rng.uniform(0.2, 0.6, K))  # irregular sample times
    # interval into sample k of trial i: a switch prev -> next at a random offset, or none
    modes = rng.integers(0, L, (N, K))
    offsets = rng.uniform(0.0, 1.0, (N, K)) * np.diff(t, prepend=0.0)
    table, trans = [], np.zeros((N, K), dtype=np.int64)
    for i in range(N):
        for k in range(1, K):
            seg = [modes[i, k - 1], modes[i, k]]
            tr = interval(system, t[k] - t[k - 1], seg, [offsets[i, k]])
            trans[i, k] = len(table)
            table.append(tr)
    F, G, Qd = (np.stack([getattr(tr, f) for tr in table]) for f in ("F", "G", "Qd"))
    switched = modes[:, 1:] != modes[:, :-1]
    assert switched.sum() > 10  # the case exercises intra-interval switches
    p = problem(6, n, 2, 1, L, 1, N=N, K=K)
    p.update(F=F, G=G, Qd=Qd, trans=trans, C=system.C, R=system.R, mode=modes)
    out = kalman_run(*kalman_args(p))
    x, P, loglik, _ = oracle_kalman_run(*kalman_args(p))
    assert_close(out.x, x)
    assert_close(out.P, P)
    assert_close(out.loglik, loglik)


def test_a_gated_sample_equals_a_missing_sample():
    p = problem(7, 3, 2, 1, 2, 3, missing=False)
    gate = 2.0  # the 63 % quantile of chi2(2): many samples fail it
    out = kalman_run(*kalman_args(p), gate=gate)
    ref = oracle_kalman_run(*kalman_args(p), gate=gate)
    gated = out.flag == GATED
    assert 0 < gated.sum() < gated.size - 10
    np.testing.assert_array_equal(out.flag, ref[3])
    assert_close(out.x, ref[0])
    assert_close(out.P, ref[1])
    np.testing.assert_array_equal(out.loglik[gated], 0.0)  # written as 0, not computed
    holes = dict(p, y=np.where(gated[..., None], np.nan, p["y"]))
    nan_run = kalman_run(*kalman_args(holes))  # no gate, the gated samples missing instead
    assert_close(out.x, nan_run.x)
    assert_close(out.P, nan_run.P)
    assert_close(out.loglik, nan_run.loglik)


def test_an_outlier_is_dropped_and_the_filter_goes_on():
    p = problem(8, 2, 2, 1, 1, 1, missing=False)
    p["y"][1, 12, 0] = 1e300  # e' S^-1 e overflows
    out = kalman_run(*kalman_args(p))
    assert out.status == OK and out.flag[1, 12] == GATED and out.flag.sum() == GATED
    assert np.all(np.isfinite(out.x)) and np.all(np.isfinite(out.P))
    holes = dict(p, y=p["y"].copy())
    holes["y"][1, 12] = np.nan
    nan_run = kalman_run(*kalman_args(holes))
    assert_close(out.x, nan_run.x)
    assert_close(out.P, nan_run.P)


def scaled(p, s):
    """The same problem in units ``s`` times smaller: ``x -> s x``, ``P -> s^2 P``."""
    return dict(p, y=s * p["y"], G=s * p["G"], Qd=s * s * p["Qd"], R=s * s * p["R"],
                x0=s * p["x0"], P0=s * s * p["P0"])


def test_a_problem_scaled_by_1e50():
    # s = 2^166 ~ 9e49: a power of two scales every input exactly and commutes with rounding,
    # so x and P scale as s and s^2 to round-off; log det S shifts by 2 m_obs log s, which
    # rounds at ulp(2 m log s) ~ 1e-13 absolute: loglik agrees to 1e-9 of its scale.
    s = 2.0**166
    p = problem(9, 3, 2, 1, 2, 3)
    out, big = kalman_run(*kalman_args(p)), kalman_run(*kalman_args(scaled(p, s)))
    assert big.status == OK
    assert_close(big.x / s, out.x)
    assert_close(big.P / s**2, out.P)
    n_obs = np.sum(~np.isnan(p["y"]), axis=-1)
    assert_close(big.loglik + n_obs * np.log(s), out.loglik)


def test_measurements_of_1e300_and_1e_300_scale_are_equilibrated():
    # output i in units d_i = 2^(+-500) (an exact scaling): S has entries ~1e300 and ~1e-300,
    # the estimate is unchanged and the log-likelihood shifts by -sum log d_i over observed i
    p = problem(11, 3, 2, 1, 2, 3)
    d = np.array([2.0**500, 2.0**-500])
    out = kalman_run(*kalman_args(p))
    far = kalman_run(*kalman_args(dict(p, y=d * p["y"], C=d[:, None] * p["C"],
                                       R=d[:, None] * p["R"] * d)))
    assert far.status == OK
    assert_close(far.x, out.x)
    assert_close(far.P, out.P)
    shift = np.where(np.isnan(p["y"]), 0.0, np.log(d)).sum(axis=-1)
    assert_close(far.loglik + shift, out.loglik)


def test_a_failed_factorization_is_a_status_then_the_package_error():
    p = problem(12, 2, 2, 0, 1, 1, missing=False)
    singular = kalman_run(*kalman_args(dict(p, R=np.zeros_like(p["R"]), P0=np.zeros((2, 2)))))
    assert singular.status == NOT_POSITIVE_DEFINITE
    with pytest.raises(np.linalg.LinAlgError, match="C P C' \\+ R is not positive definite"):
        raise_for_status(singular.status)
    overflow = kalman_run(*kalman_args(dict(p, P0=np.full((2, 2), np.inf))))
    assert overflow.status == NOT_FINITE
    with pytest.raises(np.linalg.LinAlgError, match="is not finite: the state covariance"):
        raise_for_status(overflow.status)
    raise_for_status(OK)


def test_kalman_step_equals_run():
    p = problem(13, 3, 2, 1, 2, 4)
    run = kalman_run(*kalman_args(p), gate=6.0)
    N, K, n = run.x.shape
    x, P = np.tile(p["x0"], (N, 1)), np.tile(p["P0"], (N, 1, 1))
    for k in range(K):
        t, md = p["trans"][:, k], p["mode"][:, k]
        step = kalman_step(x, P, p["y"][:, k], p["u"][:, max(k - 1, 0)], p["F"][t], p["G"][t],
                           p["Qd"][t], p["C"][md], p["R"][md], predict_first=k > 0, gate=6.0)
        x, P = step.x, step.P
        # the same compiled functions on the same numbers: equal to the last bit in practice
        assert_close(x, run.x[:, k], rtol=1e-14)
        assert_close(P, run.P[:, k], rtol=1e-14)
        assert_close(step.loglik, run.loglik[:, k], rtol=1e-14)
        np.testing.assert_array_equal(step.flag, run.flag[:, k])


def alone(p, i):
    """The arguments of trial ``i`` alone (``N = 1``)."""
    return dict(p, **{key: p[key][i:i + 1] for key in ("y", "u", "trans", "mode")})


def test_trials_that_part_ways_get_the_numbers_of_their_own_filter():
    # every trial follows the same transitions and output matrices, so a block starts as one
    # group sharing its covariance equations; missing components, the gate and an outlier split
    # it. Each trial must get the numbers of its filter run alone, and the same again when each
    # trial indexes its own copies of the tables (equal by value, so its group holds): the same
    # operations on the same numbers, hence exact equality.
    p = problem(31, 3, 2, 1, 2, 3, N=9, missing=False)
    N, K, _ = p["y"].shape
    p["trans"][:], p["mode"][:] = p["trans"][0], p["mode"][0]
    p["y"][2, 5:, 0] = np.nan  # one component from sample 5 on
    p["y"][4, 10] = np.nan  # a whole sample
    p["y"][6, 12, 1] = 1e300  # an outlier, gated whatever the gate
    p["y"][7, np.random.default_rng(31).random(K) < 0.3, 1] = np.nan  # scattered holes
    out = kalman_run(*kalman_args(p), gate=6.0)
    assert out.status == OK and out.flag[6, 12] == GATED
    assert 1 < np.count_nonzero(out.flag == GATED) < out.flag.size // 2  # the gate splits groups
    x, P, loglik, flag = oracle_kalman_run(*kalman_args(p), gate=6.0)
    assert_close(out.x, x)
    assert_close(out.P, P)
    assert_close(out.loglik, loglik)
    np.testing.assert_array_equal(out.flag, flag)
    M, L = p["F"].shape[0], p["C"].shape[0]
    copies = dict(p, F=np.tile(p["F"], (N, 1, 1)), G=np.tile(p["G"], (N, 1, 1)),
                  Qd=np.tile(p["Qd"], (N, 1, 1)), trans=p["trans"] + M * np.arange(N)[:, None],
                  C=np.tile(p["C"], (N, 1, 1)), R=np.tile(p["R"], (N, 1, 1)),
                  mode=p["mode"] + L * np.arange(N)[:, None])
    runs = [kalman_run(*kalman_args(copies), gate=6.0)]
    runs += [kalman_run(*kalman_args(alone(p, i)), gate=6.0) for i in range(N)]
    for name in ("x", "P", "loglik", "flag"):
        np.testing.assert_array_equal(getattr(runs[0], name), getattr(out, name))
        np.testing.assert_array_equal(np.concatenate([getattr(r, name) for r in runs[1:]]),
                                      getattr(out, name))


def test_a_repair_of_a_shared_covariance_is_reported_once_per_trial():
    # P0 = 1e300 I with m < n: the covariance is repaired (see the IMM test below) once per
    # sample for the group of all trials, and reported as the trials run alone report it
    p = problem(43, 3, 1, 1, 1, 1, N=4, missing=False)
    p["P0"] = 1e300 * np.eye(3)
    out = kalman_run(*kalman_args(p))
    runs = [kalman_run(*kalman_args(alone(p, i))) for i in range(4)]
    assert out.status == OK and out.repaired > 4
    assert out.repaired == sum(r.repaired for r in runs)
    assert out.smallest_eigenvalue == min(r.smallest_eigenvalue for r in runs)  # same numbers
    np.testing.assert_array_equal(out.P, np.concatenate([r.P for r in runs]))


@pytest.mark.parametrize("gate", [np.inf, 2.0])
def test_steady_state_run_and_step_match_the_oracle(gate):
    p = problem(14, 3, 2, 1, 2, 3)
    rng = np.random.default_rng(14)
    L, n, m = 2, 3, 2
    gain, P_prior, P_post = rng.standard_normal((L, n, m)), spd(rng, (L,), n), spd(rng, (L,), n)
    whiten = np.tril(rng.standard_normal((L, m, m))) + 2 * np.eye(m)
    args = [p[k] for k in ("y", "u", "F", "G", "trans", "C", "mode")]
    out = kalman_steady_run(*args, gain, P_prior, P_post, whiten, p["x0"], gate=gate)
    x, P, flag = oracle_steady_run(*args, gain, P_prior, P_post, whiten, p["x0"], gate)
    assert_close(out.x, x)
    np.testing.assert_array_equal(out.P, P)  # copied from the tables, not computed
    np.testing.assert_array_equal(out.flag, flag)
    assert np.all(np.isnan(out.loglik))
    if np.isfinite(gate):  # the case exercises the gate
        assert 0 < np.count_nonzero(flag == GATED) < flag.size
    xs = np.tile(p["x0"], (4, 1))
    for k in range(p["y"].shape[1]):
        t, md = p["trans"][:, k], p["mode"][:, k]
        step = kalman_steady_step(xs, p["y"][:, k], p["u"][:, max(k - 1, 0)], p["F"][t],
                                  p["G"][t], p["C"][md], gain[md], P_prior[md], P_post[md],
                                  whiten[md], predict_first=k > 0, gate=gate)
        xs = step.x
        assert_close(xs, out.x[:, k], rtol=1e-14)
        np.testing.assert_array_equal(step.P, out.P[:, k])
        np.testing.assert_array_equal(step.flag, out.flag[:, k])


# ---------------------------------------------------------------- IMM
@pytest.mark.parametrize("timing", TIMINGS)
@pytest.mark.parametrize("case", CASES)
def test_imm_run_matches_the_oracle(case, timing):
    p = imm_problem(20 + sum(case), *case)
    assert_imm_equal(imm_run(*imm_args(p), timing=timing),
                     oracle_imm_run(*imm_args(p), timing=timing))


def test_the_two_timings_differ_where_the_modes_differ_in_their_transitions():
    # the oracle comparisons above would pass for a kernel that ignored its timing if the two
    # coincided on these problems: they do not (a 1e-3 difference is 1e6 times RTOL)
    p = imm_problem(22, 3, 2, 1, 3, 4)
    sample, interval = (imm_run(*imm_args(p), timing=timing) for timing in TIMINGS)
    assert np.abs(sample.x - interval.x).max() > 1e-3
    assert np.abs(sample.mode_prob - interval.mode_prob).max() > 1e-3


@pytest.mark.parametrize("timing", TIMINGS)
def test_imm_gating_matches_the_oracle_and_a_gated_sample_equals_a_missing_one(timing):
    p = imm_problem(21, 3, 2, 1, 3, 3, missing=False)
    gate = 3.0
    out = imm_run(*imm_args(p), gate=gate, timing=timing)
    assert_imm_equal(out, oracle_imm_run(*imm_args(p), gate=gate, timing=timing))
    gated = out.flag == GATED
    assert gated.any() and (out.flag == PARTLY_GATED).any()
    assert_close(out.mode_prob.sum(axis=-1), np.ones(out.flag.shape))  # no NaN, no [0, 0]
    holes = dict(p, y=np.where(gated[..., None], np.nan, p["y"]))
    nan_run = imm_run(*imm_args(holes), gate=gate, timing=timing)
    for name in ("x", "P", "mode_prob", "loglik"):
        assert_close(getattr(out, name), getattr(nan_run, name))


def test_imm_outlier_is_dropped_and_the_filter_goes_on():
    p = imm_problem(22, 2, 2, 1, 3, 2, missing=False)
    p["y"][2, 9, 1] = -1e300
    out = imm_run(*imm_args(p))
    assert out.status == OK and out.flag[2, 9] == GATED and out.flag.sum() == GATED
    assert np.all(np.isfinite(out.x)) and np.all(np.isfinite(out.mode_prob))
    holes = dict(p, y=p["y"].copy())
    holes["y"][2, 9] = np.nan
    nan_run = imm_run(*imm_args(holes))
    for name in ("x", "P", "mode_prob", "loglik"):
        assert_close(getattr(out, name), getattr(nan_run, name))


def test_imm_with_one_mode_is_the_kalman_filter_in_both_timings():
    # one mode: the interaction is a copy, so both orders run the same operations (equal to
    # the last bit), and the Kalman kernel runs the same equations of linalg (its trials
    # grouped by shared covariance): 1e-12 of each array's scale leaves room for that grouping
    # only, observed ~1e-16
    p = imm_problem(23, 3, 2, 1, 1, 3)
    sample, interval = (imm_run(*imm_args(p), timing=timing) for timing in TIMINGS)
    for name in ("x", "P", "mode_prob", "loglik", "flag"):
        np.testing.assert_array_equal(getattr(sample, name), getattr(interval, name))
    K = p["y"].shape[1]
    kal = kalman_run(*kalman_args(dict(p, trans=np.tile(p["trans"][:, 0], (4, 1)),
                                       mode=np.zeros((4, K), dtype=int))))
    assert_close(sample.x, kal.x, rtol=1e-12)
    assert_close(sample.P, kal.P, rtol=1e-12)
    assert_close(sample.loglik, kal.loglik, rtol=1e-12)


def test_imm_a_problem_scaled_by_1e50():
    # as for the Kalman filter; the mode probabilities depend on loglik differences, where the
    # common shift -m_obs log s cancels up to its rounding (~1e-13): they agree to 1e-9
    s = 2.0**166
    p = imm_problem(24, 4, 2, 1, 3, 3)
    out, big = imm_run(*imm_args(p)), imm_run(*imm_args(scaled(p, s)))
    assert big.status == OK
    assert_close(big.x / s, out.x)
    assert_close(big.P / s**2, out.P)
    assert_close(big.mode_prob, out.mode_prob)


@pytest.mark.parametrize("timing", TIMINGS)
def test_imm_step_equals_run(timing):
    p = imm_problem(25, 3, 2, 1, 3, 4)
    run = imm_run(*imm_args(p), gate=8.0, timing=timing)
    N, K, n = run.x.shape
    L = p["log_prob0"].size
    x, P = np.tile(p["x0"], (N, L, 1)), np.tile(p["P0"], (N, L, 1, 1))
    log_prob = np.tile(p["log_prob0"], (N, 1))
    for k in range(K):
        step, (x, P, log_prob) = imm_step(
            x, P, log_prob, p["y"][:, k], p["u"][:, max(k - 1, 0)], p["F"], p["G"], p["Qd"],
            p["trans"][k], p["C"], p["R"], p["log_transition"], predict_first=k > 0, gate=8.0,
            timing=timing)
        # the same compiled kernel on the same numbers: equal to the last bit in practice
        for name in ("x", "P", "mode_prob", "loglik"):
            assert_close(getattr(step, name)[:, 0], getattr(run, name)[:, k], rtol=1e-14)
        assert_close(np.exp(log_prob), run.mode_prob[:, k], rtol=1e-14)
        np.testing.assert_array_equal(step.mode[:, 0], run.mode[:, k])
        np.testing.assert_array_equal(step.flag[:, 0], run.flag[:, k])


@pytest.mark.parametrize("timing", TIMINGS)
def test_imm_run_per_trial_gives_each_trial_the_numbers_of_its_own_model(timing):
    # three models (tables, C, R, transition matrix) of the same sizes, two trials each, in
    # one call: every trial as the oracle filters it under its own model alone
    parts = [imm_problem(40 + s, 3, 2, 1, 3, 4, N=2, K=12) for s in range(3)]
    shared = {key: parts[0][key] for key in ("x0", "P0", "log_prob0")}
    for part in parts:
        part.update(shared)
    M, L, K = 4, 3, 12
    trans = np.concatenate([np.broadcast_to(part["trans"] + s * M, (2, K, L))
                            for s, part in enumerate(parts)])
    out_index = np.repeat(np.arange(3)[:, None] * L + np.arange(L), 2, axis=0)
    log_transition = np.repeat([part["log_transition"] for part in parts], 2, axis=0)
    joined = {key: np.concatenate([part[key] for part in parts])
              for key in ("y", "u", "F", "G", "Qd", "C", "R")}
    out = imm_run_per_trial(joined["y"], joined["u"], joined["F"], joined["G"], joined["Qd"],
                            trans, joined["C"], joined["R"], out_index, log_transition,
                            timing=timing, **shared)
    assert out.status == OK
    for s, part in enumerate(parts):
        ref = oracle_imm_run(*imm_args(part), timing=timing)
        rows = slice(2 * s, 2 * s + 2)
        for name in ("x", "P", "mode_prob", "loglik"):
            assert_close(getattr(out, name)[rows], ref[name])
        np.testing.assert_array_equal(out.flag[rows], ref["flag"])


def test_imm_run_per_trial_names_a_model_index_out_of_range():
    p = imm_problem(43, 2, 1, 1, 2, 3, N=2, K=4)
    with pytest.raises(ValueError, match="out_index must index 0..1"):
        imm_run_per_trial(p["y"], p["u"], p["F"], p["G"], p["Qd"],
                          np.broadcast_to(p["trans"], (2, 4, 2)), p["C"], p["R"],
                          np.array([[0, 1], [1, 2]]), np.stack([p["log_transition"]] * 2),
                          p["x0"], p["P0"], p["log_prob0"])


@pytest.mark.parametrize("timing", TIMINGS)
def test_imm_mixing_of_an_all_but_unreachable_mode_stays_in_the_log_domain(timing):
    # mode 2 is reached only from modes 1 and 2, whose probabilities exp(-800) underflow to 0:
    # its predicted probability c_2 ~ exp(-800) must come out finite, not log(0) = -inf
    p = imm_problem(26, 2, 2, 1, 3, 2, N=3, K=2)
    p["log_prob0"] = np.array([0.0, -800.0, -800.0])
    x0 = np.tile(p["x0"], (3, 3, 1))
    P0 = np.tile(p["P0"], (3, 3, 1, 1))
    log_prob = np.tile(p["log_prob0"], (3, 1))
    _, (x1, _, log_prob1) = imm_step(x0, P0, log_prob, p["y"][:, 1], p["u"][:, 0], p["F"],
                                     p["G"], p["Qd"], p["trans"][1], p["C"], p["R"],
                                     p["log_transition"], predict_first=True, timing=timing)
    ref = oracle_imm_trial_step(x0[0], P0[0], log_prob[0], p["y"][0, 1], p["u"][0, 0], p["F"],
                                p["G"], p["Qd"], p["trans"][1], p["C"], p["R"],
                                p["log_transition"], True, np.inf, timing)
    assert -2000.0 < log_prob1[0, 2] < -700.0
    assert_close(log_prob1[0], ref[2])  # ~800 in scale: agreement to ~1e-6 absolute
    assert_close(x1[0], ref[0])


@pytest.mark.parametrize("timing", TIMINGS)
def test_imm_a_diffuse_prior_takes_the_information_form_lane_by_lane(timing):
    # P0 = 1e300 I, C invertible (m = n): Joseph's form loses every digit of the first
    # posterior (K C = I to eps), which the kernel detects lane by lane and replaces by the
    # information form, as the oracle does; the posterior (P0^-1 + C' R^-1 C)^-1 is then as
    # well conditioned as R, so RTOL holds (observed ~1e-12). Trials 0 and 2 are diffuse,
    # 1 and 3 not: one block of lanes takes both paths.
    p = imm_problem(40, 2, 2, 1, 2, 3, missing=False)
    out = imm_run(*imm_args(dict(p, P0=1e300 * np.eye(2))), timing=timing)
    assert out.repaired == 0
    assert_imm_equal(out, oracle_imm_run(*imm_args(dict(p, P0=1e300 * np.eye(2))),
                                         timing=timing))
    N, L = p["y"].shape[0], p["log_prob0"].size
    P = np.tile(p["P0"], (N, L, 1, 1))
    P[::2] = 1e300 * np.eye(2)
    x, log_prob = np.tile(p["x0"], (N, L, 1)), np.tile(p["log_prob0"], (N, 1))
    step, after = imm_step(x, P, log_prob, p["y"][:, 0], p["u"][:, 0], p["F"], p["G"], p["Qd"],
                           p["trans"][0], p["C"], p["R"], p["log_transition"], predict_first=False)
    assert step.status == OK and step.repaired == 0
    for i in range(N):
        ref = oracle_imm_trial_step(x[i], P[i], log_prob[i], p["y"][i, 0], p["u"][i, 0],
                                    p["F"], p["G"], p["Qd"], p["trans"][0], p["C"], p["R"],
                                    p["log_transition"], False, np.inf)
        for got, want in zip(after, ref[:3]):  # x, P, log_prob
            assert_close(got[i], want)


def test_imm_covariances_beyond_1_over_eps_are_repaired_and_reported():
    # P0 = 1e300 I with m < n: the states the measurement does not see keep 1e300 while the
    # seen ones fall to ~1, a condition number beyond 1/eps, so Joseph's and the information
    # form both round to an indefinite matrix or an S that fails its factorization: the kernel
    # repairs the covariance (eigenvalues raised to n eps max|eig|) and reports it. The results
    # are determined only to rounding there, so they are checked for finiteness and positive
    # variances, not against the oracle.
    p = imm_problem(42, 3, 2, 1, 2, 3, missing=False)
    out = imm_run(*imm_args(dict(p, P0=1e300 * np.eye(3))))
    assert out.status == OK and out.repaired > 0 and out.smallest_eigenvalue < 0.0
    assert np.all(np.isfinite(out.x)) and np.all(np.isfinite(out.P))
    assert np.all(np.diagonal(out.P, axis1=-2, axis2=-1) > 0.0)
    assert_close(out.mode_prob.sum(axis=-1), np.ones(out.flag.shape))
    clean = imm_run(*imm_args(p))
    assert clean.repaired == 0 and np.isinf(clean.smallest_eigenvalue)


def test_imm_filter_warns_about_a_repaired_covariance():
    # the problem of the test above, through IMMFilter: the kernel's report becomes the numpy
    # core's RuntimeWarning
    p = imm_problem(42, 3, 2, 1, 2, 3, missing=False)
    sys = SwitchedLinearSystem.discrete(p["F"][:2], p["G"][:2], p["C"], Q=p["Qd"][:2],
                                        R=p["R"], dt=1.0)
    y = p["y"]
    est = IMMFilter(sys, np.exp(p["log_transition"]), np.zeros(3), 1e300 * np.eye(3))
    with pytest.warns(RuntimeWarning, match="singular or indefinite to working precision"):
        out = est.run(y)
    assert np.all(np.isfinite(out.x)) and np.all(np.isfinite(out.P))


def test_results_do_not_depend_on_the_block_of_lanes():
    p = problem(27, 3, 2, 1, 2, 3, N=7)
    q = imm_problem(27, 3, 2, 1, 3, 3, N=7)
    kal = [kalman_run(*kalman_args(p), gate=5.0, lanes=lanes) for lanes in (1, 3, 16)]
    imm = [imm_run(*imm_args(q), gate=5.0, lanes=lanes) for lanes in (1, 3, 16)]
    # each lane runs the same IEEE operations whatever its block: equal to the last bit
    for out in kal[1:]:
        for name in ("x", "P", "loglik"):
            assert_close(getattr(out, name), getattr(kal[0], name), rtol=1e-14)
    for out in imm[1:]:
        for name in ("x", "P", "mode_prob", "loglik"):
            assert_close(getattr(out, name), getattr(imm[0], name), rtol=1e-14)
        np.testing.assert_array_equal(out.flag, imm[0].flag)


# ---------------------------------------------------------------- the package's filters
def vehicle_case():
    from switchest.models import vehicle_2d
    from switchest.signals import markov_at_samples
    from switchest.simulate import simulate

    system = vehicle_2d(measurement_variance=0.05, process_noise=1e-3)
    transition = np.array([[0.9, 0.06, 0.04], [0.1, 0.85, 0.05], [0.02, 0.08, 0.9]])
    t = 0.5 * np.arange(30)
    traj = simulate(system, lambda rng: markov_at_samples(transition, t, rng=rng), t,
                    (np.zeros(4), np.eye(4)), np.ones(1), trials=4, rng=3)
    y = traj.y.copy()
    y[0, 5] = np.nan
    y[1, 7, 0] = np.nan
    return system, transition, traj, y


@pytest.mark.parametrize("timing", TIMINGS)
def test_the_kernels_reproduce_the_package_filters(timing):
    # IMMFilter.run is the kernel: its transition table (one entry per mode and distinct step,
    # irregular times here) and its outputs must equal the oracle's in its timing;
    # ModeKalmanFilter (still on the numpy core) must equal kalman_run
    system, transition, traj, y = vehicle_case()
    x0, P0 = np.zeros(4), np.eye(4)
    L, K = 3, traj.t.size
    t = traj.t + np.where(np.arange(K) % 3 == 1, 0.2, 0.0)  # steps 0.7, 0.3 and 0.5
    steps, which = np.unique(np.diff(t), return_inverse=True)
    table = [mode_steps(system, h) for h in steps]
    trans = np.zeros((K, L), dtype=int)
    trans[1:] = np.arange(L) + L * which[:, None]
    ref = oracle_imm_run(y, traj.u, np.concatenate([s.F for s in table]),
                         np.concatenate([s.G for s in table]),
                         np.concatenate([s.Qd for s in table]), trans, system.C, system.R,
                         np.log(transition), x0, P0, np.full(L, -np.log(L)), timing=timing)
    out = IMMFilter(system, transition, x0, P0, timing=timing).run(y, traj.u, t)
    for name in ("x", "P", "mode_prob", "loglik"):
        assert_close(getattr(out, name), ref[name])
    np.testing.assert_array_equal(out.outlier, ref["flag"] == GATED)
    steps = mode_steps(system, 0.5)
    ref = ModeKalmanFilter(system, x0, P0).run(y, traj.u, traj.t, modes=traj.mode)
    prev = np.concatenate([traj.mode[:, :1], traj.mode[:, :-1]], axis=1)  # mode during interval
    out = kalman_run(y, traj.u, steps.F, steps.G, steps.Qd, prev, system.C, system.R, traj.mode,
                     x0, P0)
    assert_close(out.x, ref.x)
    assert_close(out.P, ref.P)
    assert_close(out.loglik, ref.loglik)


# ---------------------------------------------------------------- boundary checks
def test_the_kernels_refuse_inconsistent_arrays():
    p = problem(30, 2, 2, 1, 2, 3, N=2, K=4)
    with pytest.raises(ValueError, match=r"Qd must have shape \(M, n, n\) = \(M=3, n=2, n=2\), "
                                         r"got \(3, 2, 3\)"):
        kalman_run(*kalman_args(dict(p, Qd=np.zeros((3, 2, 3)))))
    with pytest.raises(ValueError, match=r"trans must index 0..2 \(M = 3 entries\), got 3..3"):
        kalman_run(*kalman_args(dict(p, trans=np.full((2, 4), 3))))
    with pytest.raises(ValueError, match=r"mode must index 0..1 \(L = 2 entries\), got -1..0"):
        kalman_run(*kalman_args(dict(p, mode=-np.eye(2, 4, dtype=int))))
    with pytest.raises(ValueError, match="gate must be a positive number or inf, got nan"):
        kalman_run(*kalman_args(p), gate=np.nan)
    with pytest.raises(TypeError, match="gate must be a positive number or inf, got str"):
        kalman_run(*kalman_args(p), gate="3")
    with pytest.raises(ValueError, match="lanes must be a positive int, got 0"):
        kalman_run(*kalman_args(p), lanes=0)
    q = imm_problem(30, 2, 2, 1, 2, 3, N=2, K=4)
    with pytest.raises(ValueError, match=r"log_prob0 must have shape \(L\) = \(L=2\), got \(3,\)"):
        imm_run(*imm_args(dict(q, log_prob0=np.zeros(3))))
    with pytest.raises(ValueError, match=r"timing must be one of \('sample', 'interval'\), "
                                         r"got 'samples'"):
        imm_run(*imm_args(q), timing="samples")
    with pytest.raises(TypeError, match=r"timing must be one of \('sample', 'interval'\), "
                                        r"got bool"):
        imm_step(np.zeros((2, 2, 2)), np.tile(np.eye(2), (2, 2, 1, 1)), np.zeros((2, 2)),
                 q["y"][:, 0], q["u"][:, 0], q["F"], q["G"], q["Qd"], q["trans"][0], q["C"],
                 q["R"], q["log_transition"], predict_first=True, timing=True)
