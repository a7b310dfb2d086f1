"""The C engine's Kim smoother (switchest.engine.smoother) against the numba kernel it replaces
(switchest.estimators._compiled.smoother), on many cases.

Both run the same equations in the same order, so every float output must agree to
ATOL = 1e-12 relative to the largest entry of the numba array (NaN where numba's is NaN, the
same infinities); integer outputs (mode, status, repaired) exactly. Cases: 1..3 modes,
n = 1..4 states, l = 0..2 inputs; both timings; lagged outputs (interval timing, or one mode)
and modes_out off; filtered posteriors of the numba IMM / GPB1 with missing components and
samples, and with a tight gate (gated and partly gated samples); random posteriors with
impossible transitions (log pi = -inf), modes of probability zero (log mu = -inf) in some
lanes or all; per-trial and shared transition tables; singular predicted covariances
(Qd = 0 with a singular F: the Joseph redo, repaired) in some lanes of a block, in every lane,
and conditional covariances that lose their digits (Qd = 0, F invertible: information form or
repair); ill-conditioned and badly scaled covariances, indefinite filtered covariances; the
failure statuses; lane blocks of 1, 3, 5, 16, 64 trials (and one wider than the trials) with
trial counts that are not a multiple of the block, split over two threads; zero trials, one
sample, zero samples, zero modes or states; a pair weight that underflows in the lagged moments
(numba's NaN, kept); and the covariance screen (screen_psd). Observed: the same bits everywhere
(se_repair calls the same LAPACK dsyevd as numpy.linalg.eigh).

The file is deleted with the numba code (the engine's own tests take over); the largest
relative difference seen is printed with ``-s``.
"""

import math

import numpy as np
import pytest

from switchest.engine import smoother as eng
from switchest.estimators._compiled import imm_run
from switchest.estimators._compiled import smoother as ref
from switchest.estimators._compiled.linalg import NOT_FINITE, NOT_POSITIVE_DEFINITE, OK

ATOL = 1e-12
WORST: dict[str, float] = {}
FLOATS = ("x", "P", "mode_prob", "x_modes", "P_modes")
LAGGED = ("pair_prob", "lag_x", "lag_P", "lag_cross")
TIMINGS = ("sample", "interval")


@pytest.fixture(scope="module", autouse=True)
def print_worst():
    yield
    print("\nlargest relative difference, engine vs numba smoother:")
    for name, rel in sorted(WORST.items()):
        print(f"  {name:20s} {rel:.3g}")


def close(name, actual, expected, scale=0.0):
    """``|actual - expected| <= ATOL max(max|expected|, scale)`` over the finite entries; NaN
    and the infinities where ``expected`` has them. Records the largest relative difference."""
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    assert actual.shape == expected.shape, name
    finite = np.isfinite(expected)
    np.testing.assert_array_equal(np.isnan(actual), np.isnan(expected), err_msg=name)
    np.testing.assert_array_equal(actual[~finite & ~np.isnan(expected)],
                                  expected[~finite & ~np.isnan(expected)], err_msg=name)
    if not finite.any():
        return
    scale = max(np.abs(expected[finite]).max(), scale)
    diff = np.abs(actual[finite] - expected[finite]).max()
    rel = diff / scale if scale > 0 else diff
    WORST[name] = max(WORST.get(name, 0.0), float(rel))
    assert diff <= ATOL * scale, f"{name}: {rel:.3g} relative to its largest entry"


def same(out, expected, lagged=False, modes_out=True, size=0.0):
    """Every output of two KimOutputs (outputs only where the status is OK: np.empty else);
    the smallest eigenvalue of a repaired covariance to ATOL relative to ``size``, the
    covariances' largest entry (an eigenvalue is accurate to the rounding of the matrix's
    norm, not of itself)."""
    assert type(out).__name__ == "KimOutput" and out._fields == expected._fields
    assert out.status == expected.status
    assert out.repaired == expected.repaired
    if expected.repaired:
        close("smallest_eigenvalue", out.smallest_eigenvalue, expected.smallest_eigenvalue,
              size)
    else:
        assert out.smallest_eigenvalue == expected.smallest_eigenvalue == math.inf
    if expected.status != OK:
        return
    for name in FLOATS if modes_out else FLOATS[:3]:
        close(name, getattr(out, name), getattr(expected, name))
        if not expected.repaired:  # recorded: the same operations, the same bits expected
            close(name + " (no repair)", getattr(out, name), getattr(expected, name))
    if not modes_out:
        assert out.x_modes is None and out.P_modes is None
    assert out.mode.dtype == np.int64
    np.testing.assert_array_equal(out.mode, expected.mode)
    for name in LAGGED:
        if lagged:
            close(name, getattr(out, name), getattr(expected, name))
            if not expected.repaired:
                close(name + " (no repair)", getattr(out, name), getattr(expected, name))
        else:
            assert getattr(out, name) is None and getattr(expected, name) is None


