"""Reading a hand-in's CSV log for ``so101sim grade``: the log that ``so101sim run --log`` and
``so101sim record ... --log`` write (:class:`~so101sim.recording.csvlog.CsvLog`), checked row by
row before anything is judged.

:func:`read_run_log` returns a :class:`RunLog` (times, commanded and measured angles in the
arm's units) or raises :class:`NotASo101SimLogError` with one line saying what is wrong and
where (the header, a line number, a value). Comment lines (starting with ``#``) are allowed
anywhere. Columns are taken by name: the log's ``servo_model`` column, or a comment naming
the servo model (``# arm: sts3215``, ``# servo model: ...``), says which servo model ran.
Everything is bounded: the file's size (:data:`MAX_LOG_BYTES`) and its rows
(:data:`MAX_LOG_ROWS`), checked before the rows are read.
"""

from __future__ import annotations

import csv
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import So101SimError
from ..units import JOINT_NAMES
from ..validation import check_input_file

MAX_LOG_BYTES = 64 * 1024 * 1024
"""The largest log read (64 MiB: over 400 000 rows, 14 minutes of a run at 500 steps/s)."""

MAX_LOG_ROWS = 500_000
"""The most rows read from one log (1000 s of simulated time at the shipped 2 ms step)."""

_SERVO_COMMENT = re.compile(
    r"\b(?:arm|servo[ _-]?model|servos?|actuators?|actuator[ _-]?model)\s*[:=]\s*(.+?)\s*$",
    re.IGNORECASE,
)
_LOG_WHAT = "a so101sim CSV log (so101sim run --log, so101sim record ... --log)"


class NotASo101SimLogError(So101SimError, ValueError):
    """The file given to ``so101sim grade`` is not one of so101sim's CSV logs, or is damaged."""


@dataclass(frozen=True)
class RunLog:
    """A so101sim CSV log, read and checked: one row per logged step.

    ``commanded`` and ``measured`` are ``(rows, 6)`` arrays in the arm's units (degrees, the
    gripper 0-100), joints in :data:`~so101sim.units.JOINT_NAMES` order; ``time`` (s) increases.
    """

    path: Path
    time: np.ndarray
    phases: tuple[str, ...]
    commanded: np.ndarray
    measured: np.ndarray
    comments: tuple[str, ...] = field(default=())
    servo_model: str | None = None

    @property
    def rows(self) -> int:
        return len(self.time)

    @property
    def step(self) -> float:
        """The time between the first two rows (s): the run's control step (0 with one row)."""
        return float(self.time[1] - self.time[0]) if self.rows > 1 else 0.0

    @property
    def start_time(self) -> float:
        """When the run began: one step before the first row (each row is logged after its
        step)."""
        return float(self.time[0]) - self.step

    @property
    def duration(self) -> float:
        """Simulated seconds the log covers, from :attr:`start_time` to its last row."""
        return float(self.time[-1]) - self.start_time


def _fail(path: Path, what: str) -> NotASo101SimLogError:
    return NotASo101SimLogError(f"{path}: {what}")


def _read_text(path: Path) -> str:
    size = os.stat(path).st_size
    if size > MAX_LOG_BYTES:
        raise _fail(
            path,
            f"{size / 2**20:.1f} MiB is too large for a log; expected at most "
            f"{MAX_LOG_BYTES // 2**20} MiB ({_LOG_WHAT})",
        )
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_LOG_BYTES + 1)
    except OSError as exc:
        raise _fail(path, f"cannot be read ({exc.strerror}); expected {_LOG_WHAT}") from None
    if b"\0" in raw:
        raise _fail(path, f"holds NUL bytes (binary data, not text); expected {_LOG_WHAT}")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _fail(path, f"is not UTF-8 text (byte {exc.start}); expected {_LOG_WHAT}") from None


def _servo_model(comments: list[str]) -> str | None:
    for line in comments:
        m = _SERVO_COMMENT.search(line)
        if m:
            return m.group(1)[:200]
    return None


NUMBER_COLUMNS: tuple[str, ...] = (
    "time",
    *(f"{n}_commanded" for n in JOINT_NAMES),
    *(f"{n}_measured" for n in JOINT_NAMES),
)
"""The columns a so101sim log must hold, read as numbers (with ``phase``; a ``servo_model``
column, and any other, is allowed: columns are taken by name)."""
SERVO_COLUMN = "servo_model"


