"""What ``so101sim grade`` says: a graded hand-in as a short text report
(:func:`format_grade`), a folder of hand-ins as one line per student (:func:`format_folder`)
and as a CSV summary with per-phase columns (:func:`write_summary`, :func:`summary_columns`).
Text is returned, never printed (the CLI prints it)."""

from __future__ import annotations

import csv
import os
from dataclasses import asdict
from pathlib import Path
from typing import Any

from ..errors import OutputPathError
from ..validation import check_output_path
from .grade import PHASES, GradeResult, PhaseResult
from .gradefolder import FolderResult, Handin

# (check name, column) of the figures each phase puts in the summary, after its passed,
# start_s and duration_s columns
_FIGURES = {
    "to_zero": (("start", "start_error_deg"), ("reached", "reached_error_deg")),
    "hold": (("held", "moved_deg"),),
    "return": (("reached", "reached_error_deg"), ("end", "end_error_deg")),
}
_SOURCES = {"file": "file", "folder": "sub-folder"}


def _spec_line(result: GradeResult) -> str:
    s, tol = result.spec, result.tolerances
    return (
        f"spec: rest -> all zeros in {s.move_s:g} s, hold {s.hold_s:g} s, back to the start "
        f"in {s.return_s:g} s\ntolerances: {tol.angle_deg:g}° per body joint (the gripper is "
        f"not judged), {tol.time_s:g} s per phase"
    )


def _when(p: PhaseResult) -> str:
    return "not found" if p.start is None or p.end is None else f"{p.start:.3f}-{p.end:.3f} s"


def format_grade(result: GradeResult) -> str:
    """The report of one hand-in: the log's facts, one line per phase (and the video), then
    PASS, or FAIL with each reason."""
    servo = result.servo_model or "not named in the log"
    lines = [
        f"{result.log}: {result.rows} row{'s' * (result.rows != 1)}, {result.duration:.3f} s of "
        f"simulated time; servo model: {servo}",
        _spec_line(result),
    ]
    for p in result.phases:
        for i, c in enumerate(p.checks):  # the phase's verdict on its first line
            head = f"{p.name:<8} {_when(p):<14} {'PASS' if p.passed else 'FAIL'}" if i == 0 else ""
            lines.append(f"{head:<28}  {'ok' if c.passed else '!!'} {c.text}")
    if result.video is not None:
        v = result.video
        head = f"{'video':<8} {v.path.name[:14]:<14} {'PASS' if v.passed else 'FAIL'}"
        lines.append(f"{head:<28}  {'ok' if v.passed else '!!'} {v.text}")
    if result.passed:
        lines.append("PASS")
    else:
        lines.append(f"FAIL ({len(result.failures)} reason(s))")
        lines.extend(f"  - {f}" for f in result.failures)
    return "\n".join(lines)


def _handin_line(h: Handin, width: int) -> str:
    head = f"{h.student[:40]:<{width}} {_SOURCES[h.source]:<10}"
    if h.result is None:
        return f"{head} ERROR  {h.error}"
    r = h.result
    if r.passed:
        video = f", video {r.video.length_s:.2f} s" if r.video is not None else ", no video"
        return f"{head} PASS   all phases within tolerance{video}"
    return f"{head} FAIL   {'; '.join(r.failures)}"


def format_folder(result: FolderResult) -> str:
    """One line per student (name, whether named by its file or its sub-folder, the verdict
    and the reasons), then the counts."""
    handins = result.handins
    sources = {s: sum(h.source == s for h in handins) for s in _SOURCES}
    said = ", ".join(
        f"{n} by {'file name' if s == 'file' else 'sub-folder name'}"
        for s, n in sources.items()
        if n
    )
    width = max(8, *(len(h.student[:40]) for h in handins))
    lines = [
        f"{len(handins)} hand-in(s) in {result.folder}: students named {said}",
        f"{'student':<{width}} {'named by':<10} result",
    ]
    lines.extend(_handin_line(h, width) for h in handins)
    graded = [h for h in handins if h.result is not None]
    if graded:
        lines.append(_spec_line(graded[0].result))  # type: ignore[arg-type]
    passed = sum(h.passed for h in handins)
    errors = len(handins) - len(graded)
    lines.append(f"{passed} passed, {len(graded) - passed} failed, {errors} could not be graded")
    return "\n".join(lines)


