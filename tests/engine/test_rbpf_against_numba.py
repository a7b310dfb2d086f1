"""The engine's Rao-Blackwellized particle filter (switchest.engine.rbpf, C) against the numba
kernel it replaces (switchest.estimators._compiled.rbpf).

The random stream must be bit-identical (the same uniforms, keys, resampling positions and
ancestors), so that both draw the same modes: integer and flag outputs are compared exactly,
float outputs to ``1e-12 * max |reference|`` per array (observed: equal bits). Cases: every
resampling scheme, both proposals, both timings, several thresholds, missing components and
samples, gating (an overflowing measurement), impossible switches and first modes, diffuse
priors (information form), repairs, failures, one particle to 64, n = 1..4, step vs run, the
streaming state per trial, zero trials and samples."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "estimators"))
from test_compiled_kernels import CASES, imm_problem  # noqa: E402

from switchest.engine import rbpf as engine  # noqa: E402
from switchest.estimators._compiled import rbpf as reference  # noqa: E402

RTOL = 1e-12
FLOATS = ("x", "P", "mode_prob", "loglik", "ess")
LARGEST = {}  # array name -> largest relative difference seen (reported by the last test)


def assert_same(got, want, name):
    """``|got - want| <= RTOL max |want|`` (NaN and infinities in the same places)."""
    got, want = np.asarray(got), np.asarray(want)
    assert got.shape == want.shape and got.dtype == want.dtype, name
    if want.size == 0:
        return
    finite = np.isfinite(want)
    np.testing.assert_array_equal(np.isfinite(got), finite, err_msg=name)
    np.testing.assert_array_equal(got[~finite], want[~finite], err_msg=name)
    if not finite.any():
        return
    scale = np.abs(want[finite]).max()
    diff = np.abs(got[finite] - want[finite]).max()
    rel = diff / scale if scale > 0 else diff
    LARGEST[name] = max(LARGEST.get(name, 0.0), rel)
    assert rel <= RTOL, (name, rel)


def assert_outputs_equal(got, want):
    assert (got.status, got.repaired) == (want.status, want.repaired)
    if want.status != 0:  # the outputs after a failure are incomplete
        return
    for name in ("mode", "flag"):
        assert getattr(got, name).dtype == getattr(want, name).dtype, name
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    for name in FLOATS:
        assert_same(getattr(got, name), getattr(want, name), name)
    assert got.smallest_eigenvalue == want.smallest_eigenvalue or (
        abs(got.smallest_eigenvalue - want.smallest_eigenvalue)
        <= RTOL * abs(want.smallest_eigenvalue))


def rbpf_problem(seed, n, m, l, L, M, N=4, K=30, missing=True):
    """The arguments of ``rbpf_run``: imm_problem's tables and records, its transition matrix
    (an impossible switch when L = 3) and first-mode probabilities, and keys."""
    p = imm_problem(seed, n, m, l, L, M, N=N, K=K, missing=missing)
    rng = np.random.default_rng(seed + 7)
    return dict(y=p["y"], u=p["u"], F=p["F"], G=p["G"], Qd=p["Qd"], trans=p["trans"], C=p["C"],
                R=p["R"], transition=np.exp(p["log_transition"]), x0=p["x0"], P0=p["P0"],
                prob0=np.exp(p["log_prob0"]), keys=rng.integers(0, 2**64, N, dtype=np.uint64))


ORDER = ("y", "u", "F", "G", "Qd", "trans", "C", "R", "transition", "x0", "P0", "prob0", "keys")


def run_both(p, **options):
    args = [p[key] for key in ORDER]
    return engine.rbpf_run(*args, **options), reference.rbpf_run(*args, **options)


def options(particles, proposal, timing, scheme, threshold):
    return dict(particles=particles, sample_timing=timing == "sample",
                optimal=proposal == "optimal", scheme=engine.RESAMPLING[scheme],
                threshold=threshold)


# ------------------------------------------------------------------ the random stream
ROOTS = [0, 1, 2**63 - 1, 2**63, 2**64 - 3, 2**64 - 1, 0x9E3779B97F4A7C15, 123456789]


@pytest.mark.parametrize("root", ROOTS)
def test_trial_keys_are_bit_identical(root):
    for count in (0, 1, 5, 1000):
        got = engine.trial_keys(np.uint64(root), count)
        want = reference.trial_keys(np.uint64(root), count)
        assert got.dtype == want.dtype == np.uint64
        np.testing.assert_array_equal(got, want)
    # a Python int root: numba types it int64 and then computes other keys (its int64-uint64
    # promotion); the engine converts it to uint64: the keys of the uint64 root
    np.testing.assert_array_equal(engine.trial_keys(root, 7),
                                  reference.trial_keys(np.uint64(root), 7))


def test_uniforms_are_bit_identical():
    rng = np.random.default_rng(0)
    keys = [*(np.uint64(r) for r in ROOTS), *rng.integers(0, 2**64, 20, dtype=np.uint64)]
    ks = [0, 1, 7, 10**6, 2**40, 2**62, 2**63 - 1, -1, -(2**63)]
    js = [0, 1, 2, 63, 64, 999, 2**31, 2**63 - 1, -5]
    for key in keys:
        for k in ks:
            for j in js:
                got, want = engine.uniform(key, k, j), reference.uniform(key, k, j)
                assert got == want and 0.0 <= got < 1.0, (key, k, j)


@pytest.mark.parametrize("scheme", sorted(engine.RESAMPLING))
def test_resampling_positions_and_ancestors_are_bit_identical(scheme):
    rng = np.random.default_rng(1)
    code = engine.RESAMPLING[scheme]
    for nb in (1, 2, 3, 7, 16, 17, 31, 100, 1000, 4099):
        for trial in range(3):
            key, k = rng.integers(0, 2**64, dtype=np.uint64), int(rng.integers(0, 10**6))
            got, want = np.full(nb + 2, -1.0), np.full(nb + 2, -1.0)
            engine.resampling_positions(key, k, code, nb, got)
            reference.resampling_positions(key, k, code, nb, want)
            np.testing.assert_array_equal(got, want)  # the spare entries untouched too
            w = rng.random(nb) ** 3
            w[rng.random(nb) < 0.3] = 0.0  # zero weights: never drawn
            if trial == 1:
                w[:] = 0.0
                w[rng.integers(nb)] = 1.0
            if trial == 2 and nb > 2:
                w[-1] = 0.0  # the last weight zero: the last positive one bounds the search
            if not w.any():
                w[0] = 1.0
            w /= w.sum()
            a_got, a_want = np.empty(nb, dtype=np.int64), np.empty(nb, dtype=np.int64)
            engine.ancestors(w, got[:nb].copy(), nb, a_got)
            reference.ancestors(w, want[:nb].copy(), nb, a_want)
            np.testing.assert_array_equal(a_got, a_want)
            assert np.all(w[a_got] > 0)


def test_the_stream_functions_refuse_short_arrays():
    with pytest.raises(ValueError, match="pos must be a vector"):
        engine.resampling_positions(np.uint64(1), 0, 0, 5, np.empty(4))
    with pytest.raises(ValueError, match="out must be a vector"):
        engine.ancestors(np.ones(5) / 5, np.linspace(0, 1, 5), 5, np.empty(3, dtype=np.int64))
    with pytest.raises(TypeError):
        engine.ancestors(np.ones(5) / 5, np.linspace(0, 1, 5), 5, np.empty(5))


# ------------------------------------------------------------------ whole records
@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("proposal", ["prior", "optimal"])
@pytest.mark.parametrize("timing", ["sample", "interval"])
@pytest.mark.parametrize(("scheme", "threshold"),
                         [("systematic", 0.5), ("stratified", 1.0), ("multinomial", 0.7),
                          ("systematic", 0.0)])
def test_run_matches_numba(case, proposal, timing, scheme, threshold):
    p = rbpf_problem(sum(case) * 13 + len(scheme), *case)
    for Np in (1, 7, 33):
        got, want = run_both(p, **options(Np, proposal, timing, scheme, threshold))
        assert want.status == 0
        assert_outputs_equal(got, want)


@pytest.mark.parametrize("particles", [2, 16, 64, 100])
@pytest.mark.parametrize("proposal", ["prior", "optimal"])
def test_particle_counts_and_odd_trial_counts(particles, proposal):
    for N in (1, 3, 5):
        p = rbpf_problem(100 + N, 3, 2, 1, 3, 4, N=N, K=12)
        for scheme in engine.RESAMPLING:
            got, want = run_both(p, **options(particles, proposal, "sample", scheme, 0.6))
            assert_outputs_equal(got, want)


@pytest.mark.parametrize("proposal", ["prior", "optimal"])
def test_zero_trials_and_zero_samples(proposal):
    for N, K in ((0, 5), (3, 0), (0, 0)):
        p = rbpf_problem(5, 2, 2, 1, 2, 3, N=max(N, 1), K=max(K, 1))
        p = dict(p, y=p["y"][:N, :K], u=p["u"][:N, :K], trans=p["trans"][:K], keys=p["keys"][:N])
        got, want = run_both(p, **options(5, proposal, "sample", "systematic", 0.5))
        assert got.x.shape == want.x.shape == (N, K, 2)
        assert_outputs_equal(got, want)


@pytest.mark.parametrize("proposal", ["prior", "optimal"])
@pytest.mark.parametrize("timing", ["sample", "interval"])
def test_gating_impossible_modes_and_missing_samples(proposal, timing):
    p = rbpf_problem(21, 2, 2, 1, 3, 3, N=3, K=20)
    y = p["y"].copy()
    y[0, 4] = [1e200, -1e200]  # overflows every particle's normalized innovation: gated
    y[1, 6, 0] = 1e200  # one component only
    y[2, 9] = np.nan  # nothing observed: no reweighting
    prob0 = np.array([0.0, 0.4, 0.6])  # an impossible first mode
    for scheme in engine.RESAMPLING:
        got, want = run_both(dict(p, y=y, prob0=prob0),
                             **options(11, proposal, timing, scheme, 0.5))
        assert want.flag[0, 4] == 1 and want.loglik[2, 9] == 0.0
        assert_outputs_equal(got, want)


@pytest.mark.parametrize("proposal", ["prior", "optimal"])
def test_a_diffuse_prior_takes_the_information_form(proposal):
    p = rbpf_problem(40, 2, 2, 1, 2, 3, N=4, K=10, missing=False)
    got, want = run_both(dict(p, P0=1e300 * np.eye(2)),
                         **options(9, proposal, "sample", "systematic", 0.5))
    assert want.status == 0 and want.repaired == 0
    assert_outputs_equal(got, want)


@pytest.mark.parametrize("proposal", ["prior", "optimal"])
@pytest.mark.parametrize("timing", ["sample", "interval"])
def test_repairs_are_reported_alike(proposal, timing):
    """P0 = 1e300 I with m < n: from sample 1 on, covariances beyond 1/eps are repaired (their
    eigenvalues raised to their rounding level). The results are determined only to that
    rounding (test_compiled_kernels checks them for finiteness only), so they are the same
    here only because both sides take the eigendecomposition from LAPACK's dsyevd (the engine
    binding registers scipy's: use_lapack); without it the draws part ways from sample 1."""
    p = rbpf_problem(42, 3, 2, 1, 2, 3, N=2, K=6, missing=False)
    got, want = run_both(dict(p, P0=1e300 * np.eye(3)),
                         **options(5, proposal, timing, "stratified", 1.0))
    assert want.status == 0 and want.repaired > 0 and want.smallest_eigenvalue < 0.0
    assert_outputs_equal(got, want)
    assert np.all(np.isfinite(got.x)) and np.all(np.diagonal(got.P, axis1=-2, axis2=-1) > 0.0)


