"""A measurement far off — overflowing, or beyond a gate — never breaks a Gaussian filter.

The Kalman core rejects it (no update, log-likelihood -inf); the IMM and IMM-EV1 treat a
sample every mode rejects as missing, keep the predicted mode probabilities and flag it in
``Estimate.outlier``; the filter goes on as if the sample had been NaN.
"""

import warnings

import numpy as np
import pytest
from scipy.stats import chi2

from switchest import signals as sg
from switchest.estimators import (
    IMMEV1Filter,
    IMMFilter,
    ModeKalmanFilter,
    SwitchTimeKalmanFilter,
)
from switchest.estimators.kalman import kf_update
from switchest.models import BOOST_INPUT_VOLTAGE, BOOST_SAMPLE_PERIOD, boost_converter
from switchest.simulate import simulate

SYS = boost_converter()
T = BOOST_SAMPLE_PERIOD
TRANSITION = np.array([[0.9, 0.1], [0.2, 0.8]])  # asymmetric
U = [BOOST_INPUT_VOLTAGE]
X0, P0 = np.zeros(2), np.eye(2)
# A rejected sample is handled as a missing one: x, P and the mode probabilities are carried
# over unchanged in both cases, and every later sample repeats the same operations on the same
# numbers, so the runs agree to rounding: a few ulps of each value.
RTOL = 1e-13

FILTERS = {
    "imm": lambda **kw: IMMFilter(SYS, TRANSITION, X0, P0, **kw),
    "imm-ev1": lambda **kw: IMMEV1Filter(SYS, TRANSITION, x0=X0, P0=P0, grid=3, **kw),
    "imm-ev1-marginal": lambda **kw: IMMEV1Filter(SYS, TRANSITION, x0=X0, P0=P0, grid=3,
                                                  switch_time="marginal", **kw),
}


@pytest.fixture(scope="module")
def boost():
    t = sg.periodic(T, 30 * T)
    return simulate(SYS, lambda r: sg.dwell_time(2, t[-1], 3 * T, 6 * T, rng=r), t, X0, u=U,
                    trials=2, rng=0)


def with_sample(traj, k, value):
    y = traj.y.copy()
    y[:, k, 0] = value
    return y


def assert_same_run(a, b):
    for field in ("x", "P", "mode_prob"):
        np.testing.assert_allclose(getattr(a, field), getattr(b, field), rtol=RTOL, atol=0)


@pytest.mark.parametrize("name", FILTERS)
def test_a_1e300_measurement_is_flagged_and_the_filter_goes_on_as_if_it_were_missing(name, boost):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow warning, no NaN
        hit = FILTERS[name]().run(with_sample(boost, 3, 1e300), U, boost.t)
        gap = FILTERS[name]().run(with_sample(boost, 3, np.nan), U, boost.t)
    expected = np.zeros(hit.outlier.shape, dtype=bool)
    expected[:, 3] = True
    np.testing.assert_array_equal(hit.outlier, expected)  # booleans
    assert not gap.outlier.any()
    assert np.all(np.isfinite(hit.x)) and np.all(np.isfinite(hit.P))
    np.testing.assert_allclose(hit.mode_prob.sum(axis=-1), 1.0, rtol=4 * np.finfo(float).eps)
    assert_same_run(hit, gap)


def test_imm_keeps_the_predicted_mode_probabilities_at_the_outlier(boost):
    est = FILTERS["imm"]()
    state = est.step(est.init((2,)), boost.y[:, 0], dt=None)
    u = np.full((2, 1), BOOST_INPUT_VOLTAGE)
    hit = est.step(state, np.full((2, 1), 1e300), u, dt=T)
    predicted = np.exp(state.log_prob) @ TRANSITION  # c_j = sum_i pi_ij mu_i
    np.testing.assert_allclose(np.exp(hit.log_prob), predicted, rtol=1e-14)
    assert hit.outlier.all() and np.all(np.isfinite(hit.loglik))


@pytest.mark.parametrize("name", FILTERS)
def test_a_gate_rejects_a_gross_error_that_is_otherwise_used(name, boost):
    gate = float(chi2.ppf(1 - 1e-6, df=1))  # about 4.9 sigma for one output
    y = boost.y.copy()
    y[:, 5, 0] += 1e3 * np.sqrt(SYS.R[0, 0, 0])  # 1000 sigma of the noise: beyond every hypothesis
    gated = FILTERS[name](gate=gate).run(y, U, boost.t)
    gap = FILTERS[name](gate=gate).run(with_sample(boost, 5, np.nan), U, boost.t)
    ungated = FILTERS[name]().run(y, U, boost.t)
    assert gated.outlier[:, 5].all() and not ungated.outlier.any()
    assert_same_run(gated, gap)
    assert not np.allclose(ungated.x[:, 5], gated.x[:, 5])  # without the gate y[5] is used


