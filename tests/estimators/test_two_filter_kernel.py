"""The two-filter smoother's compiled backward pass (``engine/c/two_filter.c``, through
:func:`switchest.engine.two_filter.two_filter_run`) against its numpy oracle
(two_filter_oracle.py), in both timings of the modes, with one, two and three modes (one of
three with an impossible transition), missing samples and components, samples the filter
rejected, per-trial transitions, and blocks of lanes that do not divide the trials.

Tolerance: every output equals the oracle's to RTOL = 1e-10 relative to the largest entry of
the oracle's array. The two sides take the same steps by different routes (the kernel: the
filters' equilibrated Cholesky factor of ``R`` and per-lane LU loops; the oracle: LAPACK's
Cholesky, ``solve`` and ``slogdet``), each backward stable on the well-posed systems
``I + P Omega`` and ``I + Omega Qd`` (eigenvalues >= 1) over <= 12 steps: observed agreement is
~1e-14. The results do not depend on the block size or on the thread count: those comparisons
are exact.
"""

import numpy as np
import pytest
from smoother_oracle import imm_modes, random_system, tables
from two_filter_oracle import two_filter_smooth as oracle_smooth

from switchest._linalg import mixture_moments
from switchest.engine import NOT_FINITE, OK
from switchest.engine.two_filter import two_filter_run
from switchest.estimators import set_threads
from switchest.estimators.two_filter import two_filter_smooth

RTOL = 1e-10
TRANSITIONS = {  # asymmetric: a transposed convention would be caught; L = 3 has a zero
    1: np.ones((1, 1)),
    2: np.array([[0.85, 0.15], [0.35, 0.65]]),
    3: np.array([[0.80, 0.20, 0.00], [0.10, 0.70, 0.20], [0.30, 0.10, 0.60]]),
}
TIMINGS = ("sample", "interval")
FIELDS = ("x_modes", "P_modes", "mode_prob")


def assert_close(actual, expected, rtol=RTOL):
    """Entrywise ``|actual - expected| <= rtol * max |expected|``."""
    expected = np.asarray(expected)
    np.testing.assert_allclose(actual, expected, rtol=0.0, atol=rtol * np.abs(expected).max())


