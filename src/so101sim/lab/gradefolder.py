"""A folder of lab hand-ins graded at once (``so101sim grade FOLDER``): one per CSV log at
the top of the folder (the student: the file's name) or per sub-folder holding one CSV log (the
student: the sub-folder's name), each with the video beside its log (the same name, a video
suffix) when there is one. Bounded: at most :data:`MAX_HANDINS` hand-ins; each log by
:mod:`.gradelog`'s limits."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import SettingError, So101SimError
from ..validation import check_count, checked_path
from .grade import GradeResult, LabSpec, Tolerances, grade_log

VIDEO_SUFFIXES = (".mp4", ".mov", ".mkv", ".webm", ".avi", ".gif")
"""The videos looked for beside a log in a folder of hand-ins (the same name, one of these)."""
MAX_HANDINS = 1000
"""The most hand-ins (CSV files and sub-folders) graded in one folder."""


@dataclass(frozen=True)
class Handin:
    """One student's hand-in in a folder: named by its file (``source = "file"``) or its
    sub-folder (``"folder"``); its ``result``, or the ``error`` that kept it from a grade."""

    student: str
    source: str
    log: Path | None
    result: GradeResult | None = None
    error: str = ""

    @property
    def passed(self) -> bool:
        return self.result is not None and self.result.passed


@dataclass(frozen=True)
class FolderResult:
    folder: Path
    handins: tuple[Handin, ...] = field(default=())

    @property
    def passed(self) -> bool:
        return all(h.passed for h in self.handins)


def _beside(log: Path) -> Path | None:
    for suffix in VIDEO_SUFFIXES:
        video = log.with_suffix(suffix)
        if video.is_file():
            return video
    return None


def _entries(folder: Path) -> list[tuple[str, str, Path | None, str]]:
    """(student, source, log, error) of each hand-in in ``folder``, by name."""
    try:
        names = sorted(e for e in os.listdir(folder) if not e.startswith("."))
    except OSError as exc:
        raise SettingError(f"cannot list the folder {str(folder)!r}: {exc.strerror}") from None
    out = []
    for name in names:
        entry = folder / name
        if entry.is_file() and entry.suffix.lower() == ".csv":
            out.append((entry.stem, "file", entry, ""))
        elif entry.is_dir():
            logs = sorted(
                p
                for p in entry.iterdir()
                if p.suffix.lower() == ".csv" and not p.name.startswith(".") and p.is_file()
            )
            error = ""
            if not logs:
                error = f"no CSV log in {name}/; expected one (the student's log)"
            elif len(logs) > 1:
                found = ", ".join(p.name for p in logs[:5])
                error = f"{len(logs)} CSV logs in {name}/ ({found}); expected one"
            out.append((name, "folder", logs[0] if len(logs) == 1 else None, error))
        check_count(
            len(out), "hand-ins in the folder", maximum=MAX_HANDINS,
            expected=f"at most {MAX_HANDINS} CSV logs and sub-folders",
        )  # fmt: skip
    return out


def grade_folder(
    folder: str | os.PathLike[str],
    *,
    tolerances: Tolerances | None = None,
    spec: LabSpec | None = None,
) -> FolderResult:
    """Grade every hand-in in ``folder``: each CSV file (the student: its name) and each
    sub-folder holding one CSV log (the student: the sub-folder's name), with the video
    beside the log (same name, a video suffix) when there is one. A log that cannot be
    graded is that student's ``error``; the others are still graded.

    Raises:
        SettingError: ``folder`` is not a folder, holds no hand-in, or more than
            :data:`MAX_HANDINS`.
    """
    root = checked_path(folder, "hand-in folder")
    if not root.is_dir():
        raise SettingError(f"{str(root)!r} is not a folder; expected a folder of hand-ins")
    tol = tolerances if tolerances is not None else Tolerances()
    handins = []
    for student, source, log, error in _entries(root):
        if log is None:
            handins.append(Handin(student, source, None, error=error))
            continue
        try:
            result = grade_log(log, video=_beside(log), tolerances=tol, spec=spec)
        except So101SimError as exc:
            handins.append(Handin(student, source, log, error=str(exc)))
            continue
        handins.append(Handin(student, source, log, result))
    if not handins:
        raise SettingError(
            f"{str(root)!r} holds no hand-in; expected CSV logs (one per student) or "
            "sub-folders holding one CSV log each"
        )
    return FolderResult(root, tuple(handins))


__all__ = ["MAX_HANDINS", "FolderResult", "Handin", "grade_folder"]
