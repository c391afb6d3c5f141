"""Motions as data: TOML motion files, read with :mod:`tomllib` (data only, never code).

A motion file names poses in the arm's units and lists steps::

    description = "Wave hello"   # optional
    units = "deg"                # optional: body joints in "deg" (default) or "rad";
                                 # the gripper is always 0–100 (0 closed, 100 open)
    profile = "minimum_jerk"     # optional: the moves' default profile (default "linear")
    start = "rest"               # optional: the pose the arm starts in, at rest (default "rest")

    [poses]
    up = { shoulder_lift = 0, elbow_flex = 0 }   # a pose may name only some joints
    [poses.left]                                 # or be a table of its own
    shoulder_pan = 45

    [[steps]]
    move = "up"                  # a pose name, or an inline pose: move = { wrist_flex = 30 }
    duration = 2.0               # seconds, > 0
    profile = "limited"          # optional: "linear" | "minimum_jerk" | "limited"
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
clipped onto it; durations and profile names by :mod:`so101sim.validation`. Line numbers and
the bounded reading come from :mod:`so101sim.motion.lines`. Tip moves are checked and
planned (in full, from the target before them: an unreachable point is an error with its line)
by :mod:`so101sim.motion.tip`.

(Over 400 lines: the loader is one class whose parts share the file's line lookup; the reading,
the line scan and the tip moves are in the two modules named above.)
"""

from __future__ import annotations

import os
import reprlib
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..errors import (
    JointLimitError,
    JointNameError,
    JointValueError,
    MotionFileError,
    SettingError,
    UnreachableError,
)
from ..model.load import arm_units, default_units
from ..sim.profiles import MAX_MOVE_DURATION_S
from ..units import (
    DEG_PER_RAD,
    GRIPPER,
    GRIPPER_INDEX,
    JOINT_NAMES,
    STARTING_POSE,
    ZERO_POSE,
    ArmUnits,
    normalize_joint_name,
    parse_pose,
)
from ..validation import MAX_DURATION_S, check_choice, check_duration
from .lines import (
    MAX_FILE_BYTES,
    KeyLines,
    UnreadableFileError,
    load_toml,
    read_text_limited,
)
from .segments import PROFILES, Hold, Move, Segment
from .tip import (
    TipPlanner,
    TipTarget,
    check_tip_value,
    is_tip_move,
    unreachable_reason,
)

BUILTIN_POSES: dict[str, dict[str, float]] = {"rest": dict(STARTING_POSE), "zero": dict(ZERO_POSE)}
"""Poses every motion file may use without defining them."""

UNITS = ("deg", "rad")
TOP_KEYS = ("description", "units", "profile", "start", "poses", "steps", "variants")
# "variants": the ranges of `so101sim check --variants`, read by so101sim.preflight.robust
STEP_KEYS = {
    "move": ("move", "duration", "profile", "name"),
    "hold": ("hold", "name"),
    "gripper": ("gripper", "duration", "profile", "name"),
}


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
Where = tuple[Any, ...]
"""A key path in the file (``("steps", 2, "duration")``): an error's line is looked up by it."""

_CHECK_ERRORS = (JointNameError, JointValueError, SettingError)
"""What the units module and :mod:`so101sim.validation` raise (JointLimitError is a
JointValueError, DurationError a SettingError): the loader turns them into MotionFileError."""


_REPR = reprlib.Repr()  # Python 3.11's Repr takes no arguments: set its limits
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother, _REPR.maxlong = 2, 60, 60, 60
"""Values quoted in messages: a few levels and characters of them (a file may hold a string of
a megabyte)."""


def _show(value: Any) -> str:
    return _REPR.repr(value)


def _names(names: Mapping[str, Any], most: int = 20) -> str:
    """Some of ``names``, sorted and quoted, for a message."""
    shown = [n if len(n) <= 40 else n[:37] + "..." for n in sorted(names)[:most]]
    more = f" and {len(names) - most} more" if len(names) > most else ""
    return ", ".join(shown) + more


def _file_reason(exc: Exception) -> str:
    """The reason of a units or validation error, as said about a motion file."""
    if isinstance(exc, JointLimitError):
        # The API's advice ("pass clip=True") has no counterpart in a file: keep what was wrong.
        return f"{exc.what}; choose a value inside them"
    return str(exc)


