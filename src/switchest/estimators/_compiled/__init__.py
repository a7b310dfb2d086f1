"""The compiled time loops of the Gaussian filters (numba ``njit``, ``cache=True``).

One implementation of each equation: the functions of :mod:`.linalg` (Kalman prediction,
equilibrated-Cholesky innovation, Joseph-form correction, IMM interaction and output) over
blocks of trials laid across SIMD lanes, called by the kernels that loop over trials and
samples: :mod:`.kalman_kernel` (the Kalman filter, one covariance recursion per group of
trials that share it), :mod:`.bank` (mode-matched filters with IMM interaction),
:mod:`.switch_time` (switching-time grid and refinement) and :mod:`.imm_ev1` (Shankar et al.'s
Algorithm 1). ``run`` calls a kernel on a whole record, ``step`` (the streaming API) on one
sample. Kernels return a status code instead of raising;
:func:`raise_for_status` raises the package's error for it, and :func:`warn_for_repairs` the
package's ``RuntimeWarning`` for covariances repaired to their rounding level.
"""

from __future__ import annotations

import warnings

import numpy as np

from .imm import IMMOutput, imm_run, imm_run_per_trial, imm_step
from .kalman import KalmanOutput, kalman_run, kalman_steady_run, kalman_steady_step, kalman_step
from .linalg import ACCEPTED, GATED, NOT_FINITE, NOT_POSITIVE_DEFINITE, OK, PARTLY_GATED

__all__ = [
    "ACCEPTED",
    "GATED",
    "PARTLY_GATED",
    "IMMOutput",
    "KalmanOutput",
    "imm_run",
    "imm_run_per_trial",
    "imm_step",
    "kalman_run",
    "kalman_steady_run",
    "kalman_steady_step",
    "kalman_step",
    "raise_for_status",
    "warn_for_repairs",
]

_MESSAGES = {
    NOT_POSITIVE_DEFINITE: (
        "innovation covariance C P C' + R is not positive definite: give the system a "
        "measurement noise R or the filter a positive definite P0"
    ),
    NOT_FINITE: (
        "innovation covariance C P C' + R is not finite: the state covariance P is not "
        "finite, it overflowed (an unstable mode over long intervals, or a huge P0)"
    ),
}


def raise_for_status(status: int) -> None:
    """Raise ``numpy.linalg.LinAlgError`` with the package's message for a kernel's failure
    code; return quietly for ``OK``."""
    if status == OK:
        return
    raise np.linalg.LinAlgError(_MESSAGES[status])


def warn_for_repairs(output) -> None:
    """Issue the package's ``RuntimeWarning`` if a kernel's output (:class:`IMMOutput`,
    :class:`KalmanOutput`, ...) reports covariances repaired to their rounding level: their
    condition number was beyond ``1/eps`` (the numpy core's message, for the same event)."""
    if output.repaired:
        warnings.warn(
            "the state covariance P is singular or indefinite to working precision (condition "
            "number beyond 1/eps): its eigenvalues were raised to its rounding level (its "
            f"smallest eigenvalue was {output.smallest_eigenvalue:.3g})",
            RuntimeWarning,
            stacklevel=3,
        )
