"""Accuracy measures over trials and time.

Arrays follow the package layout: trials first, time next, state last. Samples
where the estimate is NaN are excluded and counted, never silently averaged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._checks import float_array, int_array

__all__ = ["RMSE", "rmse", "mode_accuracy", "switch_time_error"]


@dataclass(frozen=True, eq=False)
class RMSE:
    """Root-mean-square error of a state estimate.

    Attributes
    ----------
    per_step : ndarray, shape (K, n)
        RMSE over trials at each sample, per state component (the curves of
        Shankar et al. Fig. 4).
    overall : ndarray, shape (n,)
        RMSE over trials and the samples from ``start`` on, per component (the
        entries of Shankar et al. Table I).
    """

    per_step: np.ndarray
    overall: np.ndarray


def rmse(estimate, truth, *, start: int = 0) -> RMSE:
    """RMSE of ``estimate`` against ``truth``, both ``(N, K, n)`` or ``(K, n)``.

    ``start`` drops the first samples (the filter's initial transient) from the
    time average.
    """
    est = float_array(estimate, "estimate")
    ref = float_array(truth, "truth")
    if est.shape != ref.shape or est.ndim not in (2, 3):
        raise ValueError(f"estimate and truth must share a shape (N, K, n) or (K, n), "
                         f"got {est.shape} and {ref.shape}")
    if est.ndim == 2:
        est, ref = est[None], ref[None]
    start = _check_start(start, est.shape[1])
    sq = (est - ref) ** 2
    with np.errstate(invalid="ignore"):
        per_step = np.sqrt(np.nanmean(sq, axis=0))
        overall = np.sqrt(np.nanmean(sq[:, start:], axis=(0, 1)))
    return RMSE(per_step=per_step, overall=overall)


def mode_accuracy(estimated, true, *, start: int = 0) -> float:
    """Fraction of samples (from ``start`` on) whose estimated mode equals the true one."""
    est = int_array(estimated, "estimated")
    ref = int_array(true, "true")
    if est.shape != ref.shape or est.ndim < 1:
        raise ValueError(f"estimated and true must share a shape (..., K), "
                         f"got {est.shape} and {ref.shape}")
    start = _check_start(start, est.shape[-1])
    return float(np.mean(est[..., start:] == ref[..., start:]))


def switch_time_error(estimated, true) -> np.ndarray:
    """Absolute errors of estimated switching instants where both exist.

    ``estimated`` and ``true`` are ``(..., K)`` arrays of switching instants per
    sample interval (NaN where there is no switch), e.g. ``Estimate.switch_time``
    and the true instants from the trajectory's segments. Returns the flat array
    of ``|estimated - true|`` over intervals where both are finite.
    """
    est = float_array(estimated, "estimated")
    ref = float_array(true, "true")
    if est.shape != ref.shape:
        raise ValueError(f"estimated and true must share a shape, got {est.shape} and {ref.shape}")
    both = np.isfinite(est) & np.isfinite(ref)
    return np.abs(est[both] - ref[both])


def _check_start(start, K: int) -> int:
    """``start`` as a sample index in ``0..K-1``."""
    if isinstance(start, (bool, np.bool_)) or not isinstance(start, (int, np.integer)):
        raise TypeError(f"start must be an int sample index, got {type(start).__name__}")
    if not 0 <= start < K:
        raise ValueError(f"start must be in 0..{K - 1}, got {start}")
    return int(start)