class _Loader:
    """Reads the TOML data of one motion file part by part, giving every error its line.

    Joint names, numbers and limits are checked by the units module (``units``, the model's
    own), durations and profile names by :mod:`so101sim.validation`; their errors become
    :class:`MotionFileError` at the line of the key they came from.
    """

    def __init__(
        self, loc: KeyLines, path: str, units: ArmUnits, model: mujoco.MjModel | None = None
    ) -> None:
        self.path = path
        self.units = units
        self.planner = TipPlanner(model)  # tip moves, planned as the run will plan them
        self.tip_plans: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.loc = loc
        self.radians = False  # body joints given in radians (units = "rad")
        lo, hi = units.limits
        self.inside = (lo + hi) / 2  # a pose inside every limit: one joint is checked at a time
        self.known: dict[str, dict[str, float]] = dict(BUILTIN_POSES)  # poses steps may name
        self.default_profile = "linear"

    # ------------------------------------------------------------------------ errors
    def fail(self, where: Where, reason: str) -> MotionFileError:
        return MotionFileError(self.path, self.loc.line(where), reason)

    @contextmanager
    def reasons(self, where: Where, prefix: str = "") -> Iterator[None]:
        """Re-raise the units' and validation's errors as MotionFileError at ``where``'s line."""
        try:
            yield
        except _CHECK_ERRORS as exc:
            raise self.fail(where, prefix + _file_reason(exc)) from None

    def check_keys(
        self, table: Mapping[str, Any], allowed: tuple[str, ...], where: Where, what: str
    ) -> None:
        for key in table:
            if key not in allowed:
                raise self.fail(
                    (*where, key),
                    f"unknown key {_show(key)} in {what}; expected {', '.join(allowed)}",
                )

    # ------------------------------------------------------------------------ the file
    def load(self, data: dict[str, Any]) -> MotionFile:
        self.check_keys(data, TOP_KEYS, (), "the motion file")
        description = self.description(data.get("description", ""))
        self.radians = self.units_name(data.get("units", "deg")) == "rad"
        self.default_profile = self.profile(data.get("profile", "linear"), ("profile",))
        poses = self.poses(data.get("poses", {}))
        self.known.update(poses)
        start = self.start(data.get("start", "rest"))
        steps = self.steps(data, start)
        return MotionFile(
            path=self.path,
            start=start,
            steps=tuple(step for step, _ in steps),
            lines=tuple(line for _, line in steps),
            poses=poses,
            description=description,
            tip_plans=dict(self.tip_plans),
        )

    def description(self, value: Any) -> str:
        if not isinstance(value, str):
            raise self.fail(("description",), "description must be a string")
        return value

    def units_name(self, value: Any) -> str:
        if value not in UNITS:
            raise self.fail(
                ("units",),
                f"unknown units {_show(value)}; expected 'deg' (default) or 'rad' for the body "
                "joints (the gripper is always 0-100)",
            )
        return str(value)

    def profile(self, value: Any, where: Where) -> str:
        with self.reasons(where):
            return check_choice(value, "profile", sorted(PROFILES))

    def duration(self, value: Any, where: Where, what: str, maximum: float) -> float:
        with self.reasons(where):
            return check_duration(value, what, maximum=maximum)

    # ------------------------------------------------------------------------ poses
    def poses(self, table: Any) -> dict[str, dict[str, float]]:
        if not isinstance(table, Mapping):
            raise self.fail(("poses",), "poses must be a table of name = { joint = value }")
        poses: dict[str, dict[str, float]] = {}
        for name, value in table.items():
            if name in BUILTIN_POSES:
                raise self.fail(
                    ("poses", name),
                    f"pose {_show(name)} is built in and cannot be redefined; choose another name",
                )
            poses[name] = self.pose(value, ("poses", name))
        return poses

    def pose(self, value: Any, where: Where) -> dict[str, float]:
        """A pose table, maybe partial: ``{joint: value}`` in arm units, JOINT_NAMES order.

        The pose is checked by the units module one key more at a time, so that the first key
        that makes it invalid (unknown, given twice, not a number, past a limit) gets the line.
        """
        if not isinstance(value, Mapping):
            raise self.fail(
                where,
                f"a pose must be a table of joint = value, got {_show(value)}; e.g. "
                "{ shoulder_lift = 10, gripper = 50 }",
            )
        given: dict[str, Any] = {}
        out: dict[str, float] = {}
        for key, raw in value.items():
            given[key] = raw
            with self.reasons((*where, key)):
                name = normalize_joint_name(key)
                out[name] = self.in_limits(name, parse_pose(given, partial=True)[name])
        return {n: out[n] for n in JOINT_NAMES if n in out}

    def in_limits(self, name: str, value: float) -> float:
        """A joint's value from the file in arm units (radians converted), checked against the
        joint's limits by the units (a value within LIMIT_TOLERANCE is clipped onto the limit).
        """
        i = JOINT_NAMES.index(name)
        if self.radians and i != GRIPPER_INDEX:
            value *= DEG_PER_RAD  # a body joint given in radians, to the arm's degrees
        values = self.inside.copy()
        values[i] = value
        return float(self.units.check_limits(values)[i])

    def named(self, name: str, where: Where) -> dict[str, float]:
        if name not in self.known:
            raise self.fail(
                where,
                f"unknown pose {_show(name)}; defined poses are {_names(self.known)} "
                "(add it under [poses])",
            )
        return self.known[name]

    def start(self, value: Any) -> dict[str, float]:
        """The start pose, named or inline; it must give all six joints."""
        if isinstance(value, str):
            pose, prefix = self.named(value, ("start",)), f"start = {_show(value)}: "
        else:
            pose, prefix = self.pose(value, ("start",)), "start: "
        with self.reasons(("start",), prefix):
            parse_pose(pose)  # all six joints
        return dict(pose)

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
        name = self.step_name(raw, where)
        if kind == "hold":
            d = self.duration(raw["hold"], (*where, "hold"), f"step {i + 1} hold", MAX_DURATION_S)
            return Hold(d, phase=name or "hold"), current
        if "duration" not in raw:
            raise self.fail(where, f"step {i + 1} ({kind}) needs a duration in seconds")
        what = f"step {i + 1} duration"
        d = self.duration(raw["duration"], (*where, "duration"), what, MAX_MOVE_DURATION_S)
        profile = self.profile(raw.get("profile", self.default_profile), (*where, "profile"))
        if kind == "move" and is_tip_move(raw["move"]):
            move, end = self.tip_move(raw["move"], where, d, profile, name or "to_tip", current)
            if self.planner.last is not None:
                self.tip_plans[i] = self.planner.last
            return move, end
        target, label = self.target(kind, raw[kind], current, (*where, kind))
        pose = self.units.array_to_pose(target)
        return Move(pose, d, profile=profile, phase=name or label), target

    def step_kind(self, i: int, raw: Any, where: Where) -> str:
        """``"move"``, ``"hold"`` or ``"gripper"``, once the step's keys are checked."""
        if not isinstance(raw, Mapping):
            raise self.fail(where, f"step {i + 1} must be a table, got {_show(raw)}")
        kinds = [k for k in STEP_KEYS if k in raw]
        if len(kinds) != 1:
            raise self.fail(
                where,
                f"step {i + 1} must have exactly one of move, hold, gripper; "
                f"it has {', '.join(kinds) or 'none'}",
            )
        self.check_keys(raw, STEP_KEYS[kinds[0]], where, f"a {kinds[0]} step")
        return kinds[0]

    def step_name(self, raw: Mapping[str, Any], where: Where) -> str | None:
        name = raw.get("name")
        if name is not None and not isinstance(name, str):
            raise self.fail((*where, "name"), f"name must be a string, got {_show(name)}")
        return name

    def tip_move(
        self,
        value: Mapping[str, Any],
        where: Where,
        duration: float,
        profile: str,
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
        move = TipTarget(**checked).move(duration, profile, phase)
        try:
            return move, self.planner.end(move, current)
        except UnreachableError as exc:
            raise self.fail((*where, "tip"), unreachable_reason(exc)) from None
        except SettingError as exc:  # a profile a straight line cannot follow
            raise self.fail((*where[:-1], "profile"), str(exc)) from None

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
