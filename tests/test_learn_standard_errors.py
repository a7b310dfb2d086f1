"""Standard errors from the observed information (switchest.learn.standard_errors) on a
log-likelihood whose curvature is known: a quadratic in the free entries, so the central
differences are exact up to rounding."""

import numpy as np
import pytest

from switchest.learn.standard_errors import observed_standard_errors
from switchest.system import SwitchedLinearSystem

PI = np.array([[0.9, 0.1], [0.3, 0.7]])
SD = {"pi01": 0.02, "pi10": 0.05, "Q0": 0.1, "R0": 0.03, "R1": 0.04}


def _system(Q1):
    return SwitchedLinearSystem.discrete([[[0.9]], [[0.5]]], None, [[[1.0]], [[1.0]]],
                                         [[[0.5]], [[Q1]]], [[[0.2]], [[0.3]]], dt=1.0)


def _loglik(system, pi, *, Q1, bowl, center=PI):
    """A Gaussian log-likelihood in the entries, maximal at the system's own values and the
    transition matrix ``center``; mode 1's Q enters with curvature ``bowl`` (positive: a
    boundary point, not a maximum, along it)."""
    values = {"pi01": pi[0, 1] - center[0, 1], "pi10": pi[1, 0] - center[1, 0],
              "Q0": system.Q[0, 0, 0] - 0.5, "R0": system.R[0, 0, 0] - 0.2,
              "R1": system.R[1, 0, 0] - 0.3}
    return (-0.5 * sum((v / SD[k]) ** 2 for k, v in values.items())
            + bowl * (system.Q[1, 0, 0] - Q1) ** 2)


def _each(**kwargs):
    """The batched form observed_standard_errors calls: candidates to their log-likelihoods."""
    return lambda candidates: np.array([_loglik(s, pi, **kwargs) for s, pi in candidates])


@pytest.mark.parametrize("center", [PI, np.array([[0.9, 0.1], [0.7, 0.3]])])
def test_interior_standard_errors_are_the_curvature(center):
    """Also with a row whose largest entry (the dependent one) is off the diagonal."""
    Q1 = 0.4
    se = observed_standard_errors(
        _system(Q1), center, ("transition", "Q", "R"),
        _each(Q1=Q1, bowl=-0.5 / 0.07**2, center=center))
    np.testing.assert_allclose(se["transition"], [[0.02, 0.02], [0.05, 0.05]], rtol=1e-6)
    np.testing.assert_allclose(se["Q"].ravel(), [0.1, 0.07], rtol=1e-6)
    np.testing.assert_allclose(se["R"].ravel(), [0.03, 0.04], rtol=1e-6)


def test_an_entry_on_the_boundary_is_held_fixed_and_named():
    Q1 = 1e-7  # mode 1's Q at zero, where the likelihood still rises towards the boundary
    with pytest.warns(RuntimeWarning, match=r"on the boundary .* at Q mode 1 \[0,0\]"):
        se = observed_standard_errors(_system(Q1), PI, ("transition", "Q", "R"),
                                      _each(Q1=Q1, bowl=1e9))
    assert np.isnan(se["Q"][1, 0, 0])
    np.testing.assert_allclose(se["Q"][0, 0, 0], 0.1, rtol=1e-6)
    np.testing.assert_allclose(se["transition"], [[0.02, 0.02], [0.05, 0.05]], rtol=1e-6)
    np.testing.assert_allclose(se["R"].ravel(), [0.03, 0.04], rtol=1e-6)


def test_an_entry_without_positive_information_is_held_fixed_and_named():
    """An interior saddle along mode 1's Q (not a maximum there): that entry is named and held
    fixed, the others' standard errors are their curvature (the likelihood separates)."""
    Q1 = 0.4
    with pytest.warns(RuntimeWarning, match=r"not positive definite at the fit along Q mode 1 "
                                            r"\[0,0\]"):
        se = observed_standard_errors(_system(Q1), PI, ("Q", "R"),
                                      _each(Q1=Q1, bowl=1.0))
    assert np.isnan(se["Q"][1, 0, 0])
    np.testing.assert_allclose(se["Q"][0, 0, 0], 0.1, rtol=1e-6)
    np.testing.assert_allclose(se["R"].ravel(), [0.03, 0.04], rtol=1e-6)


def test_no_positive_definite_information_gives_no_standard_errors():
    """Every entry's curvature points away from a maximum: no standard error at all."""
    def bowl(candidates):
        return np.array([(s.Q[0, 0, 0] - 0.5) ** 2 + (s.R[0, 0, 0] - 0.2) ** 2
                         for s, _ in candidates])

    with pytest.warns(RuntimeWarning, match="observed information of Q, R is not positive"):
        se = observed_standard_errors(_system(0.4), PI, ("Q", "R"), bowl)
    assert np.all(np.isnan(se["Q"])) and np.all(np.isnan(se["R"]))


def test_a_transition_the_fit_moved_to_zero_is_on_the_boundary():
    """An entry nonzero at the start (``allowed``) and zero at the fit is named and held fixed;
    its row's dependent entry is then fixed too (standard error 0), the other row unchanged."""
    Q1, fitted = 0.4, np.array([[1.0, 0.0], [0.3, 0.7]])
    with pytest.warns(RuntimeWarning, match=r"on the boundary .* at transition 0->1"):
        se = observed_standard_errors(_system(Q1), fitted, ("transition", "Q", "R"),
                                      _each(Q1=Q1, bowl=-0.5 / 0.07**2, center=fitted),
                                      allowed=PI > 0)
    assert np.isnan(se["transition"][0, 1]) and se["transition"][0, 0] == 0.0
    np.testing.assert_allclose(se["transition"][1], [0.05, 0.05], rtol=1e-6)
    np.testing.assert_allclose(se["R"].ravel(), [0.03, 0.04], rtol=1e-6)
