"""Spectral radius, common quadratic Lyapunov functions, JSR bounds, mean-square stability."""

import itertools
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from switchest.analysis import stability
from switchest.analysis._lmi import SolveOutcome
from switchest.analysis.stability import (
    cqlf,
    decrease_margin,
    jsr_bounds,
    ms_stable_iid,
    spectral_radius,
)

EPS = np.finfo(float).eps

REFERENCE = {
    "zhang_example1_A": {
        "provenance": "Zhang & Natarajan (001), Section 5.1, Example 1: A_1, A_2",
        "value": [[[0.9, 0.0], [0.2, 0.8]], [[0.5, 0.2], [0.2, 0.4]]],
        "claim": "A_1 and A_2 share a CQLF (feasible LMIs (13))",
    },
    "gripenberg_pair": {
        "provenance": (
            "Gripenberg (1996), Linear Algebra Appl. 234, Example: A1 = [[3,0],[1,3]]/5, "
            "A2 = [[3,-3],[0,-1]]/5, JSR in [0.6596789, 0.6596924] (issue 4 brief)"
        ),
        "value": [[[0.6, 0.0], [0.2, 0.6]], [[0.6, -0.6], [0.0, -0.2]]],
        "jsr_interval": [0.6596789, 0.6596924],
    },
}

# Two Schur-stable matrices (spectral radius 0.5) whose product has spectral
# radius 4.486: the switched system diverges, so no CQLF can exist.
SCHUR_PAIR_UNSTABLE_PRODUCT = np.array([[[0.5, 2.0], [0.0, 0.5]], [[0.5, 0.0], [2.0, 0.5]]])


# ------------------------------------------------------------------ spectral radius
def test_spectral_radius_is_batched():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(3, 4, 5, 5))
    loop = np.array([[max(abs(np.linalg.eigvals(a))) for a in row] for row in A])
    np.testing.assert_allclose(spectral_radius(A), loop)
    assert spectral_radius(A[0, 0]).shape == ()


def test_spectral_radius_of_rotation_and_jordan():
    th = 0.3
    R = 0.9 * np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    assert spectral_radius(R) == pytest.approx(0.9)
    assert spectral_radius([[0.5, 100.0], [0.0, 0.5]]) == pytest.approx(0.5)


# ------------------------------------------------------------------ CQLF
def test_cqlf_feasible_for_zhang_example1():
    ref = REFERENCE["zhang_example1_A"]
    A = np.array(ref["value"])
    cert = cqlf(A)
    assert cert.holds and cert.solver_status == "optimal"
    # independent re-check of the certificate
    P = cert.P
    np.testing.assert_allclose(P, P.T)
    assert np.linalg.eigvalsh(P)[0] == pytest.approx(1.0)
    worst = max(np.linalg.eigvalsh(a.T @ P @ a - P)[-1] for a in A)
    assert cert.margin == pytest.approx(-worst)
    assert cert.margin >= 0.5e-6


def test_schur_pair_with_unstable_product_is_infeasible():
    A = SCHUR_PAIR_UNSTABLE_PRODUCT
    assert np.all(spectral_radius(A) < 1)
    assert spectral_radius(A[0] @ A[1]) > 1  # so the JSR exceeds 1: no CQLF exists
    cert = cqlf(A)
    assert not cert.holds
    assert cert.P is None and np.isnan(cert.margin)
    assert "not a proof of instability" in cert.note


def test_continuous_cqlf_feasible_and_infeasible():
    # two Hurwitz matrices sharing V = x'x (both have negative definite symmetric parts)
    ok = np.array([[[-1.0, 0.5], [-0.5, -2.0]], [[-3.0, 1.0], [0.0, -1.0]]])
    cert = cqlf(ok, "continuous")
    assert cert.holds
    assert decrease_margin(ok, cert.P, domain="continuous") == pytest.approx(cert.margin)
    # Hurwitz pair whose average [[-1, 5], [5, -1]] has eigenvalue 4: a CQLF of the
    # pair would be one of every convex combination, so none exists
    bad = np.array([[[-1.0, 10.0], [0.0, -1.0]], [[-1.0, 0.0], [10.0, -1.0]]])
    assert np.all(np.linalg.eigvals(bad).real < 0)
    assert max(np.linalg.eigvals(bad.mean(axis=0)).real) > 0
    assert not cqlf(bad, "continuous").holds