def _check_header(path: Path, number: int, fields: list[str]) -> list[int]:
    """Where each of NUMBER_COLUMNS is in the header, or the error of a foreign header."""
    missing = [c for c in ("phase", *NUMBER_COLUMNS) if c not in fields]
    if missing or len(set(fields)) != len(fields):
        shown = ",".join(fields)[:80]
        why = f"no {missing[0]} column" if missing else "a column named twice"
        raise _fail(
            path,
            f"line {number} is {shown!r}, not the header of a so101sim log ({why}); expected "
            f"time,phase,shoulder_pan_commanded,... as in {_LOG_WHAT}",
        )
    return [fields.index(c) for c in NUMBER_COLUMNS]


def _row_values(path: Path, number: int, fields: list[str], where: list[int]) -> list[float]:
    """The 13 numbers of a row (time, 6 commanded, 6 measured), each checked finite."""
    values = []
    for name, k in zip(NUMBER_COLUMNS, where, strict=True):
        text = fields[k]
        try:
            v = float(text)
        except ValueError:
            raise _fail(
                path,
                f"line {number}: {name} = {text[:40]!r} is not a number; expected a number",
            ) from None
        if not math.isfinite(v):
            raise _fail(
                path, f"line {number}: {name} = {text!r} is not finite; expected a finite number"
            )
        values.append(v)
    return values


def read_run_log(path: str | os.PathLike[str]) -> RunLog:
    """Read and check the CSV log at ``path``.

    Raises:
        SettingError: ``path`` is not a readable file (missing, a folder, a device).
        NotASo101SimLogError: it is not a so101sim log, or is damaged: too large, not UTF-8
            text, another header, a row with another number of fields, a value that is not
            a finite number, times that do not increase, too many rows, or no row at all.
    """
    p = check_input_file(path, "log", expected=_LOG_WHAT)
    lines = _read_text(p).splitlines()
    comments: list[str] = []
    header: list[str] | None = None
    where: list[int] = []
    times: list[float] = []
    phases: list[str] = []
    servos: dict[str, None] = {}  # the servo models named, in order
    numbers: list[list[float]] = []
    for number, fields in _records(lines, comments):
        if header is None:
            where, header = _check_header(p, number, fields), fields
            phase_at = header.index("phase")
            servo_at = header.index(SERVO_COLUMN) if SERVO_COLUMN in header else None
            continue
        if len(fields) != len(header):
            raise _fail(
                p,
                f"line {number} has {len(fields)} fields; expected {len(header)}, as the "
                "header: the log is damaged or cut",
            )
        if len(times) >= MAX_LOG_ROWS:
            raise _fail(p, f"has more than {MAX_LOG_ROWS} rows; expected at most {MAX_LOG_ROWS}")
        values = _row_values(p, number, fields, where)
        if times and values[0] <= times[-1]:
            raise _fail(
                p,
                f"line {number}: time {values[0]:g} s after {times[-1]:g} s; expected times "
                "that increase row by row",
            )
        times.append(values[0])
        phases.append(fields[phase_at])
        if servo_at is not None and len(servos) < 8:
            servos[fields[servo_at][:100]] = None
        numbers.append(values[1:])
    if header is None:
        raise _fail(p, f"is empty (no header, no rows); expected {_LOG_WHAT}")
    if not times:
        raise _fail(p, "holds the header but no rows; expected the rows of a run")
    values = np.asarray(numbers, dtype=float)
    n = len(JOINT_NAMES)
    servo = ", ".join(servos) if servos else _servo_model(comments)
    return RunLog(
        p, np.asarray(times), tuple(phases), values[:, :n], values[:, n:], tuple(comments), servo
    )


def _records(lines: list[str], comments: list[str]):
    """(line number, fields) of each line that is not blank or a comment (kept in
    ``comments``); a field holding a line break is not in so101sim's logs."""
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        if line.startswith("#"):
            if len(comments) < 100:
                comments.append(line)
            continue
        yield number, next(csv.reader([line]))


__all__ = [
    "MAX_LOG_BYTES",
    "MAX_LOG_ROWS",
    "NUMBER_COLUMNS",
    "NotASo101SimLogError",
    "RunLog",
    "read_run_log",
]
