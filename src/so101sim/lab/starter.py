"""The examples shipped inside the package (scripts as a student writes them, motion files),
and copying them to a folder of one's own: ``so101sim examples DIR``. Shipping them in the
package means the docs' snippets that name ``wave.toml`` work from any folder."""

from __future__ import annotations

import shutil
from importlib import resources
from pathlib import Path

from ..errors import OutputPathError
from ..validation import checked_path


def examples_dir() -> Path:
    """The folder of the shipped examples (``wave.toml``, ``lab_motion.py``, ...)."""
    return Path(str(resources.files("so101sim") / "data" / "examples"))


def example_path(name: str) -> Path:
    """The shipped example ``name`` (e.g. ``"wave.toml"``).

    Raises:
        OutputPathError: there is no such example (the message lists them).
    """
    path = examples_dir() / name
    if not path.is_file():
        names = ", ".join(sorted(p.name for p in examples_dir().iterdir() if p.is_file()))
        raise OutputPathError(f"no example named {name!r}; the examples are {names}")
    return path


def copy_examples(folder: str | Path, *, force: bool = False) -> list[Path]:
    """Copy every shipped example into ``folder`` (made if missing); return the new paths.

    Raises:
        OutputPathError: ``folder`` is empty, too long for the file system, a file, or an
            example is already there and ``force`` is False (nothing is copied then).
    """
    # an empty name would copy into the current folder; a name too long fails in a mkdir
    dest = checked_path(folder, "examples folder", error=OutputPathError)
    if dest.exists() and not dest.is_dir():
        raise OutputPathError(f"{str(dest)!r} is a file; expected a folder to copy examples into")
    sources = sorted(
        p for p in examples_dir().iterdir() if p.is_file() and not p.name.startswith(".")
    )
    existing = [dest / p.name for p in sources if (dest / p.name).exists()]
    if existing and not force:
        raise OutputPathError(
            f"{str(existing[0])!r} already exists ({len(existing)} example(s) would be "
            "overwritten); pass --force (force=True) to overwrite them"
        )
    try:
        dest.mkdir(parents=True, exist_ok=True)
        return [Path(shutil.copy2(p, dest / p.name)) for p in sources]
    except OSError as exc:
        raise OutputPathError(f"cannot copy the examples to {str(dest)!r}: {exc}") from exc