@pytest.mark.parametrize("gate, error, match", [
    (-1.0, ValueError, "gate must be a finite positive number"),
    (0.0, ValueError, "gate must be a finite positive number"),
    (np.inf, ValueError, "gate must be a finite positive number"),
    ("9", TypeError, "gate must be a real scalar"),
])
@pytest.mark.parametrize("name", FILTERS)
def test_a_bad_gate_is_refused(name, gate, error, match):
    with pytest.raises(error, match=match):
        FILTERS[name](gate=gate)


KNOWN_MODES = {  # filters given the modes at the samples
    "mode-kf": lambda **kw: ModeKalmanFilter(SYS, X0, P0, **kw),
    "mode-kf-steady": lambda **kw: ModeKalmanFilter(SYS, X0, P0, steady_state=True, **kw),
    "switch-time-max": lambda **kw: SwitchTimeKalmanFilter(SYS, X0, P0, grid=3, **kw),
    "switch-time-refined": lambda **kw: SwitchTimeKalmanFilter(SYS, X0, P0, grid=3, refine=True,
                                                               refine_iterations=4, **kw),
    "switch-time-marginal": lambda **kw: SwitchTimeKalmanFilter(SYS, X0, P0, grid=3,
                                                                switch_time="marginal", **kw),
}


def switched_sample(traj):
    """A sample whose interval holds a switch in every trial, if there is one, else sample 5."""
    both = np.flatnonzero(np.all(traj.mode[:, 1:] != traj.mode[:, :-1], axis=0)) + 1
    return int(both[0]) if both.size else 5


@pytest.mark.parametrize("name", KNOWN_MODES)
def test_known_mode_filters_flag_an_overflowing_measurement_and_go_on(name, boost):
    k = switched_sample(boost)
    run = lambda y, **kw: KNOWN_MODES[name](**kw).run(y, U, boost.t, modes=boost.mode)  # noqa: E731
    hit = run(with_sample(boost, k, 1e300))
    gap = run(with_sample(boost, k, np.nan))
    np.testing.assert_allclose(hit.x, gap.x, rtol=RTOL, atol=0)
    np.testing.assert_allclose(hit.P, gap.P, rtol=RTOL, atol=0)
    assert hit.outlier[:, k].all() and hit.outlier.sum() == hit.outlier[:, k].size
    assert not gap.outlier.any()
    if not name.endswith("steady"):  # the steady-state filter reports no likelihood
        np.testing.assert_allclose(hit.loglik, gap.loglik, rtol=RTOL, atol=0)


@pytest.mark.parametrize("name", KNOWN_MODES)
def test_known_mode_filters_gate_a_gross_error(name, boost):
    k = switched_sample(boost)
    gate = float(chi2.ppf(1 - 1e-6, df=1))
    y = boost.y.copy()
    y[:, k, 0] += 1e3 * np.sqrt(SYS.R[0, 0, 0])
    run = lambda y, **kw: KNOWN_MODES[name](**kw).run(y, U, boost.t, modes=boost.mode)  # noqa: E731
    gated, ungated = run(y, gate=gate), run(y)
    gap = run(with_sample(boost, k, np.nan), gate=gate)
    assert gated.outlier[:, k].all() and not ungated.outlier.any()
    np.testing.assert_allclose(gated.x, gap.x, rtol=RTOL, atol=0)
    assert not np.allclose(ungated.x[:, k], gated.x[:, k])  # without the gate y[k] is used


@pytest.mark.parametrize("name", KNOWN_MODES)
def test_known_mode_filters_refuse_a_bad_gate(name):
    with pytest.raises(ValueError, match="gate must be a finite positive number"):
        KNOWN_MODES[name](gate=-1.0)


def test_core_rejects_beyond_the_gate_only():
    rng = np.random.default_rng(0)
    x, C, R = rng.standard_normal((4, 2)), rng.standard_normal((1, 2)), np.array([[0.5]])
    P = np.broadcast_to(np.eye(2), (4, 2, 2))
    S = (C @ P[0] @ C.T + R).item()
    nis = np.array([0.5, 3.0, 8.0, 30.0])  # normalized innovations squared
    y = (x @ C.T)[:, 0] + np.sqrt(nis * S)
    xn, Pn, ll = kf_update(x, P, y[:, None], C, R, gate=9.0)
    keep = nis <= 9.0
    assert np.all(np.isneginf(ll[~keep])) and np.all(np.isfinite(ll[keep]))
    np.testing.assert_allclose(xn[~keep], x[~keep], rtol=0, atol=0)  # copied, not computed
    np.testing.assert_allclose(Pn[~keep], P[~keep], rtol=0, atol=0)
    # accepted ones: the ordinary update, log N(y; C x, S) = -(nis + log S + log 2 pi) / 2
    np.testing.assert_allclose(ll[keep], -0.5 * (nis[keep] + np.log(S) + np.log(2 * np.pi)),
                               rtol=1e-12)
    assert not np.allclose(xn[keep], x[keep])
