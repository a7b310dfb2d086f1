"""Estimators, all on one protocol: ``init -> step -> run -> Estimate`` (DESIGN.md §4).

:class:`Estimator` declares the protocol; :mod:`.registry` lists the methods a user selects
by name (:data:`METHOD_NAMES`, :func:`get_method`).

The protocol comes with the package; every other name is imported from its module at its
first use (PEP 562 ``__getattr__``), so that a program using one filter loads that filter's
module and compiled kernels only (not the detectors' analysis, scipy.optimize or cvxpy).
"""

from importlib import import_module

# the protocol, re-exported (the redundant aliases say so to linters; __all__ is computed)
from .base import Estimate as Estimate
from .base import Estimator as Estimator

# module -> the names it defines that the package exports
_EXPORTS = {
    "imm": ("IMMFilter",),
    "imm_ev1": ("IMMEV1Filter",),
    "impulsive": ("ImpulsiveObserver", "ImpulsiveState", "ObserverControlTrajectory",
                  "closed_loop_matrices", "delayed_replica", "impulsive_update",
                  "simulate_observer_control"),
    "kalman": ("kf_predict", "kf_update", "steady_state_gain"),
    "min_distance": ("DetectionMatch", "MinDistanceState", "MinimumDistanceDetector",
                     "WindowEstimate", "augmented_system", "exact_step", "match_detections",
                     "window_estimate"),
    "mode_kalman": ("ModeKalmanFilter",),
    "registry": ("METHOD_NAMES", "Method", "get_method"),
    "rsls": ("RSLSObserver", "RSLSState"),
    "switch_time": ("SwitchTimeKalmanFilter", "switch_time_loglik"),
}
_MODULE_OF = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = sorted(["Estimate", "Estimator", *_MODULE_OF], key=str.lower)


def __getattr__(name: str) -> object:
    """An exported name, imported from its module at its first use and kept."""
    if name not in _MODULE_OF:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f".{_MODULE_OF[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The package's names, the deferred ones included."""
    return sorted({*globals(), *__all__})
