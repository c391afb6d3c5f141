"""Motions as data: TOML motion files, read with :mod:`tomllib` (data only, never code).

A motion file names poses in the arm's units and lists steps::

    description = "Wave hello"   # optional
    units = "deg"                # optional: body joints in "deg" (default) or "rad";
                                 # the gripper is always 0–100 (0 closed, 100 open)
    shape = "minimum_jerk"       # optional: the moves' default shape (default "linear")
    start = "rest"               # optional: the pose the arm starts in, at rest (default "rest")

    [poses]
    up = { shoulder_lift = 0, elbow_flex = 0 }   # a pose may name only some joints
    [poses.left]                                 # or be a table of its own
    shoulder_pan = 45

    [[steps]]
    move = "up"                  # a pose name, or an inline pose: move = { wrist_flex = 30 }
    duration = 2.0               # seconds, > 0
    shape = "limited"            # optional: "linear" | "minimum_jerk" | "limited"
    name = "raise"               # optional: the phase's name in reports

    [[steps]]
    hold = 1.5                   # hold the last target for 1.5 s

    [[steps]]
    gripper = 60                 # open the gripper to 60 over 0.5 s
    duration = 0.5

    [[steps]]                    # move the gripper's tip to (x, y, z) metres, base frame
    move = { tip = [0.20, 0.0, 0.05], pitch = -90, roll = 0, path = "line" }
    duration = 2.0               # pitch, roll (degrees) and path ("line" | "joint") optional

Two poses are built in: ``rest`` (the folded rest pose, :data:`~so101sim.units.STARTING_POSE`)
and ``zero`` (every joint at 0); a file may not redefine them. A pose may name only some
joints: a move to it changes those joints and keeps the others at their last target. The
``start`` pose must name all six. Joint names may be LeRobot's keys (``"shoulder_pan.pos"``).

The loader checks everything before anything moves and resolves every move against the
previous target, so it returns full-pose :class:`~so101sim.motion.Move` and
:class:`~so101sim.motion.Hold` steps. It rejects, as :class:`MotionFileError` with the file,
line and reason: TOML syntax errors, unknown keys, unknown pose names, unknown joint names, bad
units, values that are not finite numbers or lie outside the joint limits, and durations that
are not numbers > 0 or are too long (a move at most an hour,
:data:`~so101sim.sim.profiles.MAX_MOVE_DURATION_S`; a hold at most a day,
:data:`~so101sim.validation.MAX_DURATION_S`). It reads at most 1 MiB, from a regular file
only (not a device such as ``/dev/zero`` or a pipe), and refuses data nested more than 32
levels deep before :mod:`tomllib` sees it. Joint values are checked by the units module as the
API checks them: a value within :data:`~so101sim.units.LIMIT_TOLERANCE` past a limit is
clipped onto it; durations and shape names by :mod:`so101sim.validation`. Line numbers and
the bounded reading come from :mod:`so101sim.motion.lines`. Tip moves are checked and
planned (in full, from the target before them: an unreachable point is an error with its line)
by :mod:`so101sim.motion.tip`. ``profile``, the old name of ``shape``, is still read (one
logged warning per file) for one release.

The loader (:class:`_Loader`) reads the steps; the file's settings and poses, and the errors
at a key's line, are read by :class:`so101sim.motion.reader.FileReader`, which it builds on.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..errors import (
    MotionFileError,
    SettingError,
    UnreachableError,
)
from ..model.load import arm_units, default_units
from ..sim.profiles import MAX_MOVE_DURATION_S
from ..units import (
    GRIPPER,
    JOINT_NAMES,
    ArmUnits,
)
from ..validation import MAX_DURATION_S, check_name
from .lines import (
    MAX_FILE_BYTES,
    KeyLines,
    UnreadableFileError,
    load_toml,
    read_text_limited,
)
from .reader import BUILTIN_POSES, FileReader, Where, show
from .segments import Hold, Move, Segment
from .tip import (
    TipPlanner,
    TipTarget,
    check_tip_value,
    is_tip_move,
    unreachable_reason,
)

TOP_KEYS = ("description", "units", "shape", "profile", "start", "poses", "steps", "variants")
# "variants": the ranges of `so101sim check --variants`, read by so101sim.preflight.robust
STEP_KEYS = {
    "move": ("move", "duration", "shape", "profile", "name"),
    "hold": ("hold", "name"),
    "gripper": ("gripper", "duration", "shape", "profile", "name"),
}
# "profile": the old name of "shape", read for one release (FileReader.shape)


def lab_motion_path() -> Path:
    """The shipped lab motion file: rest -> zeros in 2 s, hold 2 s, back in 2 s."""
    return Path(str(resources.files("so101sim") / "data" / "motions" / "lab.toml"))


@dataclass(frozen=True)
class MotionFile:
    """A loaded motion file. Poses are in the arm's units (degrees, gripper 0–100)."""

    path: str
    start: dict[str, float]  # the pose the arm starts in, all six joints
    steps: tuple[Segment, ...]  # full-pose moves and holds, ready for run_motion
    lines: tuple[int, ...]  # the line each step starts on
    poses: dict[str, dict[str, float]] = field(default_factory=dict)  # the file's own poses
    description: str = ""
    # the tip moves as the loader planned them (step index -> (start, targets), arm units),
    # on ``model``: a run on that model uses them (motion.plan.plan_segments(known=...))
    tip_plans: dict[int, tuple[np.ndarray, np.ndarray]] = field(
        default_factory=dict, repr=False, compare=False
    )


