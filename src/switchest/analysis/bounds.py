"""Deprecated path of :mod:`switchest.analysis.switch_time_bounds` (Shankar et al.'s bounds)."""

from ._deprecation import moved_module

moved_module(__name__, "switch_time_bounds")
