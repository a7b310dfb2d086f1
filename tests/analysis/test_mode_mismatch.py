"""Mode-mismatch bias of the mode-based Kalman filter (Zhang & Natarajan, paper 001)."""

import functools
import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import solve_discrete_are
from scipy.optimize import brentq

from switchest.analysis.mode_mismatch import (
    MismatchDynamics,
    autonomous_stability,
    bias_recursion,
    bibo_gain,
    filter_stability_hypotheses,
    max_mismatch_probability,
    mean_state,
    mismatch_bias_bound,
    mismatch_dynamics,
    riccati_gains,
    stable_mismatch_region,
    steady_state_gains,
    tolerance_region,
    transformed_system,
    unstable_components,
)
from switchest.models.zhang import SMART_GRID_TAU, smart_grid, zhang_two_mode
from switchest.system import SwitchedLinearSystem

DATA = Path(__file__).resolve().parents[1] / "data"
EX1 = json.loads((DATA / "zhang_example1.json").read_text())
GRID = json.loads((DATA / "zhang_smart_grid.json").read_text())


def _pair(key):
    """'i,q' (1-based, as printed) -> (i - 1, q - 1)."""
    i, q = (int(s) for s in key.split(","))
    return i - 1, q - 1


def _assert_printed(computed, case):
    """Computed equals the printed value at its precision (half a unit of the last digit)."""
    tol = 0.5 * 10.0 ** -case["provenance"]["decimals"] + 1e-12
    np.testing.assert_array_less(np.abs(np.asarray(computed) - np.asarray(case["value"])), tol)


def _norms(M):
    return np.linalg.norm(M, ord=2, axis=(-2, -1))


@functools.cache
def example1():
    return mismatch_dynamics(zhang_two_mode())


@functools.cache
def grid():
    return mismatch_dynamics(smart_grid())


def three_mode_system():
    """Example 1 with a third, non-normal mode: a CQLF for the Lambda_i is not trivial."""
    s = zhang_two_mode()
    A = np.concatenate([s.A, [[[0.95, 0.3], [-0.2, 0.7]]]])
    C = np.concatenate([s.C, [[[1.0, 0.0], [0.0, 0.5]]]])
    Q = np.concatenate([s.Q, [0.4 * np.eye(2)]])
    return SwitchedLinearSystem.discrete(A, C=C, Q=Q, R=0.3 * np.eye(2))


# ---------------------------------------------------------------- Example 1 (§5.1)
@pytest.mark.parametrize("name", ["Lambda_1", "Lambda_2", "Gamma_1_2", "Gamma_2_1"])
def test_example1_matrices_match_printed(name):
    d = example1()
    computed = {
        "Lambda_1": d.Lambda[0],
        "Lambda_2": d.Lambda[1],
        "Gamma_1_2": d.Gamma[0, 1],
        "Gamma_2_1": d.Gamma[1, 0],
    }[name]
    _assert_printed(computed, EX1["cases"][name])


def test_example1_norms_match_printed():
    _assert_printed(_norms(example1().Lambda), EX1["cases"]["norm_Lambda"])


def test_gain_convention_a_posteriori_covariance_does_not_reproduce_example1():
    # The printed Lambda_i need K from the steady a-priori covariance M_{k|k-1}
    # (Algorithm 1 line 8). With the a-posteriori M_{k|k} in its place they are off
    # by far more than the printed precision: the convention is pinned by the data.
    s = zhang_two_mode()
    wrong = []
    for i in range(2):
        A, C, Q, R = s.A[i], s.C[i], s.Q[i], s.R[i]
        M = solve_discrete_are(A.T, C.T, Q, R)
        P = M - M @ C.T @ np.linalg.solve(C @ M @ C.T + R, C @ M)
        K = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
        wrong.append(A - K @ C @ A)
    printed = np.array([EX1["cases"]["Lambda_1"]["value"], EX1["cases"]["Lambda_2"]["value"]])
    assert np.min(np.max(np.abs(np.array(wrong) - printed), axis=(1, 2))) > 0.1


