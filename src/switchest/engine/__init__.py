"""switchest's compiled engine: the time loops of the Gaussian filters in C (``c/``), behind
thin Cython bindings (``_*.pyx``), built once by ``pip install``; nothing compiles at run time.

The engine knows arrays, not classes: only :mod:`switchest.estimators` imports it. Each family
has a wrapper module here that checks and converts its arrays once per call
(:mod:`._arrays`; the tables that do not change between calls once per filter, where a
wrapper holds them: :class:`.imm.Bank`, :class:`.kalman.KalmanRun`), allocates the outputs,
splits the batch's trials over threads (:mod:`._parallel`; the calling thread calls the kernel
directly when it runs alone) and calls its kernel, which loops over trials and samples
without the GIL:

- :mod:`.kalman`: the Kalman filter along given transitions (one covariance recursion per
  group of trials that share it) and the fixed-gain filter;
- :mod:`.imm`, :mod:`.gpb`: mode-matched filters with IMM or GPB1 interaction, and GPB2;
- :mod:`.switch_time`: switching-time grid and refinement (Shankar et al.);
- :mod:`.imm_ev1`: Shankar et al.'s Algorithm 1;
- :mod:`.smoother`: Kim's backward pass;
- :mod:`.rbpf`: the Rao-Blackwellized particle filter.

All share the equations of ``c/linalg.c`` (Kalman prediction, equilibrated-Cholesky innovation,
Joseph-form correction, IMM interaction and output). Kernels return a status code instead of
raising: :func:`raise_for_status` raises the package's error for it, and
:func:`warn_for_repairs` the package's ``RuntimeWarning`` for covariances repaired to their
rounding level.
"""

from __future__ import annotations

import warnings

import numpy as np

from ._parallel import MixtureOutput, Report, Reported, set_threads, threads

__all__ = [
    "ACCEPTED",
    "GATED",
    "NOT_FINITE",
    "NOT_POSITIVE_DEFINITE",
    "NO_MEMORY",
    "OK",
    "PARTLY_GATED",
    "MixtureOutput",
    "Report",
    "Reported",
    "raise_for_status",
    "set_threads",
    "threads",
    "warn_for_repairs",
]

# status codes a kernel returns (c/se_common.h)
OK = 0
NOT_POSITIVE_DEFINITE = 1  # an innovation covariance failed its Cholesky factorization
NOT_FINITE = 2  # an innovation covariance holds an infinity or NaN (the covariance overflowed)
NO_MEMORY = 3  # the kernel's scratch space could not be allocated

# per-sample flags a kernel writes
ACCEPTED = 0  # updated (or nothing observed)
GATED = 1  # the measurement was an outlier or failed the gate: treated as missing
PARTLY_GATED = 2  # multiple-model filters: some modes gated the measurement, others used it

_MESSAGES = {
    NOT_POSITIVE_DEFINITE: (
        "innovation covariance C P C' + R is not positive definite: give the system a "
        "measurement noise R or the filter a positive definite P0"
    ),
    NOT_FINITE: (
        "innovation covariance C P C' + R is not finite: the state covariance P is not "
        "finite, it overflowed (an unstable mode over long intervals, a huge P0, or an x0 so "
        "large that the spread of the modes' means overflows)"
    ),
}


def raise_for_status(status: int) -> None:
    """Raise ``numpy.linalg.LinAlgError`` with the package's message for a kernel's failure
    code (``MemoryError`` when its scratch space could not be allocated); return quietly for
    ``OK``."""
    if status == OK:
        return
    if status == NO_MEMORY:
        raise MemoryError("the filter's scratch space could not be allocated")
    raise np.linalg.LinAlgError(_MESSAGES[status])


def warn_for_repairs(output) -> None:
    """Issue the package's ``RuntimeWarning`` if a kernel's output reports covariances
    repaired to their rounding level: their condition number was beyond ``1/eps`` (the numpy
    core's message, for the same event)."""
    if output.repaired:
        warnings.warn(
            "the state covariance P is singular or indefinite to working precision (condition "
            "number beyond 1/eps): its eigenvalues were raised to its rounding level (its "
            f"smallest eigenvalue was {output.smallest_eigenvalue:.3g})",
            RuntimeWarning,
            stacklevel=3,
        )
