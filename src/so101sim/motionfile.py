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

Two poses are built in: ``rest`` (the folded rest pose, :data:`~so101sim.units.STARTING_POSE`)
and ``zero`` (every joint at 0); a file may not redefine them. A pose may name only some
joints: a move to it changes those joints and keeps the others at their last target. The
``start`` pose must name all six. Joint names may be LeRobot's keys (``"shoulder_pan.pos"``).

The loader checks everything before anything moves and resolves every move against the
previous target, so it returns full-pose :class:`~so101sim.motion.Move` and
:class:`~so101sim.motion.Hold` steps. It rejects, as :class:`MotionFileError` with the file,
line and reason: TOML syntax errors, unknown keys, unknown pose names, unknown joint names, bad
units, values that are not finite numbers or lie outside the joint limits, and durations that
are not numbers > 0.

Line numbers: :mod:`tomllib` reports none for values, so the loader scans the text itself for
table headers (``[poses]``, ``[poses.x]``, the n-th ``[[steps]]``), ``key =`` lines (dotted keys
too) and the keys inside single-line inline tables, and maps each key path to its line. Where a
path is not found that way (e.g. a multi-line ``steps = [...]`` array), the error points at the
line of the nearest enclosing key or table that was found.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .errors import DurationError, JointNameError, JointValueError, MotionFileError
from .model import default_units
from .motion import PROFILES, Hold, Move, Segment
from .units import (
    DEG_PER_RAD,
    GRIPPER,
    GRIPPER_INDEX,
    JOINT_NAMES,
    STARTING_POSE,
    ZERO_POSE,
    ArmUnits,
    check_number,
    normalize_joint_name,
)
from .validation import check_duration

BUILTIN_POSES: dict[str, dict[str, float]] = {"rest": dict(STARTING_POSE), "zero": dict(ZERO_POSE)}
"""Poses every motion file may use without defining them."""

UNITS = ("deg", "rad")
TOP_KEYS = ("description", "units", "profile", "start", "poses", "steps")
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


# ---------------------------------------------------------------------------- line numbers
_BARE = r"[A-Za-z0-9_-]+"
_QUOTED = r"\"(?:[^\"\\]|\\.)*\"|'[^']*'"
_KEYPART = rf"(?:{_BARE}|{_QUOTED})"
_DOTTED = rf"{_KEYPART}(?:\s*\.\s*{_KEYPART})*"
_HEADER_RE = re.compile(rf"^\s*(\[\[|\[)\s*({_DOTTED})\s*\]\]?")
_KEY_RE = re.compile(rf"^\s*({_DOTTED})\s*=\s*(.*)$")
_INLINE_KEY_RE = re.compile(rf"({_KEYPART})\s*=")
_PART_RE = re.compile(_KEYPART)


def _split_key(dotted: str) -> tuple[str, ...]:
    parts = []
    for p in _PART_RE.findall(dotted):
        parts.append(p[1:-1] if p[:1] in "\"'" else p)
    return tuple(parts)


class _Locator:
    """Maps key paths (``("steps", 2, "duration")``) to 1-based line numbers."""

    def __init__(self, text: str) -> None:
        self.lines: dict[tuple[Any, ...], int] = {}
        table: tuple[Any, ...] = ()
        counts: dict[tuple[str, ...], int] = {}
        for number, raw in enumerate(text.splitlines(), start=1):
            m = _HEADER_RE.match(raw)
            if m:
                path = _split_key(m.group(2))
                if m.group(1) == "[[":
                    k = counts.get(path, 0)
                    counts[path] = k + 1
                    table = (*path, k)
                else:
                    table = path
                self.lines.setdefault(table, number)
                continue
            m = _KEY_RE.match(raw)
            if not m:
                continue
            path = (*table, *_split_key(m.group(1)))
            self.lines.setdefault(path, number)
            value = m.group(2)
            if value.lstrip().startswith("{"):
                for inner in _INLINE_KEY_RE.findall(value):
                    self.lines.setdefault((*path, *_split_key(inner)), number)

    def line(self, path: tuple[Any, ...]) -> int:
        for n in range(len(path), 0, -1):
            if path[:n] in self.lines:
                return self.lines[path[:n]]
        return 1


