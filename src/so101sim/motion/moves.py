"""What a motion is made of, as data: :class:`Move`, :class:`Hold` (a :data:`Segment` each),
the lab's motion and a run's result (:class:`RunResult`). No stepping and no planning here:
:mod:`.plan` plans segments, :mod:`.segments` runs them."""

from __future__ import annotations

import sys
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..sim.moveplan import Shape
from ..sim.simulation import SegmentResult
from ..units import STARTING_POSE, ZERO_POSE, Pose

_RENAMED = (
    "Move's profile is deprecated and goes in the next release; use shape (e.g. "
    'Move(pose, 2.0, shape="minimum_jerk")): "profile" names the arm profile, the servos\' model'
)


@dataclass(frozen=True, init=False)
class Move:
    """Move to ``target`` (a pose) over ``duration`` seconds with ``shape`` (``"linear"``,
    ``"minimum_jerk"``, ``"limited"`` or a function, :mod:`so101sim.sim.profiles`); or, with
    ``tip`` = (x, y, z) metres and no target, move the gripper's tip there (optional tool
    ``pitch``/``roll`` in degrees) along a straight line (``path="line"``) or in joint space
    (``path="joint"``): see :meth:`Simulation.move_to` and :meth:`Move.to_tip`.

    ``profile=`` (and the attribute ``profile``) is the old name of ``shape``, accepted for one
    release with a DeprecationWarning; given with ``shape``, ``profile`` wins (as
    ``dataclasses.replace(move, profile=...)`` expects)."""

    target: Pose | None
    duration: float
    shape: Shape
    phase: str
    tip: tuple[float, float, float] | None
    pitch: float | None
    roll: float | None
    path: str

    def __init__(
        self,
        target: Pose | None,
        duration: float,
        shape: Shape | None = None,
        phase: str = "move",
        tip: tuple[float, float, float] | None = None,
        pitch: float | None = None,
        roll: float | None = None,
        path: str = "line",
        *,
        profile: Shape | None = None,
    ) -> None:
        if profile is not None:
            warnings.warn(_RENAMED, DeprecationWarning, stacklevel=_caller_level())
            shape = profile
        values = (target, duration, "linear" if shape is None else shape, phase)
        for name, value in zip(("target", "duration", "shape", "phase"), values, strict=True):
            object.__setattr__(self, name, value)
        for name, value in (("tip", tip), ("pitch", pitch), ("roll", roll), ("path", path)):
            object.__setattr__(self, name, value)

    @property
    def profile(self) -> Shape:
        """Deprecated: the move's :attr:`shape` (its old name)."""
        warnings.warn(_RENAMED, DeprecationWarning, stacklevel=2)
        return self.shape

    @classmethod
    def to_tip(
        cls,
        tip: Sequence[float],
        duration: float,
        *,
        pitch: float | None = None,
        roll: float | None = None,
        path: str = "line",
        shape: Shape | None = None,
        phase: str = "move",
        profile: Shape | None = None,
    ) -> Move:
        """A move of the tip to ``tip`` (metres, base frame); ``profile=`` as in :class:`Move`."""
        if profile is not None:
            warnings.warn(_RENAMED, DeprecationWarning, stacklevel=2)
            shape = profile
        return cls(None, duration, shape, phase, tuple(tip), pitch, roll, path)  # type: ignore[arg-type]


def _caller_level() -> int:
    """The stack level of the code that made a Move (past ``dataclasses.replace``)."""
    frame: Any = sys._getframe(2)
    level = 2
    while frame is not None and frame.f_code.co_filename.endswith("dataclasses.py"):
        frame, level = frame.f_back, level + 1
    return level


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
