"""The arm's own units, joint names and named poses.

The real SO-101 (driven through LeRobot, calibrated in degrees) reports:

* the five body joints in **degrees**, 0 being the middle of the joint's range (the model's
  "new calibration" puts the joint zero there too, so degrees are exactly ``rad * 180 / π``);
* the **gripper on 0–100**: 0 fully closed, 100 fully open.

MuJoCo works in radians. The gripper's 0–100 maps *linearly* onto the gripper joint's range:
0 is the lower limit (closed, −10°), 100 the upper limit (open, 100°). The lab handout's
``qpos * 100 / π`` is wrong: it would put "100" at π rad, far outside that joint's −10°..100°
range, and "0" at 0 rad rather than at the closed stop.

At the edges, poses are plain dicts keyed by joint name (``"shoulder_pan"``) or by LeRobot's
keys (``"shoulder_pan.pos"``); inside, they are NumPy arrays in :data:`JOINT_NAMES` order.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .errors import JointLimitError, JointNameError, JointValueError
from .validation import check_range

JOINT_NAMES: tuple[str, ...] = (
    "shoulder_pan",
    "shoulder_lift",
    "elbow_flex",
    "wrist_flex",
    "wrist_roll",
    "gripper",
)
"""The six joints, in the real arm's (and the model's) order."""

DEG_PER_RAD = 180.0 / math.pi
"""Degrees per radian (exact π): a body joint's arm unit is the degree."""

GRIPPER = "gripper"
GRIPPER_INDEX = JOINT_NAMES.index(GRIPPER)
BODY_JOINTS: tuple[str, ...] = JOINT_NAMES[:GRIPPER_INDEX]
LEROBOT_SUFFIX = ".pos"

Pose = Mapping[str, float]
"""A pose at the edges: joint name (or ``name.pos``) -> value in the arm's units."""

STARTING_POSE: dict[str, float] = {
    "shoulder_pan": 0.0,
    "shoulder_lift": -98.0,
    "elbow_flex": 88.0,
    "wrist_flex": 60.0,
    "wrist_roll": 0.0,
    "gripper": 0.0,
}
"""The folded rest pose the real arm sits in when switched off.

Upper arm laid back against its stop (2° short of the −100° limit), forearm folded over it,
wrist tipped down, gripper closed. Every joint is inside its limits and no two parts of the
arm, nor the arm and the floor, come within 3 mm of each other in the shipped model.
"""

LIMIT_TOLERANCE = 0.5
"""Arm units (degrees, or gripper units) a target may lie beyond a limit and still be accepted,
clipped onto the limit. A joint resting on its stop reads a hair past it (the gripper closed
reads about -0.00002), and sending a measured pose back as a command must not fail."""

ZERO_POSE: dict[str, float] = dict.fromkeys(JOINT_NAMES, 0.0)
"""Every joint at 0: body joints mid-range (upper arm up, forearm forward), gripper closed."""


def unit_symbol(name: str) -> str:
    """The symbol written after a joint's value: ``"°"`` for body joints, ``""`` for the
    gripper's 0–100."""
    return "" if name == GRIPPER else "°"


def format_value(name: str, value: float, digits: int | None = None) -> str:
    """One joint value with its unit: ``"12.5°"`` for a body joint, ``"60"`` for the gripper.

    ``digits=None`` writes the shortest form (``:g``); a number of digits writes that many
    decimals, with no ``-0.00``.
    """
    v = float(value)
    if digits is None:
        return f"{v:g}{unit_symbol(name)}"
    return f"{round(v, digits) + 0.0:.{digits}f}{unit_symbol(name)}"


