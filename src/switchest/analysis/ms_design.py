"""Deprecated path of :mod:`switchest.analysis.subsystem_observers` (Wang et al.'s design)."""

from ._deprecation import moved_module

moved_module(__name__, "subsystem_observers")
