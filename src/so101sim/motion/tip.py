"""Tip moves in motion files: ``move = { tip = [0.20, 0.0, 0.05], pitch = -90 }``.

A move whose table has a ``tip`` key moves the gripper's tip (the ``gripperframe`` site) to
(x, y, z) metres in the base frame (x forward, y left, z up), as
:meth:`Simulation.move_to(tip=...) <so101sim.sim.simulation.Simulation.move_to>` does:

* ``tip``: three finite numbers, each within :data:`MAX_TIP_M` (2 m) of the base frame's
  origin along its axis (the arm reaches 0.48 m; a larger number is a typo or millimetres);
* ``pitch``, ``roll``: optional, degrees in -180..180 (``pitch = -90`` points straight down);
* ``path``: ``"line"`` (default: the tip follows a straight line) or ``"joint"`` (inverse
  kinematics for the end only, then a joint-space move).

``duration``, ``shape`` and ``name`` stay keys of the step, as for any move. The checks here
raise :class:`~so101sim.errors.SettingError` (the loader, :mod:`so101sim.motion.file`, gives
them the file and line); :class:`TipPlanner` plans each tip move in full from the target
before it, exactly as the run will, so an unreachable point is reported when the file is loaded
and the moves after it continue from the pose the arm will really be in.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from ..errors import JointNameError, SettingError, UnreachableError
from ..exitgate import mujoco_call
from ..model.load import load_model
from ..sim.moveplan import Shape, plan_tip_move
from ..sim.profiles import step_count
from ..sim.simulation import Simulation
from ..units import normalize_joint_name
from ..validation import check_choice, check_range, shown
from .segments import Move

TIP_KEYS = ("tip", "pitch", "roll", "path")
"""The keys of a tip move's table."""

STEP_ONLY_KEYS = ("duration", "shape", "profile", "name")
"""Keys that belong to the step, not to the move's table (a likely slip)."""

PATHS = ("line", "joint")

MAX_TIP_M = 2.0
"""The largest |x|, |y| or |z| of a tip target accepted, in metres."""


@dataclass(frozen=True)
class TipTarget:
    """A checked tip move's target: metres and degrees."""

    tip: tuple[float, float, float]
    pitch: float | None = None
    roll: float | None = None
    path: str = "line"

    def move(self, duration: float, shape: Shape, phase: str) -> Move:
        """The :class:`~so101sim.motion.Move` for this target."""
        return Move.to_tip(
            self.tip,
            duration,
            pitch=self.pitch,
            roll=self.roll,
            path=self.path,
            shape=shape,
            phase=phase,
        )


def is_tip_move(value: Any) -> bool:
    """Whether a move's value is a tip move's table."""
    return isinstance(value, Mapping) and "tip" in value


def check_tip(value: Any) -> tuple[float, float, float]:
    """Three finite numbers (metres), each within ±:data:`MAX_TIP_M`."""
    expected = (
        f"three numbers in metres, each within ±{MAX_TIP_M:g} m, e.g. tip = [0.20, 0.0, 0.05] "
        "(x forward, y left, z up from the base frame)"
    )
    if not isinstance(value, list) or len(value) != 3:
        what = f"a list of {len(value)}" if isinstance(value, list) else shown(value)
        raise SettingError(f"tip = {what} is not three numbers; expected {expected}")
    x, y, z = (
        check_range(v, f"tip {axis}", low=-MAX_TIP_M, high=MAX_TIP_M, unit=" m", expected=expected)
        for axis, v in zip("xyz", value, strict=True)
    )
    return (x, y, z)


def check_angle(value: Any, what: str) -> float:
    """Degrees in -180..180 (the kinematics' range for pitch and roll)."""
    return check_range(value, what, low=-180.0, high=180.0, unit="°")


def check_tip_value(key: str, value: Any) -> Any:
    """One key of a tip move's table and its value, checked.

    Raises:
        SettingError: the value is invalid, or the key is a joint (a pose and a tip in one
            move) or not one of :data:`TIP_KEYS`.
    """
    if key not in TIP_KEYS:
        raise SettingError(_key_problem(key))
    if key == "tip":
        return check_tip(value)
    if key == "path":
        return check_choice(value, "path", PATHS)
    return check_angle(value, key)


def _key_problem(key: str) -> str:
    try:
        joint = normalize_joint_name(key)
    except JointNameError:
        hint = " (duration, shape and name are keys of the step)"
        return f"unknown key {shown(key)} in a tip move; expected {', '.join(TIP_KEYS)}" + (
            hint if key in STEP_ONLY_KEYS else ""
        )
    return (
        f"a move gives both a tip and a pose (joint {joint!r}); expected one of them: "
        "move = { tip = [x, y, z], pitch = ..., roll = ..., path = ... } or a pose"
    )


def unreachable_reason(exc: UnreachableError) -> str:
    """An unreachable tip's message as said about a motion file: the API's advice
    (``closest=True``) has no counterpart in a file, and ``path`` is written as TOML."""
    text = str(exc).replace(", or pass closest=True to get the closest reachable pose", "")
    return "the tip cannot get there: " + text.replace("path='joint'", 'path = "joint"')


class TipPlanner:
    """Plans tip moves on a scratch :class:`~so101sim.sim.simulation.Simulation` (planning only,
    never stepped), the way :func:`~so101sim.motion.run_segments` will: the model is loaded on
    the first tip move (the shipped one unless given)."""

    def __init__(self, model: mujoco.MjModel | None = None) -> None:
        self._model = model
        self._sim: Simulation | None = None
        self.last: tuple[np.ndarray, np.ndarray] | None = None  # the last move planned

    def end(self, move: Move, current: np.ndarray) -> np.ndarray:
        """The target (arm units) a tip move from ``current`` ends on.

        Raises:
            UnreachableError: the tip, or a point of its line, is out of reach.
            SettingError: a shape a straight line cannot follow (``limited``).
        """
        return self.plan(move, current)[1][-1].copy()

    def plan(self, move: Move, current: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tip move from ``current`` planned in full: ``(start, targets)`` in arm units, as
        the run will command them (``start`` is ``current`` as the run reads it back), and
        kept as :attr:`last` (the loader hands it to the run: a line is solved once).

        Raises:
            UnreachableError, SettingError: as :meth:`end`.
        """
        if self._sim is None:
            self._sim = Simulation(self._model or load_model(), initial_pose=None)
        self._sim.command_array(current, check=False)
        with mujoco_call():  # as Simulation.plan_tip_move; the loader checked the duration
            start, targets = plan_tip_move(
                self._sim,
                move.tip,  # type: ignore[arg-type]
                move.duration,
                pitch=move.pitch,
                roll=move.roll,
                path=move.path,
                shape=move.shape,
                steps=step_count(move.duration, self._sim.timestep),
            )
        self.last = (start, targets)
        return start, targets


__all__ = [
    "MAX_TIP_M",
    "PATHS",
    "STEP_ONLY_KEYS",
    "TIP_KEYS",
    "TipPlanner",
    "TipTarget",
    "check_angle",
    "check_tip",
    "check_tip_value",
    "is_tip_move",
    "unreachable_reason",
]