def test_gamma_diagonal_is_lambda_and_definitions():
    s = three_mode_system()
    d = mismatch_dynamics(s)
    for i, t in itertools.product(range(3), repeat=2):
        np.testing.assert_allclose(
            d.Gamma[i, t], s.A[t] - d.K[i] @ s.C[t] @ s.A[t], rtol=1e-14, atol=1e-15
        )
    np.testing.assert_array_equal(d.Gamma[[0, 1, 2], [0, 1, 2]], d.Lambda)
    np.testing.assert_array_equal(d.S[[0, 1, 2], [0, 1, 2]], 0.0)
    assert not d.Lambda.flags.writeable and not d.Gamma.flags.writeable


def test_steady_gain_is_the_limit_of_algorithm1():
    # Oracle for the DARE call: iterate Algorithm 1 lines 6-10 to convergence.
    s = three_mode_system()
    np.testing.assert_allclose(
        riccati_gains(s, P0=np.eye(2), steps=400), steady_state_gains(s), rtol=1e-10, atol=1e-12
    )
    # One step from P0 = 0 is K = Q C'(C Q C' + R)^{-1}, by hand.
    K1 = riccati_gains(s, P0=np.zeros((2, 2)), steps=1)
    for i in range(3):
        C, Q, R = s.C[i], s.Q[i], s.R[i]
        np.testing.assert_allclose(K1[i], Q @ C.T @ np.linalg.inv(C @ Q @ C.T + R), rtol=1e-12)


def test_example1_cqlf_for_lambdas_and_for_the_original_modes():
    # §5.1: Lambda_1, Lambda_2 share a CQLF (Theorem 3) and so do A_1, A_2
    # (original system stable): Algorithm 2 then puts no zero in the region.
    stab = autonomous_stability(example1())
    assert stab.holds and stab.each_mode_contracts
    uc = unstable_components(zhang_two_mode())
    assert uc.certificate.holds and uc.holds is True and not uc.components.any()
    assert stable_mismatch_region(zhang_two_mode()).all()


def test_fig6_max_mismatch_needs_eta_times_sup_input_1_04():
    case = EX1["cases"]["fig6_max_mismatch"]
    d = example1()
    c = case["eta_times_sup_input"]
    lam_max = max_mismatch_probability(d, bound=case["bound"], eta=c, sup_input=1.0)
    _assert_printed(lam_max, case)
    # eta and sup||u|| enter only through their product
    assert max_mismatch_probability(d, bound=0.3, eta=0.52, sup_input=2.0) == pytest.approx(lam_max)
    # The product that reproduces the printed digits is pinned to ~1e-5 around 1.04
    # (solve lam_max(c) = printed +- half a unit in the 6th decimal).

    def f(c, target):
        return max_mismatch_probability(d, bound=0.3, eta=c, sup_input=1.0) - target

    lo = brentq(f, 0.5, 2.0, args=(case["value"] + 5e-7,))
    hi = brentq(f, 0.5, 2.0, args=(case["value"] - 5e-7,))
    assert lo < c < hi and hi - lo < 1e-5
    # Fig. 6's lam_{1,2} = lam_{2,1} = 0.154554 sits on the boundary of eq. (18).
    for lam12, inside in [(case["value"] - 1e-6, True), (case["value"] + 1e-5, False)]:
        lam = np.array([[1 - lam12, lam12], [lam12, 1 - lam12]])
        check = tolerance_region(d, lam, bound=0.3, eta=c, sup_input=1.0)
        assert check.holds is inside


