"""switchest: estimation in switched linear systems.

The public API is re-exported here; nothing is defined in this file.
"""

from .system import SwitchedLinearSystem

__all__ = ["SwitchedLinearSystem"]
__version__ = "0.1.0"
