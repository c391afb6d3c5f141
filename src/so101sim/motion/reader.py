"""Reading a motion file's data (:mod:`so101sim.motion.file` holds the loader): errors at
the line of the key they came from, unknown keys, the file's settings (description, units,
shape, durations) and its poses (named, inline, the start pose), each checked by the units
module or :mod:`so101sim.validation` as the API checks them.
"""

from __future__ import annotations

import logging
import reprlib
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any

from ..errors import (
    JointLimitError,
    JointNameError,
    JointValueError,
    MotionFileError,
    SettingError,
)
from ..sim.profiles import PROFILES
from ..units import (
    DEG_PER_RAD,
    GRIPPER_INDEX,
    JOINT_NAMES,
    STARTING_POSE,
    ZERO_POSE,
    ArmUnits,
    normalize_joint_name,
    parse_pose,
)
from ..validation import check_choice, check_duration, check_name
from .lines import KeyLines

log = logging.getLogger(__name__)

BUILTIN_POSES: dict[str, dict[str, float]] = {"rest": dict(STARTING_POSE), "zero": dict(ZERO_POSE)}
"""Poses every motion file may use without defining them."""

UNITS = ("deg", "rad")


Where = tuple[Any, ...]
"""A key path in the file (``("steps", 2, "duration")``): an error's line is looked up by it."""

_CHECK_ERRORS = (JointNameError, JointValueError, SettingError)
"""What the units module and :mod:`so101sim.validation` raise (JointLimitError is a
JointValueError, DurationError a SettingError): the loader turns them into MotionFileError."""


_REPR = reprlib.Repr()  # Python 3.11's Repr takes no arguments: set its limits
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother, _REPR.maxlong = 2, 60, 60, 60
"""Values quoted in messages: a few levels and characters of them (a file may hold a string of
a megabyte)."""


def show(value: Any) -> str:
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


class FileReader:
    """Reads the parts of one motion file's TOML data that are not its steps, giving every
    error its line (:class:`so101sim.motion.file._Loader` reads the steps on top of it).

    Joint names, numbers and limits are checked by the units module (``units``, the model's
    own), durations and shape names by :mod:`so101sim.validation`; their errors become
    :class:`MotionFileError` at the line of the key they came from.
    """

    def __init__(self, loc: KeyLines, path: str, units: ArmUnits) -> None:
        self.path = path
        self.units = units
        self.loc = loc
        self.radians = False  # body joints given in radians (units = "rad")
        lo, hi = units.limits
        self.inside = (lo + hi) / 2  # a pose inside every limit: one joint is checked at a time
        self.known: dict[str, dict[str, float]] = dict(BUILTIN_POSES)  # poses steps may name
        self.default_shape = "linear"
        self.old_key_lines: list[int] = []  # where the file spells "shape" "profile"
        self.shape_key = "shape"  # the key the step being read names its shape by

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
                    f"unknown key {show(key)} in {what}; expected {', '.join(allowed)}",
                )

    # ------------------------------------------------------------------------ settings
    def description(self, value: Any) -> str:
        if not isinstance(value, str):
            raise self.fail(("description",), "description must be a string")
        return value

    def units_name(self, value: Any) -> str:
        if value not in UNITS:
            raise self.fail(
                ("units",),
                f"unknown units {show(value)}; expected 'deg' (default) or 'rad' for the body "
                "joints (the gripper is always 0-100)",
            )
        return str(value)

    def shape(self, table: Mapping[str, Any], where: Where, default: str) -> str:
        """A move's shape, from ``table``'s ``shape`` key (or ``profile``, its old name: one
        logged warning per file, :meth:`warn_old_key`), or ``default``."""
        if "shape" in table and "profile" in table:
            raise self.fail(
                (*where, "profile"),
                "both shape and profile given; expected shape only (profile is its old name)",
            )
        key = "profile" if "profile" in table else "shape"
        if key not in table:
            return default
        if key == "profile":
            self.old_key_lines.append(self.loc.line((*where, key)))
        with self.reasons((*where, key)):
            return check_choice(table[key], key, sorted(PROFILES))

    def warn_old_key(self) -> None:
        """One logged warning for a file that names a move's shape ``profile``."""
        if self.old_key_lines:
            lines = ", ".join(str(n) for n in self.old_key_lines[:5])
            more = " ..." if len(self.old_key_lines) > 5 else ""
            log.warning(
                "%s: the key 'profile' (line %s%s) is the old name of 'shape' and goes in the "
                "next release; rename it to 'shape' ('profile' names the arm profile, the "
                "servos' model)",
                self.path,
                lines,
                more,
            )

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
                    f"pose {show(name)} is built in and cannot be redefined; choose another name",
                )
            with self.reasons(("poses", name)):  # a pose's name is a step's default name
                check_name(name, "pose name")
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
                f"a pose must be a table of joint = value, got {show(value)}; e.g. "
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
                f"unknown pose {show(name)}; defined poses are {_names(self.known)} "
                "(add it under [poses])",
            )
        return self.known[name]

    def start(self, value: Any) -> dict[str, float]:
        """The start pose, named or inline; it must give all six joints."""
        if isinstance(value, str):
            pose, prefix = self.named(value, ("start",)), f"start = {show(value)}: "
        else:
            pose, prefix = self.pose(value, ("start",)), "start: "
        with self.reasons(("start",), prefix):
            parse_pose(pose)  # all six joints
        return dict(pose)


__all__ = ["BUILTIN_POSES", "UNITS", "FileReader", "Where", "show"]