def test_theorem4_bound_is_the_minimum_over_the_simplex():
    # Oracle: for total mismatch probability P in each column, minimize
    # max_q sum_{i != q} lam[i, q] ||S_{i,q}|| over a grid of the simplex (eq. (16)).
    d = mismatch_dynamics(three_mode_system())
    P, eta, sup_u = 0.3, 1.7, 2.5
    norms = _norms(d.S)
    grid_w = np.linspace(0.0, 1.0, 201)
    per_q = [
        min(P * (w * norms[o[0], q] + (1 - w) * norms[o[1], q]) for w in grid_w)
        for q in range(3)
        for o in [[i for i in range(3) if i != q]]
    ]
    expected = eta * sup_u * max(per_q)
    assert mismatch_bias_bound(d, P, eta=eta, sup_input=sup_u) == pytest.approx(expected, rel=1e-12)
    assert mismatch_bias_bound(d, 0.0, eta=eta, sup_input=sup_u) == 0.0
    # and max_mismatch_probability inverts it
    B = mismatch_bias_bound(d, P, eta=eta, sup_input=sup_u)
    assert max_mismatch_probability(d, bound=B, eta=eta, sup_input=sup_u) == pytest.approx(P)


def test_tolerance_region_values():
    d = mismatch_dynamics(three_mode_system())
    lam = np.array([[0.7, 0.1, 0.0], [0.2, 0.8, 0.35], [0.1, 0.1, 0.65]])  # asymmetric
    chk = tolerance_region(d, lam, bound=1.0, eta=2.0, sup_input=0.5)
    norms = _norms(d.S)
    expected = [
        lam[1, 0] * norms[1, 0] + lam[2, 0] * norms[2, 0],
        lam[0, 1] * norms[0, 1] + lam[2, 1] * norms[2, 1],
        lam[0, 2] * norms[0, 2] + lam[1, 2] * norms[1, 2],
    ]
    np.testing.assert_allclose(chk.value, expected, rtol=1e-14)
    assert chk.threshold == 1.0 and chk.holds is bool(max(expected) <= 1.0)
    # eq. (18) is a sufficient condition for (17): ||G_q|| <= value[q]
    G = transformed_system(d, lam).G
    assert np.all(_norms(G) <= chk.value + 1e-12)


def test_bibo_gain_bounds_the_bias():
    # eta of bibo_gain: sup ||x*_k|| <= eta sup ||G_q u_k|| along any switching, from e_0 = 0.
    s = three_mode_system()
    d = mismatch_dynamics(s)
    eta = bibo_gain(d)
    assert np.isfinite(eta) and eta >= 1.0
    rng = np.random.default_rng(5)
    lam = rng.dirichlet(np.ones(3), size=3).T
    modes = rng.integers(0, 3, size=(200, 60))
    u = rng.uniform(-1.0, 1.0, size=(200, 60, 2))
    e = bias_recursion(d, lam, modes, u)
    Gu = np.einsum("...ab,...b->...a", transformed_system(d, lam).G[modes], u)
    assert np.max(np.linalg.norm(e, axis=-1)) <= eta * np.max(np.linalg.norm(Gu, axis=-1))


def test_bibo_gain_from_the_certificate_covers_transient_growth():
    # Non-normal Lambda_i with ||Lambda_i|| > 1 (so P = I gives nothing) but a CQLF:
    # eta must cover the impulse response, i.e. exceed every product norm.
    Lam = np.array([[[0.3, 3.0], [0.0, 0.3]], [[0.3, 2.0], [0.0, 0.2]]])
    d = MismatchDynamics(K=np.zeros((2, 2, 2)), Lambda=Lam, Gamma=np.zeros((2, 2, 2, 2)))
    eta = bibo_gain(d)
    assert np.isfinite(eta)
    worst = max(
        np.linalg.norm(functools.reduce(np.matmul, [Lam[i] for i in word]), ord=2)
        for length in range(1, 7)
        for word in itertools.product(range(2), repeat=length)
    )
    assert worst > 3.0 and eta >= worst


# ---------------------------------------------------------------- recursion (9)
def test_recursion_equals_enumeration_of_filter_modes():
    # Oracle: average eq. (7) over every filter-mode sequence with its probability
    # prod_k lam[i_k, q_k] (L^K sequences), versus the mean recursion (9).
    s = three_mode_system()
    d = mismatch_dynamics(s)
    lam = np.array([[0.6, 0.1, 0.3], [0.3, 0.7, 0.2], [0.1, 0.2, 0.5]])
    modes = np.array([0, 2, 1, 1, 0])
    u = mean_state(s, modes, np.array([2.0, -1.0]))
    e0 = np.array([0.3, 0.1])
    mean = np.zeros((len(modes) + 1, 2))
    for seq in itertools.product(range(3), repeat=len(modes)):
        w = np.prod([lam[i, q] for i, q in zip(seq, modes)])
        e = [e0]
        for k, (i, t) in enumerate(zip(seq, modes)):
            e.append(d.Lambda[i] @ e[-1] + (d.Lambda[i] - d.Gamma[i, t]) @ u[k])
        mean += w * np.array(e)
    np.testing.assert_allclose(
        bias_recursion(d, lam, modes, u[:-1], e0=e0), mean, rtol=1e-12, atol=1e-14
    )


