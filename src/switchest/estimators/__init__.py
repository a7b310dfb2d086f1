"""Estimators, all on one protocol: ``init -> step -> run -> Estimate``.

:class:`Estimator` declares the protocol; :mod:`.registry` lists the methods a user selects
by name (:data:`METHOD_NAMES`, :func:`get_method`, :func:`methods`, :func:`methods_with`).

The protocol comes with the package; every other name is imported from its module at its
first use (PEP 562 ``__getattr__``), so that a program using one filter loads that filter's
module and compiled kernels only (not the detectors' analysis, scipy.optimize or cvxpy).
"""

from .._lazy import deferred

# the protocol, re-exported (the redundant aliases say so to linters; __all__ is computed)
from .base import Estimate as Estimate
from .base import Estimator as Estimator
from .base import TimingWarning as TimingWarning

# module -> the names it defines that the package exports
_EXPORTS = {
    "exact_mixture": ("ExactMixtureFilter", "ExactMixtureState"),
    "gpb": ("GPB1Filter", "GPB2Filter"),
    "imm": ("IMMFilter",),
    "imm_between": ("BetweenSamplesIMMFilter",),
    "imm_ev1": ("IMMEV1Filter",),
    "impulsive": ("ImpulsiveObserver", "ImpulsiveState", "ObserverControlTrajectory",
                  "closed_loop_matrices", "delayed_replica", "impulsive_update",
                  "simulate_observer_control"),
    "kalman": ("kf_predict", "kf_update", "steady_state_gain"),
    "min_distance": ("DetectionMatch", "MinDistanceState", "MinimumDistanceDetector",
                     "WindowEstimate", "augmented_system", "exact_step", "match_detections",
                     "window_estimate"),
    "mode_bank": ("IMMState", "Members", "ModeBankFilter", "ModeMatchedRun",
                  "SmootherDivergenceWarning"),
    "mode_kalman": ("ModeKalmanFilter",),
    "rbpf": ("RBPFState", "RBPFilter"),
    "registry": ("METHOD_NAMES", "Method", "get_method", "methods", "methods_with"),
    "rsls": ("RSLSObserver", "RSLSState", "fine_step_error_system"),
    "smoothing": ("SmoothedModes", "smooth_mode_matched"),
    "switch_time": ("SwitchTimeKalmanFilter", "switch_time_loglik"),
    "parallel": ("set_threads", "threads"),
}
__getattr__, __dir__ = deferred(__name__, globals(), _EXPORTS)
__all__ = sorted(["Estimate", "Estimator", "TimingWarning",
                  *(n for names in _EXPORTS.values() for n in names)], key=str.lower)
