"""What a move or hold of a :class:`~so101sim.sim.simulation.Simulation` did: the
:class:`SegmentResult`, and the observer that computes its summary block by block
(:class:`ErrorTracker`: the largest tracking error and the last target, so a segment needs no
per-step arrays for its summary)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from ..units import JOINT_NAMES, ArmUnits
from .stepping import Observer, Trace

SegmentKind = Literal["move", "hold", "step"]

TRACE_AUTO_STEPS = 60_000
"""Segments of at most this many steps (two minutes at 2 ms) keep their per-step trace unless
told otherwise; longer ones keep only their summary, so memory stays flat."""


@dataclass(frozen=True)
class SegmentResult:
    """What one move or hold did. Poses are dicts in the arm's units; arrays are per step."""

    phase: str
    kind: SegmentKind
    start_time: float
    end_time: float
    steps: int
    start: dict[str, float]  # commanded pose at the start
    target: dict[str, float]  # final commanded pose
    reached: dict[str, float]  # measured pose at the end
    max_tracking_error: dict[str, float]  # max |commanded - measured| over the segment
    completed: bool
    times: np.ndarray = field(repr=False)  # (n,) simulated time after each step
    commanded: np.ndarray = field(repr=False)  # (n, 6) arm units
    measured: np.ndarray = field(repr=False)  # (n, 6) arm units

    @property
    def duration(self) -> float:
        return self.end_time - self.start_time

    @property
    def final_error(self) -> dict[str, float]:
        """|target - reached| per joint at the end of the segment."""
        return {n: abs(self.target[n] - self.reached[n]) for n in JOINT_NAMES}

    @property
    def worst_tracking_error(self) -> tuple[str, float]:
        """(joint, error) of the largest tracking error over the segment."""
        name = max(self.max_tracking_error, key=self.max_tracking_error.__getitem__)
        return name, self.max_tracking_error[name]


def keep_trace(trace: bool | None, n: int) -> bool:
    """Whether a segment of ``n`` steps keeps its per-step arrays (``trace``; None: when it is
    at most :data:`TRACE_AUTO_STEPS` steps)."""
    return n <= TRACE_AUTO_STEPS if trace is None else bool(trace)


class ErrorTracker(Observer):
    """The largest |commanded - measured| per joint (arm units) and the last commanded target,
    computed block by block, so a segment needs no per-step arrays for its summary."""

    def __init__(self, units: ArmUnits, start: np.ndarray) -> None:
        self.units = units
        self.max = np.zeros(len(start))
        self.last = np.asarray(start, dtype=float)

    def on_steps(self, trace: Trace, phase: str) -> None:
        commanded = self.units.from_radians(trace.ctrl)
        measured = self.units.from_radians(trace.qpos)
        # along contiguous rows: NumPy reduces them several times faster than columns
        error = np.ascontiguousarray(np.abs(commanded - measured).T)
        self.max = np.maximum(self.max, error.max(axis=1))
        self.last = commanded[-1]


__all__ = ["TRACE_AUTO_STEPS", "ErrorTracker", "SegmentKind", "SegmentResult", "keep_trace"]
