"""Output files of a recording: checking a path before anything runs, and writing a file under
a temporary name so that the path holds either the finished file or nothing.

:func:`check_output_path` refuses, before anything runs, what cannot end well: a missing or
read-only folder (tried by creating and removing the temporary file there, so ``/proc``, ``/sys``
and read-only mounts are caught too), a name longer than the file system allows, and an existing
device, pipe or socket (``--force`` replaces regular files only: ``--log /dev/null --force``
must not replace ``/dev/null``). :class:`PendingFile` is the temporary file and its rename; its
steps may be repeated, so a finish interrupted by Ctrl-C can be resumed. :func:`write_error`
turns an ``OSError`` met while writing (a full disk) into an :class:`OutputPathError`.
"""

from __future__ import annotations

import errno
import os
import stat
from collections.abc import Callable, Sequence
from pathlib import Path

from ..errors import OutputPathError

DEFAULT_NAME_MAX = 255
"""Bytes in a file name where the file system does not say (Linux, macOS and Windows: 255)."""
DEFAULT_PATH_MAX = 4096
"""Bytes in a path where the system does not say (Linux: 4096)."""
_KINDS = (
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a named pipe"),
    (stat.S_ISSOCK, "a socket"),
)


def check_output_path(
    path: str | os.PathLike[str],
    *,
    force: bool = False,
    what: str = "output",
    suffixes: Sequence[str] = (),
) -> Path:
    """Check that ``path`` can be written, before anything runs; return it as a Path.

    Raises:
        OutputPathError: the suffix is not one of ``suffixes``; the name or the path is longer
            than the file system allows; the folder does not exist or no file can be created
            in it; the path is a folder, a device, a pipe or a socket; or the file exists and
            ``force`` is False.
    """
    p = Path(path).expanduser()
    if suffixes and p.suffix.lower() not in suffixes:
        raise OutputPathError(
            f"{what} file {str(p)!r} has the wrong extension; expected one of {', '.join(suffixes)}"
        )
    folder = _check_folder(p, what)
    _check_length(p, folder, what)
    _check_target(p, what, force)
    _try_creating(PendingFile(p), what)
    return p


def _check_folder(p: Path, what: str) -> Path:
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
    return folder


def _limit(folder: Path, name: str, default: int) -> int:
    try:
        value = os.pathconf(folder, name)
    except (OSError, ValueError, AttributeError):  # not known here (or not POSIX)
        return default
    return value if value > 0 else default


def _check_length(p: Path, folder: Path, what: str) -> None:
    name_max = _limit(folder, "PC_NAME_MAX", DEFAULT_NAME_MAX)
    size = len(os.fsencode(p.name))
    if size > name_max:
        raise OutputPathError(
            f"the {what} file name {p.name[:40]!r}… is {size} bytes long; expected at most "
            f"{name_max} bytes (the file system's limit)"
        )
    path_max = _limit(folder, "PC_PATH_MAX", DEFAULT_PATH_MAX)
    size = len(os.fsencode(os.path.abspath(p)))
    if size >= path_max:
        raise OutputPathError(
            f"the {what} path {str(p)[:40]!r}… is {size} bytes long; expected fewer than "
            f"{path_max} bytes (the system's limit)"
        )


def _check_target(p: Path, what: str, force: bool) -> None:
    try:
        mode = os.stat(p).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise OutputPathError(
            f"cannot write the {what} {str(p)!r}: {exc.strerror}; expected a path you can write"
        ) from None
    if stat.S_ISDIR(mode):
        raise OutputPathError(f"the {what} path {str(p)!r} is a folder; expected a file name")
    for test, kind in _KINDS:
        if test(mode):
            raise OutputPathError(
                f"the {what} path {str(p)!r} is {kind}, not a regular file; expected the name "
                "of a regular file (so101sim never replaces devices, pipes or sockets)"
            )
    if not force:
        raise OutputPathError(
            f"the {what} file {str(p)!r} already exists; expected a new file name, or force "
            "overwriting (--force)"
        )


def _try_creating(pending: PendingFile, what: str) -> None:
    """Create and remove the temporary file: the folder's permission bits do not tell about
    ``/proc``, ``/sys``, read-only mounts or root."""
    try:
        fd = os.open(pending.tmp, os.O_WRONLY | os.O_CREAT, 0o644)
    except OSError as exc:
        raise OutputPathError(
            f"cannot write the {what} {str(pending.path)!r}: creating a file in "
            f"{str(pending.folder)!r} failed ({exc.strerror}); expected a folder where files "
            "can be created"
        ) from None
    os.close(fd)
    pending.discard()


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


def temp_name(path: Path, name_max: int = DEFAULT_NAME_MAX) -> str:
    """The hidden temporary name of ``path``: ``.<stem>.<pid>.partial<suffix>``, the stem cut
    so that the name fits in ``name_max`` bytes (a legal 250-byte name stays writable)."""
    stem, tail = path.stem, f".{os.getpid()}.partial{path.suffix}"
    room = name_max - 1 - len(os.fsencode(tail))
    while stem and len(os.fsencode(stem)) > room:
        stem = stem[:-1]
    return f".{stem}{tail}"


class PendingFile:
    """A file written under a hidden temporary name (:attr:`tmp`) next to ``path`` and renamed
    over it by :meth:`commit`; :meth:`discard` removes it. A path never holds half a file.

    Both steps may be repeated (after an interruption): a commit that already happened is not
    done again.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.folder = path.parent if str(path.parent) else Path(".")
        self.tmp = self.folder / temp_name(path, _limit(self.folder, "PC_NAME_MAX", 255))
        self.committed = False
        self._renaming = False

    def commit(self) -> None:
        if self.committed:
            return
        if self._renaming and not self.tmp.exists() and self.path.exists():
            self.committed = True  # renamed, then interrupted before this was noted
            return
        self._renaming = True
        os.replace(self.tmp, self.path)
        self.committed = True

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


def write_atomically(path: Path, write: Callable[[Path], object], what: str = "output") -> Path:
    """Call ``write(tmp)`` to write the file under a temporary name, then move it to ``path``;
    on any error (Ctrl-C included) the temporary file is removed and the error raised (an
    ``OSError``, such as a full disk, as :class:`OutputPathError`)."""
    pending = PendingFile(path)
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