def test_recursion_batched_equals_looped():
    s = three_mode_system()
    d = mismatch_dynamics(s)
    rng = np.random.default_rng(2)
    lam = rng.dirichlet(np.ones(3), size=3).T
    modes = rng.integers(0, 3, size=(4, 3, 12))
    u = mean_state(s, modes, rng.normal(size=(4, 3, 2)))[..., :-1, :]
    e0 = rng.normal(size=(3, 2))  # broadcast over the first batch axis
    batched = bias_recursion(d, lam, modes, u, e0=e0)
    assert batched.shape == (4, 3, 13, 2)
    # one trajectory alone or in a stack: the same 2-term sums per step, possibly in another
    # order or with FMA; a few ulps per step over the K = 12 steps, relative to the trajectory
    tol = 4 * 12 * 2 * np.finfo(float).eps
    for a, b in itertools.product(range(4), range(3)):
        np.testing.assert_allclose(
            batched[a, b], bias_recursion(d, lam, modes[a, b], u[a, b], e0=e0[b]),
            rtol=tol, atol=tol * np.abs(batched[a, b]).max(),
        )


def test_mean_state_follows_the_modes():
    s = zhang_two_mode()
    m = mean_state(s, [1, 0, 0], [1.0, 2.0])
    np.testing.assert_allclose(m[-1], s.A[0] @ s.A[0] @ s.A[1] @ [1.0, 2.0], rtol=1e-15)
    assert m.shape == (4, 2)


def test_recursion_matches_monte_carlo_mode_mismatch_filter():
    """Oracle: a batched steady-gain Kalman filter with random filter modes (Zhang eq. (6)).

    Each trial simulates model (1) along a fixed true mode sequence; at every step the
    filter's mode i is drawn from lam[:, q_k]. The empirical mean of x_hat_k - x_k over
    N trials must match recursion (9) within 5 standard errors per step and component.
    """
    s = zhang_two_mode()
    d = mismatch_dynamics(s)
    lam = np.array([[0.7, 0.25], [0.3, 0.75]])
    rng = np.random.default_rng(20181128)
    N, K = 20_000, 25
    modes = rng.integers(0, 2, size=K)
    m0 = np.array([3.0, -2.0])
    x = m0 + np.sqrt(0.2) * rng.standard_normal((N, 2))
    xh = np.broadcast_to(m0, (N, 2)).copy()  # filter starts at the prior mean: e_0 = 0
    sqQ = np.linalg.cholesky(s.Q)
    sqR = np.linalg.cholesky(s.R)
    diff = np.empty((K, N, 2))
    for k, t in enumerate(modes):
        x = x @ s.A[t].T + rng.standard_normal((N, 2)) @ sqQ[t].T
        y = x @ s.C[t].T + rng.standard_normal((N, 2)) @ sqR[t].T
        i = (rng.random(N)[:, None] > np.cumsum(lam[:, t])[:-1]).sum(axis=1)
        xp = np.einsum("nab,nb->na", s.A[i], xh)
        innov = y - np.einsum("nab,nb->na", s.C[i], xp)
        xh = xp + np.einsum("nab,nb->na", d.K[i], innov)
        diff[k] = xh - x
    mc = diff.mean(axis=1)
    se = diff.std(axis=1, ddof=1) / np.sqrt(N)
    theory = bias_recursion(d, lam, modes, mean_state(s, modes, m0)[:-1])[1:]
    z = np.abs(mc - theory) / se
    assert z.max() < 5.0, f"max |z| = {z.max():.2f}"
    # the check has power: the bias is many standard errors away from zero
    assert np.max(np.abs(theory) / se) > 20.0


