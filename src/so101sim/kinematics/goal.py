"""What IK is asked: the goal (a tip position and, optionally, an orientation) and the
solver's settings, checked as they come from a user."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..errors import SettingError
from ..validation import check_count, check_positive, check_range

DEFAULT_RESTARTS = 8
MAX_RESTARTS = 1000
DEFAULT_ITERATIONS = 100
MAX_ITERATIONS = 10_000


class Reached(Protocol):
    """How close an attempt came: metres and radians."""

    position_error: float
    orientation_error: float


@dataclass(frozen=True)
class Goal:
    """What IK aims for, in the base frame: a position, and optionally pitch (rad), approach
    (unit vector) and roll (rad), or the whole tool frame (a rotation matrix). ``pitch`` and
    ``approach`` exclude each other; ``rotation`` excludes the three."""

    position: np.ndarray
    pitch: float | None = None
    approach: np.ndarray | None = None
    roll: float | None = None
    rotation: np.ndarray | None = None

    @property
    def oriented(self) -> bool:
        """Whether any orientation is asked."""
        return not (self.pitch is None and self.approach is None and self.roll is None) or (
            self.rotation is not None
        )

    def describe(self) -> str:
        x, y, z = (float(v) for v in self.position)
        text = f"({x:.4f}, {y:.4f}, {z:.4f}) m"
        if self.pitch is not None:
            text += f" with pitch {math.degrees(self.pitch):g}°"
        if self.approach is not None:
            ax, ay, az = (float(v) for v in self.approach)
            text += f" pointing along ({ax:.3f}, {ay:.3f}, {az:.3f})"
        if self.roll is not None:
            text += f" and roll {math.degrees(self.roll):g}°"
        if self.rotation is not None:
            ax, ay, az = (float(v) for v in self.rotation[:, 0])
            text += f" with the tool frame asked (pointing along ({ax:.3f}, {ay:.3f}, {az:.3f}))"
        return text


@dataclass(frozen=True)
class Settings:
    """IK's checked settings (see :func:`solve_ik`)."""

    restarts: int = DEFAULT_RESTARTS
    max_iterations: int = DEFAULT_ITERATIONS
    tolerance_mm: float = 1.0
    tolerance_deg: float = 1.0
    seed: int = 0

    @classmethod
    def checked(
        cls,
        restarts: int,
        max_iterations: int,
        tolerance_mm: float,
        tolerance_deg: float,
        seed: int,
    ) -> Settings:
        return cls(
            restarts=check_count(restarts, "restarts", maximum=MAX_RESTARTS),
            max_iterations=check_count(
                max_iterations, "max_iterations", minimum=1, maximum=MAX_ITERATIONS
            ),
            tolerance_mm=check_positive(tolerance_mm, "tolerance_mm", maximum=1000.0, unit=" mm"),
            tolerance_deg=check_positive(tolerance_deg, "tolerance_deg", maximum=180.0, unit="°"),
            seed=check_count(seed, "seed"),
        )

    def accepts(self, att: Reached) -> bool:
        """Whether ``att`` came within the tolerances."""
        return (
            att.position_error * 1000.0 <= self.tolerance_mm
            and math.degrees(att.orientation_error) <= self.tolerance_deg
        )


Vector = Sequence[float] | np.ndarray
Matrix = Sequence[Sequence[float]] | np.ndarray


def point(target: Vector, what: str = "tip target") -> np.ndarray:
    """Three finite coordinates (metres) as an array; raises SettingError otherwise."""
    pos = np.asarray(target, dtype=float) if _is_vector(target) else None
    if pos is None or pos.shape != (3,):
        raise SettingError(
            f"{what} {target!r} is not three numbers; expected (x, y, z) in metres, in the "
            "base frame (x forward, y left, z up)"
        )
    return np.array(
        [check_range(v, f"{what} {a}", unit=" m") for a, v in zip("xyz", pos, strict=True)]
    )


def make_goal(target: Vector, orientation: Mapping[str, object] | None = None) -> Goal:
    """A checked :class:`Goal` from a user's numbers: ``target`` in metres, ``orientation``
    the optional ``pitch``/``roll`` (degrees), ``approach`` (a direction) and ``rotation``
    (3x3); None values count as not given.

    Raises:
        SettingError: not three finite coordinates, an angle outside -180..180, a direction
            of length zero, a matrix that is not a rotation, or clashing orientations.
    """
    asked = {k: v for k, v in (orientation or {}).items() if v is not None}
    if "pitch" in asked and "approach" in asked:
        raise SettingError(
            "both pitch and approach are given; expected one of them (pitch: the tool's angle "
            "above the horizontal; approach: a direction to point along)"
        )
    if "rotation" in asked and len(asked) > 1:
        raise SettingError(
            "a rotation is given with pitch, approach or roll; expected either the whole tool "
            "frame (rotation) or some of its angles, not both"
        )
    checks = {"pitch": _angle, "roll": _angle, "approach": _unit, "rotation": _rotation}
    return Goal(point(target), **{k: checks[k](v, k) for k, v in asked.items()})


def _rotation(value: Matrix, what: str) -> np.ndarray:
    try:
        r = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        r = np.zeros(0)
    ok = r.shape == (3, 3) and np.isfinite(r).all()
    if not ok or np.abs(r.T @ r - np.eye(3)).max() > 1e-6 or np.linalg.det(r) < 0:
        raise SettingError(
            f"{what} {value!r} is not a rotation matrix; expected a 3x3 matrix whose columns "
            "are the tool's x (approach), y (jaw side) and z axes, as TipPose.rotation gives"
        )
    return r


def _is_vector(value: object) -> bool:
    return isinstance(value, np.ndarray | Sequence) and not isinstance(value, str | bytes)


def _angle(value: float, what: str) -> float:
    """Degrees in -180..180, returned in radians."""
    return math.radians(check_range(value, what, low=-180.0, high=180.0, unit="°"))


def _unit(approach: Vector, what: str) -> np.ndarray:
    expected = "three numbers giving a direction, e.g. (0, 0, -1) for pointing straight down"
    a = np.asarray(approach, dtype=float) if _is_vector(approach) else None
    if a is None or a.shape != (3,) or not np.isfinite(a).all() or np.linalg.norm(a) < 1e-9:
        raise SettingError(f"{what} {approach!r} is not a direction; expected {expected}")
    return a / np.linalg.norm(a)
