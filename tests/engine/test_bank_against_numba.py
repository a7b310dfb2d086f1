"""The C multiple-model bank (engine/c/bank.c, gpb.c: the IMM, GPB1 and GPB2) against the numba
kernels it replaces (estimators/_compiled/bank.py, gpb.py).

Tolerance: every float output within 1e-12 of the numba one, relative to the largest finite
entry of numba's array; non-finite entries (a -inf log-probability of an unreachable mode)
equal exactly; integer and flag outputs, status and repair count exactly. The two sides run
the same operations in the same order (no contraction into FMAs on either side), so they
agree to the last bit in practice. This file goes with the numba code.
"""

import math

import numpy as np
import pytest

from switchest.engine import _gpb, _imm
from switchest.engine import gpb as engine_gpb
from switchest.engine import imm as engine_imm
from switchest.estimators._compiled import gpb as numba_gpb
from switchest.estimators._compiled import imm as numba_imm
from switchest.estimators._compiled.bank import filter_bank as numba_filter_bank
from switchest.estimators._compiled.gpb import gpb2_bank as numba_gpb2_bank
from switchest.estimators._compiled.linalg import NOT_FINITE, NOT_POSITIVE_DEFINITE, OK

RTOL = 1e-12
TIMINGS = ("sample", "interval")
INTERACTIONS = ("mix", "collapse")
# (n states, m outputs, l inputs, L modes, M table entries)
CASES = [(1, 1, 0, 1, 1), (2, 3, 1, 2, 3), (4, 2, 2, 3, 4), (3, 1, 1, 3, 2), (4, 3, 0, 2, 5),
         (1, 2, 1, 4, 3), (2, 1, 0, 1, 2), (3, 3, 2, 4, 6)]
LARGEST = {}  # name -> largest relative difference seen, printed at the end


