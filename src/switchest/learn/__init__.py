"""Learning a switched linear system from data: maximum likelihood by expectation-maximization.

:func:`fit` estimates the mode transition matrix, the process-noise covariance (the intensity
of a continuous-time system) and the measurement-noise covariance, optionally ``A``, ``B``
(discrete time) and ``C``, from one or several trials of measurements, with the modes known or
not, per mode or tied across the modes on request, with the switches at the samples or
between them (:mod:`~switchest.learn.between` with the modes known,
:mod:`~switchest.learn.chain` without), gating outliers;
:class:`FitResult` holds the fitted model, the log-likelihood trace and standard errors.
"""

from .em import fit
from .markov_step import rates_from_transition
from .result import FitResult

__all__ = ["FitResult", "fit", "rates_from_transition"]
