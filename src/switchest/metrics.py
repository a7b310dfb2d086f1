"""Accuracy measures over trials and time.

Arrays follow the package layout: trials first, time next, state last. Samples
where the estimate is NaN are excluded and counted, never silently averaged.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ._checks import float_array, int_array

__all__ = ["FEWEST_SAMPLES", "IMPLAUSIBLE_Z", "RMSE", "InnovationConsistency",
           "innovation_consistency", "rmse", "mode_accuracy", "switch_time_error"]

IMPLAUSIBLE_Z = 4.0
""":math:`|z|` of :class:`InnovationConsistency` beyond which a filter's (or a fit's) residuals are
implausible for a model that fits the data."""
FEWEST_SAMPLES = 20
"""Samples below which the consistency check says nothing."""


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
    err = est - ref
    return RMSE(per_step=_rms(err, axis=(0,)), overall=_rms(err[:, start:], axis=(0, 1)))


def _rms(err: np.ndarray, axis: tuple[int, ...]) -> np.ndarray:
    """:math:`\\sqrt{\\operatorname{nanmean}(\\mathrm{err}^2)}` over ``axis``, the errors divided by
    their largest magnitude first so that their squares neither overflow (errors of 1e200) nor
    underflow; infinite where an error is."""
    with warnings.catch_warnings():  # an all-NaN slice: nanmean below says so
        warnings.filterwarnings("ignore", "All-NaN slice", RuntimeWarning)
        scale = np.nanmax(np.abs(err), axis=axis)
    unit = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
    with np.errstate(invalid="ignore", over="ignore"):
        out = unit * np.sqrt(np.nanmean((err / np.expand_dims(unit, axis)) ** 2, axis=axis))
    return np.where(np.isinf(scale), np.inf, out)


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
    of :math:`|\\mathrm{estimated} - \\mathrm{true}|` over intervals where both are finite.
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


@dataclass(frozen=True)
class InnovationConsistency:
    """Whether a Kalman-type filter's residuals match the covariance it claims.

    Attributes
    ----------
    mean_nis : float
        Mean normalized innovation squared over the samples used.
    expected : float
        Its expectation for a consistent filter: the mean number of observed outputs.
    samples : int
        Samples used (observed, not gated, with a finite estimate).
    z : float
        :math:`(\\mathrm{mean\\_nis} - \\mathrm{expected}) / \\mathrm{sd}`,
        :math:`\\mathrm{sd} = \\sqrt{2\\, \\mathrm{expected} / \\mathrm{samples}}` (the NIS of a
        consistent filter is chi-square with ``m`` degrees of freedom, independent over time).
    """

    mean_nis: float
    expected: float
    samples: int
    z: float


def innovation_consistency(system, y, x, P, modes, *, used=None) -> InnovationConsistency:
    """The normalized innovations squared of a filter, recovered from its posterior estimates.

    For a Kalman update with gain :math:`K = P^- C^\\top S^{-1}` the posterior residual
    :math:`r = y - C x^+` equals :math:`R S^{-1} e` (:math:`e` the innovation,
    :math:`S = C P^- C^\\top + R`), and :math:`R - C P^+ C^\\top = R S^{-1} R`; hence
    :math:`r^\\top (R - C P^+ C^\\top)^{-1} r = e^\\top S^{-1} e`, the NIS, with no
    access to the filter's internals (Bar-Shalom, Li & Kirubarajan §5.4: a consistent filter's
    NIS is chi-square with ``m`` degrees of freedom). Missing components (NaN in ``y``) are left
    out of :math:`r`, :math:`R` and :math:`C`, as the update does.

    Parameters
    ----------
    system : SwitchedLinearSystem
    y : array_like, shape (K, m)
        Measurements (NaN: missing).
    x, P : array_like, shapes (K, n), (K, n, n)
        The filter's posterior means and covariances.
    modes : array_like of int, shape (K,)
        The mode whose ``C``, ``R`` each update used.
    used : array_like of bool, shape (K,), optional
        The samples the filter used (False: gated as an outlier); default all.
    """
    y = float_array(y, "y", ndim=2)
    x = float_array(x, "x", ndim=2)
    P = float_array(P, "P", ndim=3)
    modes = int_array(modes, "modes", ndim=1)
    K = y.shape[0]
    if x.shape[0] != K or P.shape[0] != K or modes.shape != (K,):
        raise ValueError(f"y, x, P and modes must have the same number of samples, got "
                         f"{y.shape[0]}, {x.shape[0]}, {P.shape[0]}, {modes.shape[0]}")
    used = np.ones(K, dtype=bool) if used is None else np.asarray(used, dtype=bool)
    seen = np.isfinite(y)
    ok = (used & seen.any(axis=1) & np.all(np.isfinite(x), axis=1)
          & np.all(np.isfinite(P), axis=(1, 2)))
    nis, dims = [], []
    # one batch of Cholesky solves per (mode, observed components): no loop over samples
    patterns = np.concatenate([modes[:, None], seen], axis=1)[ok]
    for key in np.unique(patterns, axis=0):
        at = np.flatnonzero(ok)[np.all(patterns == key, axis=1)]
        obs = key[1:].astype(bool)
        C = system.C[key[0]][obs]
        M = system.R[key[0]][np.ix_(obs, obs)] - C @ P[at] @ C.T  # (k, o, o)
        r = y[at][:, obs] - x[at] @ C.T
        M = (M + np.swapaxes(M, 1, 2)) / 2
        # R S^-1 R is positive definite for a proper update: a sample where it is not (by
        # eigenvalue) is left out rather than failing the batch factorization
        eig = np.linalg.eigvalsh(M)
        proper = eig[:, 0] > 1e-12 * np.abs(eig[:, -1])
        root = np.linalg.cholesky(M[proper])
        w = np.linalg.solve(root, r[proper][..., None])[..., 0]
        nis += np.sum(w**2, axis=1).tolist()
        dims += [int(obs.sum())] * int(proper.sum())
    if not nis:
        return InnovationConsistency(np.nan, np.nan, 0, np.nan)
    mean, expected = float(np.mean(nis)), float(np.mean(dims))
    return InnovationConsistency(mean, expected, len(nis),
                                 (mean - expected) / np.sqrt(2 * expected / len(nis)))