def record(name, actual, expected):
    """``actual`` against ``expected`` at RTOL of the largest finite entry; non-finite entries
    exactly; integers exactly. Records the largest relative difference under ``name``."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape and actual.dtype == expected.dtype, name
    if expected.dtype.kind != "f":
        np.testing.assert_array_equal(actual, expected, err_msg=name)
        return
    finite = np.isfinite(expected)
    np.testing.assert_array_equal(actual[~finite], expected[~finite], err_msg=name)
    if not finite.any():
        return
    scale = np.abs(expected[finite]).max()
    diff = np.abs(actual[finite] - expected[finite]).max()
    rel = diff / scale if scale > 0 else diff
    LARGEST[name] = max(LARGEST.get(name, 0.0), rel)
    assert rel <= RTOL, f"{name}: relative difference {rel:.3g}"


def compare_output(out, ref, family):
    assert out.status == ref.status
    assert out.repaired == ref.repaired
    assert out.smallest_eigenvalue == ref.smallest_eigenvalue or (
        math.isclose(out.smallest_eigenvalue, ref.smallest_eigenvalue, rel_tol=RTOL))
    if out.status != OK:  # outputs incomplete (np.empty): nothing else to compare
        return
    for field in ("x", "P", "mode_prob", "mode", "loglik", "flag"):
        record(f"{family}.{field}", getattr(out, field), getattr(ref, field))
    if ref.x_modes is None:
        assert out.x_modes is None and out.P_modes is None
    else:
        record(f"{family}.x_modes", out.x_modes, ref.x_modes)
        record(f"{family}.P_modes", out.P_modes, ref.P_modes)


def compare_repaired(run, ref_run, p, family, **kw):
    """A problem whose covariances are repaired (condition numbers beyond 1/eps): numba's
    repair takes LAPACK's eigendecomposition, the engine's a Jacobi one (linalg.c), equal to
    rounding (eps max|eig|) only, and the results of such a problem are determined only to
    that rounding (the states of scale 1e300 swamp the others): they part after the first
    repair, and so do the later repair counts and smallest eigenvalues. So the outputs are
    compared up to the sample of the first repair (the same sample on both sides), the repair
    counts for being positive and the rest for being finite, with positive variances."""
    out, ref = run(*args(p), **kw), ref_run(*args(p), **kw)
    assert out.status == ref.status == OK
    assert out.repaired > 0 and ref.repaired > 0

    def first_repair(f):
        K = p["y"].shape[1]
        return next(k for k in range(1, K + 1)
                    if f(*args(dict(p, y=p["y"][:, :k], u=p["u"][:, :k], trans=p["trans"][:k])),
                         **kw).repaired)

    first = first_repair(ref_run)
    assert first_repair(run) == first
    for field in ("x", "P", "mode_prob", "mode", "loglik", "flag"):
        record(f"{family}.{field}", getattr(out, field)[:, :first - 1],
               getattr(ref, field)[:, :first - 1])
    assert np.all(np.isfinite(out.x)) and np.all(np.isfinite(out.P))
    assert np.all(np.diagonal(out.P, axis1=-2, axis2=-1) > 0.0)
    np.testing.assert_allclose(out.mode_prob.sum(axis=-1), 1.0, rtol=0, atol=1e-12)


def compare_state(state, ref_state, family):
    for name, a, b in zip(("x_last", "P_last", "log_prob_last"), state, ref_state, strict=True):
        record(f"{family}.{name}", a, b)


# ---------------------------------------------------------------- problems
def spd(rng, shape, n, floor=0.1):
    W = rng.standard_normal((*shape, n, n))
    return W @ np.swapaxes(W, -1, -2) / n + floor * np.eye(n)


def problem(seed, n, m, l, L, M, N=4, K=30, missing=True):
    """Random stable transitions (a table of ``M``, a random entry per mode and sample), a
    simulated record with NaN holes, inputs, and an asymmetric transition matrix with one
    impossible switch when ``L >= 3``: the arguments of ``imm_run``."""
    rng = np.random.default_rng(seed)
    W = rng.standard_normal((M, n, n))
    F = 0.95 * W / np.maximum(np.abs(np.linalg.eigvals(W)).max(axis=-1), 1.0)[:, None, None]
    G = rng.standard_normal((M, n, l))
    V = rng.standard_normal((M, n, max(n - 1, 1)))
    Qd = 0.2 * V @ np.swapaxes(V, -1, -2)  # rank n - 1: a singular process noise
    C, R = rng.standard_normal((L, m, n)), spd(rng, (L,), m)
    trans = rng.integers(0, M, (K, L))
    u = rng.standard_normal((N, K, l))
    x, y = rng.standard_normal((N, n)), np.empty((N, K, m))
    for k in range(K):
        mode = rng.integers(0, L, N)
        if k:
            t = trans[k, mode]
            x = np.einsum("nij,nj->ni", F[t], x) + np.einsum("nij,nj->ni", G[t], u[:, k - 1])
            x += 0.3 * rng.standard_normal((N, n))
        y[:, k] = np.einsum("nij,nj->ni", C[mode], x) + rng.standard_normal((N, m))
    if missing:
        y[rng.random((N, K, m)) < 0.15] = np.nan  # single components
        y[rng.random((N, K)) < 0.1] = np.nan  # whole samples
    transition = rng.dirichlet(np.ones(L), size=L) + 2.0 * np.eye(L)
    if L >= 3:
        transition[0, 2] = 0.0
    transition /= transition.sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore"):
        log_transition = np.log(transition)
    return dict(y=y, u=u, F=F, G=G, Qd=Qd, trans=trans, C=C, R=R, log_transition=log_transition,
                x0=rng.standard_normal(n), P0=spd(rng, (), n, floor=0.5),
                log_prob0=np.log(rng.dirichlet(np.ones(L))))


def args(p):
    keys = ["y", "u", "F", "G", "Qd", "trans", "C", "R", "log_transition", "x0", "P0",
            "log_prob0"]
    return [p[key] for key in keys]


def both_runs(p, **kw):
    """imm_run of the engine and of numba on the same problem."""
    return engine_imm.imm_run(*args(p), **kw), numba_imm.imm_run(*args(p), **kw)


def both_gpb2(p, **kw):
    return engine_gpb.gpb2_run(*args(p), **kw), numba_gpb.gpb2_run(*args(p), **kw)


# ---------------------------------------------------------------- imm_run: IMM and GPB1
@pytest.mark.parametrize("interaction", INTERACTIONS)
@pytest.mark.parametrize("timing", TIMINGS)
@pytest.mark.parametrize("case", CASES)
def test_imm_run_equals_numba(case, timing, interaction):
    p = problem(20 + sum(case), *case, N=7)
    for kw in (dict(), dict(gate=4.0, modes_out=True), dict(lanes=3, modes_out=True)):
        out, ref = both_runs(p, timing=timing, interaction=interaction, **kw)
        compare_output(out, ref, interaction)
        assert out.status == OK


@pytest.mark.parametrize("N", [1, 5, 16, 17, 33])
@pytest.mark.parametrize("lanes", [1, 3, 8, 16, 40])
def test_trial_counts_and_blocks_of_lanes(N, lanes):
    p = problem(31, 3, 2, 1, 3, 4, N=N, K=9)
    for interaction in INTERACTIONS:
        out, ref = both_runs(p, gate=5.0, lanes=lanes, interaction=interaction, modes_out=True)
        compare_output(out, ref, interaction)
    # the results do not depend on the block: against numba's default block too
    default = numba_imm.imm_run(*args(p), gate=5.0, interaction=interaction, modes_out=True)
    for field in ("x", "P", "mode_prob", "loglik", "x_modes", "P_modes"):
        np.testing.assert_array_equal(getattr(out, field), getattr(default, field))


@pytest.mark.parametrize("interaction", INTERACTIONS)
@pytest.mark.parametrize("timing", TIMINGS)
def test_gating_and_outliers(timing, interaction):
    p = problem(21, 3, 2, 1, 3, 3, missing=False, N=9)
    p["y"][1, 7, 0] = 1e300  # an outlier: its likelihood overflows in every mode
    p["y"][2, 9, 1] = -1e300
    p["y"][3, 4] = [1e6, -1e6]
    out, ref = both_runs(p, gate=3.0, timing=timing, interaction=interaction, modes_out=True)
    compare_output(out, ref, interaction)
    assert (out.flag == 1).any() and (out.flag == 2).any()  # GATED and PARTLY_GATED seen


@pytest.mark.parametrize("interaction", INTERACTIONS)
@pytest.mark.parametrize("timing", TIMINGS)
def test_unreachable_and_all_but_unreachable_modes(timing, interaction):
    p = problem(54, 2, 2, 1, 3, 3, N=5)
    with np.errstate(divide="ignore"):
        p["log_transition"] = np.log([[0.9, 0.1, 0.0], [0.2, 0.8, 0.0], [0.1, 0.1, 0.8]])
        p["log_prob0"] = np.log([0.6, 0.4, 0.0])
    out, ref = both_runs(p, timing=timing, interaction=interaction, modes_out=True)
    compare_output(out, ref, interaction)
    q = problem(26, 2, 2, 1, 3, 2, N=3, K=6)
    q["log_prob0"] = np.array([0.0, -800.0, -800.0])  # their products underflow: log domain
    out, ref = both_runs(q, timing=timing, interaction=interaction, modes_out=True)
    compare_output(out, ref, interaction)


@pytest.mark.parametrize("interaction", INTERACTIONS)
@pytest.mark.parametrize("timing", TIMINGS)
def test_diffuse_priors_and_repairs(timing, interaction):
    p = problem(40, 2, 2, 1, 2, 3, missing=False)  # m = n: the information form
    out, ref = both_runs(dict(p, P0=1e300 * np.eye(2)), timing=timing, interaction=interaction,
                         modes_out=True)
    compare_output(out, ref, interaction)
    q = problem(42, 3, 2, 1, 2, 3, missing=False)  # m < n: repaired
    compare_repaired(engine_imm.imm_run, numba_imm.imm_run, dict(q, P0=1e300 * np.eye(3)),
                     interaction, timing=timing, interaction=interaction)
    s = 2.0**166  # scaled by 1e50
    big = dict(q, y=q["y"] * s, u=q["u"] * s, Qd=q["Qd"] * s**2, R=q["R"] * s**2,
               x0=q["x0"] * s, P0=q["P0"] * s**2)
    out, ref = both_runs(big, timing=timing, interaction=interaction)
    compare_output(out, ref, interaction)


@pytest.mark.parametrize("interaction", INTERACTIONS)
def test_failures_return_the_same_status(interaction):
    p = problem(43, 2, 2, 1, 2, 3, missing=False)
    out, ref = both_runs(dict(p, R=-np.tile(np.eye(2), (2, 1, 1)), P0=np.zeros((2, 2))),
                         interaction=interaction)
    assert ref.status == NOT_POSITIVE_DEFINITE
    compare_output(out, ref, interaction)
    out, ref = both_runs(dict(p, P0=np.full((2, 2), np.inf)), interaction=interaction)
    assert ref.status == NOT_FINITE
    compare_output(out, ref, interaction)


def test_zero_sizes():
    p = problem(44, 2, 2, 0, 2, 3, N=3, K=5)
    for q in (dict(p, y=p["y"][:0], u=p["u"][:0]),  # N = 0
              dict(p, y=p["y"][:, :0], u=p["u"][:, :0], trans=p["trans"][:0])):  # K = 0
        for interaction in INTERACTIONS:
            out, ref = both_runs(q, interaction=interaction, modes_out=True)
            compare_output(out, ref, interaction)
        out, ref = both_gpb2(q, modes_out=True)
        compare_output(out, ref, "gpb2")


@pytest.mark.parametrize("timing", TIMINGS)
def test_imm_run_per_trial_equals_numba(timing):
    rng = np.random.default_rng(45)
    N, K, L, M, S = 19, 11, 3, 4, 5
    p = problem(45, 3, 2, 1, L, M, N=N, K=K)
    trans = rng.integers(0, M, (N, K, L))
    C, R = rng.standard_normal((S, 2, 3)), spd(rng, (S,), 2)
    out_index = rng.integers(0, S, (N, L))
    lt = rng.dirichlet(np.ones(L), size=(N, L)) + np.eye(L)
    lt = np.log(lt / lt.sum(axis=-1, keepdims=True))
    a = (p["y"], p["u"], p["F"], p["G"], p["Qd"], trans, C, R, out_index, lt, p["x0"],
         p["P0"], p["log_prob0"])
    for gate in (math.inf, 4.0):
        out = engine_imm.imm_run_per_trial(*a, gate=gate, timing=timing)
        ref = numba_imm.imm_run_per_trial(*a, gate=gate, timing=timing)
        compare_output(out, ref, "per_trial")


@pytest.mark.parametrize("interaction", INTERACTIONS)
@pytest.mark.parametrize("timing", TIMINGS)
def test_imm_step_equals_numba(timing, interaction):
    p = problem(25, 2, 2, 1, 3, 4, N=21)
    N, K, _ = p["y"].shape
    L = p["log_prob0"].size
    x, P = np.tile(p["x0"], (N, L, 1)), np.tile(p["P0"], (N, L, 1, 1))
    P[::3] = 1e300 * np.eye(2)  # diffuse in some trials (m = n: the information form)
    log_prob = np.tile(p["log_prob0"], (N, 1))
    state = ref_state = (x, P, log_prob)
    for k in range(K):
        a = (p["y"][:, k], p["u"][:, max(k - 1, 0)], p["F"], p["G"], p["Qd"], p["trans"][k],
             p["C"], p["R"], p["log_transition"])
        kw = dict(predict_first=k > 0, gate=8.0, timing=timing, interaction=interaction)
        out, state = engine_imm.imm_step(*state, *a, **kw)
        ref, ref_state = numba_imm.imm_step(*ref_state, *a, **kw)
        assert ref.repaired == 0
        compare_output(out, ref, "step")
        compare_state(state, ref_state, "step")
    # predict_first at the first sample of a record (a streaming start)
    out, state = engine_imm.imm_step(x, P, log_prob, *a, predict_first=True, timing=timing)
    ref, ref_state = numba_imm.imm_step(x, P, log_prob, *a, predict_first=True, timing=timing)
    compare_output(out, ref, "step")
    compare_state(state, ref_state, "step")


# ---------------------------------------------------------------- the kernel itself
def kernel_args(p, N, rng, shared):
    """filter_bank's arguments with per-trial or shared tables and an output table that
    changes per sample (a path the wrappers do not take)."""
    K, L = p["trans"].shape
    n = p["x0"].size
    S = p["C"].shape[0]
    trans = p["trans"][None] if shared else rng.integers(0, p["F"].shape[0], (N, K, L))
    out_index = (rng.integers(0, S, (1, K, L)) if shared else rng.integers(0, S, (N, K, L)))
    lt = p["log_transition"][None] if shared else np.log(
        rng.dirichlet(np.ones(L), size=(N, L)))
    x0 = rng.standard_normal((N, L, n))
    P0 = spd(rng, (N, L), n, floor=0.5)
    lp0 = np.log(rng.dirichlet(np.ones(L), size=N))
    return [p["y"], p["u"], p["F"], p["G"], p["Qd"], trans, p["C"], p["R"], out_index,
            np.exp(lt), lt, x0, P0, lp0]


def kernel_outputs(N, K, L, n, modes):
    size = (N, K, L) if modes else (0, 0, 0)
    return [np.empty((N, K, n)), np.empty((N, K, n, n)), np.empty((N, K, L)),
            np.empty((N, K), dtype=np.int64), np.empty((N, K)),
            np.empty((N, K), dtype=np.uint8), np.empty((*size, n)), np.empty((*size, n, n)),
            np.empty((N, L, n)), np.empty((N, L, n, n)), np.empty((N, L)), np.empty(2)]


@pytest.mark.parametrize("shared", [True, False])
@pytest.mark.parametrize("case", CASES[1:6])
def test_filter_bank_kernel_with_per_sample_output_tables(case, shared):
    rng = np.random.default_rng(sum(case))
    N = 13
    p = problem(50 + sum(case), *case, N=N, K=12)
    K, L = p["trans"].shape
    n = p["x0"].size
    a = kernel_args(p, N, rng, shared)
    for interaction in (0, 1):
        for sample_timing in (False, True):
            for predict_first in (False, True):
                for lanes in (4, 16):
                    o1, o2 = kernel_outputs(N, K, L, n, True), kernel_outputs(N, K, L, n, True)
                    s1 = _imm.filter_bank(*a, interaction, sample_timing, predict_first, 6.0,
                                       lanes, *o1)
                    s2 = numba_filter_bank(*a, interaction, sample_timing, predict_first,
                                           6.0, lanes, *o2)
                    assert s1 == s2 == OK
                    for i, (u, v) in enumerate(zip(o1, o2, strict=True)):
                        record(f"kernel[{i}]", u, v)


# ---------------------------------------------------------------- GPB2
@pytest.mark.parametrize("timing", TIMINGS)
@pytest.mark.parametrize("case", CASES)
def test_gpb2_run_equals_numba(case, timing):
    p = problem(60 + sum(case), *case, N=7)
    for kw in (dict(), dict(gate=4.0, modes_out=True), dict(lanes=3, modes_out=True)):
        out, ref = both_gpb2(p, timing=timing, **kw)
        compare_output(out, ref, "gpb2")
        assert out.status == OK


@pytest.mark.parametrize("timing", TIMINGS)
def test_gpb2_gating_unreachable_diffuse_repairs_failures(timing):
    p = problem(51, 3, 2, 1, 3, 3, missing=False, N=9)
    p["y"][1, 7, 0] = 1e300
    out, ref = both_gpb2(p, gate=3.0, timing=timing, modes_out=True)
    compare_output(out, ref, "gpb2")
    assert (out.flag == 1).any() and (out.flag == 2).any()
    q = problem(54, 2, 2, 1, 3, 3, N=5)
    with np.errstate(divide="ignore"):
        q["log_transition"] = np.log([[0.9, 0.1, 0.0], [0.2, 0.8, 0.0], [0.1, 0.1, 0.8]])
        q["log_prob0"] = np.log([0.6, 0.4, 0.0])
    out, ref = both_gpb2(q, timing=timing, modes_out=True)
    compare_output(out, ref, "gpb2")
    d = problem(40, 2, 2, 1, 2, 3, missing=False)
    out, ref = both_gpb2(dict(d, P0=1e300 * np.eye(2)), timing=timing, modes_out=True)
    compare_output(out, ref, "gpb2")
    r = problem(42, 3, 2, 1, 2, 3, missing=False)
    compare_repaired(engine_gpb.gpb2_run, numba_gpb.gpb2_run, dict(r, P0=1e300 * np.eye(3)),
                     "gpb2", timing=timing)
    out, ref = both_gpb2(dict(d, R=-np.tile(np.eye(2), (2, 1, 1)), P0=np.zeros((2, 2))),
                         timing=timing)
    assert ref.status == NOT_POSITIVE_DEFINITE
    compare_output(out, ref, "gpb2")
    out, ref = both_gpb2(dict(d, P0=np.full((2, 2), np.inf)), timing=timing)
    assert ref.status == NOT_FINITE
    compare_output(out, ref, "gpb2")


@pytest.mark.parametrize("N", [1, 17])
@pytest.mark.parametrize("lanes", [1, 5, 16])
def test_gpb2_trial_counts_and_blocks_of_lanes(N, lanes):
    p = problem(52, 3, 2, 1, 3, 3, N=N, K=8)
    out, ref = both_gpb2(p, gate=5.0, lanes=lanes, modes_out=True)
    compare_output(out, ref, "gpb2")


@pytest.mark.parametrize("timing", TIMINGS)
def test_gpb2_step_equals_numba(timing):
    p = problem(64, 3, 2, 1, 3, 4, N=19)
    N, K, _ = p["y"].shape
    L = p["log_prob0"].size
    x, P = np.tile(p["x0"], (N, L, 1)), np.tile(p["P0"], (N, L, 1, 1))
    log_prob = np.tile(p["log_prob0"], (N, 1))
    state = ref_state = (x, P, log_prob)
    for k in range(K):
        a = (p["y"][:, k], p["u"][:, max(k - 1, 0)], p["F"], p["G"], p["Qd"], p["trans"][k],
             p["C"], p["R"], p["log_transition"])
        kw = dict(predict_first=k > 0, gate=8.0, timing=timing)
        out, state = engine_gpb.gpb2_step(*state, *a, **kw)
        ref, ref_state = numba_gpb.gpb2_step(*ref_state, *a, **kw)
        compare_output(out, ref, "gpb2_step")
        compare_state(state, ref_state, "gpb2_step")
    out, state = engine_gpb.gpb2_step(x, P, log_prob, *a, predict_first=True, timing=timing)
    ref, ref_state = numba_gpb.gpb2_step(x, P, log_prob, *a, predict_first=True, timing=timing)
    compare_output(out, ref, "gpb2_step")
    compare_state(state, ref_state, "gpb2_step")


@pytest.mark.parametrize("predict_first", [False, True])
def test_gpb2_kernel_with_shared_and_per_trial_transitions(predict_first):
    rng = np.random.default_rng(70)
    N = 11
    p = problem(70, 3, 2, 2, 3, 4, N=N, K=10)
    K, L = p["trans"].shape
    n = p["x0"].size
    x0, P0 = rng.standard_normal((N, L, n)), spd(rng, (N, L), n, floor=0.5)
    lp0 = np.log(rng.dirichlet(np.ones(L), size=N))
    for trans in (p["trans"][None], rng.integers(0, 4, (N, K, L))):
        for sample_timing in (False, True):
            a = [p["y"], p["u"], p["F"], p["G"], p["Qd"], trans, p["C"], p["R"],
                 p["log_transition"], x0, P0, lp0, sample_timing, predict_first, 6.0, 4]
            o1, o2 = kernel_outputs(N, K, L, n, True), kernel_outputs(N, K, L, n, True)
            assert _gpb.gpb2_bank(*a, *o1) == numba_gpb2_bank(*a, *o2) == OK
            for i, (u, v) in enumerate(zip(o1, o2, strict=True)):
                record(f"gpb2_kernel[{i}]", u, v)


def test_wrappers_check_as_numba_does():
    p = problem(30, 2, 2, 1, 2, 3, N=2, K=4)
    for module in (engine_imm, numba_imm):
        with pytest.raises(ValueError, match=r"log_prob0 must have shape \(L\) = \(L=2\)"):
            module.imm_run(*args(dict(p, log_prob0=np.zeros(3))))
        with pytest.raises(ValueError, match="interaction must be one of"):
            module.imm_run(*args(p), interaction="gpb1")
        with pytest.raises(ValueError, match="timing must be one of"):
            module.imm_run(*args(p), timing="samples")
        with pytest.raises(ValueError, match="lanes must be a positive int, got 0"):
            module.imm_run(*args(p), lanes=0)
    for module in (engine_gpb, numba_gpb):
        with pytest.raises(ValueError, match="gate must be a positive number or inf, got nan"):
            module.gpb2_run(*args(p), gate=np.nan)
    assert (engine_imm.MIX, engine_imm.COLLAPSE, engine_imm.LANES) == (0, 1, 16)
    assert engine_imm.IMMOutput._fields == numba_imm.IMMOutput._fields


def test_zzz_print_largest_differences():
    """Not a check: the largest relative difference per output seen by the tests above (run
    with ``-s`` to read them)."""
    for name in sorted(LARGEST):
        print(f"{name:24s} {LARGEST[name]:.3g}")
