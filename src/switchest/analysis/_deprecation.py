"""Old names of the analysis results' fields, kept readable for one release."""

from __future__ import annotations

import warnings


def renamed_field(old: str, new: str = "holds") -> property:
    """A read-only property ``old`` that warns ``DeprecationWarning`` and returns ``new``.

    The verdicts of every analysis result are read from one field, ``holds`` (the proven
    statement); the names they had before (``feasible``, ``stable``, ``found`` ...) stay
    readable through this property.
    """

    def get(self):
        warnings.warn(f"{type(self).__name__}.{old} is deprecated: read .{new}",
                      DeprecationWarning, stacklevel=2)
        return getattr(self, new)

    return property(get, doc=f"Deprecated alias of :attr:`{new}` (warns).")
