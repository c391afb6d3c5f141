"""Writing a run to a CSV log (:class:`CsvLog`): one row per control step with the simulated
time, the phase, and the commanded and measured value of each joint (:func:`csv_columns`)."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..model import arm_units
from ..simulation import Observer, Trace
from ..units import JOINT_NAMES
from .paths import PendingFile, check_output_path


def csv_columns() -> list[str]:
    """The CSV log's columns: ``time`` (s), ``phase``, then ``<joint>_commanded`` and
    ``<joint>_measured`` for each joint (degrees; the gripper 0–100)."""
    return [
        "time",
        "phase",
        *(f"{n}_commanded" for n in JOINT_NAMES),
        *(f"{n}_measured" for n in JOINT_NAMES),
    ]


class CsvLog(Observer):
    """An observer that writes one CSV row per control step (= per physics step): simulated
    time (4 decimals), phase, commanded and measured value of each joint in the arm's units
    (6 decimals).

    Rows are flushed after each block of steps; :meth:`close` moves the file into place, so an
    interrupted run leaves a complete CSV of the steps taken so far.
    """

    def __init__(
        self, path: str | os.PathLike[str], model: mujoco.MjModel, *, force: bool = False
    ) -> None:
        self.path = check_output_path(path, force=force, what="log")
        self.units = arm_units(model)
        self.rows = 0
        self.closed = False
        self._file = PendingFile(self.path)
        self._fh: Any = None
        self._writer: Any = None

    def _open(self) -> None:
        self._fh = open(self._file.tmp, "w", newline="", encoding="utf-8")  # noqa: SIM115
        self._writer = csv.writer(self._fh, lineterminator="\n")
        self._writer.writerow(csv_columns())

    def on_steps(self, trace: Trace, phase: str) -> None:
        if self.closed:
            return
        if self._fh is None:
            self._open()
        if not len(trace):
            return
        values = np.column_stack(
            [trace.time, self.units.from_radians(trace.ctrl), self.units.from_radians(trace.qpos)]
        )
        self._writer.writerows(
            [f"{t:.4f}", phase, *(f"{v:.6f}" for v in joints)] for t, *joints in values.tolist()
        )
        self._fh.flush()
        self.rows += len(values)

    def close(self) -> Path | None:
        """Close and move the file into place (None if no step was logged: no file is made)."""
        if self.closed:
            return self.path if self.rows else None
        self.closed = True
        if self._fh is None:
            return None
        self._fh.close()
        return self._file.finish(keep=self.rows > 0)
