"""Whether a fit's timing of the switches can represent the data: the innovations after the mode
changes.

A fit with known modes switching at the samples holds each mode over the whole interval after
its sample. On data whose switches fall inside the intervals that is wrong exactly at the
intervals where the mode changes, and the fit puts the model error into ``Q`` and ``R``: the
normalized innovations squared (NIS) of the fitted model's Kalman filter then average about
their dimension ``m`` overall, the fit having made them so, but far more after a mode change
than elsewhere. A model that fits has NIS chi-square with ``m`` degrees of freedom at every
sample (Bar-Shalom, Li & Kirubarajan 2001, §5.4), so the mean over the ``S`` samples after a
mode change lies within a few :math:`\\sqrt{2 m / S}` of ``m``
(:func:`switchest.metrics.innovation_consistency`, the check of ``switchest estimate``).
"""

from __future__ import annotations

import warnings

import numpy as np

from ..estimators import ModeKalmanFilter
from ..metrics import FEWEST_SAMPLES, IMPLAUSIBLE_Z, innovation_consistency
from ..system import SwitchedLinearSystem
from .data import Record

__all__ = ["warn_if_mistimed"]


def warn_if_mistimed(system: SwitchedLinearSystem, x0, P0, data: Record) -> None:
    """Warn (``RuntimeWarning``) when the mean NIS of ``system``'s Kalman filter along the known
    modes over the samples after a mode change is more than
    :data:`~switchest.metrics.IMPLAUSIBLE_Z` standard deviations above its value for a model
    that fits (module docstring)."""
    est = ModeKalmanFilter(system, x0, P0).run(data.y, data.u, data.t, modes=data.modes)
    change = np.zeros(data.shape, dtype=bool)
    change[:, 1:] = data.modes[:, 1:] != data.modes[:, :-1]
    N, K = data.shape
    n = est.x.shape[-1]
    flat = (data.y.reshape(N * K, -1), est.x.reshape(N * K, n), est.P.reshape(N * K, n, n),
            data.modes.reshape(N * K))  # the check is sample by sample: the trials in one row
    after, others = (innovation_consistency(system, *flat, used=where.reshape(N * K))
                     for where in (change, ~change))
    if after.samples < FEWEST_SAMPLES or after.z <= IMPLAUSIBLE_Z:
        return
    mean, expected, samples, z = after.mean_nis, after.expected, after.samples, after.z
    others = ("" if not others.samples else
              f" and {others.mean_nis:.3g} over the {others.samples} others")
    warnings.warn(f"implausible fit: mean normalized innovation squared {mean:.3g} over the "
                  f"{samples} samples after a mode change{others}, {expected:g} expected for a "
                  f"filter whose model fits the data (z = {z:.1f}); the residuals after a mode "
                  "change are larger than the fitted model's covariance claims: switches "
                  "between the samples do it (the fit held each mode over the interval after "
                  "its sample), which switch_times='between' models (switchest fit "
                  "--switch-times between)", RuntimeWarning,
                  stacklevel=4)
