"""Deprecated path of :mod:`switchest.analysis.impulsive_lmis` (Etienne et al.'s LMIs)."""

from ._deprecation import moved_module

moved_module(__name__, "impulsive_lmis")
