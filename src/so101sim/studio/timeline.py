"""A run's timeline in the studio: its frames (time, phase, joint positions, commanded and
measured angles), bounded in memory however long the run.

:class:`Frame` is one state; :class:`Timeline` keeps at most ``capacity`` of them (every other
one dropped when full: the rate halves), and :meth:`Timeline.at` finds the frame shown at a
simulated time. The studio's player (:mod:`.server`) replays and scrubs it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..units import GRIPPER, JOINT_NAMES

MAX_FRAMES = 20_000
"""Frames a timeline keeps at most; beyond, every other frame is dropped (the rate halves), so
an hour-long run holds as much memory as a ten-minute one."""
FRAME_RATE = 30.0  # frames per simulated second on the timeline (and live, at most)


@dataclass(frozen=True)
class Frame:
    """One state on the timeline: simulated time, phase, joint positions (qpos, mocap) and the
    commanded and measured angles in the arm's units (JOINT_NAMES order; None: not known)."""

    time: float
    phase: str
    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    commanded: np.ndarray | None
    measured: np.ndarray


class Timeline:
    """The frames of a run, at most ``capacity``: when full, every other frame is dropped and
    the spacing doubles (bounded memory, however long the run)."""

    def __init__(self, rate: float = FRAME_RATE, capacity: int = MAX_FRAMES) -> None:
        self.period = self._period0 = 1.0 / rate
        self.capacity = max(2, int(capacity))
        self.frames: list[Frame] = []
        self._next = -np.inf

    def add(self, frame: Frame, force: bool = False) -> bool:
        """Keep ``frame`` if a frame is due at its time (or ``force``); True if kept."""
        if self.frames and frame.time < self.frames[-1].time:  # the clock went back: a reset
            self.frames.clear()
            self.period = self._period0
        elif not force and frame.time < self._next:
            return False
        self.frames.append(frame)
        self._next = frame.time + self.period - 1e-9
        if len(self.frames) > self.capacity:
            self.frames = self.frames[::2]
            self.period *= 2
        return True

    @property
    def duration(self) -> float:
        return self.frames[-1].time - self.frames[0].time if self.frames else 0.0

    def at(self, t: float) -> Frame:
        """The last frame at or before simulated time ``t`` (the first one before it)."""
        times = [f.time for f in self.frames]
        i = int(np.searchsorted(times, t, side="right")) - 1
        return self.frames[max(0, min(i, len(self.frames) - 1))]


def angles_table(frame: Frame) -> str:
    """Markdown: one row per joint, commanded and measured (degrees; gripper 0-100)."""
    rows = ["| joint | commanded | measured |", "|---|---:|---:|"]
    for i, name in enumerate(JOINT_NAMES):
        unit = "" if name == GRIPPER else "°"
        cmd = "–" if frame.commanded is None else f"{frame.commanded[i]:.1f}{unit}"
        rows.append(f"| {name} | {cmd} | {frame.measured[i]:.1f}{unit} |")
    return "\n".join(rows)
