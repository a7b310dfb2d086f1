"""Deprecated module path: the mean-square design of subsystem observers (Wang et al.) moved
to :mod:`switchest.analysis.subsystem_observers`.

Importing this module warns ``DeprecationWarning`` and gives the same objects.
"""

import warnings

from .subsystem_observers import *  # noqa: F403 - every public name of the module it became
from .subsystem_observers import __all__ as _moved

__all__ = list(_moved)

warnings.warn(
    "switchest.analysis.ms_design is deprecated: its names are in "
    "switchest.analysis.subsystem_observers",
    DeprecationWarning,
    stacklevel=2,
)
