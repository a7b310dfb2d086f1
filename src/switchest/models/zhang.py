"""The two examples of Zhang & Natarajan (paper 001, "On the statistical convergence of
bias in mode-based Kalman filter for switched systems").

Both are discrete-time models :math:`x_k = A_q x_{k-1} + B_q w_k`,
:math:`y_k = C_q x_k + v_k` with :math:`w_k \\sim \\mathcal{N}(0, Q)`,
:math:`v_k \\sim \\mathcal{N}(0, R)` (Zhang eq. (1)). A
:class:`~switchest.system.SwitchedLinearSystem` carries the per-mode process-noise
covariance, so the paper's noise input matrix is folded in: :math:`Q_q = B_q Q B_q^\\top`.
The systems have no control input (``B`` of the returned system is ``(L, n, 0)``).
"""

from __future__ import annotations

from numbers import Real

import numpy as np

from .._checks import positive_scalar
from ..system import SwitchedLinearSystem

__all__ = ["SMART_GRID_TAU", "smart_grid", "zhang_two_mode"]

#: Sampling period that reproduces the printed smart-grid numbers (Zhang §5.2):
#: :math:`\|\Lambda_2\| = 0.8837` and :math:`\|\Lambda_3\| = 0.8611` hold to the printed four
#: decimals for :math:`\tau \in [0.09996, 0.10004]` only; the paper does not state :math:`\tau`.
SMART_GRID_TAU = 0.1

# Zhang & Natarajan, Table 1: one row per mode (1-based q = 1, 2, 3 in the paper),
# columns k_G, alpha, sigma_G, sigma_D.
_TABLE1 = np.array(
    [
        [0.1, 0.1, 0.1, 0.1],  # q = 1, failure mode (L, G, D) = (0, 0, 0)
        [3.0, 0.5, 0.8, 0.8],  # q = 2, grid connected (1, 1, 0)
        [3.0, 0.49, 1.5, 1.0],  # q = 3, grid connected with loads (1, 1, 1)
    ]
)


def zhang_two_mode() -> SwitchedLinearSystem:
    """The second-order, two-mode switched system of Zhang & Natarajan, §5.1 (Example 1).

    .. math::

        \\begin{aligned}
        A_1 &= \\begin{bmatrix} 0.9 & 0 \\\\ 0.2 & 0.8 \\end{bmatrix}, &
        A_2 &= \\begin{bmatrix} 0.5 & 0.2 \\\\ 0.2 & 0.4 \\end{bmatrix}, \\\\
        B_1 &= \\begin{bmatrix} 1 & 0 \\\\ 0 & 0.8 \\end{bmatrix}, &
        B_2 &= \\begin{bmatrix} 1.3 & 0.4 \\\\ 0.2 & 0.7 \\end{bmatrix}, \\\\
        C_1 &= I, \\quad C_2 = 5 I, & Q &= 0.5 I, \\quad R = 0.3 I.
        \\end{aligned}

    Returns
    -------
    SwitchedLinearSystem
        Discrete time, step 1 (the paper gives none), with process-noise covariance
        :math:`B_q Q B_q^\\top` per mode and :math:`R = 0.3 I` for both modes.
    """
    A = np.array([[[0.9, 0.0], [0.2, 0.8]], [[0.5, 0.2], [0.2, 0.4]]])
    B = np.array([[[1.0, 0.0], [0.0, 0.8]], [[1.3, 0.4], [0.2, 0.7]]])
    C = np.array([np.eye(2), 5.0 * np.eye(2)])
    Q = 0.5 * np.eye(2)
    return SwitchedLinearSystem.discrete(
        A, C=C, Q=B @ Q @ np.swapaxes(B, -1, -2), R=0.3 * np.eye(2), dt=1.0
    )


def smart_grid(tau: float = SMART_GRID_TAU) -> SwitchedLinearSystem:
    """The three-mode smart-grid model of Zhang & Natarajan, §2.2 and §5.2 (Table 1).

    State :math:`x = [P_G, P_D]^\\top` (grid power, load power) of the SDE
    :math:`dx = \\operatorname{diag}(k_G, -\\alpha)\\, x\\, dt
    + \\operatorname{diag}(\\sigma_G, \\sigma_D)\\, dW`, sampled with period
    :math:`\\tau` as the paper does it (eqs. (3)–(4)):

    .. math::

        \\begin{aligned}
        A_q &= \\operatorname{diag}(e^{k_G \\tau}, e^{-\\alpha \\tau}), \\\\
        B_q &= \\operatorname{diag}(k_G, -\\alpha)^{-1} (A_q - I)
               \\operatorname{diag}(\\sigma_G, \\sigma_D),
        \\end{aligned}

    with Table 1's parameters per mode, :math:`C_q = I`, :math:`Q = 2 I`, :math:`R = I` (§5.2).
    Eq. (4) is the paper's discretization of the noise (a zero-order-hold input
    :math:`B_q w_k` with :math:`\\operatorname{Var} w_k = Q`), not the exact sampled covariance
    of the SDE;
    it is kept because the printed numbers depend on it.

    Parameters
    ----------
    tau : float, optional
        Sampling period. The paper does not state it; the default
        :data:`SMART_GRID_TAU` ``= 0.1`` is the value that reproduces the printed
        :math:`\\|\\Lambda_2\\| = 0.8837`, :math:`\\|\\Lambda_3\\| = 0.8611` and the printed
        :math:`T_{i,q}` of §5.2 (found by a one-dimensional search; see
        ``tests/data/zhang_smart_grid.json``). The printed :math:`\\|\\Lambda_1\\| = 0.9817`
        is not a steady-state value at any :math:`\\tau` that also gives the other two: it is
        the Algorithm 1 gain after about 100 steps (see
        :func:`switchest.analysis.mode_mismatch.riccati_gains`).

    Returns
    -------
    SwitchedLinearSystem
        Discrete time with ``dt = tau``; mode :math:`q - 1` is the paper's mode :math:`q`.
        Process-noise covariance per mode :math:`B_q Q B_q^\\top`. :math:`P_G` is unstable in
        every mode (:math:`k_G > 0`), so the switched system is unstable.

    Raises
    ------
    ValueError, TypeError
        If ``tau`` is not a finite positive real number.
    """
    if not isinstance(tau, Real):  # positive_scalar alone would accept the string "0.1"
        raise TypeError(f"tau must be a real scalar, got {type(tau).__name__}")
    tau = positive_scalar(tau, "tau")
    rate = np.stack([_TABLE1[:, 0], -_TABLE1[:, 1]], axis=1)  # (3, 2) diagonal of the SDE drift
    sigma = _TABLE1[:, 2:]  # (3, 2) diagonal of the diffusion
    a = np.exp(rate * tau)
    b = (a - 1.0) / rate * sigma  # eq. (4), diagonal
    A = _diag(a)
    Q = _diag(2.0 * b * b)  # B_q (2 I) B_q' for diagonal B_q
    return SwitchedLinearSystem.discrete(A, C=np.eye(2), Q=Q, R=np.eye(2), dt=tau)


def _diag(d: np.ndarray) -> np.ndarray:
    """Stack of diagonal matrices from a (L, n) array of diagonals."""
    return d[:, :, None] * np.eye(d.shape[1])
