"""Kim's fixed-interval smoother (compiled) against its numpy oracle (smoother_oracle.py).

Tolerance: every float output equals the oracle to RTOL = 1e-9 relative to the largest entry
of the oracle's array, the contract of the compiled kernels (test_compiled_kernels.py). The
two sides compute the same quantities by different algebra (the kernel: Joseph's form of a
pseudo-measurement update plus ``J P_s J'``, equilibrated Cholesky loops; the oracle:
``P + J (P_s - P_pred) J'`` with LAPACK), each backward stable, on predicted covariances of
condition number below 1e4 over <= 12 steps: observed agreement is ~1e-15.
"""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy_oracle import kalman_run as oracle_kalman_run
from smoother_oracle import (
    imm_modes,
    kim_smooth,
    random_system,
    rts_smooth,
    rts_smooth_pinv,
    tables,
)

from switchest.estimators._compiled.smoother import kim_smooth as compiled_kim_smooth
from switchest.estimators.smoothing import SmoothedModes, smooth_mode_matched

RTOL = 1e-9
TRANSITIONS = {  # asymmetric: a transposed convention would be caught
    2: np.array([[0.85, 0.15], [0.35, 0.65]]),
    3: np.array([[0.80, 0.15, 0.05], [0.10, 0.70, 0.20], [0.30, 0.10, 0.60]]),
}
FIELDS = ("x", "P", "mode_prob", "x_modes", "P_modes")


def assert_close(actual, expected, rtol=RTOL):
    """Entrywise ``|actual - expected| <= rtol * max |expected|``."""
    expected = np.asarray(expected)
    np.testing.assert_allclose(actual, expected, rtol=0.0, atol=rtol * np.abs(expected).max())