# ---------------------------------------------------------------- Lemmas 3-4, Theorems 2-3
def test_lemma3_spectral_radius_identity():
    # Lemma 3's proof: rho(A_i - L_i C_i) = rho(Lambda_i) < 1 with L_i = A_i K_i.
    for s in (zhang_two_mode(), three_mode_system(), smart_grid()):
        d = mismatch_dynamics(s)
        stab = autonomous_stability(d)
        closed = s.A - s.A @ d.K @ s.C
        np.testing.assert_allclose(
            stab.lambda_radius, np.max(np.abs(np.linalg.eigvals(closed)), axis=-1), rtol=1e-10
        )
        assert stab.each_mode_contracts


def test_lemma3_hypotheses():
    # §5.1 and §5.2: every mode controllable and observable.
    assert filter_stability_hypotheses(zhang_two_mode()).all()
    assert filter_stability_hypotheses(smart_grid()).all()
    # noise on the second state only, and it does not reach the first: not controllable;
    # C sees only the first state of a decoupled A: not observable.
    A = np.diag([0.5, 0.8])
    s = SwitchedLinearSystem.discrete(
        np.stack([A, A]),
        C=np.array([[[1.0, 1.0]], [[1.0, 0.0]]]),
        Q=np.stack([np.diag([0.0, 1.0]), np.eye(2)]),
        R=[[1.0]],
    )
    np.testing.assert_array_equal(filter_stability_hypotheses(s), [False, False])


def test_lemma4_one_nonzero_per_column():
    d = mismatch_dynamics(three_mode_system())
    lam = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # always wrong
    stab = autonomous_stability(d, lam)
    assert stab.one_mode_per_column
    np.testing.assert_allclose(stab.F_radius, stab.lambda_radius[[1, 2, 0]], rtol=1e-12)
    assert np.all(stab.F_radius < 1.0)
    assert autonomous_stability(d, np.full((3, 3), 1 / 3)).one_mode_per_column is False


@functools.cache
def _three_mode_dynamics():
    return mismatch_dynamics(three_mode_system())


@settings(max_examples=15, deadline=None)
@given(
    st.lists(st.floats(0.0, 1.0), min_size=9, max_size=9).filter(
        lambda v: min(sum(v[0:3]), sum(v[3:6]), sum(v[6:9])) > 1e-3
    )
)
def test_theorems_2_3_any_lambda(raw):
    # Theorem 3: the CQLF P of {Lambda_i} is a CQLF of every F_q, for any lam.
    lam = np.array(raw).reshape(3, 3).T
    lam = lam / lam.sum(axis=0)
    stab = autonomous_stability(_three_mode_dynamics(), lam)
    assert stab.holds
    assert stab.F_margin > 0.0 and np.all(stab.F_radius < 1.0)


# ---------------------------------------------------------------- smart grid (§5.2)
def test_smart_grid_tau_search():
    # tau is unstated; ||Lambda_2(tau)|| is monotone, and solving it for the printed
    # 0.8837 gives tau = 0.1, where ||Lambda_3|| = 0.8611 holds as well.
    def norm2(tau, q):
        return _norms(mismatch_dynamics(smart_grid(tau)).Lambda)[q]

    target = GRID["cases"]["norm_Lambda"]["value"]
    for q in (1, 2):
        tau = brentq(lambda t, q: norm2(t, q) - target[q], 0.05, 0.2, args=(q,), xtol=1e-9)
        assert abs(tau - GRID["tau"]) < 1e-3
    assert SMART_GRID_TAU == GRID["tau"]


def _grid_transient():
    s = smart_grid(GRID["tau"])
    spec = GRID["transient_gain"]
    return mismatch_dynamics(s, gains=riccati_gains(s, P0=np.eye(2), steps=spec["steps"]))


