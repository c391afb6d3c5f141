"""Writing a run to a CSV log (:class:`CsvLog`): one row per control step with the simulated
time, the phase, and the commanded and measured value of each joint (:func:`csv_columns`).

The log streams to disk: each block of steps is formatted and written at once, so memory stays
flat however long the run, and an interruption leaves whole rows only."""

from __future__ import annotations

import contextlib
import csv
import io
import os
from pathlib import Path
from typing import IO, NoReturn

import mujoco
import numpy as np

from ..model.build import servo_name
from ..model.load import arm_units
from ..sim.simulation import Observer, Trace
from ..units import JOINT_NAMES
from .paths import PendingFile, check_output_path, write_error


def csv_columns() -> list[str]:
    """The CSV log's columns: ``time`` (s), ``phase``, then ``<joint>_commanded`` and
    ``<joint>_measured`` for each joint (degrees; the gripper 0–100), then ``servo_model``:
    the run's servo model (``sts3215``, ``official``, a profile's name; ``unknown`` for a model
    so101sim cannot name). Readers take the columns by name (logs before ``servo_model``
    was added read the same)."""
    return [
        "time",
        "phase",
        *(f"{n}_commanded" for n in JOINT_NAMES),
        *(f"{n}_measured" for n in JOINT_NAMES),
        "servo_model",
    ]


def _csv_line(fields: list[str]) -> str:
    """``fields`` as one CSV line (quoted where needed), without the line end."""
    out = io.StringIO()
    csv.writer(out, lineterminator="").writerow(fields)
    return out.getvalue()


class CsvLog(Observer):
    """An observer that writes one CSV row per control step (= per physics step): simulated
    time (4 decimals), phase, commanded and measured value of each joint in the arm's units
    (6 decimals).

    Rows are written and flushed after each block of steps, each block in one write;
    :meth:`close` moves the file into place, so an interrupted run leaves a complete CSV of the
    steps taken so far. A write that fails (a full disk) raises
    :class:`~so101sim.errors.OutputPathError` and leaves nothing at the path.
    """

    def __init__(
        self, path: str | os.PathLike[str], model: mujoco.MjModel, *, force: bool = False
    ) -> None:
        self.path = check_output_path(path, force=force, what="log")
        self.units = arm_units(model)
        self.servo = _csv_line([servo_name(model)]).replace("%", "%%")
        self.rows = 0
        self.closed = False
        self._file = PendingFile(self.path, force=force)
        self._fh: IO[str] | None = None
        self._finished = False
        self._written: Path | None = None
        self._formats: dict[str, str] = {}

    def _open(self) -> IO[str]:
        try:
            self._fh = open(self._file.tmp, "w", newline="", encoding="utf-8")  # noqa: SIM115
            self._fh.write(_csv_line(csv_columns()) + "\n")
        except OSError as exc:
            self._fail(exc)
        return self._fh

    def _row_format(self, phase: str) -> str:
        """The %-format of a row of ``phase`` (its CSV-quoted name inside)."""
        fmt = self._formats.get(phase)
        if fmt is None:
            name = _csv_line([phase]).replace("%", "%%")
            fmt = ",".join(["%.4f", name, *["%.6f"] * (2 * len(JOINT_NAMES)), self.servo])
            if len(self._formats) < 256:  # phases are few; bound the cache anyway
                self._formats[phase] = fmt
        return fmt

    def on_steps(self, trace: Trace, phase: str) -> None:
        if self.closed:
            return
        fh = self._fh if self._fh is not None else self._open()
        if not len(trace.time):
            return
        values = np.column_stack(
            [trace.time, self.units.from_radians(trace.ctrl), self.units.from_radians(trace.qpos)]
        )
        fmt = self._row_format(phase)
        text = "".join([fmt % tuple(row) + "\n" for row in values.tolist()])
        try:
            fh.write(text)
            fh.flush()
        except OSError as exc:
            self._fail(exc)
        self.rows += len(values)

    def _fail(self, exc: OSError) -> NoReturn:
        """Drop the file and raise the error (a full disk): nothing is left at the path."""
        self.closed = self._finished = True
        if self._fh is not None:
            with contextlib.suppress(OSError):  # the same full disk: the file is dropped
                self._fh.close()
        self._file.discard()
        raise write_error("log", self.path, exc) from exc

    def abandon(self) -> None:
        """Stop logging and remove the unfinished file (nothing is left at the path)."""
        self.closed = True
        if self._finished:
            return
        self._finished = True
        if self._fh is not None:
            with contextlib.suppress(OSError):
                self._fh.close()
        self._file.discard()

    def close(self) -> Path | None:
        """Close and move the file into place (None if no step was logged: no file is made).

        May be interrupted (Ctrl-C) and called again: it goes on where it stopped.

        Raises:
            OutputPathError: the last rows could not be written (a full disk); nothing is left
                at the path.
        """
        self.closed = True
        if self._finished:
            return self._written
        if self._fh is not None:
            try:
                self._fh.close()  # a second close() does nothing
                self._written = self._file.finish(keep=self.rows > 0)
            except OSError as exc:
                self._fail(exc)
        self._finished = True
        return self._written
