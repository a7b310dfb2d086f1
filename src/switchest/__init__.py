"""switchest: estimation in switched linear systems.

The public API is re-exported here; this file defines nothing else but the lookup of the
deferred names. The system, signal and simulation types come with the package; the subpackages
and the names they define are imported at their first use (PEP 562 ``__getattr__``), so that
``import switchest`` and the command line start without importing scipy, cvxpy and
matplotlib.
"""

from importlib import import_module

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

# name -> the submodule that defines it; a name equal to its submodule is the submodule. (The
# function `simulate` shares its submodule's name, so it is imported above: importing the
# submodule later would bind the module to `switchest.simulate`.)
_DEFERRED = {
    "analysis": "analysis",
    "discretize": "discretize",
    "estimators": "estimators",
    "metrics": "metrics",
    "models": "models",
    "Estimate": "estimators",
    "Transition": "discretize",
    "interval": "discretize",
}


def __getattr__(name: str) -> object:
    """A deferred name of the API, imported at its first use and kept."""
    if name not in _DEFERRED:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module = import_module(f".{_DEFERRED[name]}", __name__)
    value = module if name == _DEFERRED[name] else getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The package's names, the deferred ones included."""
    return sorted({*globals(), *__all__})
