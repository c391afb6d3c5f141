"""Output files of a recording: checking a path before anything runs, and writing a file under
a temporary name so that the path holds either the finished file or nothing."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

from ..errors import OutputPathError


def check_output_path(
    path: str | os.PathLike[str],
    *,
    force: bool = False,
    what: str = "output",
    suffixes: Sequence[str] = (),
) -> Path:
    """Check that ``path`` can be written, before anything runs; return it as a Path.

    Raises:
        OutputPathError: the folder does not exist or is not writable, the path is a folder,
            the suffix is not one of ``suffixes``, or the file exists and ``force`` is False.
    """
    p = Path(path).expanduser()
    if suffixes and p.suffix.lower() not in suffixes:
        raise OutputPathError(
            f"{what} file {str(p)!r} has the wrong extension; expected one of {', '.join(suffixes)}"
        )
    _check_folder(p, what)
    if p.is_dir():
        raise OutputPathError(f"the {what} path {str(p)!r} is a folder; expected a file name")
    if p.exists() and not force:
        raise OutputPathError(
            f"the {what} file {str(p)!r} already exists; expected a new file name, or force "
            "overwriting (--force)"
        )
    return p


def _check_folder(p: Path, what: str) -> None:
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise OutputPathError(
            f"cannot write the {what} {str(p)!r}: the folder {str(folder)!r} does not exist; "
            "expected an existing folder (create it first)"
        )
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(
            f"cannot write the {what} {str(p)!r}: the folder {str(folder)!r} is not writable; "
            "expected a folder you can write to"
        )


def check_distinct(*paths: str | os.PathLike[str] | None) -> None:
    """Raise OutputPathError if two of the given paths (None: not written) are the same file."""
    resolved = [Path(p).expanduser().resolve() for p in paths if p is not None]
    if len(set(resolved)) != len(resolved):
        raise OutputPathError("the video, plot and log paths must differ; got the same twice")


class PendingFile:
    """A file written under a hidden temporary name (:attr:`tmp`) next to ``path`` and renamed
    over it by :meth:`commit`; :meth:`discard` removes it. A path never holds half a file."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.tmp = path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")

    def commit(self) -> None:
        os.replace(self.tmp, self.path)

    def discard(self) -> None:
        self.tmp.unlink(missing_ok=True)

    def finish(self, keep: bool) -> Path | None:
        """Commit (``keep``: return the path) or discard (return None) the written file."""
        if not keep:
            self.discard()
            return None
        self.commit()
        return self.path


def write_atomically(path: Path, write: Callable[[Path], object]) -> Path:
    """Call ``write(tmp)`` to write the file under a temporary name, then move it to ``path``;
    on any error (Ctrl-C included) the temporary file is removed and the error raised."""
    pending = PendingFile(path)
    try:
        write(pending.tmp)
        pending.commit()
    except BaseException:
        pending.discard()
        raise
    return path
