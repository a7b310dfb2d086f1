"""Deprecated path of :mod:`switchest.analysis.mode_mismatch` (Zhang & Natarajan's bias)."""

from ._deprecation import moved_module

moved_module(__name__, "mode_mismatch")
