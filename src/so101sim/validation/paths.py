"""Checking paths from a user, one check for each direction: :func:`check_input_file` (a file
to read: the model, a script) and :func:`check_output_path` (a file to write: videos, plots,
logs, the workspace picture). Both refuse an empty path and names or paths longer than the file
system allows (``NAME_MAX`` and ``PATH_MAX`` from ``os.pathconf``) before anything touches the
file system, so no ``OSError`` ("File name too long") escapes as a traceback."""

from __future__ import annotations

import contextlib
import os
import stat
import time
from collections.abc import Sequence
from pathlib import Path

from ..errors import OutputPathError, SettingError
from .numbers import shown

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


def check_path_text(path: object, what: str, *, error: type[Exception] = SettingError) -> str:
    """``path`` (a str or ``os.PathLike``) as text, if it names something: not empty, not
    blank, no NUL character; else raise ``error`` naming ``what``."""
    if isinstance(path, bytes | os.PathLike):
        path = os.fsdecode(path)  # type: ignore[arg-type]
    if not isinstance(path, str):
        raise error(f"the {what} path {shown(path)} is not a path; expected a file name (text)")
    if not path.strip():
        raise error(f"the {what} path is empty ({path!r}); expected a file name")
    if "\0" in path:
        raise error(f"the {what} path {shown(path)} holds a NUL character; expected a file name")
    return path


def path_limit(folder: str | os.PathLike[str], name: str, default: int) -> int:
    """``os.pathconf(folder, name)`` (``"PC_NAME_MAX"``, ``"PC_PATH_MAX"``), or ``default``
    where the system does not say."""
    try:
        value = os.pathconf(folder, name)
    except (OSError, ValueError, AttributeError):  # not known here (or not POSIX)
        return default
    return value if value > 0 else default


def _nearest_folder(p: Path) -> Path:
    """The nearest existing folder at or above ``p`` (the current one for a relative path
    whose folders do not exist), found without ever failing on a long name."""
    q = Path(os.path.abspath(p))
    for candidate in (q, *q.parents):
        try:
            if candidate.is_dir():
                return candidate
        except (OSError, ValueError):  # too long, a NUL: go up
            continue
    return Path("/")


def check_path_length(path: Path, what: str, *, error: type[Exception] = SettingError) -> None:
    """Raise ``error`` if a name in ``path`` is longer than the file system's ``NAME_MAX`` or
    the whole path (made absolute) reaches ``PATH_MAX``, before any call that would fail with
    "File name too long"."""
    folder = _nearest_folder(path)
    name_max = path_limit(folder, "PC_NAME_MAX", DEFAULT_NAME_MAX)
    for part in path.parts:
        size = len(os.fsencode(part))
        if size > name_max:
            named = what if what.endswith(("file", "folder")) else f"{what} file"
            where = f"the {named} name"
            if part != path.name:
                where = f"a folder name in the {what} path"
            raise error(
                f"{where} {part[:40]!r}… is {size} bytes long; expected at most "
                f"{name_max} bytes (the file system's limit)"
            )
    path_max = path_limit(folder, "PC_PATH_MAX", DEFAULT_PATH_MAX)
    size = len(os.fsencode(os.path.abspath(path)))
    if size >= path_max:
        raise error(
            f"the {what} path {str(path)[:40]!r}… is {size} bytes long; expected fewer than "
            f"{path_max} bytes (the system's limit)"
        )


def checked_path(path: object, what: str, *, error: type[Exception] = SettingError) -> Path:
    """``path`` as a Path (``~`` expanded) after :func:`check_path_text` and
    :func:`check_path_length`."""
    p = Path(check_path_text(path, what, error=error)).expanduser()
    check_path_length(p, what, error=error)
    return p


def check_input_file(
    path: object,
    what: str,
    *,
    expected: str = "an existing regular file",
    error: type[Exception] = SettingError,
) -> Path:
    """``path`` as a Path if it names a regular file that can be read; else raise ``error``
    saying what it is instead (empty, too long, missing, a folder, a device, a pipe,
    unreadable) and ``expected``."""
    p = checked_path(path, what, error=error)
    try:
        mode = os.stat(p).st_mode
    except FileNotFoundError:
        raise error(f"the {what} {str(p)!r} does not exist; expected {expected}") from None
    except OSError as exc:
        raise error(
            f"the {what} {str(p)!r} cannot be read ({exc.strerror}); expected {expected}"
        ) from None
    if stat.S_ISDIR(mode):
        raise error(f"the {what} {str(p)!r} is a folder, not a regular file; expected {expected}")
    for test, kind in _KINDS:
        if test(mode):
            raise error(f"the {what} {str(p)!r} is {kind}, not a regular file; expected {expected}")
    if not stat.S_ISREG(mode):
        raise error(f"the {what} {str(p)!r} is not a regular file; expected {expected}")
    if not os.access(p, os.R_OK):
        raise error(
            f"the {what} {str(p)!r} cannot be read (permission denied); expected {expected}"
        )
    return p


def temp_name(path: Path, name_max: int = DEFAULT_NAME_MAX) -> str:
    """The hidden temporary name of ``path``: ``.<stem>.<pid>.partial<suffix>``, the stem cut
    so that the name fits in ``name_max`` bytes (a legal 250-byte name stays writable)."""
    stem, tail = path.stem, f".{os.getpid()}.partial{path.suffix}"
    room = name_max - 1 - len(os.fsencode(tail))
    while stem and len(os.fsencode(stem)) > room:
        stem = stem[:-1]
    return f".{stem}{tail}"