@dataclass(frozen=True)
class ArmUnits:
    """Conversions between the arm's units and a model's radians, for one set of joint limits.

    ``lower``/``upper`` are the joint limits in radians, in :data:`JOINT_NAMES` order.
    Conversions are affine, vectorised, and work on arrays of shape ``(..., 6)``.
    """

    lower: np.ndarray
    upper: np.ndarray

    @property
    def scale(self) -> np.ndarray:
        """Radians per arm unit, per joint."""
        s = np.full(len(JOINT_NAMES), math.pi / 180.0)
        s[GRIPPER_INDEX] = (self.upper[GRIPPER_INDEX] - self.lower[GRIPPER_INDEX]) / 100.0
        return s

    def per_degree(self) -> np.ndarray:
        """Arm units per degree of joint rotation, per joint: 1 for body joints, and for the
        gripper 100 over its range in degrees."""
        return (math.pi / 180.0) / self.scale

    @property
    def offset(self) -> np.ndarray:
        """Radians at arm value 0, per joint."""
        o = np.zeros(len(JOINT_NAMES))
        o[GRIPPER_INDEX] = self.lower[GRIPPER_INDEX]
        return o

    @cached_property
    def _gripper(self) -> tuple[float, float]:
        """The gripper's (radians at 0, radians per unit): read once, the same numbers as
        :attr:`offset` and :attr:`scale` (a conversion runs on every robot call)."""
        return float(self.lower[GRIPPER_INDEX]), float(self.scale[GRIPPER_INDEX])

    def joint_to_radians(self, index: int, value: float) -> float:
        """One joint's value (arm units) -> radians, bit for bit as :meth:`to_radians`."""
        if index == GRIPPER_INDEX:
            low, per_unit = self._gripper
            return low + value * per_unit
        return math.radians(value)

    def values_from_radians(self, q: Sequence[float]) -> list[float]:
        """Six joint angles in radians (plain floats, JOINT_NAMES order) -> arm units, bit for
        bit as :meth:`from_radians`, without NumPy (a robot reads its pose on every call)."""
        out = [math.degrees(x) for x in q]
        low, per_unit = self._gripper
        out[GRIPPER_INDEX] = (q[GRIPPER_INDEX] - low) / per_unit
        return out

    def to_radians(self, values: np.ndarray) -> np.ndarray:
        """Arm units (degrees, gripper 0–100) -> joint angles in radians."""
        v = np.asarray(values, dtype=float)
        out = np.radians(v)
        low, per_unit = self._gripper
        out[..., GRIPPER_INDEX] = low + v[..., GRIPPER_INDEX] * per_unit
        return out

    def from_radians(self, q: np.ndarray) -> np.ndarray:
        """Joint angles in radians -> arm units (degrees, gripper 0–100)."""
        q = np.asarray(q, dtype=float)
        out = np.degrees(q)
        low, per_unit = self._gripper
        out[..., GRIPPER_INDEX] = (q[..., GRIPPER_INDEX] - low) / per_unit
        return out

    @cached_property
    def limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) limits in the arm's units: degrees, and 0..100 for the gripper
        (computed once; read-only arrays)."""
        lo, hi = self.from_radians(self.lower), self.from_radians(self.upper)
        lo.flags.writeable = hi.flags.writeable = False
        return lo, hi

    def limits_dict(self) -> dict[str, tuple[float, float]]:
        """Joint name -> (lower, upper) in the arm's units."""
        lo, hi = self.limits
        return {n: (float(lo[i]), float(hi[i])) for i, n in enumerate(JOINT_NAMES)}

    def check_limits(self, values: np.ndarray, *, clip: bool = False) -> np.ndarray:
        """Return ``values`` (arm units), clipped to the limits if ``clip``, else raise.

        Values within :data:`LIMIT_TOLERANCE` of a limit are clipped onto it without error.

        Raises:
            JointLimitError: a value lies outside its joint's limits and ``clip`` is False.
        """
        lo, hi = self.limits
        tol = LIMIT_TOLERANCE
        if clip:
            return np.clip(values, lo, hi)
        bad = np.flatnonzero((values < lo - tol) | (values > hi + tol))
        if bad.size:
            i = int(bad[0])
            n = JOINT_NAMES[i]
            raise JointLimitError(
                f"{n} = {format_value(n, values[i])} is outside the joint's limits "
                f"{format_value(n, lo[i])}..{format_value(n, hi[i])}",
                "choose a target inside them, or pass clip=True to clip targets to the limits "
                "instead",
                joint=n,
                value=float(values[i]),
                lower=float(lo[i]),
                upper=float(hi[i]),
            )
        return np.clip(values, lo, hi)  # only corrections within the tolerance remain

    def pose_to_array(
        self,
        pose: Pose,
        *,
        base: np.ndarray | None = None,
        clip: bool = False,
        check_limits: bool = True,
    ) -> np.ndarray:
        """Validate a pose dict and return it as an array in arm units, :data:`JOINT_NAMES` order.

        Keys may be joint names or LeRobot keys (``"elbow_flex.pos"``). With ``base`` (an array
        in arm units), missing joints keep the base's value; without it all six are required.

        Raises:
            JointNameError: unknown, duplicated or (without ``base``) missing joint names.
            JointValueError: a value that is not a finite real number.
            JointLimitError: a value outside the joint's limits (unless ``clip``).
        """
        values = parse_pose(pose, partial=base is not None)
        out = np.array(base, dtype=float) if base is not None else np.empty(len(JOINT_NAMES))
        for name, v in values.items():
            out[JOINT_NAMES.index(name)] = v
        return self.check_limits(out, clip=clip) if check_limits else out

    def array_to_pose(self, values: np.ndarray) -> dict[str, float]:
        """An array in arm units -> ``{joint name: value}``."""
        return {n: float(values[i]) for i, n in enumerate(JOINT_NAMES)}