@pytest.mark.parametrize("proposal", ["prior", "optimal"])
def test_a_problem_scaled_by_1e50_and_measurements_of_1e300(proposal):
    p = rbpf_problem(9, 3, 2, 1, 2, 3, N=3, K=12)
    s = 2.0**166  # every input scaled exactly
    big = dict(p, y=s * p["y"], G=s * p["G"], Qd=s * s * p["Qd"], R=s * s * p["R"],
               x0=s * p["x0"], P0=s * s * p["P0"])
    d = np.array([2.0**500, 2.0**-500])  # outputs in units 1e150 apart: S of 1e300 and 1e-300
    far = dict(p, y=d * p["y"], C=d[:, None] * p["C"], R=d[:, None] * p["R"] * d)
    for q in (big, far):
        got, want = run_both(q, **options(8, proposal, "interval", "systematic", 0.5))
        assert want.status == 0
        assert_outputs_equal(got, want)


@pytest.mark.parametrize("proposal", ["prior", "optimal"])
def test_failures_are_the_same_status(proposal):
    p = rbpf_problem(12, 2, 2, 0, 1, 1, N=2, K=5, missing=False)
    zero = dict(p, R=np.zeros_like(p["R"]), P0=np.zeros((2, 2)), Qd=np.zeros_like(p["Qd"]))
    got, want = run_both(zero, **options(4, proposal, "sample", "systematic", 0.5))
    assert got.status == want.status == 1  # NOT_POSITIVE_DEFINITE
    huge = dict(p, F=1e200 * np.ones_like(p["F"]))  # P overflows: S not finite
    got, want = run_both(huge, **options(4, proposal, "interval", "systematic", 0.5))
    assert got.status == want.status == 2