# ---------------------------------------------------------------------------- the loader
class _Loader(FileReader):
    """Reads one motion file's TOML data, its steps on top of what :class:`FileReader` reads,
    every rule a motion file obeys with its file:line error, in the order a file is read."""

    def __init__(
        self, loc: KeyLines, path: str, units: ArmUnits, model: mujoco.MjModel | None = None
    ) -> None:
        super().__init__(loc, path, units)
        self.planner = TipPlanner(model)  # tip moves, planned as the run will plan them
        self.tip_plans: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    # ------------------------------------------------------------------------ the file
    def load(self, data: dict[str, Any]) -> MotionFile:
        self.check_keys(data, TOP_KEYS, (), "the motion file")
        description = self.description(data.get("description", ""))
        self.radians = self.units_name(data.get("units", "deg")) == "rad"
        self.default_shape = self.shape(data, (), "linear")
        poses = self.poses(data.get("poses", {}))
        self.known.update(poses)
        start = self.start(data.get("start", "rest"))
        steps = self.steps(data, start)
        self.warn_old_key()
        return MotionFile(
            path=self.path,
            start=start,
            steps=tuple(step for step, _ in steps),
            lines=tuple(line for _, line in steps),
            poses=poses,
            description=description,
            tip_plans=dict(self.tip_plans),
        )

    # ------------------------------------------------------------------------ steps
    def steps(self, data: Mapping[str, Any], start: dict[str, float]) -> list[tuple[Segment, int]]:
        """Every step as a full-pose Move or a Hold, with the line it starts on."""
        table = data.get("steps")
        if not isinstance(table, list) or not table:
            raise self.fail(
                ("steps",) if "steps" in data else (),
                "a motion file needs at least one step: [[steps]] with move, hold or gripper",
            )
        current = np.array([start[n] for n in JOINT_NAMES])
        steps: list[tuple[Segment, int]] = []
        for i, raw in enumerate(table):
            step, current = self.step(i, raw, current)
            steps.append((step, self.loc.line(("steps", i))))
        return steps

    def step(self, i: int, raw: Any, current: np.ndarray) -> tuple[Segment, np.ndarray]:
        """Step ``i`` (0-based) from the target ``current``, and the target after it."""
        where = ("steps", i)
        kind = self.step_kind(i, raw, where)
        name = self.step_name(i, raw, where)
        if kind == "hold":
            d = self.duration(raw["hold"], (*where, "hold"), f"step {i + 1} hold", MAX_DURATION_S)
            return Hold(d, phase=name or "hold"), current
        if "duration" not in raw:
            raise self.fail(where, f"step {i + 1} ({kind}) needs a duration in seconds")
        what = f"step {i + 1} duration"
        d = self.duration(raw["duration"], (*where, "duration"), what, MAX_MOVE_DURATION_S)
        shape = self.shape(raw, where, self.default_shape)
        self.shape_key = "profile" if "profile" in raw else "shape"  # for a tip move's error
        if kind == "move" and is_tip_move(raw["move"]):
            move, end = self.tip_move(raw["move"], where, d, shape, name or "to_tip", current)
            if self.planner.last is not None:
                self.tip_plans[i] = self.planner.last
            return move, end
        target, label = self.target(kind, raw[kind], current, (*where, kind))
        pose = self.units.array_to_pose(target)
        return Move(pose, d, shape=shape, phase=name or label), target

    def step_kind(self, i: int, raw: Any, where: Where) -> str:
        """``"move"``, ``"hold"`` or ``"gripper"``, once the step's keys are checked."""
        if not isinstance(raw, Mapping):
            raise self.fail(where, f"step {i + 1} must be a table, got {show(raw)}")
        kinds = [k for k in STEP_KEYS if k in raw]
        if len(kinds) != 1:
            raise self.fail(
                where,
                f"step {i + 1} must have exactly one of move, hold, gripper; "
                f"it has {', '.join(kinds) or 'none'}",
            )
        self.check_keys(raw, STEP_KEYS[kinds[0]], where, f"a {kinds[0]} step")
        return kinds[0]

    def step_name(self, i: int, raw: Mapping[str, Any], where: Where) -> str | None:
        """The step's ``name``: a string on one line (no control character: it is printed in
        every report, :func:`so101sim.validation.check_name`), or None."""
        name = raw.get("name")
        if name is not None and not isinstance(name, str):
            raise self.fail((*where, "name"), f"name must be a string, got {show(name)}")
        if name is not None:
            with self.reasons((*where, "name")):
                check_name(name, f"step {i + 1} name")
        return name

    def tip_move(
        self,
        value: Mapping[str, Any],
        where: Where,
        duration: float,
        shape: str,
        phase: str,
        current: np.ndarray,
    ) -> tuple[Move, np.ndarray]:
        """A tip move (:mod:`so101sim.motion.tip`) and the target it ends on, planned in
        full from ``current`` so that a point out of reach is reported here, with its line."""
        where = (*where, "move")
        checked = {}
        for key, raw in value.items():
            with self.reasons((*where, key)):
                checked[key] = check_tip_value(key, raw)
        move = TipTarget(**checked).move(duration, shape, phase)
        try:
            return move, self.planner.end(move, current)
        except UnreachableError as exc:
            raise self.fail((*where, "tip"), unreachable_reason(exc)) from None
        except SettingError as exc:  # a shape a straight line cannot follow
            raise self.fail((*where[:-1], self.shape_key), str(exc)) from None

    def target(
        self, kind: str, value: Any, current: np.ndarray, where: Where
    ) -> tuple[np.ndarray, str]:
        """A move's or gripper step's full target (joints it does not name keep ``current``),
        and the step's default name."""
        if kind == "gripper":
            pose, label = self.pose({GRIPPER: value}, where), "gripper"
        elif isinstance(value, str):
            pose, label = self.named(value, where), f"to_{value}"
        else:
            pose, label = self.pose(value, where), "move"
        return self.units.pose_to_array(pose, base=current, check_limits=False), label