def normalize_joint_name(key: object) -> str:
    """``"shoulder_pan"`` or LeRobot's ``"shoulder_pan.pos"`` -> ``"shoulder_pan"``.

    Raises:
        JointNameError: not one of the six joints (the message lists them).
    """
    if isinstance(key, str):
        name = key[: -len(LEROBOT_SUFFIX)] if key.endswith(LEROBOT_SUFFIX) else key
        if name in JOINT_NAMES:
            return name
    raise JointNameError(
        f"unknown joint {key!r}; valid joints are {', '.join(JOINT_NAMES)} "
        f"(LeRobot's keys such as 'shoulder_pan.pos' are accepted too)"
    )


def check_number(name: str, value: object) -> float:
    """Return ``value`` as a float if it is a finite real number (or a 0-d array/tensor of
    one), else raise JointValueError."""
    expected = f"a finite value in {'0..100' if name == GRIPPER else 'degrees'}"
    return check_range(value, name, expected=expected, error=JointValueError)


def parse_pose(pose: Pose, *, partial: bool = False) -> dict[str, float]:
    """Check a pose dict's names and values (not limits) and return ``{joint: float}``.

    Raises:
        JointNameError: ``pose`` is not a dict, or names unknown/duplicated/missing joints.
        JointValueError: a value is not a finite real number.
    """
    if not isinstance(pose, Mapping):
        raise JointNameError(
            f"a pose must be a dict keyed by joint name, got {type(pose).__name__}; "
            f"expected keys {', '.join(JOINT_NAMES)}"
        )
    out: dict[str, float] = {}
    for key, value in pose.items():
        name = normalize_joint_name(key)
        if name in out:
            raise JointNameError(f"joint {name!r} is given twice (as {name!r} and {name}.pos)")
        out[name] = check_number(name, value)
    missing = [n for n in JOINT_NAMES if n not in out]
    if missing and not partial:
        raise JointNameError(
            f"pose is missing {', '.join(missing)}; a pose needs all six joints: "
            f"{', '.join(JOINT_NAMES)}"
        )
    return out


def unit_warnings(values: np.ndarray) -> list[str]:
    """Likely unit mistakes in a pose (array in arm units, JOINT_NAMES order), as sentences:
    body joints that all look like radians (every one within ±π, some fractional and not all
    near 0, e.g. 1.57), or a gripper between 0 and 1 beside body joints in degrees (a fraction
    where 0-100 is expected). An empty list when the pose looks like the arm's units."""
    v = np.asarray(values, dtype=float)
    body = v[:GRIPPER_INDEX]
    out = []
    fractional = np.abs(body - np.round(body)) > 1e-9
    if np.all(np.abs(body) <= math.pi) and np.any(np.abs(body) >= 0.5) and fractional.any():
        i = int(np.argmax(np.abs(body)))
        out.append(
            f"the target looks like radians ({JOINT_NAMES[i]} = {body[i]:g}, every body joint "
            f"within ±π); so101sim expects degrees ({body[i]:g} rad = "
            f"{math.degrees(body[i]):.1f}°)"
        )
    g = v[GRIPPER_INDEX]
    if 0 < g <= 1 and np.any(np.abs(body) > math.pi):
        out.append(
            f"gripper = {g:g} looks like a fraction; the gripper is 0 (closed) to 100 (open), "
            f"so {g:g} is {g:g} % open"
        )
    return out


def to_lerobot(pose: Pose) -> dict[str, float]:
    """``{"shoulder_pan": v}`` -> LeRobot's ``{"shoulder_pan.pos": v}``."""
    return {f"{normalize_joint_name(k)}{LEROBOT_SUFFIX}": float(v) for k, v in pose.items()}


def format_pose(pose: Pose, digits: int = 2) -> str:
    """A pose as one readable line: ``shoulder_pan=0.00° ... gripper=0.00``."""
    return " ".join(
        f"{normalize_joint_name(k)}={format_value(normalize_joint_name(k), v, digits)}"
        for k, v in pose.items()
    )
