"""Reading a so101sim CSV log (``so101sim run --log``, or written by a script driving the real
follower): one episode, each line bounded (a 200 MB line is refused, not read whole)."""

from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

import numpy as np

from ..units import JOINT_NAMES
from .logdata import MAX_FRAMES, ArmLog, Episode, LogError, choose_episodes, regular_file

__all__ = ["MAX_LINE", "read_csv_log"]

MAX_LINE = 64 * 1024
"""The longest line a CSV log may have, in characters (a so101sim row is about 200)."""


def _lines(fh: TextIO, path: Path) -> Iterator[str]:
    number = 0
    while True:
        line = fh.readline(MAX_LINE + 1)
        if not line:
            return
        number += 1
        if len(line) > MAX_LINE:
            raise LogError(
                f"CSV log {str(path)!r}: line {number} is longer than {MAX_LINE} characters; "
                "expected a log written by so101sim (--log)"
            )
        yield line


def read_csv_log(path: Path, episodes: list[int] | None) -> ArmLog:
    """The CSV log at ``path`` as one episode (episode 0) in arm units.

    Raises:
        LogError: missing columns, short or overlong rows, values that are not finite numbers,
            times that do not increase.
    """
    regular_file(path, "CSV log")
    kinds = ("commanded", "measured")
    need_cols = ["time"] + [f"{n}_{k}" for n in JOINT_NAMES for k in kinds]
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(_lines(fh, path))
            missing = [c for c in need_cols if c not in (reader.fieldnames or [])]
            if missing:
                raise LogError(
                    f"CSV log {str(path)!r} lacks the columns {', '.join(missing[:3])}; expected "
                    "a log written by so101sim (--log)"
                )
            rows = []
            for i, row in enumerate(reader):
                if i >= MAX_FRAMES:
                    raise LogError(f"CSV log {str(path)!r} has more than {MAX_FRAMES} rows")
                values = [row.get(c) for c in need_cols]
                if any(v is None for v in values):
                    raise LogError(
                        f"CSV log {str(path)!r}: row {i + 2} has fewer fields than the header; "
                        "expected a log written by so101sim (--log)"
                    )
                rows.append([float(v) for v in values])
    except LogError:
        raise
    except (OSError, ValueError, UnicodeDecodeError, csv.Error) as exc:
        text = " ".join(str(exc).split())[:200]
        raise LogError(f"CSV log {str(path)!r} cannot be read: {text}") from exc
    if len(rows) < 3:
        raise LogError(f"CSV log {str(path)!r} has fewer than three rows")
    a = np.array(rows)
    if not np.isfinite(a).all():
        row = int(np.flatnonzero(~np.isfinite(a).all(axis=1))[0]) + 2
        raise LogError(
            f"CSV log {str(path)!r}: row {row} holds a value that is not a finite number (NaN or "
            "infinity); expected times, commands and measurements"
        )
    choose_episodes([0], episodes, str(path))
    # so101sim's --log writes each row's measurement after that row's command has acted (one
    # physics step later); a recording pairs each command with the state read before it
    # (LeRobot's order, what the replay assumes): frame k is row k's command with row k-1's
    # measurement, so the first row gives only the first measured state.
    t = a[1:, 0] - a[1, 0]
    cmd = a[1:, 1::2][:, : len(JOINT_NAMES)]
    meas = a[:-1, 2::2][:, : len(JOINT_NAMES)]
    dt = np.diff(t)
    if (dt <= 0).any():
        raise LogError(f"CSV log {str(path)!r}: times do not increase")
    fps = 1.0 / float(np.median(dt))
    return ArmLog(fps, [Episode(0, t, cmd, meas)], str(path), "csv", [])
