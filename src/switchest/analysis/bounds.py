"""Deprecated module path: the switching-time error bounds (Shankar et al.) moved to
:mod:`switchest.analysis.switch_time_bounds`; ``lemma2_bounds`` is now ``switch_matrix_bounds``.

Importing this module warns ``DeprecationWarning`` and gives the same objects.
"""

import warnings

from .switch_time_bounds import *  # noqa: F403 - every public name of the module it became
from .switch_time_bounds import __all__ as _moved
from .switch_time_bounds import switch_matrix_bounds as lemma2_bounds

__all__ = [*_moved, "lemma2_bounds"]

warnings.warn(
    "switchest.analysis.bounds is deprecated: its names are in "
    "switchest.analysis.switch_time_bounds (lemma2_bounds -> switch_matrix_bounds)",
    DeprecationWarning,
    stacklevel=2,
)
