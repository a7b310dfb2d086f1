"""SwitchedLinearSystem: constructors, broadcasting of shared matrices, validation."""

from types import SimpleNamespace

import numpy as np
import pytest

from switchest import SwitchedLinearSystem


def two_modes():
    A = np.array([[[0.0, 1.0], [-2.0, -3.0]], [[-1.0, 0.0], [0.5, -0.2]]])
    return A


def test_shared_matrices_broadcast_to_every_mode():
    sys = SwitchedLinearSystem.continuous(two_modes(), B=[[0.0], [1.0]], C=[[1.0, 0.0]],
                                          Q=np.eye(2), R=[[0.5]])
    assert (sys.n_modes, sys.n_states, sys.n_inputs, sys.n_outputs) == (2, 2, 1, 1)
    assert sys.B.shape == (2, 2, 1) and sys.C.shape == (2, 1, 2)
    np.testing.assert_array_equal(sys.R[1], [[0.5]])
    assert sys.domain == "continuous" and sys.dt is None


def test_defaults_mean_no_input_full_state_no_noise():
    sys = SwitchedLinearSystem.discrete(two_modes(), dt=0.1)
    assert sys.B.shape == (2, 2, 0)
    np.testing.assert_array_equal(sys.C[0], np.eye(2))
    assert not sys.has_measurement_noise and not np.any(sys.Q)
    assert sys.dt == 0.1 and not sys.is_continuous


def test_arrays_are_read_only_copies():
    A = two_modes()
    sys = SwitchedLinearSystem.continuous(A)
    A[0, 0, 0] = 99.0
    assert sys.A[0, 0, 0] == 0.0
    with pytest.raises(ValueError):
        sys.A[0, 0, 0] = 1.0


def test_from_statespace_reads_ABCD_attributes():
    mods = [SimpleNamespace(A=a, B=np.ones((2, 1)), C=np.eye(2), D=np.zeros((2, 1)), dt=0.0)
            for a in two_modes()]
    sys = SwitchedLinearSystem.from_statespace(mods, R=np.eye(2))
    assert sys.is_continuous and sys.n_modes == 2
    np.testing.assert_array_equal(sys.A, two_modes())
    disc = [SimpleNamespace(A=a, B=np.ones((2, 1)), C=np.eye(2), D=0, dt=0.5) for a in two_modes()]
    assert SwitchedLinearSystem.from_statespace(disc).dt == 0.5


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(A=np.zeros((2, 2, 3))), "A must be square"),
        (dict(A=np.zeros((0, 2, 2))), "at least one mode"),
        (dict(A=two_modes(), B=np.zeros((3, 2, 1))), "disagree on the number of modes"),
        (dict(A=two_modes(), B=np.zeros((3, 1))), r"B must be \(n, l\)"),
        (dict(A=two_modes(), C=np.zeros((1, 3))), r"C must be \(m, n\)"),
        (dict(A=np.full((2, 2), np.nan)), "A must be finite"),
        (dict(A=two_modes(), Q=[[1.0, 0.5], [0.0, 1.0]]), "Q must be symmetric"),
        (dict(A=two_modes(), Q=[[1.0, 0.0], [0.0, -0.3]]), "eigenvalue -0.3"),
        (dict(A=two_modes(), C=[[1.0, 0.0]], R=[[0.0]]), "R must be symmetric positive definite"),
        (dict(A=two_modes(), R=np.eye(3)), r"R must be \(m, m\)"),
        (dict(A=np.zeros(3)), "A must have 2 or 3 dimensions"),
    ],
)
def test_bad_input_names_the_argument(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SwitchedLinearSystem.continuous(**kwargs)


def test_bad_types_and_steps():
    with pytest.raises(TypeError, match="A must be numeric"):
        SwitchedLinearSystem.continuous("abc")
    with pytest.raises(ValueError, match="dt must be a finite positive"):
        SwitchedLinearSystem.discrete(two_modes(), dt=0.0)
    with pytest.raises(ValueError, match=r"D must be zero"):
        SwitchedLinearSystem.from_statespace(
            [SimpleNamespace(A=np.eye(1), B=np.eye(1), C=np.eye(1), D=np.eye(1))])
    with pytest.raises(ValueError, match="share one time base"):
        SwitchedLinearSystem.from_statespace(
            [SimpleNamespace(A=np.eye(1), B=np.eye(1), C=np.eye(1), D=0, dt=dt) for dt in (0, 0.1)]
        )
    with pytest.raises(TypeError, match="missing D"):
        SwitchedLinearSystem.from_statespace(
            [SimpleNamespace(A=np.eye(1), B=np.eye(1), C=np.eye(1))])


def test_replace_keeps_the_domain_and_checks_the_new_matrices():
    sys = SwitchedLinearSystem.discrete(two_modes(), dt=0.25)
    new = sys.replace(Q=2 * np.eye(sys.n_states))
    assert new.domain == "discrete" and new.dt == 0.25
    np.testing.assert_array_equal(new.Q, np.broadcast_to(2 * np.eye(sys.n_states), sys.Q.shape))
    np.testing.assert_array_equal(new.A, sys.A)
    assert SwitchedLinearSystem.continuous(two_modes()).replace(R=np.eye(2)).is_continuous
    with pytest.raises(ValueError, match="Q must be symmetric"):
        sys.replace(Q=-np.eye(sys.n_states))
    with pytest.raises(TypeError, match=r"replace takes A, B, C, Q, R, timing, got \['D'\]"):
        sys.replace(D=0)