def _printed_T(skip_typos=True):
    typos = {(t["T"], tuple(e - 1 for e in t["entry"])) for t in GRID["cases"]["typos"]["value"]}
    for key, value in GRID["cases"]["T"]["value"].items():
        mask = np.ones((2, 2), dtype=bool)
        for tkey, entry in typos:
            if skip_typos and tkey == key:
                mask[entry] = False
        yield key, np.array(value), mask


def test_smart_grid_printed_values_with_algorithm1_gains_at_step_99():
    # With the Algorithm 1 gain after 99 steps from Sigma_0 = I every printed
    # ||Lambda_q|| and T_{i,q} entry (except the two typos) is reproduced.
    d = _grid_transient()
    _assert_printed(_norms(d.Lambda), GRID["cases"]["norm_Lambda"])
    for key, printed, mask in _printed_T():
        T = d.S[_pair(key)]
        assert np.all(np.abs(T - printed)[mask] <= 0.5e-4 + 1e-12), (key, T)


def test_smart_grid_steady_state_gains_reproduce_all_but_mode_1():
    # Steady-state gains (eq. (6)) reproduce ||Lambda_2||, ||Lambda_3|| and every T_{i,q}
    # without the mode-1 gain; the mode-1 values are a transient of Algorithm 1.
    d = grid()
    norms = _norms(d.Lambda)
    printed = GRID["cases"]["norm_Lambda"]["value"]
    assert np.all(np.abs(norms[1:] - printed[1:]) <= 0.5e-4)
    assert abs(norms[0] - printed[0]) > 5e-4  # 0.9828 at steady state vs printed 0.9817
    for key, T_printed, mask in _printed_T():
        i, q = _pair(key)
        err = np.abs(d.S[i, q] - T_printed)[mask]
        if i == 0:
            assert err.max() > 0.5e-4  # T_{1,2}, T_{1,3} carry the mode-1 gain
        else:
            assert err.max() <= 0.5e-4 + 1e-12, key


def test_smart_grid_T_typos_are_a_slipped_decimal():
    # Printed T_{2,3}[2,2] = -0.0088 and T_{3,2}[2,2] = 0.0086; the computed values
    # are -0.00088 and 0.00086 (under either gain): the printed ones are 10x.
    for d in (grid(), _grid_transient()):
        for typo in GRID["cases"]["typos"]["value"]:
            i, q = _pair(typo["T"])
            r, c = (e - 1 for e in typo["entry"])
            value = d.S[i, q][r, c]
            assert round(value, 4) == typo["computed_at_printed_precision"] != typo["printed"]
            assert round(10 * value, 4) == typo["printed"]


def test_smart_grid_cqlf_and_unstable_components():
    # §5.2: Lambda_1..3 share a CQLF; A_1..3 do not; I = {1} (0-based {0}).
    assert autonomous_stability(grid()).holds
    uc = unstable_components(smart_grid())
    assert not uc.certificate.holds and uc.holds is False
    expected = np.zeros(2, dtype=bool)
    expected[np.array(GRID["cases"]["unstable_components"]["value"]) - 1] = True
    np.testing.assert_array_equal(uc.components, expected)


def test_smart_grid_algorithm2_region_is_printed():
    mask = stable_mismatch_region(smart_grid())
    region = GRID["cases"]["stable_region"]["value"]
    for key in region["zero"]:
        assert not mask[_pair(key)], key
    for key in region["free"]:
        assert mask[_pair(key)], key
    # the transient gains give the same region
    assert np.array_equal(stable_mismatch_region(smart_grid(), dynamics=_grid_transient()), mask)


def _lam_from(setting):
    lam = np.zeros((3, 3))
    for key, value in setting.items():
        lam[_pair(key)] = value
    lam[np.arange(3), np.arange(3)] = 1.0 - lam.sum(axis=0)
    return lam


