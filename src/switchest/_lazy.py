"""Packages whose names are imported at their first use (PEP 562).

A package lists the names each of its modules exports; :func:`deferred` gives it the module
``__getattr__`` that imports a name's module when the name is first looked up (and keeps the
value in the package's namespace), and the ``__dir__`` that lists the deferred names too. So
``import switchest.estimators`` stays cheap and a program loads only the modules it uses.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import import_module


def deferred(package: str, namespace: dict, exports: dict[str, tuple[str, ...]]
             ) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package`` (its ``__name__``) with namespace
    ``namespace`` (its ``globals()``), whose submodule ``module`` exports ``exports[module]``.
    """
    module_of = {name: module for module, names in exports.items() for name in names}

    def getattr_(name: str) -> object:
        if name not in module_of:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(import_module(f".{module_of[name]}", package), name)
        namespace[name] = value
        return value

    def dir_() -> list[str]:
        return sorted({*namespace, *module_of})

    return getattr_, dir_
