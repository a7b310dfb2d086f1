"""Deprecated module path: the minimum-distance detector's constants and windows (Lee) moved
to :mod:`switchest.analysis.min_distance_design`.

Importing this module warns ``DeprecationWarning`` and gives the same objects.
"""

import warnings

from .min_distance_design import *  # noqa: F403 - every public name of the module it became
from .min_distance_design import __all__ as _moved

__all__ = list(_moved)

warnings.warn(
    "switchest.analysis.lee is deprecated: its names are in "
    "switchest.analysis.min_distance_design",
    DeprecationWarning,
    stacklevel=2,
)
