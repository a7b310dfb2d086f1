"""Etienne, Motchon, Duviella & Guelton §4: the academic example and its scenario."""

import dataclasses
import math

import numpy as np
import pytest

from switchest.models.etienne import ETIENNE_SCENARIO, EtienneScenario, etienne_academic

PAPER = {
    "provenance": "Etienne, Motchon, Duviella, Guelton, §4 (4.1 Syntheses, Analyse)",
    "A": [[[0.2, -0.5], [0.5, -0.3]], [[0.2, 0.3], [-1.0, 0.4]]],
    "B": [[[-0.4], [1.8]], [[0.1], [1.5]]],
    "C": [[[1.0, 0.0]], [[1.0, 0.0]]],
    "tau": (0.3, 0.4),
    "s": 7.0,
    "theorem8": {"alpha": 0.2, "mu_s": 5.0, "mu_c": 0.98},
    "theorem10": {"delta": 0.15, "mu_c_bar": 5.0, "alpha_bar": 3.0},
    "K": [[[2.1124, -0.9336]], [[-1.3111, -1.3158]]],
}


def test_matrices_equal_the_printed_ones():
    sys = etienne_academic()
    np.testing.assert_array_equal(sys.A, PAPER["A"])
    np.testing.assert_array_equal(sys.B, PAPER["B"])
    np.testing.assert_array_equal(sys.C, PAPER["C"])
    assert sys.is_continuous and not sys.has_measurement_noise and not np.any(sys.Q)


def test_modes_are_observable_and_only_mode_one_is_stable():
    sys = etienne_academic()
    for i in range(2):
        W = np.vstack([sys.C[i], sys.C[i] @ sys.A[i]])
        assert np.linalg.matrix_rank(W) == 2  # (A_i, C_i) observable (Remark 9: detectable)
    real = [np.linalg.eigvals(A).real.max() for A in sys.A]
    assert real[0] < 0 < real[1]  # "not necessary for the system to be stable" (§4.1)


def test_scenario_holds_the_printed_values():
    s = ETIENNE_SCENARIO
    assert (s.tau_min, s.tau_max) == PAPER["tau"] and s.dwell == PAPER["s"]
    assert (s.alpha, s.mu_s, s.mu_c) == tuple(PAPER["theorem8"].values())
    assert (s.delta, s.mu_c_bar, s.alpha_bar) == tuple(PAPER["theorem10"].values())
    np.testing.assert_array_equal(s.K, PAPER["K"])
    assert s.K.shape == (2, 1, 2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.alpha = 1.0  # type: ignore[misc]
    assert EtienneScenario(delta=0.0).delta == 0.0


def test_controller_stabilizes_each_mode_with_u_equal_K_x():
    """u = K_sigma_hat x_hat (§3.2): each A_i + B_i K_i is Hurwitz; with u = -K x it is not."""
    sys, K = etienne_academic(), ETIENNE_SCENARIO.K
    for i in range(2):
        assert np.linalg.eigvals(sys.A[i] + sys.B[i] @ K[i]).real.max() < 0
        assert np.linalg.eigvals(sys.A[i] - sys.B[i] @ K[i]).real.max() > 0


def test_theorem8_scalar_condition_holds():
    """Condition (9) and the rate (11) with the paper's scalars."""
    s = ETIENNE_SCENARIO
    threshold = math.log(s.mu_s) / s.dwell + math.log(s.mu_c) / s.tau_max
    assert s.alpha > threshold
    assert threshold == pytest.approx(0.17941, abs=1e-5)
    assert 0.5 * (s.alpha - threshold) == pytest.approx(0.010294, abs=1e-6)


def test_theorem10_scalar_condition_fails_with_the_printed_scalars():
    """Condition (28) is positive (violated) for the values §4 says satisfy Theorem 10."""
    s = ETIENNE_SCENARIO
    r = s.delta / s.dwell
    lhs = (
        -s.alpha * (1 - r)
        + s.alpha_bar * r
        + math.log(s.mu_s) / s.dwell
        + math.log(s.mu_c) / s.tau_max * (1 - r)
        + s.delta * math.log(s.mu_c_bar) / (s.tau_min * s.dwell)
    )
    assert lhs == pytest.approx(0.16403, abs=1e-5)
    assert lhs > 0