# ------------------------------------------------------------------ streaming
def random_state(rng, N, Np, n, L):
    x = rng.standard_normal((N, Np, n))
    W = rng.standard_normal((N, Np, n, n))
    P = W @ np.swapaxes(W, -1, -2) / n + 0.2 * np.eye(n)
    mode = rng.integers(0, L, (N, Np))
    logw = rng.standard_normal((N, Np))
    logw -= np.log(np.exp(logw).sum(axis=1, keepdims=True))
    return x, P, mode, logw


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("proposal", ["prior", "optimal"])
@pytest.mark.parametrize("timing", ["sample", "interval"])
def test_step_matches_numba_from_any_state(case, proposal, timing):
    n, m, l, L, M = case
    p = rbpf_problem(sum(case), *case, N=5, K=6)
    rng = np.random.default_rng(3)
    for Np in (1, 6, 19):
        for scheme, threshold in (("systematic", 0.9), ("stratified", 0.3), ("multinomial", 1.0)):
            state = random_state(rng, 5, Np, n, L)
            for k in range(4):
                args = (p["y"][:, k], p["u"][:, k], p["F"], p["G"], p["Qd"], p["trans"][k],
                        p["C"], p["R"], p["transition"], p["prob0"], p["keys"], 17 + k)
                kw = dict(predict_first=k > 0, **options(Np, proposal, timing, scheme,
                                                         threshold))
                kw.pop("particles")
                got, got_state = engine.rbpf_step(*state, *args, **kw)
                want, want_state = reference.rbpf_step(*state, *args, **kw)
                assert_outputs_equal(got, want)
                for name, a, b in zip(("x_last", "P_last", "mode_last", "logw_last"),
                                      got_state, want_state):
                    if a.dtype == np.int64:
                        np.testing.assert_array_equal(a, b, err_msg=name)
                    else:
                        assert_same(a, b, name)
                state = want_state


