"""Old names of the analysis, kept readable for one release: result fields and module paths."""

from __future__ import annotations

import sys
import warnings
from importlib import import_module

from . import DEPRECATED_NAMES


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


def moved_module(old: str, new: str) -> None:
    """Make the module named ``old`` a deprecated path of its sibling module ``new``.

    Called once, from the body of the old module (``moved_module(__name__, "new_name")``):
    the old module gets every public name of the new one (its ``__all__``) and, under their
    old names, the objects of :data:`switchest.analysis.DEPRECATED_NAMES` that the new one
    exports; importing the old module warns ``DeprecationWarning`` at the importing line.
    """
    package = old.rpartition(".")[0]
    target = import_module(f"{package}.{new}")
    renamed = {was: now for was, now in DEPRECATED_NAMES.items() if now in target.__all__}
    namespace = vars(sys.modules[old])
    namespace.update({name: getattr(target, name) for name in target.__all__})
    namespace.update({was: getattr(target, now) for was, now in renamed.items()})
    namespace["__all__"] = [*target.__all__, *renamed]
    aliases = ", ".join(f"{was} -> {now}" for was, now in renamed.items())
    warnings.warn(f"{old} is deprecated: its names are in {package}.{new}"
                  + (f" ({aliases})" if aliases else ""),
                  DeprecationWarning, stacklevel=3)  # 1 here, 2 the old module, 3 its importer
