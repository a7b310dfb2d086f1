"""Estimators, all on one protocol: ``init -> step -> run -> Estimate`` (DESIGN.md §4).

:class:`Estimator` declares the protocol; :mod:`.registry` lists the methods a user selects
by name (:data:`METHOD_NAMES`, :func:`get_method`).
"""

from .base import Estimate, Estimator
from .imm import IMMFilter
from .imm_ev1 import IMMEV1Filter
from .impulsive import (
    ImpulsiveObserver,
    ImpulsiveState,
    ObserverControlTrajectory,
    closed_loop_matrices,
    delayed_replica,
    impulsive_update,
    simulate_observer_control,
)
from .kalman import kf_predict, kf_update, steady_state_gain
from .min_distance import (
    DetectionMatch,
    MinDistanceState,
    MinimumDistanceDetector,
    WindowEstimate,
    augmented_system,
    exact_step,
    match_detections,
    window_estimate,
)
from .mode_kalman import ModeKalmanFilter
from .registry import METHOD_NAMES, Method, get_method
from .rsls import RSLSObserver, RSLSState
from .switch_time import SwitchTimeKalmanFilter, switch_time_loglik

__all__ = [
    "augmented_system",
    "closed_loop_matrices",
    "delayed_replica",
    "DetectionMatch",
    "Estimate",
    "Estimator",
    "exact_step",
    "get_method",
    "IMMEV1Filter",
    "IMMFilter",
    "impulsive_update",
    "ImpulsiveObserver",
    "ImpulsiveState",
    "kf_predict",
    "kf_update",
    "match_detections",
    "Method",
    "METHOD_NAMES",
    "MinDistanceState",
    "MinimumDistanceDetector",
    "ModeKalmanFilter",
    "ObserverControlTrajectory",
    "RSLSObserver",
    "RSLSState",
    "simulate_observer_control",
    "steady_state_gain",
    "switch_time_loglik",
    "SwitchTimeKalmanFilter",
    "window_estimate",
    "WindowEstimate",
]