def test_a_solver_claim_is_not_trusted_without_the_numpy_check(monkeypatch):
    # Make the "solver" report optimal with P = I for a family that has no CQLF:
    # the numpy re-verification must refuse it.
    def fake_solve(problem, **_):
        (P,) = problem.variables()
        P.value = np.eye(2)
        return SolveOutcome("optimal", "CLARABEL", True)

    monkeypatch.setattr(stability, "solve_sdp", fake_solve)
    cert = cqlf(SCHUR_PAIR_UNSTABLE_PRODUCT)
    assert not cert.holds
    assert cert.solver_status == "optimal"
    assert "failed the numpy check" in cert.note


def test_single_matrix_family_and_margin_scaling():
    A = np.array([[0.5, 0.1], [0.0, 0.2]])
    cert = cqlf(A, margin=1e-3)
    assert cert.holds and cert.margin >= 0.5e-3


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        ({"matrices": np.ones((2, 2, 3))}, ValueError, "non-empty square"),
        ({"matrices": np.ones(3)}, ValueError, "matrices must have 2 to 3 dimensions"),
        ({"matrices": np.eye(2), "domain": "hybrid"}, ValueError, "domain must be 'discrete'"),
        ({"matrices": np.eye(2), "margin": 0.0}, ValueError, "margin must be a finite positive"),
        ({"matrices": [[np.nan, 0], [0, 1]]}, ValueError, "matrices must be finite"),
    ],
)
def test_cqlf_rejects_bad_input(kwargs, exc, match):
    with pytest.raises(exc, match=match):
        cqlf(**kwargs)


# ------------------------------------------------------------------ JSR
def test_jsr_brackets_gripenberg_pair_within_one_percent():
    ref = REFERENCE["gripenberg_pair"]
    lo_ref, hi_ref = ref["jsr_interval"]
    start = time.perf_counter()
    b = jsr_bounds(np.array(ref["value"]))
    elapsed = time.perf_counter() - start
    assert b.lower <= hi_ref and b.upper >= lo_ref  # a valid bracket of the true value
    assert b.upper <= 1.01 * b.lower  # within 1 %
    assert b.lower == pytest.approx(lo_ref, abs=1e-7)  # the product found is the known one
    assert b.ellipsoid >= b.upper  # the CQLF norm alone is more conservative
    print(f"Gripenberg JSR bracket [{b.lower:.7f}, {b.upper:.7f}] in {elapsed:.2f} s")


def test_jsr_lower_bound_word_reproduces_it():
    A = np.array(REFERENCE["gripenberg_pair"]["value"])
    b = jsr_bounds(A)
    W = np.eye(2)
    for m in b.word:  # first applied first
        W = A[m] @ W
    assert spectral_radius(W) ** (1 / len(b.word)) == pytest.approx(b.lower)


def test_jsr_of_commuting_family_is_the_largest_spectral_radius():
    # simultaneously diagonalizable by an orthogonal Q: JSR = max spectral radius exactly
    rng = np.random.default_rng(3)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    A = np.stack([Q @ np.diag(d) @ Q.T for d in ([0.7, -0.2, 0.1], [0.3, 0.5, -0.6])])
    b = jsr_bounds(A)
    assert b.lower == pytest.approx(0.7)
    assert b.lower <= b.upper <= 0.7 * (1 + 1e-3)


def test_jsr_bounds_bracket_brute_force_norm_bounds():
    # Independent bounds: max rho(W)^(1/k) <= JSR <= max ||W||_2^(1/k) over all
    # products of length k = 8 (brute force).
    rng = np.random.default_rng(4)
    A = rng.normal(size=(2, 3, 3)) / 2.5
    k = 8
    prods = []
    for word in itertools.product(range(2), repeat=k):
        W = np.eye(3)
        for m in word:
            W = A[m] @ W
        prods.append(W)
    prods = np.array(prods)
    lo_bf = float(np.max(spectral_radius(prods))) ** (1 / k)
    hi_bf = float(np.max(np.linalg.norm(prods, 2, axis=(1, 2)))) ** (1 / k)
    b = jsr_bounds(A)
    assert b.lower >= lo_bf * (1 - 1e-12)
    assert b.upper <= b.ellipsoid
    assert b.lower <= hi_bf and b.lower <= b.upper