# ---------------------------------------------------------------------------- the loader
class _Loader:
    def __init__(self, text: str, path: str, units: ArmUnits) -> None:
        self.path = path
        self.units = units
        self.loc = _Locator(text)
        self.radians = False  # body joints given in radians (units = "rad")
        lo, hi = units.limits
        self.lo, self.hi = lo, hi

    def fail(self, where: tuple[Any, ...], reason: str) -> MotionFileError:
        return MotionFileError(self.path, self.loc.line(where), reason)

    def check_keys(
        self, table: Mapping[str, Any], allowed: tuple[str, ...], where: tuple[Any, ...], what: str
    ) -> None:
        for key in table:
            if key not in allowed:
                raise self.fail(
                    (*where, key),
                    f"unknown key {key!r} in {what}; expected {', '.join(allowed)}",
                )

    def duration(self, value: Any, where: tuple[Any, ...], what: str) -> float:
        try:
            return check_duration(value, what)
        except DurationError as exc:
            raise self.fail(where, str(exc)) from None

    def profile(self, value: Any, where: tuple[Any, ...]) -> str:
        if not isinstance(value, str) or value not in PROFILES:
            raise self.fail(
                where,
                f"unknown profile {value!r}; expected one of {', '.join(sorted(PROFILES))}",
            )
        return value

    def joint_value(self, name: str, value: Any, where: tuple[Any, ...]) -> float:
        try:
            v = check_number(name, value)
        except JointValueError as exc:
            raise self.fail(where, str(exc)) from None
        i = JOINT_NAMES.index(name)
        if self.radians and i != GRIPPER_INDEX:
            v *= DEG_PER_RAD  # a body joint given in radians, to the arm's degrees
        if not (self.lo[i] - 1e-9 <= v <= self.hi[i] + 1e-9):
            unit = "" if name == GRIPPER else "°"
            raise self.fail(
                where,
                f"{name} = {v:g}{unit} is outside the joint's limits "
                f"{self.lo[i]:.2f}{unit}..{self.hi[i]:.2f}{unit}; choose a value inside them",
            )
        return float(min(max(v, self.lo[i]), self.hi[i]))

    def pose(self, value: Any, where: tuple[Any, ...], *, full: bool = False) -> dict[str, float]:
        if not isinstance(value, Mapping):
            raise self.fail(
                where,
                f"a pose must be a table of joint = value, got {value!r}; e.g. "
                "{ shoulder_lift = 10, gripper = 50 }",
            )
        out: dict[str, float] = {}
        for key, v in value.items():
            try:
                name = normalize_joint_name(key)
            except JointNameError as exc:
                raise self.fail((*where, key), str(exc)) from None
            if name in out:
                raise self.fail((*where, key), f"joint {name!r} is given twice")
            out[name] = self.joint_value(name, v, (*where, key))
        missing = [n for n in JOINT_NAMES if n not in out]
        if full and missing:
            raise self.fail(
                where,
                f"the start pose is missing {', '.join(missing)}; it needs all six joints: "
                f"{', '.join(JOINT_NAMES)}",
            )
        return {n: out[n] for n in JOINT_NAMES if n in out}

    def load(self, data: dict[str, Any]) -> MotionFile:
        self.check_keys(data, TOP_KEYS, (), "the motion file")
        description = data.get("description", "")
        if not isinstance(description, str):
            raise self.fail(("description",), "description must be a string")
        units = data.get("units", "deg")
        if units not in UNITS:
            raise self.fail(
                ("units",),
                f"unknown units {units!r}; expected 'deg' (default) or 'rad' for the body "
                "joints (the gripper is always 0-100)",
            )
        self.radians = units == "rad"
        default_profile = self.profile(data.get("profile", "linear"), ("profile",))

        poses: dict[str, dict[str, float]] = {}
        raw_poses = data.get("poses", {})
        if not isinstance(raw_poses, Mapping):
            raise self.fail(("poses",), "poses must be a table of name = { joint = value }")
        for name, value in raw_poses.items():
            if name in BUILTIN_POSES:
                raise self.fail(
                    ("poses", name),
                    f"pose {name!r} is built in and cannot be redefined; choose another name",
                )
            poses[name] = self.pose(value, ("poses", name))
        known = {**BUILTIN_POSES, **poses}

        start_value = data.get("start", "rest")
        if isinstance(start_value, str):
            if start_value not in known:
                raise self.unknown_pose(start_value, ("start",), known)
            start = dict(known[start_value])
            if len(start) != len(JOINT_NAMES):
                raise self.fail(
                    ("start",),
                    f"the start pose {start_value!r} names only {', '.join(start)}; it needs "
                    f"all six joints: {', '.join(JOINT_NAMES)}",
                )
        else:
            start = self.pose(start_value, ("start",), full=True)

        raw_steps = data.get("steps")
        if not isinstance(raw_steps, list) or not raw_steps:
            raise self.fail(
                ("steps",) if "steps" in data else (),
                "a motion file needs at least one step: [[steps]] with move, hold or gripper",
            )
        current = np.array([start[n] for n in JOINT_NAMES])
        steps: list[Segment] = []
        lines: list[int] = []
        for i, raw in enumerate(raw_steps):
            where = ("steps", i)
            if not isinstance(raw, Mapping):
                raise self.fail(where, f"step {i + 1} must be a table, got {raw!r}")
            kinds = [k for k in STEP_KEYS if k in raw]
            if len(kinds) != 1:
                raise self.fail(
                    where,
                    f"step {i + 1} must have exactly one of move, hold, gripper; "
                    f"it has {', '.join(kinds) or 'none'}",
                )
            kind = kinds[0]
            self.check_keys(raw, STEP_KEYS[kind], where, f"a {kind} step")
            name = raw.get("name")
            if name is not None and not isinstance(name, str):
                raise self.fail((*where, "name"), f"name must be a string, got {name!r}")
            lines.append(self.loc.line(where))
            if kind == "hold":
                d = self.duration(raw["hold"], (*where, "hold"), f"step {i + 1} hold")
                steps.append(Hold(d, phase=name or "hold"))
                continue
            if "duration" not in raw:
                raise self.fail(where, f"step {i + 1} ({kind}) needs a duration in seconds")
            d = self.duration(raw["duration"], (*where, "duration"), f"step {i + 1} duration")
            profile = self.profile(raw.get("profile", default_profile), (*where, "profile"))
            target = current.copy()
            if kind == "gripper":
                target[GRIPPER_INDEX] = self.joint_value(GRIPPER, raw["gripper"], (*where, kind))
                default_name = "gripper"
            else:
                value = raw["move"]
                if isinstance(value, str):
                    if value not in known:
                        raise self.unknown_pose(value, (*where, "move"), known)
                    pose = known[value]
                    default_name = f"to_{value}"
                else:
                    pose = self.pose(value, (*where, "move"))
                    default_name = "move"
                for joint, v in pose.items():
                    target[JOINT_NAMES.index(joint)] = v
            current = target
            steps.append(
                Move(
                    self.units.array_to_pose(target),
                    d,
                    profile=profile,
                    phase=name or default_name,
                )
            )
        return MotionFile(
            path=self.path,
            start=start,
            steps=tuple(steps),
            lines=tuple(lines),
            poses=poses,
            description=description,
        )

    def unknown_pose(
        self, name: Any, where: tuple[Any, ...], known: Iterable[str]
    ) -> MotionFileError:
        return self.fail(
            where,
            f"unknown pose {name!r}; defined poses are {', '.join(sorted(known))} "
            "(add it under [poses])",
        )


