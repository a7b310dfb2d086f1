"""Extreme but valid problems run: measurements of 1e50, priors of 1e300.

The Kalman core factors an equilibrated innovation covariance, takes the log-determinant
and the normalized innovation from that factor, and falls back to the information form where
Joseph's form loses its digits (a diffuse prior): a problem scaled by s gives the unscaled
results scaled by s, and a prior of 1e300 gives, after the first update, the results of the
(already diffuse) prior 1e12.
"""

import warnings

import numpy as np
import pytest
from scipy.linalg import expm

from switchest import SwitchedLinearSystem
from switchest import signals as sg
from switchest.estimators import IMMEV1Filter, IMMFilter, ModeKalmanFilter, SwitchTimeKalmanFilter
from switchest.models.catalog import catalog
from switchest.simulate import simulate

EPS = np.finfo(float).eps
A = np.array([[[-0.4, 1.0], [-1.0, -0.3]], [[-0.1, 0.0], [0.5, -1.2]]])
B = np.array([[[0.0], [1.0]], [[1.0], [0.0]]])
C = np.array([[1.0, 0.2], [0.3, -1.0]])  # invertible: one measurement sees the whole state
Q = 0.05 * np.eye(2)
R = np.array([[0.1, 0.02], [0.02, 0.2]])
X0, P0 = np.array([0.5, -0.5]), np.eye(2)
TRANSITION = np.array([[0.8, 0.2], [0.35, 0.65]])
EPSILON = 1e-9  # IMM-EV1's covariance inflation, an absolute covariance: scaled with the problem


def system(s=1.0):
    """The problem in units where x and y are s times larger."""
    return SwitchedLinearSystem.continuous(A, s * B, C, Q=s * s * Q, R=s * s * R)


FILTERS = {
    "mode-kalman": lambda sys, x0, p0, s: ModeKalmanFilter(sys, x0, p0),
    "switch-time": lambda sys, x0, p0, s: SwitchTimeKalmanFilter(sys, x0, p0, grid=3),
    "imm": lambda sys, x0, p0, s: IMMFilter(sys, TRANSITION, x0, p0),
    "imm-ev1": lambda sys, x0, p0, s: IMMEV1Filter(sys, TRANSITION, x0=x0, P0=p0, grid=3,
                                                   epsilon=s * s * EPSILON),
}


@pytest.fixture(scope="module")
def traj():
    t = sg.periodic(0.25, 6.0)
    return simulate(system(), lambda r: sg.dwell_time(2, 6.0, 0.6, 1.2, rng=r), t, (X0, P0),
                    u=np.ones(1), trials=3, rng=0)


def run(name, traj, *, s=1.0, p0=1.0):
    est = FILTERS[name](system(s), s * X0, s * s * p0 * P0, s)
    kw = {"modes": traj.mode} if name in ("mode-kalman", "switch-time") else {}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow, no repair
        return est.run(s * traj.y, np.ones(1), traj.t, **kw)  # B is scaled


@pytest.mark.parametrize("name", FILTERS)
def test_a_problem_scaled_by_1e50_gives_the_scaled_results(name, traj):
    s = 1e50
    one, big = run(name, traj), run(name, traj, s=s)
    # Multiplying the inputs by s (not a power of two) perturbs each by half an ulp; a stable
    # filter carries such perturbations forward without growth, adding a few ulps per sample,
    # amplified by the conditioning of the covariances it factors: K samples, cond(P).
    K = traj.t.size
    cond = float(np.max(np.linalg.cond(one.P)))
    rtol = 8 * K * EPS * cond
    np.testing.assert_allclose(big.x / s, one.x, rtol=rtol, atol=rtol * np.abs(one.x).max())
    np.testing.assert_allclose(big.P / s**2, one.P, rtol=rtol, atol=rtol * np.abs(one.P).max())
    if one.mode_prob is not None:
        np.testing.assert_allclose(big.mode_prob, one.mode_prob, atol=rtol)
    if one.loglik is not None:
        # log N(s y; s C x, s^2 S) = log N(y; C x, S) - m log s: the shift of 2 log s ~ 230 is
        # rounded once per sample
        m = traj.y.shape[-1]
        shift = m * np.log(s)
        np.testing.assert_allclose(big.loglik + shift, one.loglik, rtol=0,
                                   atol=8 * EPS * (np.abs(one.loglik).max() + 2 * shift))