def test_jsr_of_nilpotent_and_unit_families():
    # a nilpotent matrix has JSR 0 (the bisection toward 0 must stop); the pair
    # {E12, E21} has JSR 1 (E12 E21 is a projection)
    E12 = np.array([[0.0, 1.0], [0.0, 0.0]])
    b = jsr_bounds(E12[None])
    assert b.lower == 0.0  # rho = 0 lowered by its rounding allowance, clipped at 0: exactly 0
    # The upper bound is rigorous, so it allows for rounding. A CQLF of E12 / r needs
    # P_22 ~ 1 / r^2: its decrease margin is verified only while the rounding of A' P A - P,
    # ~ 2 (3n + 1) eps / r^2, stays below it, i.e. down to r ~ sqrt(14 eps) ~ 6e-8; the
    # solver's P is not the optimal one, so the bisection stops within a few halvings of that.
    assert 0.0 < b.upper <= 1e-5
    # In the spectral norm the tree stops at E12^2 = 0 (zero to working precision): its bound
    # is the square root of the rounding allowance of a product of two unit-norm 2 x 2
    # matrices, 2 (k + 3) n eps cond(I)_F = 2 * 5 * 2 * 2 eps = 40 eps
    assert jsr_bounds(E12[None], quadratic=False).upper <= np.sqrt(40 * EPS) * (1 + 1e-9)
    b = jsr_bounds(np.stack([E12, E12.T]))
    assert b.lower == pytest.approx(1.0) and b.upper == pytest.approx(1.0)


def test_jsr_rejects_bad_options():
    A = np.array(REFERENCE["gripenberg_pair"]["value"])
    with pytest.raises(ValueError, match="max_length must be a positive int, got 0"):
        jsr_bounds(A, max_length=0)
    with pytest.raises(TypeError, match="max_products must be an int"):
        jsr_bounds(A, max_products=1.5)
    with pytest.raises(ValueError, match="matrices must have 3 dimensions"):
        jsr_bounds(A[0])


# ------------------------------------------------------------------ mean-square stability
def _exact_second_moment(A, p, x0, k):
    """E[x_k x_k'] by enumerating all L^k mode sequences (independent oracle)."""
    S = np.zeros((A.shape[1],) * 2)
    for word in itertools.product(range(len(p)), repeat=k):
        x = x0
        w = 1.0
        for m in word:
            x = A[m] @ x
            w *= p[m]
        S += w * np.outer(x, x)
    return S


def test_ms_recursion_matches_enumeration():
    rng = np.random.default_rng(5)
    A = rng.normal(size=(3, 2, 2)) * 0.8
    p = np.array([0.5, 0.3, 0.2])
    x0 = np.array([1.0, -2.0])
    n = 2
    M = np.einsum("i,iab,icd->acbd", p, A, A).reshape(n * n, n * n)
    k = 6
    vec = np.linalg.matrix_power(M, k) @ np.outer(x0, x0).ravel()
    np.testing.assert_allclose(vec.reshape(n, n), _exact_second_moment(A, p, x0, k), rtol=1e-10)
    assert ms_stable_iid(A, p).radius == pytest.approx(max(abs(np.linalg.eigvals(M))))


def test_ms_stability_verdicts():
    # scalar: E[x^2] multiplies by sum p_i a_i^2
    A = np.array([[[1.2]], [[0.1]]])
    res = ms_stable_iid(A, [0.5, 0.5])
    assert res.radius == pytest.approx(0.5 * 1.44 + 0.5 * 0.01) and res.holds
    res = ms_stable_iid(A, [0.8, 0.2])
    assert res.radius == pytest.approx(0.8 * 1.44 + 0.2 * 0.01) and not res.holds
    # each mode Schur, yet mean-square unstable under i.i.d. switching
    res = ms_stable_iid(SCHUR_PAIR_UNSTABLE_PRODUCT, [0.5, 0.5])
    assert not res.holds


def test_ms_rejects_bad_probabilities():
    with pytest.raises(ValueError, match="p must sum to 1"):
        ms_stable_iid(SCHUR_PAIR_UNSTABLE_PRODUCT, [0.5, 0.6])
    with pytest.raises(ValueError, match="p must have length 2"):
        ms_stable_iid(SCHUR_PAIR_UNSTABLE_PRODUCT, [1.0])


