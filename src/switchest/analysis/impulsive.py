"""Deprecated module path: the impulsive observer's LMIs and rates (Etienne et al.) moved to
:mod:`switchest.analysis.impulsive_lmis`; ``theorem8_rate`` is now
``impulsive_observer_decay_rate`` and ``theorem10_rate`` is ``impulsive_closed_loop_decay_rate``.

Importing this module warns ``DeprecationWarning`` and gives the same objects.
"""

import warnings

from .impulsive_lmis import *  # noqa: F403 - every public name of the module it became
from .impulsive_lmis import __all__ as _moved
from .impulsive_lmis import impulsive_closed_loop_decay_rate as theorem10_rate
from .impulsive_lmis import impulsive_observer_decay_rate as theorem8_rate

__all__ = [*_moved, "theorem10_rate", "theorem8_rate"]

warnings.warn(
    "switchest.analysis.impulsive is deprecated: its names are in "
    "switchest.analysis.impulsive_lmis (theorem10_rate -> "
    "impulsive_closed_loop_decay_rate, theorem8_rate -> "
    "impulsive_observer_decay_rate)",
    DeprecationWarning,
    stacklevel=2,
)