def both(args, **options):
    """The engine's and numba's kim_smooth of the same arguments, compared; the engine's."""
    out = eng.kim_smooth(*args, **options)
    expected = ref.kim_smooth(*args, **options)
    with np.errstate(invalid="ignore"):
        size = float(np.nanmax(np.abs(args[1]), initial=0.0))
    same(out, expected, options.get("lagged", False), options.get("modes_out", True), size)
    return out, expected


def spd(rng, shape, n, floor=0.1):
    V = rng.standard_normal((*shape, n, n))
    return V @ np.swapaxes(V, -1, -2) / n + floor * np.eye(n)


def log(a):
    with np.errstate(divide="ignore"):
        return np.log(a)


def transition_matrix(rng, L, impossible=True):
    T = rng.dirichlet(np.ones(L), size=L) + 2.0 * np.eye(L)
    if impossible and L == 3:
        T[0, 2] = 0.0  # an impossible switch
        T[2, 1] = 0.0
    return T / T.sum(axis=1, keepdims=True)


def table(rng, n, l, M, singular=0, lost=0):
    """Random transitions ``F, G, Qd (M, ...)``; entry 0 with ``singular`` a reset (Qd = 0, F
    with a zero row: P_pred singular), entry 1 with ``lost`` Qd = 0 and F invertible."""
    W = rng.standard_normal((M, n, n))
    radius = np.abs(np.linalg.eigvals(W)).max(axis=-1)
    F = 0.95 * W / np.maximum(radius, 1.0)[:, None, None]
    G = rng.standard_normal((M, n, l))
    V = rng.standard_normal((M, n, max(n - 1, 1)))
    Qd = 0.2 * V @ np.swapaxes(V, -1, -2) + 1e-3 * np.eye(n)
    if singular:
        F[0, -1] = 0.0
        Qd[0] = 0.0
    if lost and M > 1:
        F[1] = 0.9 * np.eye(n) + 0.05 * np.triu(np.ones((n, n)), 1)
        Qd[1] = 0.0
    return F, G, Qd


def imm_case(seed, n, m, l, L, M, N=7, K=20, gate=math.inf, timing="interval",
             interaction="mix", per_trial=False):
    """The numba IMM's (or GPB1's) filtered mode-matched posteriors of a random switched system
    with NaN holes: the arguments of ``kim_smooth``."""
    rng = np.random.default_rng(seed)
    F, G, Qd = table(rng, n, l, M)
    C = rng.standard_normal((L, m, n))
    R = spd(rng, (L,), m)
    trans = rng.integers(0, M, (K, L))
    u = rng.standard_normal((N, K, l))
    y = 2.0 * rng.standard_normal((N, K, m))
    y[rng.random((N, K, m)) < 0.15] = np.nan
    y[rng.random((N, K)) < 0.1] = np.nan
    y[rng.random((N, K)) < 0.05] *= 50.0  # outliers for the gate
    T = transition_matrix(rng, L)
    out = imm_run(y, u, F, G, Qd, trans, C, R, log(T), rng.standard_normal(n), spd(rng, (), n, 0.5),
                  log(rng.dirichlet(np.ones(L))), gate=gate, timing=timing,
                  interaction=interaction, modes_out=True)
    assert out.status == OK
    if per_trial:
        trans = rng.integers(0, M, (N, K, L))
    else:
        trans = trans[None]
    return [out.x_modes, out.P_modes, log(out.mode_prob), u, F, G, Qd, trans, log(T)], out.flag