def grade_dict(result: GradeResult) -> dict[str, Any]:
    """One hand-in as plain data for JSON: ``log``, ``passed``, ``failures``, ``servo_model``,
    ``rows``, ``duration_s``, ``tolerances``, ``phases`` (each with its ``checks``), ``video``."""
    phases = [
        {
            "name": p.name,
            "passed": p.passed,
            "start_s": p.start,
            "duration_s": p.duration,
            "checks": [asdict(c) for c in p.checks],
        }
        for p in result.phases
    ]
    video = None
    if result.video is not None:
        video = asdict(result.video) | {"path": str(result.video.path)}
    return {
        "log": str(result.log),
        "passed": result.passed,
        "failures": result.failures,
        "servo_model": result.servo_model,
        "rows": result.rows,
        "duration_s": result.duration,
        "tolerances": asdict(result.tolerances),
        "phases": phases,
        "video": video,
    }


def folder_dict(result: FolderResult) -> dict[str, Any]:
    """A folder's grades as plain data for JSON: ``folder``, ``passed``, ``handins`` (each:
    ``student``, ``named_by``, ``log``, ``error``, ``grade``: :func:`grade_dict` or None)."""
    handins = [
        {
            "student": h.student,
            "named_by": _SOURCES[h.source],
            "log": None if h.log is None else str(h.log),
            "error": h.error or None,
            "grade": None if h.result is None else grade_dict(h.result),
        }
        for h in result.handins
    ]
    return {"folder": str(result.folder), "passed": result.passed, "handins": handins}


def summary_columns() -> list[str]:
    """The summary's columns: the student, the files, the verdict, then per phase
    ``<phase>_passed``, ``<phase>_start_s``, ``<phase>_duration_s`` and its figures, then the
    video's, then every reason."""
    cols = ["student", "named_by", "log", "video", "result", "servo_model", "rows", "duration_s"]
    for name in PHASES:
        cols += [f"{name}_passed", f"{name}_start_s", f"{name}_duration_s"]
        cols += [f"{name}_{column}" for _, column in _FIGURES[name]]
    return [*cols, "video_passed", "video_length_s", "reasons"]


def _number(value: float | None, digits: int = 3) -> str:
    return "" if value is None else f"{value:.{digits}f}"


def _summary_row(h: Handin) -> dict[str, str]:
    row = {
        "student": h.student,
        "named_by": _SOURCES[h.source],
        "log": str(h.log) if h.log is not None else "",
        "result": "ERROR" if h.result is None else ("PASS" if h.passed else "FAIL"),
        "reasons": h.error,
    }
    r = h.result
    if r is None:
        return row
    row |= {"servo_model": r.servo_model or "", "rows": str(r.rows)}
    row |= {"duration_s": _number(r.duration), "reasons": "; ".join(r.failures)}
    for p in r.phases:
        row[f"{p.name}_passed"] = str(p.passed).lower()
        row[f"{p.name}_start_s"] = _number(p.start)
        row[f"{p.name}_duration_s"] = _number(p.duration)
        for check_name, column in _FIGURES[p.name]:
            check = p.check(check_name)
            row[f"{p.name}_{column}"] = _number(check.value if check else None, 2)
    if r.video is not None:
        row |= {"video": str(r.video.path), "video_passed": str(r.video.passed).lower()}
        row["video_length_s"] = _number(r.video.length_s)
    return row


def check_summary_path(path: str | os.PathLike[str], *, force: bool = False) -> Path:
    """The summary's path, checked before anything is graded (a new .csv file, or ``force``).

    Raises:
        OutputPathError: it cannot be written, is not .csv, or exists and ``force`` is False.
    """
    return check_output_path(path, force=force, what="summary", suffixes=(".csv",))


def write_summary(
    result: FolderResult, path: str | os.PathLike[str], *, force: bool = False
) -> Path:
    """Write the folder's summary (one row per student, :func:`summary_columns`) to ``path``.

    Raises:
        OutputPathError: as :func:`check_summary_path`, or the write failed.
    """
    p = check_summary_path(path, force=force)
    columns = summary_columns()
    try:
        with open(p, "w", newline="", encoding="utf-8") as fh:
            writer = csv.DictWriter(fh, fieldnames=columns, restval="")
            writer.writeheader()
            writer.writerows(_summary_row(h) for h in result.handins)
    except OSError as exc:
        raise OutputPathError(
            f"could not write the summary {str(p)!r}: {exc.strerror}; expected a writable file"
        ) from None
    return p


__all__ = [
    "check_summary_path",
    "folder_dict",
    "format_folder",
    "format_grade",
    "grade_dict",
    "summary_columns",
    "write_summary",
]