STALE_TEMP_S = 3600.0
"""A temporary output file (:func:`temp_name`) whose process is gone and that was not written
for this long (seconds) was left by a killed run: the next run of the same output deletes it."""


def remove_stale_temps(path: Path, older_than: float = STALE_TEMP_S) -> list[Path]:
    """Delete the temporary files of ``path`` (``.<stem>.<pid>.partial<suffix>``) that a
    killed run left: their process is not running and they were last written more than
    ``older_than`` seconds ago (a live writer, even one this machine cannot see, writes
    more often than that). Returns those deleted; anything unsure is left."""
    folder = path.parent if str(path.parent) else Path(".")
    gone = []
    now = time.time()
    for f in folder.glob(f".*.partial{path.suffix}"):
        stem, _, pid = f.name[1 : -len(f".partial{path.suffix}")].rpartition(".")
        cut = path.stem.startswith(stem) and len(os.fsencode(f.name)) > 200  # stem cut to fit
        if not pid.isdigit() or (stem != path.stem and not cut) or _running(int(pid)):
            continue
        with contextlib.suppress(OSError):  # gone already, or not ours to delete
            if f.is_file() and not f.is_symlink() and now - f.stat().st_mtime > older_than:
                f.unlink()
                gone.append(f)
    return gone


def _running(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (OSError, OverflowError):  # another user's process, or not a pid here: unsure
        return True
    return True


def check_output_path(
    path: object,
    *,
    force: bool = False,
    what: str = "output",
    suffixes: Sequence[str] = (),
    error: type[Exception] = OutputPathError,
) -> Path:
    """Check that ``path`` can be written, before anything runs; return it as a Path.

    Raises (``error``, :class:`~so101sim.errors.OutputPathError` by default):
        the path is empty; the suffix is not one of ``suffixes``; a name or the path is
        longer than the file system allows; the folder does not exist or no file can be
        created in it (tried by creating and removing a temporary file there, so ``/proc``,
        read-only mounts and root are caught too); the path is a folder, a device, a pipe or
        a socket (``force`` replaces regular files only); or the file exists and ``force`` is
        False.
    """
    p = Path(check_path_text(path, what, error=error)).expanduser()
    if suffixes and p.suffix.lower() not in suffixes:
        raise error(
            f"{what} file {str(p)!r} has the wrong extension; expected one of {', '.join(suffixes)}"
        )
    check_path_length(p, what, error=error)
    folder = _check_folder(p, what, error)
    _check_target(p, what, force, error)
    _try_creating(p, folder, what, error)
    return p


def _check_folder(p: Path, what: str, error: type[Exception]) -> Path:
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise error(
            f"cannot write the {what} {str(p)!r}: the folder {str(folder)!r} does not exist; "
            "expected an existing folder (create it first)"
        )
    if not os.access(folder, os.W_OK | os.X_OK):
        raise error(
            f"cannot write the {what} {str(p)!r}: the folder {str(folder)!r} is not writable; "
            "expected a folder you can write to"
        )
    return folder


def _check_target(p: Path, what: str, force: bool, error: type[Exception]) -> None:
    try:
        mode = os.stat(p).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise error(
            f"cannot write the {what} {str(p)!r}: {exc.strerror}; expected a path you can write"
        ) from None
    if stat.S_ISDIR(mode):
        raise error(f"the {what} path {str(p)!r} is a folder; expected a file name")
    for test, kind in _KINDS:
        if test(mode):
            raise error(
                f"the {what} path {str(p)!r} is {kind}, not a regular file; expected the name "
                "of a regular file (so101sim never replaces devices, pipes or sockets)"
            )
    if not force:
        raise error(
            f"the {what} file {str(p)!r} already exists; expected a new file name, or force "
            "overwriting (--force)"
        )


def _try_creating(p: Path, folder: Path, what: str, error: type[Exception]) -> None:
    """Create and remove the temporary file: the folder's permission bits do not tell about
    ``/proc``, ``/sys``, read-only mounts or root."""
    tmp = folder / temp_name(p, path_limit(folder, "PC_NAME_MAX", DEFAULT_NAME_MAX))
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT, 0o644)
    except OSError as exc:
        raise error(
            f"cannot write the {what} {str(p)!r}: creating a file in {str(folder)!r} failed "
            f"({exc.strerror}); expected a folder where files can be created"
        ) from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(tmp)


def claim_path(tmp: Path, path: Path) -> None:
    """Move the finished file ``tmp`` to ``path`` only if nothing is there: in one atomic
    step (a hard link, which fails if anything is at ``path``, then ``tmp`` removed), or,
    where the file system has no hard links, by creating ``path`` with ``O_EXCL`` and renaming
    over it. Two processes claiming the same path: one wins, the other gets the error.

    Raises:
        OutputPathError: something appeared at ``path`` (``tmp`` is removed).
    """
    try:
        os.link(tmp, path)  # EEXIST if anything is there, however it came
    except FileExistsError:
        _taken(tmp, path)
    except OSError:  # no hard links here (FAT, some network file systems)
        try:
            os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
        except FileExistsError:
            _taken(tmp, path)
        os.replace(tmp, path)
        return
    tmp.unlink()


def _taken(tmp: Path, path: Path) -> None:
    with contextlib.suppress(OSError):
        tmp.unlink()
    raise OutputPathError(
        f"{str(path)!r} appeared while this run wrote it (another process wrote the same "
        "file?), so this run's file was not kept; expected a path no other run writes, or "
        "--force to replace it"
    )