def test_smart_grid_fig7_settings():
    # Setting I lies in the region and its bias stays bounded while E(x_k) explodes;
    # Setting II violates it at exactly the printed entries and its bias explodes.
    mask = stable_mismatch_region(smart_grid())
    lam1 = _lam_from(GRID["cases"]["fig7_setting_I"]["value"])
    lam2 = _lam_from(GRID["cases"]["fig7_setting_II"]["value"])
    assert not np.any((lam1 > 0) & ~mask)
    outside = {(int(i), int(q)) for i, q in zip(*np.nonzero((lam2 > 0) & ~mask))}
    assert outside == {_pair(k) for k in GRID["cases"]["fig7_setting_II"]["outside"]}

    s, d = smart_grid(), grid()
    modes = np.random.default_rng(7).integers(0, 3, size=150)
    u = mean_state(s, modes, np.array([1.0, 1.0]))
    assert np.linalg.norm(u[-1]) > 1e12  # P_G grows like exp(0.3 k) in modes 2-3
    e1 = np.linalg.norm(bias_recursion(d, lam1, modes, u[:-1]), axis=-1)
    e2 = np.linalg.norm(bias_recursion(d, lam2, modes, u[:-1]), axis=-1)
    assert e1.max() < 1.0  # bounded: G_q annihilates the unstable component
    assert e2[-1] > 1e12 and e2[-1] / np.linalg.norm(u[-1]) > 1e-3


def test_algorithm2_finds_switching_instability_of_schur_modes():
    # Both modes Schur, their product not: no CQLF; words of length 2 find the
    # unstable components {0, 1}; the decoupled third state is stable.
    A1 = np.array([[0.5, 2.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.5]])
    A2 = np.array([[0.5, 0.0, 0.0], [2.0, 0.5, 0.0], [0.0, 0.0, 0.5]])
    s = SwitchedLinearSystem.discrete(np.stack([A1, A2]), Q=np.eye(3), R=np.eye(3))
    uc = unstable_components(s, max_length=2)
    assert not uc.certificate.holds and uc.holds is False
    np.testing.assert_array_equal(uc.components, [True, True, False])
    assert (0, 1) in uc.words and (0,) not in uc.words
    # length 1 cannot decide: every component is marked, conservatively
    short = unstable_components(s, max_length=1)
    assert short.holds is None and short.components.all()
    # the region: a mismatch is allowed only if T_{i,q} vanishes on columns 0 and 1
    mask = stable_mismatch_region(s)
    S = mismatch_dynamics(s).S
    expected = np.all(np.abs(S[..., :, :2]) < 1e-12, axis=(-2, -1))
    np.testing.assert_array_equal(mask, expected)
    assert mask.diagonal().all()


# ---------------------------------------------------------------- input validation
def test_bad_lam_is_refused():
    d = example1()
    with pytest.raises(ValueError, match=r"lam must have shape \(2, 2\).*got \(3, 3\)"):
        transformed_system(d, np.eye(3))
    with pytest.raises(
        ValueError, match=r"lam columns must sum to 1 .*got column 1 summing to 1\.1"
    ):
        transformed_system(d, [[0.9, 0.1], [0.1, 1.0]])
    with pytest.raises(ValueError, match=r"lam must have non-negative entries, got minimum -0\.1"):
        transformed_system(d, [[1.1, 0.0], [-0.1, 1.0]])
    with pytest.raises(ValueError, match=r"lam must be finite"):
        transformed_system(d, [[np.nan, 0.0], [1.0, 1.0]])


def test_row_stochastic_lam_is_refused_not_transposed():
    d = example1()
    rows_sum_to_one = np.array([[0.9, 0.1], [0.3, 0.7]])
    with pytest.raises(
        ValueError, match=r"lam columns must sum to 1 .*got column 1 summing to 0\.8"
    ):
        transformed_system(d, rows_sum_to_one)
    ts = transformed_system(d, rows_sum_to_one.T)
    np.testing.assert_allclose(ts.F[1], 0.3 * d.Lambda[0] + 0.7 * d.Lambda[1], rtol=1e-14)


