"""The steady-state Kalman gain of one mode, from its discrete algebraic Riccati equation.

A design, not a filter: :class:`switchest.estimators.ModeKalmanFilter` runs with these gains
and :mod:`.mode_mismatch` computes the bias they leave under mode mismatch (Zhang &
Natarajan, paper 001, eq. (6)).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_discrete_are

from .._linalg import symmetrize

__all__ = ["steady_state_gain"]


def steady_state_gain(
    F: np.ndarray, C: np.ndarray, Qd: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steady-state filter gain and covariances of :math:`x^+ = F x + w`, :math:`y = C x + v`.

    Solves the discrete algebraic Riccati equation for the a-priori covariance

    .. math::

        P = F P F^\\top - F P C^\\top (C P C^\\top + R)^{-1} C P F^\\top + Q_d

    and returns :math:`K = P C^\\top (C P C^\\top + R)^{-1}` (the filter-form gain of Zhang &
    Natarajan eq. (6), :math:`x_{k|k} = x_{k|k-1} + K (y_k - C x_{k|k-1})`), ``P`` and the
    a-posteriori :math:`(I - K C) P`. Works on one mode; loop over modes outside (L is small
    and the Riccati solver is not batched).

    Parameters
    ----------
    F : ndarray, shape (n, n)
        Transition matrix of the mode.
    C : ndarray, shape (m, n)
        Output matrix.
    Qd, R : ndarray
        Process-noise ``(n, n)`` and measurement-noise ``(m, m)`` covariances per step.

    Returns
    -------
    K : ndarray, shape (n, m)
    P, P_post : ndarray, shape (n, n)
        Steady a-priori and a-posteriori covariances.
    """
    P = solve_discrete_are(F.T, C.T, Qd, R)
    S = C @ P @ C.T + R
    K = np.linalg.solve(S, C @ P).T  # S symmetric: K' = S^-1 C P
    P_post = symmetrize((np.eye(F.shape[0]) - K @ C) @ P)
    return K, symmetrize(P), P_post