@pytest.mark.parametrize("proposal", ["prior", "optimal"])
def test_stepping_reproduces_the_run(proposal):
    p = rbpf_problem(8, 2, 2, 1, 2, 3, N=3, K=8)
    opts = options(10, proposal, "sample", "multinomial", 0.5)
    whole = engine.rbpf_run(*[p[key] for key in ORDER], **opts)
    Np = opts.pop("particles")
    state = (np.tile(p["x0"], (3, Np, 1)), np.tile(p["P0"], (3, Np, 1, 1)),
             np.zeros((3, Np), dtype=np.int64), np.full((3, Np), -np.log(Np)))
    for k in range(8):
        out, state = engine.rbpf_step(*state, p["y"][:, k], p["u"][:, max(k - 1, 0)], p["F"],
                                      p["G"], p["Qd"], p["trans"][k], p["C"], p["R"],
                                      p["transition"], p["prob0"], p["keys"], k,
                                      predict_first=k > 0, **opts)
        for name in FLOATS + ("mode", "flag"):
            np.testing.assert_array_equal(getattr(out, name)[:, 0], getattr(whole, name)[:, k])


def test_a_step_of_no_trials():
    p = rbpf_problem(8, 2, 2, 1, 2, 3, N=1, K=2)
    state = tuple(a[:0] for a in random_state(np.random.default_rng(0), 1, 4, 2, 2))
    out, after = engine.rbpf_step(*state, p["y"][:0, 0], p["u"][:0, 0], p["F"], p["G"], p["Qd"],
                                  p["trans"][1], p["C"], p["R"], p["transition"], p["prob0"],
                                  p["keys"][:0], 1, predict_first=True, sample_timing=True,
                                  optimal=True, scheme=0, threshold=0.5)
    assert out.status == 0 and out.x.shape == (0, 1, 2) and after[0].shape == (0, 4, 2)


def test_the_binding_refuses_inconsistent_arrays():
    p = rbpf_problem(8, 2, 2, 1, 2, 3, N=2, K=3)
    out = engine.rbpf_run(*[p[key] for key in ORDER], particles=3, sample_timing=True,
                          optimal=False, scheme=0, threshold=0.5)
    assert out.status == 0
    with pytest.raises(ValueError, match="keys must have shape"):
        engine.rbpf_run(*[p[key] for key in ORDER[:-1]], p["keys"][:1], particles=3,
                        sample_timing=True, optimal=False, scheme=0, threshold=0.5)


def test_zz_largest_relative_difference():
    print("\nlargest relative difference per array (engine vs numba):",
          {k: float(f"{v:.3g}") for k, v in sorted(LARGEST.items())})
