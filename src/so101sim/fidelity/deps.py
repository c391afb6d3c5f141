"""The optional packages of :mod:`so101sim.fidelity` (scipy for fitting, pyarrow for LeRobot's
parquet files): imported when needed, with an error that says what to install."""

from __future__ import annotations

import importlib
from types import ModuleType

from ..errors import MissingDependencyError

__all__ = ["MissingDependencyError", "need"]


def need(module: str, package: str) -> ModuleType:
    """``module`` imported, or :class:`MissingDependencyError` naming the package to install."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingDependencyError(
            f"{module} is needed here but {package!r} is not installed ({exc}); install it with "
            f"`pip install 'so101sim[fidelity]'` (or `pip install {package}`)"
        ) from exc
