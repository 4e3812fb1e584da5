"""Lazy re-exports for package ``__init__`` modules (PEP 562).

A package lists which submodule provides each public name; the names are
imported on first use, so importing one light submodule does not load the
heavy ones (OpenCV, scipy) the others need.
"""
from __future__ import annotations

import importlib
from typing import Callable, Mapping, Sequence

__all__ = ["lazy_exports"]


def lazy_exports(package: str, providers: Mapping[str, Sequence[str]], namespace: dict,
                 exported: Sequence[str]) -> tuple[Callable, Callable]:
    """Module ``__getattr__`` and ``__dir__`` that import each name from its submodule on first use.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    providers : mapping of str to sequence of str
        Submodule (relative name) -> the names it provides.
    namespace : dict
        The package's ``globals()``: an imported name is stored there, so the
        lookup runs once per name.
    exported : sequence of str
        The package's ``__all__`` (listed by ``dir()``).

    Returns
    -------
    getattr_, dir_ : callable
        To assign to the package's ``__getattr__`` and ``__dir__``.

    Examples
    --------
    >>> ns = {}
    >>> get, _ = lazy_exports("tudorvision", {"_checks": ("TudorVisionError",)}, ns, ["TudorVisionError"])
    >>> get("TudorVisionError").__name__, "TudorVisionError" in ns
    ('TudorVisionError', True)
    """
    where = {name: module for module, names in providers.items() for name in names}

    def getattr_(name: str):
        try:
            module = where[name]
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(f".{module}", package), name)
        namespace[name] = value
        return value

    def dir_():
        return sorted(set(namespace) | set(exported))

    return getattr_, dir_
