"""Deprecated module path: the mode-mismatch bias of the mode-based Kalman filter (Zhang &
Natarajan) moved to :mod:`switchest.analysis.mode_mismatch`; ``lemma3_hypotheses`` is now
``filter_stability_hypotheses`` and ``theorem4_bound`` is ``mismatch_bias_bound``.

Importing this module warns ``DeprecationWarning`` and gives the same objects.
"""

import warnings

from .mode_mismatch import *  # noqa: F403 - every public name of the module it became
from .mode_mismatch import __all__ as _moved
from .mode_mismatch import filter_stability_hypotheses as lemma3_hypotheses
from .mode_mismatch import mismatch_bias_bound as theorem4_bound

__all__ = [*_moved, "lemma3_hypotheses", "theorem4_bound"]

warnings.warn(
    "switchest.analysis.bias is deprecated: its names are in "
    "switchest.analysis.mode_mismatch (lemma3_hypotheses -> "
    "filter_stability_hypotheses, theorem4_bound -> mismatch_bias_bound)",
    DeprecationWarning,
    stacklevel=2,
)