def test_bad_recursion_arguments_are_refused():
    d, s = example1(), zhang_two_mode()
    lam = np.eye(2)
    with pytest.raises(ValueError, match=r"modes must be 0-based mode indices in \[0, 1\], got 2"):
        bias_recursion(d, lam, [0, 2], np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"mean_x must have shape \(\.\.\., 2, 2\).*got \(3, 2\)"):
        bias_recursion(d, lam, [0, 1], np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"e0 must have shape \(\.\.\., 2\), got \(3,\)"):
        bias_recursion(d, lam, [0, 1], np.zeros((2, 2)), e0=np.zeros(3))
    with pytest.raises(TypeError, match=r"modes must hold integers"):
        mean_state(s, ["a"], [0.0, 0.0])
    with pytest.raises(ValueError, match=r"modes must have at least 1 dimension"):
        mean_state(s, 1, [0.0, 0.0])


def test_bad_systems_and_gains_are_refused():
    s = zhang_two_mode()
    cont = SwitchedLinearSystem.continuous(s.A, C=s.C, Q=s.Q, R=s.R)
    with pytest.raises(ValueError, match=r"system must be discrete-time .*got domain 'continuous'"):
        mismatch_dynamics(cont)
    noise_free = SwitchedLinearSystem.discrete(s.A, C=s.C, Q=s.Q)
    with pytest.raises(ValueError, match=r"system must have measurement noise"):
        steady_state_gains(noise_free)
    with pytest.raises(TypeError, match=r"system must be a SwitchedLinearSystem, got ndarray"):
        steady_state_gains(s.A)
    undetectable = SwitchedLinearSystem.discrete(
        [[1.5, 0.0], [0.0, 0.5]], C=[[0.0, 1.0]], Q=np.eye(2), R=[[1.0]]
    )
    with pytest.raises(ValueError, match=r"system mode 0 has no stabilizing steady-state"):
        steady_state_gains(undetectable)
    with pytest.raises(
        ValueError, match=r"gains must have shape \(2, 2, 2\) \(L, n, m\), got \(2, 2, 1\)"
    ):
        mismatch_dynamics(s, gains=np.zeros((2, 2, 1)))
    with pytest.raises(ValueError, match=r"P0 must have shape \(2, 2\), got \(3, 3\)"):
        riccati_gains(s, P0=np.eye(3), steps=3)
    with pytest.raises(ValueError, match=r"P0 must be symmetric positive semidefinite"):
        riccati_gains(s, P0=-np.eye(2), steps=3)
    with pytest.raises(ValueError, match=r"steps must be a positive int, got 0"):
        riccati_gains(s, P0=np.eye(2), steps=0)
    with pytest.raises(TypeError, match=r"steps must be an int, got float"):
        riccati_gains(s, P0=np.eye(2), steps=2.0)
    with pytest.raises(ValueError, match=r"max_length must be a positive int, got 0"):
        unstable_components(s, max_length=0)
    with pytest.raises(TypeError, match=r"dynamics must be a MismatchDynamics, got dict"):
        stable_mismatch_region(s, dynamics={})
    with pytest.raises(ValueError, match=r"dynamics must belong to system"):
        stable_mismatch_region(smart_grid(), dynamics=example1())


def test_bad_bound_arguments_are_refused():
    d = example1()
    with pytest.raises(
        ValueError, match=r"probability must be a probability in \[0, 1\], got 1\.5"
    ):
        mismatch_bias_bound(d, 1.5, eta=1.0, sup_input=1.0)
    with pytest.raises(ValueError, match=r"eta must be a finite positive number, got -1\.0"):
        mismatch_bias_bound(d, 0.1, eta=-1.0, sup_input=1.0)
    with pytest.raises(TypeError, match=r"sup_input must be a real scalar, got str"):
        max_mismatch_probability(d, bound=0.3, eta=1.0, sup_input="1")
    with pytest.raises(ValueError, match=r"bound must be a finite positive number, got 0"):
        tolerance_region(d, np.eye(2), bound=0, eta=1.0, sup_input=1.0)
    one_mode = mismatch_dynamics(
        SwitchedLinearSystem.discrete([[0.5]], C=[[1.0]], Q=[[1.0]], R=[[1.0]])
    )
    with pytest.raises(ValueError, match=r"dynamics must have at least two modes .*got 1"):
        mismatch_bias_bound(one_mode, 0.1, eta=1.0, sup_input=1.0)