def parse_motion(
    text: str,
    *,
    path: str = "<string>",
    units: ArmUnits | None = None,
    model: mujoco.MjModel | None = None,
) -> MotionFile:
    """Read a motion from TOML text; ``path`` is only used in error messages.

    ``units`` gives the joint limits to check against (default: ``model``'s, else the shipped
    model's); ``model`` plans the tip moves (default: the shipped model, loaded on the first).

    Raises:
        MotionFileError: the text is not valid TOML, is too large (over 1 MiB) or nests too
            deep, or says something invalid (with the line).
    """
    data, loc = load_toml(text, path)
    if units is None:
        units = arm_units(model) if model is not None else default_units()
    return _Loader(loc, path, units, model).load(data)


def load_motion(
    path: str | Path,
    *,
    units: ArmUnits | None = None,
    model: mujoco.MjModel | None = None,
) -> MotionFile:
    """Read a motion file (TOML, UTF-8, at most 1 MiB). Nothing in it is evaluated.

    ``units`` and ``model`` as in :func:`parse_motion` (``model`` plans the tip moves).

    Raises:
        MotionFileError: the file does not exist, cannot be read, is not a regular file (a
            folder, a device such as ``/dev/zero``, a pipe), is larger than 1 MiB, is not
            UTF-8, is not valid TOML, or says something invalid.
    """
    if not isinstance(path, str | os.PathLike) or not str(path).strip():
        raise MotionFileError(
            repr(path), 0, "the motion file path is empty; expected a TOML motion file (text)"
        )
    p = Path(path)
    try:
        text = read_text_limited(p, MAX_FILE_BYTES)
        if "\0" in text:  # valid UTF-8 but binary data (NUL bytes are never in TOML)
            raise UnreadableFileError("it holds NUL bytes (binary data)")
    except UnreadableFileError as exc:
        reason = "no such file" if exc.missing else f"not a motion file: {exc}"
        raise MotionFileError(str(p), 0, f"{reason}; expected a TOML motion file (text)") from None
    return parse_motion(text, path=str(p), units=units, model=model)


__all__ = [
    "BUILTIN_POSES",
    "MotionFile",
    "MotionFileError",
    "lab_motion_path",
    "load_motion",
    "parse_motion",
]
