"""Deprecated path of :mod:`switchest.analysis.min_distance_design` (Lee et al.'s detector)."""

from ._deprecation import moved_module

moved_module(__name__, "min_distance_design")