def random_case(seed, n, l, L, M, N=9, K=8, zero_modes=True, singular=0, lost=0,
                per_trial=True, cond=None, scale=1.0, indefinite=False):
    """Random filtered posteriors and tables: the arguments of ``kim_smooth``. ``zero_modes``:
    log mu = -inf for some modes in some lanes (and for a mode in every lane of a sample);
    ``cond``: covariances of that condition number; ``scale``: all covariances scaled."""
    rng = np.random.default_rng(seed)
    x = scale ** 0.5 * rng.standard_normal((N, K, L, n))
    if cond is None:
        P = spd(rng, (N, K, L), n, 0.2)
    else:
        Q = np.linalg.qr(rng.standard_normal((N, K, L, n, n)))[0]
        ev = np.geomspace(1.0, 1.0 / cond, n)
        P = (Q * ev) @ np.swapaxes(Q, -1, -2)
        P = 0.5 * (P + np.swapaxes(P, -1, -2))
    P = scale * P
    if indefinite:
        P[rng.random((N, K, L)) < 0.2] -= 0.5 * scale * np.eye(n)
    prob = rng.dirichlet(np.ones(L), (N, K))
    lp = log(prob)
    if zero_modes and L > 1:
        mask = rng.random((N, K, L)) < 0.2
        mask[..., 0] &= ~mask[..., 1:].all(axis=-1)  # keep one mode possible
        mask[:, :, -1] &= ~mask[:, :, :-1].all(axis=-1)
        lp[mask] = -np.inf
        lp[:, K // 2, 0] = -np.inf  # a mode impossible in every lane of a sample
        lp[:, K // 2, 1:] = log(rng.dirichlet(np.ones(L - 1), N))
    F, G, Qd = table(rng, n, l, M, singular, lost)
    if per_trial:
        trans = rng.integers(0, M, (N, K, L))
    else:
        trans = rng.integers(0, M, (1, K, L))
    return [x, P, lp, rng.standard_normal((N, K, l)), F, G, Qd, trans,
            log(transition_matrix(rng, L))]


# --------------------------------------------------------------------- filtered by the IMM
# (n, m, l, L, M)
IMM_CASES = [(1, 1, 0, 1, 1), (2, 3, 1, 2, 3), (4, 2, 2, 3, 4), (3, 1, 1, 3, 2), (4, 3, 0, 2, 5),
             (2, 1, 1, 1, 2)]


@pytest.mark.parametrize("timing", TIMINGS)
@pytest.mark.parametrize("case", IMM_CASES, ids=str)
def test_imm_posteriors(case, timing):
    args, _ = imm_case(sum(case), *case, timing=timing)
    both(args, timing=timing)
    both(args, timing=timing, lanes=3)
    both(args, timing=timing, modes_out=False)
    if timing == "interval" or case[3] == 1:
        both(args, timing=timing, lagged=True)
        both(args, timing=timing, lagged=True, lanes=5, modes_out=False)


@pytest.mark.parametrize("timing", TIMINGS)
@pytest.mark.parametrize("case", IMM_CASES[1:4], ids=str)
def test_gated_gpb1_and_per_trial_tables(case, timing):
    args, flag = imm_case(7 + sum(case), *case, gate=3.0, timing=timing,
                          interaction="collapse", per_trial=True, N=11)
    assert (flag == 1).any() or (flag == 2).any()  # gated samples in the filter
    for lanes in (1, 4, 64):
        both(args, timing=timing, lanes=lanes)
    both(args, timing="interval", lagged=True, lanes=4)


# --------------------------------------------------------------------- random posteriors
@pytest.mark.parametrize("timing", TIMINGS)
@pytest.mark.parametrize("n, l, L, M", [(1, 0, 1, 1), (1, 1, 2, 3), (2, 1, 2, 4), (3, 2, 3, 5),
                                        (4, 0, 3, 3), (4, 1, 2, 2)], ids=str)
@pytest.mark.parametrize("lanes", [1, 3, 5, 16, 64])
def test_random_posteriors_impossible_transitions_and_modes(n, l, L, M, lanes, timing):
    args = random_case(n + 10 * L + M, n, l, L, M, N=13)
    both(args, timing=timing, lanes=lanes)
    if timing == "interval" or L == 1:
        both(args, timing=timing, lanes=lanes, lagged=True)
    shared = random_case(n + 10 * L + M + 1, n, l, L, M, N=13, per_trial=False)
    both(shared, timing=timing, lanes=lanes)


@pytest.mark.parametrize("timing", TIMINGS)
@pytest.mark.parametrize("n, L", [(1, 1), (2, 2), (3, 3), (4, 2)], ids=str)
@pytest.mark.parametrize("lanes", [1, 3, 16])
def test_singular_predictions_redone_in_some_lanes(n, L, lanes, timing):
    """Entry 0 a reset with Qd = 0 (P_pred singular, repaired in Joseph's form), entry 1 with
    Qd = 0 and F invertible (the conditional loses its digits), drawn per trial and step."""
    args = random_case(3 * n + L, n, 1, L, 4, N=11, K=7, singular=1, lost=1)
    out, expected = both(args, timing=timing, lanes=lanes)
    # n = 1: the reset is F = 0, Qd = 0, P_pred = 0 exactly, beyond repair (status 1)
    assert expected.repaired > 0 or (n == 1 and expected.status == NOT_POSITIVE_DEFINITE)
    if timing == "interval" or L == 1:
        both(args, timing=timing, lanes=lanes, lagged=True)


@pytest.mark.parametrize("timing", TIMINGS)
def test_every_prediction_singular(timing):
    """Every mode's transition a reset with Qd = 0: every lane redone, every P_pred repaired."""
    args = random_case(5, 2, 1, 2, 2, N=6, K=6, zero_modes=False, per_trial=False)
    F, Qd = args[4], args[6]
    F[:, -1] = 0.0
    Qd[:] = 0.0
    out, expected = both(args, timing=timing, lanes=4)
    assert expected.repaired > 0


@pytest.mark.parametrize("timing", TIMINGS)
@pytest.mark.parametrize("cond, scale", [(1e8, 1.0), (1e13, 1.0), (1e15, 1e-3), (1e3, 1e150),
                                         (1e3, 1e-150), (1e10, 1e40)], ids=str)
def test_ill_conditioned_and_badly_scaled_covariances(cond, scale, timing):
    args = random_case(int(math.log10(cond)), 3, 1, 2, 3, N=7, K=6, cond=cond, scale=scale,
                       lost=1)
    args[6] = args[6] * scale  # the process noise at the covariances' scale
    both(args, timing=timing, lanes=3)
    both(args, timing="interval", lanes=3, lagged=True)


@pytest.mark.parametrize("timing", TIMINGS)
def test_covariances_indefinite_at_rounding_level(timing):
    """Filtered covariances with an eigenvalue of -1e-13 max|P| (within the -1e-12 the package's
    check admits) and reset states without noise: most predictions are repaired (se_repair's
    eigendecomposition, LAPACK's dsyevd on both sides). The smoothed moments are sensitive to
    its rounding here (numba's own output moves by up to 1.2e-11 of its largest entry when P_f
    moves by one ulp), so this holds only with the same eigensolver."""
    rng = np.random.default_rng(23)
    args = random_case(23, 3, 1, 3, 4, N=10, K=6, zero_modes=False, per_trial=False)
    P = args[1]
    w, V = np.linalg.eigh(P)
    pick = rng.random(P.shape[:3]) < 0.3
    w[pick, 0] = -1e-13 * np.abs(w[pick]).max(axis=-1)
    P = (V * w[..., None, :]) @ np.swapaxes(V, -1, -2)
    args[1] = 0.5 * (P + np.swapaxes(P, -1, -2))
    args[4][:, -1] = 0.0  # reset states, no noise: P_pred as singular as P
    args[6][:] = 0.0
    _, expected = both(args, timing=timing, lanes=4)
    assert expected.repaired > 0
    both(args, timing="interval", lanes=4, lagged=True)


@pytest.mark.parametrize("timing", TIMINGS)
def test_strongly_indefinite_covariances(timing):
    """Filtered covariances with eigenvalues of -0.5 (which the package refuses): the repaired
    P_pred has an eigenvalue at its rounding level along a direction P_j F' does not vanish
    in, so J and the smoothed moments are of order 1/eps (1e13 after one step, 1e28 after five)
    and depend on the rounding of the repair's eigenvectors: numba's own output moves by 3 %
    when P_f moves by one ulp. The same operations and eigensolver give the same numbers."""
    for K in (2, 6):
        args = random_case(17, 3, 1, 3, 4, N=10, K=K, indefinite=True)
        _, expected = both(args, timing=timing, lanes=4)
        assert expected.repaired > 0


def test_an_underflowing_pair_weight_in_the_lagged_moments():
    """A finite log-probability of -800 gives a pair weight exp(.) = 0 ahead of the others in
    the lagged accumulation: numba's West update divides 0 by 0 there (NaN in lag_x, lag_P);
    the engine must give the same numbers (reported, not fixed)."""
    args = random_case(3, 2, 0, 2, 2, N=3, K=4, zero_modes=False)
    args[2][0, 1, 0] = -800.0
    _, expected = both(args, lagged=True)
    assert np.isnan(expected.lag_x).any()


# --------------------------------------------------------------------- statuses, sizes
@pytest.mark.parametrize("timing", TIMINGS)
def test_failure_statuses(timing):
    args = random_case(8, 2, 1, 2, 3, N=5, K=5, zero_modes=False)
    big = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
    big[1][2, 2] *= 1e308  # P_pred overflows: not finite
    big[4][:] *= 10.0
    out, _ = both(big, timing=timing, lanes=2)
    assert out.status == NOT_FINITE
    nan = [a.copy() for a in args]
    nan[1][3, 1, 0, 0, 0] = np.nan
    out, _ = both(nan, timing=timing)
    assert out.status == NOT_FINITE
    one = random_case(9, 1, 0, 1, 1, N=3, K=4)  # n = 1: a NaN prediction fails its repair
    one[1][1, 2] = np.nan
    one[4][:] = 0.0
    one[6][:] = 0.0
    out, _ = both(one, timing=timing)
    assert out.status in (NOT_FINITE, NOT_POSITIVE_DEFINITE)


@pytest.mark.parametrize("timing", TIMINGS)
def test_zero_trials_one_sample_one_state(timing):
    for N, K in ((0, 5), (0, 1), (3, 1), (1, 2), (65, 3)):
        args = random_case(N + K, 1, 0, 2, 2, N=max(N, 1), K=K, zero_modes=False)
        args = [a[:N] if i < 4 else a for i, a in enumerate(args)]
        if args[7].shape[0] != 1:
            args[7] = args[7][:N] if N else args[7][:1]
        both(args, timing=timing)
        both(args, timing="interval", lagged=True, lanes=7)
        both(args, timing=timing, modes_out=False)


def test_zero_samples():
    """K = 0: nothing to smooth (numba corrupts the heap for N > 0 here, so only the engine
    runs: OK with empty outputs; with N = 0 both). Lagged, both wrappers fail allocating
    K - 1 = -1 intervals (numpy's ValueError)."""
    for N in (0, 4):
        args = [np.zeros((N, 0, 2, 2)), np.zeros((N, 0, 2, 2, 2)), np.zeros((N, 0, 2)),
                np.zeros((N, 0, 1)), np.zeros((1, 2, 2)), np.zeros((1, 2, 1)),
                np.zeros((1, 2, 2)), np.zeros((1, 0, 2), dtype=np.int64), np.zeros((2, 2))]
        out = eng.kim_smooth(*args)
        assert out.status == OK and out.x.shape == (N, 0, 2) and out.repaired == 0
        assert out.P_modes.shape == (N, 0, 2, 2, 2)
        with pytest.raises(ValueError, match="negative dimensions"):  # K - 1 intervals: both
            eng.kim_smooth(*args, lagged=True)
        if N == 0:
            both(args)


@pytest.mark.parametrize("N, K, L, n, l", [(3, 4, 0, 2, 1), (3, 4, 2, 0, 1), (3, 4, 1, 0, 0)],
                         ids=str)
def test_zero_modes_or_states(N, K, L, n, l):
    args = [np.zeros((N, K, L, n)), np.zeros((N, K, L, n, n)), np.zeros((N, K, L)),
            np.zeros((N, K, l)), np.zeros((1, n, n)), np.zeros((1, n, l)), np.zeros((1, n, n)),
            np.zeros((1, K, L), dtype=np.int64), np.zeros((L, L))]
    both(args)
    both(args, lagged=True)


def test_a_block_wider_than_the_trials():
    """The engine's lane stride is min(lanes, N): the same numbers, no scratch for lanes no
    trial fills (numba allocates them all, and fails for lanes = 2**50)."""
    args = random_case(1, 2, 1, 2, 3, N=3, K=4)
    out = eng.kim_smooth(*args, lanes=2**62, lagged=True)
    same(out, ref.kim_smooth(*args, lagged=True), lagged=True)


@pytest.mark.parametrize("timing", TIMINGS)
def test_trials_split_over_threads(timing):
    """Two threads over whole lane blocks (switchest.engine.set_threads): the same numbers, the
    repairs summed over the threads' ranges."""
    from switchest.engine import _parallel, set_threads
    before = _parallel._setting  # None: the default
    set_threads(2)
    try:
        args = random_case(31, 2, 1, 2, 4, N=203, K=200, singular=1, lost=1)
        for options in ({"timing": timing}, {"timing": "interval", "lagged": True},
                        {"timing": timing, "lanes": 16, "modes_out": False}):
            _, expected = both(args, **options)
            assert expected.repaired > 0
    finally:
        set_threads(before)


def test_the_same_errors_for_bad_arguments():
    args = random_case(1, 2, 1, 2, 3, N=3, K=4)
    for bad, match in (({"timing": "x"}, "timing"), ({"lanes": 0}, "lanes"),
                       ({"timing": "sample", "lagged": True}, "lagged moments")):
        for mod in (eng, ref):
            with pytest.raises((ValueError, TypeError), match=match):
                mod.kim_smooth(*args, **bad)
    wrong = list(args)
    wrong[7] = args[7][:2]
    for mod in (eng, ref):
        with pytest.raises(ValueError, match="trans must have shape"):
            mod.kim_smooth(*wrong)
    assert eng.LANES == ref.LANES and eng.__all__ == ref.__all__


def test_the_binding_refuses_arrays_that_disagree():
    """The binding re-checks the shapes the wrapper allocated (no out-of-bounds writes)."""
    args = random_case(2, 2, 1, 2, 3, N=3, K=4)
    N, K, L, n = args[0].shape
    outs = [np.empty((N, K, n)), np.empty((N, K, n, n)), np.empty((N, K, L)),
            np.empty((N, K), dtype=np.int64), np.empty((N, K, L, n)), np.empty((N, K, L, n, n)),
            np.empty(2), False, np.zeros((N, 0, L, L)), np.zeros((N, 0, L, n)),
            np.zeros((N, 0, L, n, n)), np.zeros((N, 0, L, n, n))]
    assert eng.kim_backward(*args, 4, False, *outs) == OK
    short = list(outs)
    short[1] = np.empty((N, K, n, n - 1))
    with pytest.raises(ValueError):
        eng.kim_backward(*args, 4, False, *short)
    lag = list(outs)
    lag[7] = True  # lagged with no interval axis
    with pytest.raises(ValueError):
        eng.kim_backward(*args, 4, False, *lag)


# --------------------------------------------------------------------- screen_psd
@pytest.mark.parametrize("n", [1, 2, 3, 5, 33])
def test_screen_psd(n):
    rng = np.random.default_rng(n)
    M = 40
    A = spd(rng, (M,), n, 0.0)
    A[::3] -= 0.3 * np.eye(n)  # indefinite
    A[1::5] *= 1e-300
    A[2] = 0.0  # zero: passes with the shift
    A[4, 0, -1] += 1e-9  # asymmetric
    A[7] = np.outer(np.arange(n), np.arange(n))  # semidefinite, rank one
    for shift in (0.0, 0.5e-12, 1e-6):
        results = []
        for mod in (eng, ref):
            sym, failed = np.empty_like(A), np.ones(M, dtype=np.bool_)
            results.append((mod.screen_psd(A, shift, sym, failed), sym, failed))
        (s_e, sym_e, f_e), (s_r, sym_r, f_r) = results
        assert s_e == s_r
        np.testing.assert_array_equal(sym_e, sym_r)
        np.testing.assert_array_equal(f_e, f_r)
    readonly = A.copy()
    readonly.flags.writeable = False
    sym, failed = np.empty_like(A), np.empty(M, dtype=np.bool_)
    assert eng.screen_psd(readonly, 1e-6, sym, failed) == s_r  # the last shift, 1e-6
    np.testing.assert_array_equal(sym, sym_r)
    np.testing.assert_array_equal(failed, f_r)
    empty = np.empty((0, n, n))
    assert eng.screen_psd(empty, 1e-6, empty.copy(), np.empty(0, bool)) == \
        ref.screen_psd(empty, 1e-6, empty.copy(), np.empty(0, bool))
