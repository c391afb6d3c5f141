"""What a motion is made of, as data: :class:`Move`, :class:`Hold` (a :data:`Segment` each),
the lab's motion and a run's result (:class:`RunResult`). No stepping and no planning here:
:mod:`.plan` plans segments, :mod:`.segments` runs them."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from ..sim.profiles import Profile
from ..sim.simulation import SegmentResult
from ..units import STARTING_POSE, ZERO_POSE, Pose


@dataclass(frozen=True)
class Move:
    """Move to ``target`` (a pose) over ``duration`` seconds with ``profile``; or, with
    ``tip`` = (x, y, z) metres and no target, move the gripper's tip there (optional tool
    ``pitch``/``roll`` in degrees) along a straight line (``path="line"``) or in joint space
    (``path="joint"``): see :meth:`Simulation.move_to` and :meth:`Move.to_tip`."""

    target: Pose | None
    duration: float
    profile: str | Profile = "linear"
    phase: str = "move"
    tip: tuple[float, float, float] | None = None
    pitch: float | None = None
    roll: float | None = None
    path: str = "line"

    @classmethod
    def to_tip(
        cls,
        tip: Sequence[float],
        duration: float,
        *,
        pitch: float | None = None,
        roll: float | None = None,
        path: str = "line",
        profile: str | Profile = "linear",
        phase: str = "move",
    ) -> Move:
        """A move of the tip to ``tip`` (metres, base frame)."""
        return cls(None, duration, profile, phase, tuple(tip), pitch, roll, path)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Hold:
    """Hold the last target for ``duration`` seconds."""

    duration: float
    phase: str = "hold"


Segment = Move | Hold
"""One part of a motion: a :class:`Move` or a :class:`Hold` (each runs many physics steps)."""


@dataclass(frozen=True)
class RunResult:
    """The segments of a motion, in order. ``completed`` is False if it was cut short."""

    segments: list[SegmentResult]

    @property
    def completed(self) -> bool:
        return all(s.completed for s in self.segments)

    @property
    def end_time(self) -> float:
        return self.segments[-1].end_time if self.segments else 0.0


LAB_MOTION: tuple[Segment, ...] = (
    Move(ZERO_POSE, 2.0, phase="to_zero"),
    Hold(2.0, phase="hold"),
    Move(STARTING_POSE, 2.0, phase="return"),
)
"""The lab's motion: from the rest pose to all zeros in 2 s, hold 2 s, back in 2 s."""


__all__ = ["LAB_MOTION", "Hold", "Move", "RunResult", "Segment"]