_TOML_LINE_RE = re.compile(r"\(at line (\d+), column \d+\)")  # tomllib's position


def parse_motion(text: str, *, path: str = "<string>", units: ArmUnits | None = None) -> MotionFile:
    """Read a motion from TOML text; ``path`` is only used in error messages.

    ``units`` gives the joint limits to check against (default: the shipped model's).

    Raises:
        MotionFileError: the text is not valid TOML, or says something invalid (with the line).
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        m = _TOML_LINE_RE.search(msg)
        # "(at line L, column C)", or "(at end of document)": then the last line
        line = int(m.group(1)) if m else max(1, len(text.splitlines()))
        reason = _TOML_LINE_RE.sub("", msg).replace("(at end of document)", "").strip()
        if not m:
            reason += " at the end of the file"
        raise MotionFileError(path, line, f"not valid TOML: {reason}") from None
    return _Loader(text, path, units if units is not None else default_units()).load(data)


def load_motion(path: str | Path, *, units: ArmUnits | None = None) -> MotionFile:
    """Read a motion file (TOML). Nothing in it is evaluated.

    Raises:
        MotionFileError: the file cannot be read, is not valid TOML, or says something invalid.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")  # editors on Windows may write a BOM
    except FileNotFoundError:
        raise MotionFileError(
            str(p), 0, "no such file; expected a TOML motion file (see `so101sim run --help`)"
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise MotionFileError(str(p), 0, f"cannot read the file: {exc}") from None
    return parse_motion(text, path=str(p), units=units)


__all__ = [
    "BUILTIN_POSES",
    "MotionFile",
    "MotionFileError",
    "lab_motion_path",
    "load_motion",
    "parse_motion",
]