# ------------------------------------------------------------------ verdicts robust to rounding
def test_cqlf_accepts_a_margin_only_beyond_its_rounding(monkeypatch):
    # The "solver" returns P = I for A = a I: the decrease margin is 1 - a^2. Half the posed
    # margin, 5e-7, must be met beyond the rounding allowance of the check (about 1e-14 here).
    def fake_solve(problem, **_):
        (P,) = problem.variables()
        P.value = np.eye(2)
        return SolveOutcome("optimal", "CLARABEL", True)

    monkeypatch.setattr(stability, "solve_sdp", fake_solve)
    just = np.sqrt(1 - 0.5e-6 - 1e-16) * np.eye(2)  # margin 5e-7 + 1e-16: within rounding
    cert = cqlf(just[None], margin=1e-6)
    assert not cert.holds and "rounding allowance" in cert.note
    clear = np.sqrt(1 - 0.5e-6 - 1e-12) * np.eye(2)  # 1e-12 above: beyond any rounding here
    assert cqlf(clear[None], margin=1e-6).holds


def test_decrease_margin_refuses_a_non_finite_P():
    A = np.array(REFERENCE["zhang_example1_A"]["value"])
    with pytest.raises(ValueError, match=r"P must be finite, got nan at index \(0, 1\)"):
        decrease_margin(A, [[1.0, np.nan], [np.nan, 1.0]])
    with pytest.raises(ValueError, match="P must be finite, got inf"):
        decrease_margin(A, [[np.inf, 0.0], [0.0, 1.0]])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 4), top=st.floats(0.05, 3.0))
def test_jsr_bracket_holds_and_is_ordered_whatever_the_rounding(seed, n, top):
    # Symmetric matrices sharing their eigenvectors: the JSR is the largest |eigenvalue|, `top`.
    # The stored matrices are that family rounded, whose JSR is top to within a few ulps of
    # ||A|| (Weyl): 4 n eps top.
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    d = rng.uniform(-top, top, size=(2, n))
    d[0, 0] = top
    A = np.einsum("ab,kb,cb->kac", Q, d, Q)
    slack = 4 * n * EPS * top
    for quadratic in (False, True) if seed % 5 == 0 else (False,):  # the CQLF bisection is slow
        b = jsr_bounds(A, quadratic=quadratic)
        assert b.lower <= b.upper
        assert b.lower <= top + slack and b.upper >= top - slack


def test_jsr_in_the_spectral_norm_and_its_option():
    A = np.array(REFERENCE["gripenberg_pair"]["value"])
    lo_ref, hi_ref = REFERENCE["gripenberg_pair"]["jsr_interval"]
    b = jsr_bounds(A, quadratic=False)
    assert b.lower <= hi_ref and b.upper >= lo_ref
    assert b.ellipsoid >= np.max(np.linalg.norm(A, 2, axis=(1, 2)))  # the spectral-norm bound
    with pytest.raises(TypeError, match="quadratic must be a bool, got str"):
        jsr_bounds(A, quadratic="no")


def test_ms_stability_of_orthogonal_modes_is_not_decided_by_the_last_bits():
    # Orthogonal A_i preserve E[x'x]: the radius is 1 exactly, computed 1 +- a few ulps;
    # "radius < 1" alone would call it stable on some machines.
    rng = np.random.default_rng(6)
    A = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(2)])
    res = ms_stable_iid(A, [0.3, 0.7])
    assert res.radius == pytest.approx(1.0, rel=1e-13) and not res.holds


def test_ms_stability_matrix_free_beyond_n_32_equals_the_dense_radius():
    rng = np.random.default_rng(7)
    n, p = 40, np.array([0.25, 0.75])
    A = rng.normal(size=(2, n, n)) / np.sqrt(n)
    M = np.einsum("i,iab,icd->acbd", p, A, A).reshape(n * n, n * n)
    dense = float(np.max(np.abs(np.linalg.eigvals(M))))
    res = ms_stable_iid(A, p)
    # ARPACK converges to a relative 1e-12; both carry the rounding of n^2 x n^2 eigenvalues
    size = float(p @ np.sum(A * A, axis=(1, 2)))
    tol = 1e-12 * dense + 2 * 2 * (n * n + 2) * EPS * size
    assert res.radius == pytest.approx(dense, rel=0, abs=tol)
    assert res.holds == (dense < 1)
