"""Output files of a recording: checking a path before anything runs, and writing a file under
a temporary name so that the path holds either the finished file or nothing.

:func:`check_output_path` refuses, before anything runs, what cannot end well: a missing or
read-only folder (tried by creating and removing the temporary file there, so ``/proc``, ``/sys``
and read-only mounts are caught too), a name longer than the file system allows, and an existing
device, pipe or socket (``--force`` replaces regular files only: ``--log /dev/null --force``
must not replace ``/dev/null``). :class:`PendingFile` is the temporary file and its rename; its
steps may be repeated, so a finish interrupted by Ctrl-C can be resumed.

**Claimed atomically.** Without ``force``, the finished file is linked to its path, which
fails if anything is there (``os.link``: one atomic step, no window), instead of renamed over
it: two processes writing the same ``--log``, ``--record`` or ``--plot`` at once give one file
and one error (:class:`~so101sim.errors.OutputPathError`, "appeared while this run wrote it"),
never two successes and a lost file. With ``force`` it is renamed over what is there, as
before. A file system without hard links claims the path with ``O_EXCL`` and then renames.

:func:`write_error` turns an ``OSError`` met while writing (a full disk) into an
:class:`OutputPathError`.
"""

from __future__ import annotations

import errno
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from ..errors import OutputPathError
from ..validation import (
    DEFAULT_NAME_MAX,
    DEFAULT_PATH_MAX,
    claim_path,
    path_limit,
    remove_stale_temps,
    temp_name,
)
from ..validation import check_output_path as _check_output_path

__all__ = [
    "DEFAULT_NAME_MAX",
    "DEFAULT_PATH_MAX",
    "PendingFile",
    "check_distinct",
    "check_output_path",
    "temp_name",
    "write_atomically",
    "write_error",
]


def check_output_path(
    path: str | os.PathLike[str],
    *,
    force: bool = False,
    what: str = "output",
    suffixes: Sequence[str] = (),
) -> Path:
    """Check that ``path`` can be written, before anything runs; return it as a Path
    (:func:`so101sim.validation.check_output_path`, the one check of every output: this module
    re-exports it for the recording's files).

    Raises:
        OutputPathError: the path is empty; the suffix is not one of ``suffixes``; the name or
            the path is longer than the file system allows; the folder does not exist or no
            file can be created in it; the path is a folder, a device, a pipe or a socket; or
            the file exists and ``force`` is False.
    """
    return _check_output_path(path, force=force, what=what, suffixes=suffixes)


def check_distinct(*paths: str | os.PathLike[str] | None) -> None:
    """Raise OutputPathError if two of the given paths (None: not written) are the same file."""
    resolved = [Path(p).expanduser().resolve() for p in paths if p is not None]
    if len(set(resolved)) != len(resolved):
        raise OutputPathError("the video, plot and log paths must differ; got the same twice")


def write_error(what: str, path: Path, exc: OSError | str) -> OutputPathError:
    """The error for an output that could not be written (``exc``: the OSError, or what the
    writer said), saying that nothing was left at ``path``."""
    if isinstance(exc, OSError):
        reason = exc.strerror or str(exc)
        full = exc.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))
    else:
        reason = exc
        full = "No space left" in exc or "Disk quota" in exc
    advice = "free some space or choose another folder" if full else "choose another folder"
    return OutputPathError(
        f"could not write the {what} {str(path)!r}: {reason}, so nothing was left at that "
        f"path; expected a writable folder with free space ({advice})"
    )


class PendingFile:
    """A file written under a hidden temporary name (:attr:`tmp`) next to ``path`` and renamed
    over it by :meth:`commit`; :meth:`discard` removes it. A path never holds half a file.

    Both steps may be repeated (after an interruption): a commit that already happened is not
    done again.
    """

    def __init__(self, path: Path, *, force: bool = False) -> None:
        self.path = path
        self.force = force  # False: refuse a path that holds a file by then (claimed once)
        self.folder = path.parent if str(path.parent) else Path(".")
        self.tmp = self.folder / temp_name(path, path_limit(self.folder, "PC_NAME_MAX", 255))
        remove_stale_temps(path)  # those a run killed by SIGKILL left (its process gone)
        self.committed = False
        self._renaming = False

    def commit(self) -> None:
        if self.committed:
            return
        if self._renaming and not self.tmp.exists() and self.path.exists():
            self.committed = True  # renamed, then interrupted before this was noted
            return
        if self._renaming and _same_file(self.tmp, self.path):
            self.tmp.unlink()  # linked, then interrupted before the temporary name went
            self.committed = True
            return
        self._renaming = True
        if self.force:
            os.replace(self.tmp, self.path)
        else:
            self._claim()  # refused: the temporary file removed, OutputPathError raised
        self.committed = True

    def _claim(self) -> None:
        """Move the temporary file to :attr:`path` unless something is there (atomic)."""
        try:
            claim_path(self.tmp, self.path)
        except OutputPathError:
            self._renaming = False  # refused: what is at the path is not this file
            raise

    def discard(self) -> None:
        if not self.committed:
            self.tmp.unlink(missing_ok=True)

    def finish(self, keep: bool) -> Path | None:
        """Commit (``keep``: return the path) or discard (return None) the written file."""
        if not keep:
            self.discard()
            return None
        self.commit()
        return self.path


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def write_atomically(
    path: Path, write: Callable[[Path], object], what: str = "output", *, force: bool = False
) -> Path:
    """Call ``write(tmp)`` to write the file under a temporary name, then move it to ``path``
    (without ``force``: only if nothing is there by then, see :class:`PendingFile`); on any
    error (Ctrl-C included) the temporary file is removed and the error raised (an
    ``OSError``, such as a full disk, as :class:`OutputPathError`)."""
    pending = PendingFile(path, force=force)
    try:
        write(pending.tmp)
        pending.commit()
    except OSError as exc:
        pending.discard()
        raise write_error(what, path, exc) from exc
    except BaseException:
        pending.discard()
        raise
    return path
