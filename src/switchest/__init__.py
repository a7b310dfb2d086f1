"""switchest: estimation in switched linear systems.

The public API is re-exported here; nothing is defined in this file.
"""

from . import analysis, discretize, estimators, metrics, models, signals
from .discretize import Transition, interval
from .estimators import Estimate
from .signals import SwitchingSignal
from .simulate import Trajectory, simulate
from .system import SwitchedLinearSystem

__all__ = [
    "Estimate",
    "SwitchedLinearSystem",
    "SwitchingSignal",
    "Trajectory",
    "Transition",
    "analysis",
    "discretize",
    "estimators",
    "interval",
    "metrics",
    "models",
    "signals",
    "simulate",
]
__version__ = "0.1.0"
