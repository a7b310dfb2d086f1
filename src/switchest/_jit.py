"""How switchest compiles its loops: numba ``njit``, cached on disk, numpy's error model.

``cache=True`` keeps the machine code beside the sources, so only the first process after an
install compiles; ``error_model="numpy"`` drops numba's zero-division checks (callers check
every divisor first) and lets the compiler vectorize the loops.
"""

from __future__ import annotations

from numba import njit

__all__ = ["jit"]

jit = njit(cache=True, error_model="numpy")