def filtered_case(seed, L, N=3, K=12, n=3, m=2, l=1):
    """A continuous-time system at irregular sample times with inputs and missing samples, and
    the numpy IMM's mode-matched posteriors: the smoother's arguments (as a dict) and the
    IMM's combined estimate."""
    rng = np.random.default_rng(seed)
    system = random_system(rng, n, m, l, L)
    t = np.cumsum(np.r_[0.0, rng.choice([0.1, 0.25, 0.4], K - 1)])
    F, G, Qd, trans = tables(system, t)
    y = rng.standard_normal((N, K, m))
    y[0, K // 3] = np.nan  # a missing sample
    y[-1, K // 2, 0] = np.nan  # a missing component
    u = rng.standard_normal((N, K, l))
    transition = TRANSITIONS[L]
    xm, Pm, pm, xc = imm_modes(y, u, F, G, Qd, trans, system.C, system.R, transition,
                               rng.standard_normal(n), np.eye(n), np.full(L, 1.0 / L))
    args = {"x_modes": xm, "P_modes": Pm, "mode_prob": pm, "u": u, "F": F, "G": G, "Qd": Qd,
            "trans": trans, "transition": transition}
    return args, xc


@pytest.mark.parametrize("L", [2, 3])
def test_matches_the_numpy_kim_oracle(L):
    args, _ = filtered_case(L, L)
    ours = smooth_mode_matched(**args)
    ref = kim_smooth(*(args[a] for a in ("x_modes", "P_modes", "mode_prob", "u", "F", "G", "Qd")),
                     args["trans"][None], args["transition"])
    for name, expected in zip(("x", "P", "mode_prob", "mode", "x_modes", "P_modes"), ref):
        if name == "mode":
            np.testing.assert_array_equal(ours.mode, expected)
        else:
            assert_close(getattr(ours, name), expected)
    assert not np.allclose(ours.x[:, :-1], args["x_modes"][:, :-1, 0], atol=1e-3)  # it smooths


def test_per_trial_transitions_match_the_oracle():
    """``trans (N, K, L)``: each trial its own sampling times (the table holds every step)."""
    args, _ = filtered_case(5, 2)
    N, K, L = args["mode_prob"].shape
    rng = np.random.default_rng(6)
    M = args["F"].shape[0]
    trans = np.repeat(args["trans"][None], N, axis=0)
    trans[:, 1:] = rng.integers(0, M // L, (N, K - 1, 1)) * L + np.arange(L)
    args["trans"] = trans
    ours = smooth_mode_matched(**args)
    ref = kim_smooth(*(args[a] for a in ("x_modes", "P_modes", "mode_prob", "u", "F", "G", "Qd",
                                         "trans", "transition")))
    for name, expected in zip(("x", "P", "mode_prob", "mode", "x_modes", "P_modes"), ref):
        assert_close(getattr(ours, name), expected)


def test_one_mode_is_the_rts_smoother():
    """With one mode Kim's recursion is the RTS smoother (Rauch, Tung & Striebel 1965), here
    on a numpy Kalman filter at irregular times with inputs and missing samples."""
    rng = np.random.default_rng(11)
    system = random_system(rng, n=3, m=1, l=2, L=1)
    N, K = 4, 15
    t = np.cumsum(np.r_[0.0, rng.choice([0.05, 0.3], K - 1)])
    F, G, Qd, trans = tables(system, t)
    y, u = rng.standard_normal((N, K, 1)), rng.standard_normal((N, K, 2))
    y[2, 3:6] = np.nan
    tr = np.broadcast_to(trans[:, 0], (N, K))
    x, P, _, _ = oracle_kalman_run(y, u, F, G, Qd, tr, system.C, system.R, np.zeros((N, K), int),
                                   np.zeros(3), 4.0 * np.eye(3))
    ours = smooth_mode_matched(x[:, :, None], P[:, :, None], np.ones((N, K, 1)), u, F, G, Qd,
                               trans, np.ones((1, 1)))
    for i in range(N):
        xs, Ps = rts_smooth(x[i], P[i], u[i], F, G, Qd, trans[:, 0])
        assert_close(ours.x[i], xs)
        assert_close(ours.P[i], Ps)
        assert_close(ours.x_modes[i, :, 0], xs)
    np.testing.assert_array_equal(ours.mode_prob, 1.0)


def test_the_last_sample_is_the_filtered_posterior():
    args, xc = filtered_case(2, 3)
    ours = smooth_mode_matched(**args)
    assert_close(ours.x_modes[:, -1], args["x_modes"][:, -1], rtol=1e-14)
    assert_close(ours.mode_prob[:, -1], args["mode_prob"][:, -1], rtol=1e-14)
    assert_close(ours.x[:, -1], xc[:, -1], rtol=1e-12)


def test_results_do_not_depend_on_the_block_of_lanes():
    args, _ = filtered_case(3, 2, N=7)
    flat = [args[a] for a in ("x_modes", "P_modes")]
    with np.errstate(divide="ignore"):
        log_prob = np.log(args["mode_prob"])
    common = (*flat, log_prob, args["u"], args["F"], args["G"], args["Qd"], args["trans"][None],
              np.log(args["transition"]))
    one = compiled_kim_smooth(*common, lanes=1)
    for lanes in (3, 16):
        other = compiled_kim_smooth(*common, lanes=lanes)
        for name in FIELDS:
            assert_close(getattr(other, name), getattr(one, name), rtol=1e-13)


def test_batch_axes_and_a_single_trial():
    args, _ = filtered_case(4, 2, N=4)
    flat = smooth_mode_matched(**args)
    batched = smooth_mode_matched(**{k: (v.reshape(2, 2, *v.shape[1:])
                                         if k in ("x_modes", "P_modes", "mode_prob", "u") else v)
                                     for k, v in args.items()})
    assert batched.x.shape == (2, 2, *flat.x.shape[1:])
    assert batched.P_modes.shape == (2, 2, *flat.P_modes.shape[1:])
    assert_close(batched.x.reshape(flat.x.shape), flat.x, rtol=1e-14)
    single = smooth_mode_matched(**{k: (v[1] if k in ("x_modes", "P_modes", "mode_prob", "u")
                                        else v) for k, v in args.items()})
    assert single.x.shape == flat.x.shape[1:] and single.mode.shape == flat.mode.shape[1:]
    assert_close(single.P, flat.P[1], rtol=1e-14)


def _kalman_filtered(F, rng, K=6):
    """A one-state-pair Kalman filter with ``Qd = 0`` along ``F`` (one table entry), measured
    through ``C = [1, 0.5]``: its filtered ``x (K, n)``, ``P``."""
    C, R = np.array([[1.0, 0.5]]), np.array([[0.1]])
    zero = np.zeros((1, 2, 2))
    x, P, _, _ = oracle_kalman_run(rng.standard_normal((1, K, 1)), np.zeros((1, K, 1)), F[None],
                                   np.zeros((1, 2, 1)), zero, np.zeros((1, K), int), C[None],
                                   R[None], np.zeros((1, K), int), np.zeros(2), np.eye(2))
    return x[0], P[0]


@pytest.mark.parametrize("F", [
    np.array([[0.9, 0.3], [0.0, 0.0]]),  # a reset state: P_pred has a zero row
    0.5 * np.array([[1.0, 1.0], [1.0, 1.0]]),  # rank one, no zero row
], ids=["zero-row", "rank-one"])
def test_a_singular_predicted_covariance_is_repaired_as_a_pseudo_inverse_would(F):
    """``Qd = 0`` with a singular ``F``: ``P_pred`` is singular. Its repair (eigenvalues raised
    to the rounding level, with a warning) gives the pseudo-inverse smoother: the gain
    vanishes in the directions ``P_pred`` cannot reach."""
    x, P = _kalman_filtered(F, np.random.default_rng(0))
    K = x.shape[0]
    with pytest.warns(RuntimeWarning, match="singular or indefinite"):
        ours = smooth_mode_matched(x[:, None], P[:, None], np.ones((K, 1)), None, F[None],
                                   np.zeros((1, 2, 1)), np.zeros((1, 2, 2)),
                                   np.zeros((K, 1), int), np.ones((1, 1)))
    xs, Ps = rts_smooth_pinv(x, P, np.zeros((K, 1)), F[None], np.zeros((1, 2, 1)),
                             np.zeros((1, 2, 2)), np.zeros(K, int))
    assert_close(ours.x, xs)
    assert_close(ours.P, Ps)
    assert np.linalg.eigvalsh(ours.P).min() >= -1e-12 * np.abs(Ps).max()


def test_no_process_noise_with_an_invertible_transition():
    """``Qd = 0``, ``F`` invertible: ``x_k = F^-1 x_{k+1}`` exactly, so
    ``P_s(k) = F^-1 P_s(k+1) F^-T``; the conditional covariance, zero, has lost its digits in
    Joseph's form and is repaired to stay positive semidefinite."""
    F = np.array([[0.9, 0.2], [-0.1, 0.8]])
    x, P = _kalman_filtered(F, np.random.default_rng(1))
    K = x.shape[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # the repair of a zero covariance
        ours = smooth_mode_matched(x[:, None], P[:, None], np.ones((K, 1)), None, F[None],
                                   np.zeros((1, 2, 1)), np.zeros((1, 2, 2)),
                                   np.zeros((K, 1), int), np.ones((1, 1)))
    Fi = np.linalg.inv(F)
    for k in range(K - 1):
        assert_close(ours.P[k], Fi @ ours.P[k + 1] @ Fi.T)
        assert_close(ours.x[k], Fi @ ours.x[k + 1])
    assert np.linalg.eigvalsh(ours.P).min() >= 0.0


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), L=st.sampled_from([1, 2, 3]))
def test_invariants(seed, L):
    """Smoothed mode probabilities are probabilities; every covariance is symmetric positive
    semidefinite; with one mode the smoothed covariance never exceeds the filtered one
    (RTS: ``P_f - P_s = J (P_pred - P_s(k+1)) J' >= 0``)."""
    rng = np.random.default_rng(seed)
    transition = TRANSITIONS[L] if L > 1 else np.ones((1, 1))
    system = random_system(rng, n=2, m=1, l=1, L=L)
    K, N = 8, 2
    t = np.cumsum(np.r_[0.0, rng.uniform(0.05, 0.5, K - 1)])
    F, G, Qd, trans = tables(system, t)
    y, u = 2.0 * rng.standard_normal((N, K, 1)), rng.standard_normal((N, K, 1))
    xm, Pm, pm, _ = imm_modes(y, u, F, G, Qd, trans, system.C, system.R, transition,
                              np.zeros(2), np.eye(2), np.full(L, 1.0 / L))
    out = smooth_mode_matched(xm, Pm, pm, u, F, G, Qd, trans, transition)
    assert np.all((out.mode_prob >= 0.0) & (out.mode_prob <= 1.0))
    np.testing.assert_allclose(out.mode_prob.sum(axis=-1), 1.0, rtol=1e-12)
    for P in (out.P, out.P_modes):
        np.testing.assert_array_equal(P, np.swapaxes(P, -1, -2))
        scale = np.abs(P).max(axis=(-1, -2), keepdims=True)[..., 0]
        assert np.all(np.linalg.eigvalsh(P) >= -1e-12 * scale)
    if L == 1:
        gap = np.linalg.eigvalsh(Pm[:, :, 0] - out.P)
        assert np.all(gap >= -1e-12 * np.abs(Pm).max())


# ---------------------------------------------------------------------- argument checks
@pytest.mark.parametrize("change, message", [
    (lambda a: {**a, "P_modes": a["P_modes"][..., :1]}, r"P_modes must have shape"),
    (lambda a: {**a, "x_modes": a["x_modes"][0, 0, 0]}, r"x_modes must have shape"),
    (lambda a: {**a, "mode_prob": a["mode_prob"] * 0.9}, r"mode_prob must sum to 1"),
    (lambda a: {**a, "mode_prob": a["mode_prob"][..., :1]}, r"mode_prob must have shape"),
    (lambda a: {**a, "transition": a["transition"].T}, r"transition rows must sum to 1"),
    (lambda a: {**a, "trans": a["trans"] + 100}, r"trans must index the table's 0\.\.\d+"),
    (lambda a: {**a, "trans": a["trans"][1:]}, r"trans must have shape \(K, L\)"),
    (lambda a: {**a, "u": a["u"][:, :, :0]}, r"u must have shape"),
    (lambda a: {**a, "G": a["G"][:1]}, r"G must have shape \(M, n, l\)"),
    (lambda a: {**a, "Qd": a["Qd"] + np.triu(np.ones(3), 1)}, r"Qd must be symmetric"),
    (lambda a: {**a, "x_modes": np.where(np.isnan(a["x_modes"]), 0, np.nan)},
     r"x_modes must be finite"),
    (lambda a: {**a, "trans": a["trans"] * 0.5}, r"trans must hold integers"),
], ids=["P_modes-shape", "x_modes-ndim", "mode_prob-sum", "mode_prob-shape", "transition",
        "trans-range", "trans-shape", "u-shape", "G-shape", "Qd-asymmetric", "x_modes-nan",
        "trans-float"])
def test_bad_arguments_are_refused_with_a_message(change, message):
    args, _ = filtered_case(8, 2, N=2, K=4)
    with pytest.raises((ValueError, TypeError), match=message):
        smooth_mode_matched(**change(args))


def test_the_result_type():
    args, _ = filtered_case(9, 2, N=1, K=4)
    out = smooth_mode_matched(**args)
    assert isinstance(out, SmoothedModes)
    assert out.mode.dtype.kind == "i"


def test_without_the_mode_matched_outputs_the_rest_is_the_same():
    """``modes_out=False`` (what ``ModeBankFilter.smooth`` asks for) saves writing the smoothed
    mode-matched posteriors and changes nothing else."""
    from switchest.estimators.smoothing import smooth_filtered

    args, _ = filtered_case(4, 3)
    full = smooth_mode_matched(**args)
    lean = smooth_filtered(**args, modes_out=False)
    assert lean.x_modes is None and lean.P_modes is None
    for name in ("x", "P", "mode_prob", "mode"):
        np.testing.assert_array_equal(getattr(lean, name), getattr(full, name), err_msg=name)