@pytest.mark.parametrize("name", FILTERS)
def test_a_prior_of_1e300_is_as_diffuse_as_1e12_after_the_first_update(name, traj):
    diffuse, huge = run(name, traj, p0=1e12), run(name, traj, p0=1e300)
    assert np.all(np.isfinite(huge.x)) and np.all(np.isfinite(huge.P))
    # The first measurement sees the whole state (C invertible): the posterior is
    # (P0^-1 + H)^-1 = H^-1 - H^-1 P0^-1 H^-1 + ..., H = C' R^-1 C, so the prior 1e12 differs
    # from the diffuse limit by ||H^-1|| / 1e12 relative, which the stable filter carries
    # forward without growth over its K samples; 1e300 is the limit to rounding.
    H_inv = np.linalg.inv(C.T @ np.linalg.solve(R, C))
    rtol = 10 * np.linalg.norm(H_inv, 2) / 1e12 + 8 * traj.t.size * EPS
    np.testing.assert_allclose(huge.x, diffuse.x, rtol=rtol, atol=rtol * np.abs(diffuse.x).max())
    np.testing.assert_allclose(huge.P, diffuse.P, rtol=rtol, atol=rtol * np.abs(diffuse.P).max())
    if diffuse.mode_prob is not None:
        np.testing.assert_allclose(huge.mode_prob, diffuse.mode_prob, atol=rtol)


CATALOG_EXTREMES = [
    ("shankar-boost", "P0"),  # the inductor current is seen only through the dynamics
    ("wang-ieee5bus", "P0"),
    ("shankar-vehicle", "y"),  # every measurement 1e50 times too large: IMM mixtures 1e48 apart
    ("zhang-smart-grid", "y"),
]


def _steps(sys, t):
    """Every mode's transition matrix over the longest sampling interval of ``t``."""
    if sys.domain == "discrete":
        return sys.A
    return np.stack([expm(A * np.diff(t).max()) for A in sys.A])


@pytest.mark.parametrize("name, what", CATALOG_EXTREMES)
def test_ill_conditioned_catalog_problems_run_and_keep_psd_covariances(name, what):
    spec = catalog()[name]
    sys = spec.system
    t = spec.sample_times(rng=0)[:30]
    n, L = sys.n_states, sys.n_modes
    traj = simulate(sys, spec.signal(np.random.default_rng(0), t), t, (np.zeros(n), np.eye(n)),
                    u=np.ones(sys.n_inputs), rng=1)
    y = traj.y * 1e50 if what == "y" else traj.y
    p0 = 1e300 * np.eye(n) if what == "P0" else np.eye(n)
    transition = np.full((L, L), 0.1 / (L - 1)) + (0.9 - 0.1 / (L - 1)) * np.eye(L)
    filters = [ModeKalmanFilter(sys, np.zeros(n), p0), IMMFilter(sys, transition, np.zeros(n), p0)]
    for est in filters:
        kw = {"modes": traj.mode} if isinstance(est, ModeKalmanFilter) else {}
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # an overflow or NaN warning fails the test, but
            # a covariance whose condition exceeds 1/eps is repaired with a RuntimeWarning
            warnings.filterwarnings("ignore", "the state covariance P is singular or indefinite",
                                    RuntimeWarning)
            out = est.run(y, np.ones(sys.n_inputs), t, **kw)
        assert np.all(np.isfinite(out.x)) and np.all(np.isfinite(out.P))
        scale = np.abs(out.P).max(axis=(-2, -1))
        # Joseph's form M P M' + K R K' after the prediction F P F' + Qd is PSD to its rounding:
        # n-term products whose entries carry up to about 2 n eps of |F| |P| |F'| and
        # |M| |P| |M'| each (|M|^2 a few units, |F|^2 up to 1.4e4 on the 5-bus system): a
        # negative eigenvalue within 8 n^2 eps |F|^2 of the scale is rounding
        growth = max(1.0, float(np.max(np.linalg.norm(_steps(sys, t), ord=2, axis=(1, 2)))) ** 2)
        assert np.all(np.linalg.eigvalsh(out.P)[..., 0] >= -8 * n**2 * EPS * growth * scale)
        if out.mode_prob is not None:
            np.testing.assert_allclose(out.mode_prob.sum(-1), 1.0, rtol=4 * L * EPS)


def test_a_covariance_that_leaves_the_floating_point_range_is_reported():
    sys = SwitchedLinearSystem.discrete([[[1e200]]], C=[[1.0]], Q=[[1.0]], R=[[1.0]], dt=1.0)
    est = ModeKalmanFilter(sys, np.zeros(1), [[1.0]])  # P = 1e400 P+ after one step
    with np.errstate(over="ignore"), pytest.raises(np.linalg.LinAlgError,
                                                   match="the state covariance P is not finite"):
        est.run(np.zeros((3, 1)), modes=np.zeros(3, dtype=int))


def test_repair_is_announced():
    spec = catalog()["wang-ieee5bus"]
    sys = spec.system
    t = spec.sample_times(rng=0)[:10]
    n = sys.n_states
    modes = np.zeros(t.size, dtype=int)
    y = np.zeros((t.size, sys.n_outputs))
    with pytest.warns(RuntimeWarning, match="singular or indefinite to working precision"):
        ModeKalmanFilter(sys, np.zeros(n), 1e300 * np.eye(n)).run(y, t=t, modes=modes)