def case(seed, L, N=11, K=12, n=3, m=2, l=1, timing="interval"):
    """A continuous-time system at irregular sample times with inputs, missing samples and
    components, and two samples the filter rejected (wild values, flagged in ``outlier``); the
    numpy IMM's mode-matched posteriors in the ``timing``: the smoother's arguments (a dict)."""
    rng = np.random.default_rng(seed)
    system = random_system(rng, n, m, l, L)
    t = np.cumsum(np.r_[0.0, rng.choice([0.1, 0.25, 0.4], K - 1)])
    F, G, Qd, trans = tables(system, t)
    y = rng.standard_normal((N, K, m))
    y[0, K // 3] = np.nan  # a missing sample
    y[-1, K // 2, 0] = np.nan  # a missing component
    y[1, 4, 1] = np.nan
    u = rng.standard_normal((N, K, l))
    transition = TRANSITIONS[L]
    observed = y.copy()
    outlier = np.zeros((N, K), dtype=bool)
    outlier[2, 5] = outlier[N - 2, K - 3] = True
    observed[outlier] = np.nan  # what the filter saw: nothing where it rejected the sample
    y[outlier] = 1e6
    with np.errstate(divide="ignore"):  # log 0 = -inf: an impossible transition
        xm, Pm, pm, _ = imm_modes(observed, u, F, G, Qd, trans, system.C, system.R, transition,
                                  rng.standard_normal(n), np.eye(n), np.full(L, 1.0 / L),
                                  timing=timing)
    return {"x_modes": xm, "P_modes": Pm, "mode_prob": pm, "y": y, "u": u, "F": F, "G": G,
            "Qd": Qd, "trans": trans[None], "transition": transition, "C": system.C,
            "R": system.R, "outlier": outlier}


def compare(args, timing, lanes):
    """The kernel's output in the ``timing`` and ``lanes``, checked against the oracle's."""
    out = two_filter_run(**args, timing=timing, lanes=lanes)
    assert out.status == OK and out.repaired == 0
    for name, expected in zip(FIELDS, oracle_smooth(**args, timing=timing)):
        assert_close(getattr(out, name), expected)
    x, P = mixture_moments(out.mode_prob[..., None], out.x_modes, out.P_modes)
    assert_close(out.x, x[..., 0, :])  # the combined moments of the smoothed mixture
    assert_close(out.P, P[..., 0, :, :])
    np.testing.assert_array_equal(out.mode, np.argmax(out.mode_prob, axis=-1))
    return out


@pytest.mark.parametrize("timing", TIMINGS)
@pytest.mark.parametrize("L", [1, 2, 3])
def test_matches_the_numpy_oracle(L, timing):
    """In blocks of 1 lane, of 4 (11 trials: two full blocks and a partial one) and of 64 (one
    block wider than the trials), the same numbers to the last bit, within RTOL of the
    oracle's; the smoothed estimates move away from the filtered ones."""
    args = case(L, L, timing=timing)
    outputs = [compare(args, timing, lanes) for lanes in (1, 4, 64)]
    for other in outputs[1:]:
        for name in FIELDS:
            np.testing.assert_array_equal(getattr(other, name), getattr(outputs[0], name))
    assert not np.allclose(outputs[0].x_modes[:, :-1], args["x_modes"][:, :-1], atol=1e-3)
    np.testing.assert_array_equal(outputs[0].x_modes[:, -1], args["x_modes"][:, -1])


@pytest.mark.parametrize("timing", TIMINGS)
def test_a_block_wider_than_64_lanes(timing):
    """A block of 80 lanes: the normalization of the pairs' log-weights works 64 lanes at a
    time (one full pass and one of 16), and the LU's row exchanges blend over every lane of the
    block, some of which pivot and some not; the bits of blocks of 1 lane, within RTOL of the
    oracle."""
    rng = np.random.default_rng(13)
    args = case(13, 3, N=8, timing=timing)
    pick = rng.integers(0, 8, 80)  # 80 trials of the eight records
    big = {name: (value[pick] if name in ("x_modes", "P_modes", "mode_prob", "y", "u",
                                          "outlier") else value)
           for name, value in args.items()}
    wide = compare(big, timing, lanes=80)
    one = two_filter_run(**big, timing=timing, lanes=1)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(wide, name), getattr(one, name))


@pytest.mark.parametrize("timing", TIMINGS)
def test_the_timings_differ_with_several_modes(timing):
    args = case(7, 2, timing=timing)
    other = "interval" if timing == "sample" else "sample"
    ours, theirs = two_filter_run(**args, timing=timing), two_filter_run(**args, timing=other)
    assert not np.allclose(ours.x_modes, theirs.x_modes, atol=1e-3)


@pytest.mark.parametrize("timing", TIMINGS)
def test_per_trial_transitions_match_the_oracle(timing):
    """``trans (N, K, L)``: each trial its own sampling steps (the table holds every step)."""
    args = case(5, 2, timing=timing)
    N, K, L = args["mode_prob"].shape
    rng = np.random.default_rng(6)
    M = args["F"].shape[0]
    trans = np.repeat(args["trans"], N, axis=0)
    trans[:, 1:] = rng.integers(0, M // L, (N, K - 1, 1)) * L + np.arange(L)
    args["trans"] = trans
    shared = two_filter_run(**case(5, 2, timing=timing), timing=timing)
    ours = compare(args, timing, lanes=4)
    assert not np.allclose(ours.x_modes, shared.x_modes, atol=1e-3)  # the table is read


def test_a_rejected_sample_is_missing():
    """The wild values of the samples flagged as outliers are not read: the same bits as with
    those samples NaN and no flags."""
    args = case(9, 2)
    absent = dict(args, y=np.where(args["outlier"][..., None], np.nan, args["y"]),
                  outlier=None)
    flagged, missing = two_filter_run(**args), two_filter_run(**absent)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(flagged, name), getattr(missing, name))


@pytest.mark.parametrize("timing", TIMINGS)
def test_without_the_mode_matched_outputs_the_same_numbers(timing):
    """``modes_out=False`` (what ``IMMFilter.smooth`` asks for): no mode-matched posteriors,
    and the bits of the mode probabilities and of the mixture's moments of a full run."""
    args = case(8, 3, timing=timing)
    full, short = (two_filter_run(**args, timing=timing, lanes=4, modes_out=modes)
                   for modes in (True, False))
    assert short.x_modes is None and short.P_modes is None and short.status == OK
    for name in ("mode_prob", "x", "P", "mode"):
        np.testing.assert_array_equal(getattr(short, name), getattr(full, name))


def test_the_same_numbers_on_one_and_two_threads():
    """A batch split over two threads (whole blocks of lanes each) gives the bits of one."""
    rng = np.random.default_rng(12)
    args = case(12, 3, N=8, K=30)
    N = 1500
    pick = rng.integers(0, 8, N)  # 1500 trials of the eight records, 45000 trial-samples
    big = {name: (value[pick] if name in ("x_modes", "P_modes", "mode_prob", "y", "u",
                                          "outlier") else value)
           for name, value in args.items()}
    try:
        set_threads(1)
        one = two_filter_run(**big, lanes=8)
        set_threads(2)
        two = two_filter_run(**big, lanes=8)
    finally:
        set_threads(None)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name))
    assert_close(one.mode_prob[:8], oracle_smooth(**{
        name: (value[:8] if name in ("x_modes", "P_modes", "mode_prob", "y", "u", "outlier")
               else value) for name, value in big.items()})[2])


def test_a_result_beyond_double_precision_is_refused():
    """Filtered means of 1e200 overflow the evidence (:math:`x^\\top \\Omega x`): the kernel
    stops with ``NOT_FINITE`` and the smoother raises the numpy version's LinAlgError.
    (Covariances of 1e300 need not overflow: :math:`(I + P \\Omega)^{-1} P` stays finite, and
    whether an intermediate does turned on the machine.)"""
    args = case(3, 2)
    args["x_modes"] = args["x_modes"] * 1e200
    assert two_filter_run(**args).status == NOT_FINITE
    with pytest.raises(np.linalg.LinAlgError, match="the two-filter smoother lost its digits"):
        two_filter_smooth(**args, timing="interval")
    with pytest.raises(np.linalg.LinAlgError, match="lost its digits"), \
            np.errstate(over="ignore", invalid="ignore"):  # the overflow it then refuses
        oracle_smooth(**args)


def test_bad_shapes_are_refused():
    args = case(4, 2)
    with pytest.raises(ValueError, match="trans must have shape"):
        two_filter_run(**dict(args, trans=np.repeat(args["trans"], 2, axis=0)))
    with pytest.raises(ValueError, match="outlier must have shape"):
        two_filter_run(**dict(args, outlier=args["outlier"][:, 1:]))
    with pytest.raises(ValueError, match="R must have shape"):
        two_filter_run(**dict(args, R=args["R"][:1]))
