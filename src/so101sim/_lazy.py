"""A package's names imported on first use (PEP 562), each name written once.

A package lists the names it offers lazily once, as the imports of its ``if TYPE_CHECKING:``
block, which editors and type checkers read as they are; at run time that block does not run,
and :func:`lazy_names` reads it from the package's source instead (on the first look-up, not
at import). The package then says::

    __getattr__, __dir__ = lazy_names(__name__)

and ``package.Name`` imports the module that defines ``Name`` the first time it is asked for,
and no sooner (``import so101sim`` stays free of MuJoCo). ``package.submodule`` imports the
submodule, as an eager ``from . import submodule`` would have shown it. ``__all__`` is the
lazy names with the public names the package imported eagerly from its own modules (and
``__version__``), so nothing is listed twice.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any


def _names_under_type_checking(path: Path) -> dict[str, tuple[str, str]]:
    """``name -> (relative module, attribute)`` of the relative imports under
    ``if TYPE_CHECKING:`` at the top of the file ``path``."""
    import ast  # imported here: only a first look-up needs it, not ``import so101sim``

    tree = ast.parse(path.read_text(encoding="utf-8"))
    found: dict[str, tuple[str, str]] = {}
    for node in tree.body:
        if not (isinstance(node, ast.If) and getattr(node.test, "id", None) == "TYPE_CHECKING"):
            continue
        for imp in node.body:
            if isinstance(imp, ast.ImportFrom) and imp.level:
                module = "." * imp.level + (imp.module or "")
                for alias in imp.names:
                    found[alias.asname or alias.name] = (module, alias.name)
    return found


def _is_public_module_of(module: object, package: str) -> bool:
    parts = str(module).split(".")
    top = package.split(".")
    return (
        parts[: len(top)] == top
        and len(parts) > len(top)
        and not any(part.startswith("_") for part in parts[len(top) :])
    )


def lazy_names(package: str) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for the package named ``package`` (see the module)."""
    names: dict[str, tuple[str, str]] = {}

    def table() -> dict[str, tuple[str, str]]:
        if not names:
            origin = sys.modules[package].__spec__.origin  # type: ignore[union-attr]
            names.update(_names_under_type_checking(Path(str(origin))))
        return names

    def public() -> list[str]:
        namespace = vars(sys.modules[package])
        eager = [  # public names the package imported from its own public modules
            k
            for k, v in namespace.items()
            if not k.startswith("_")
            and not isinstance(v, ModuleType)  # a submodule is no name (a callable one too)
            and _is_public_module_of(getattr(v, "__module__", ""), package)
        ]
        extra = ["__version__"] if "__version__" in namespace else []
        return sorted({*eager, *table(), *extra})

    def __getattr__(name: str) -> Any:
        if name == "__all__":
            return public()
        entry = table().get(name)
        if entry is not None:
            module, attr = entry
            value = getattr(importlib.import_module(module, package), attr)
            setattr(sys.modules[package], name, value)  # later look-ups skip this function
            return value
        if not name.startswith("__") and importlib.util.find_spec(f"{package}.{name}"):
            return importlib.import_module(f"{package}.{name}")
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(table()))

    return __getattr__, __dir__


__all__ = ["lazy_names"]
