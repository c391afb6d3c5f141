"""An arm profile's data: one servo's parameters (:class:`ServoParams`), the whole arm's
(:class:`ArmProfile`), their bounds and the supply-voltage scaling. What the fields mean is in
:mod:`so101sim.model.arm`; loading and writing TOML is :mod:`.profiles`, applying a profile to a
model :mod:`.apply`, writing a servo into a compiled model :mod:`.runtime`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, fields, replace
from typing import Any

from ..errors import ProfileError
from ..validation import check_range

STALL_TORQUE_NM: dict[float, float] = {7.4: 19.5 * 0.0980665, 12.0: 30.0 * 0.0980665}
"""Rated stall torque (N·m) of the STS3215 at its supply: the 7.4 V version (C001, 19.5 kg·cm)
and the 12 V version (C018, 30 kg·cm). Both run at about the same no-load speed (0.222 s/60°),
so their back-EMF damping (stall torque / no-load speed) scales the same way."""

PROFILE_DEFAULT = "sts3215"
"""The profile the project loads when none is named: the one that predicts a real STS3215 best
(validation runs of the servo bench: 0.0153 rad mean per-run error against 0.211 for
``official``; docs/fidelity.md). ``official`` (the vendored actuators) is one option away."""

OFFICIAL = "official"
"""The profile of the vendored model's own actuators: a model loaded with it is the file as it
is."""


# field -> (low, high, unit, low_open): every number in a profile is bounded
_BOUNDS: dict[str, tuple[float, float, str]] = {
    "kp_per_p": (0.0, 1000.0, " N·m/rad per P unit"),
    "firmware_p": (0.0, 255.0, ""),
    "firmware_d": (0.0, 255.0, ""),
    "kv": (0.0, 100.0, " N·m·s/rad"),
    "torque_limit": (0.0, 50.0, " N·m"),
    "damping": (0.0, 50.0, " N·m·s/rad"),
    "viscous": (0.0, 50.0, " N·m·s/rad"),
    "frictionloss": (0.0, 10.0, " N·m"),
    "drive_frictionloss": (0.0, 10.0, " N·m"),
    "load_friction": (0.0, 0.5, " N·m per N·m of servo torque"),
    "armature": (0.0, 1.0, " kg·m²"),
    "delay_s": (0.0, 0.5, " s"),
    "smoothing_s": (0.0, 0.5, " s"),
    "max_velocity": (0.0, 1000.0, " rad/s"),
    "offset": (-0.2, 0.2, " rad"),
    "torque_scale": (0.0, 1.0, ""),
}
_OPEN_LOW = {"torque_limit", "torque_scale"}

REQUIRED_FIELDS: tuple[str, ...] = (
    "kp_per_p",
    "firmware_p",
    "torque_limit",
    "damping",
    "frictionloss",
    "armature",
)
"""The servo fields a profile that extends no other must give (the others default to none:
no delay, no slew limit, no drive friction, ...). An empty profile, or one with only a name,
would otherwise be a servo nobody measured (issue 30: the wrist reached 126.8° against its
±95° limit)."""

NOSLIP_ITERATIONS = 10
"""MuJoCo's noslip iterations a profile with ``static_friction`` gets: the joints' Coulomb
friction (``frictionloss``) then holds a load below it exactly, as a geared servo does, instead
of letting the joint creep at a speed proportional to the load (MuJoCo's soft friction)."""

CALIBRATION_BOUNDS: dict[str, tuple[float, float]] = {
    "scale": (0.7, 1.3),
    "offset": (-20.0, 20.0),
    "scale_sd": (0.0, 1.0),
    "offset_sd": (0.0, 40.0),
}
"""A ``[calibration.<joint>]`` table's fields: a range-mode recording's reading of a body joint is
``scale`` × its angle (degrees) + ``offset`` (degrees), with their standard deviations; written
by ``so101sim fit`` for a recording without LeRobot's calibration JSON and used by ``compare``
and ``fit`` on such recordings. It does not change the model."""

UNCERTAIN_FIELDS: tuple[str, ...] = (
    "kp_per_p",
    "torque_limit",
    "damping",
    "viscous",
    "frictionloss",
    "drive_frictionloss",
    "armature",
    "delay_s",
    "max_velocity",
    "offset",
)
"""The servo fields an ``[uncertainty]`` table may give a standard deviation for (those a drawn
servo changes in a compiled model)."""
UNCERTAIN_LIMIT: dict[str, float] = {k: _BOUNDS[k][1] - _BOUNDS[k][0] for k in UNCERTAIN_FIELDS}
"""The largest standard deviation a table may give each field (its range's width)."""
MAX_SIGMAS = 3.0
"""Draws from a profile's uncertainty are cut at this many standard deviations."""


@dataclass(frozen=True)
class ServoParams:
    """One joint's servo, at the profile's supply voltage once :meth:`ArmProfile.joint` made it.

    ``torque_scale`` is the firmware's torque limit as a fraction (LeRobot writes
    ``Max_Torque_Limit`` 500 of 1000 to the gripper: half the current, half the torque)."""

    kp_per_p: float = 1.0
    firmware_p: float = 16.0
    firmware_d: float = 32.0
    kv: float = 0.0
    torque_limit: float = 2.94
    damping: float = 0.0
    viscous: float = 0.0
    frictionloss: float = 0.0
    drive_frictionloss: float = 0.0
    load_friction: float = 0.0
    armature: float = 0.0
    delay_s: float = 0.0
    smoothing_s: float = 0.0
    max_velocity: float = 0.0
    offset: float = 0.0
    torque_scale: float = 1.0

    @property
    def kp(self) -> float:
        """The position actuator's stiffness, N·m/rad."""
        return self.kp_per_p * self.firmware_p

    @property
    def force_limit(self) -> float:
        """The actuator's force range bound, N·m (torque limit times the firmware fraction)."""
        return self.torque_limit * self.torque_scale

    @property
    def joint_frictionloss(self) -> float:
        """The joint's Coulomb friction while the servo drives, N·m."""
        return self.frictionloss + self.drive_frictionloss

    @property
    def joint_damping(self) -> float:
        """The joint's damping: back-EMF plus viscous friction, N·m·s/rad."""
        return self.damping + self.viscous


def _check_params(values: dict[str, Any], where: str) -> dict[str, float]:
    known = {f.name for f in fields(ServoParams)}
    out: dict[str, float] = {}
    for key, value in values.items():
        if key not in known:
            raise ProfileError(
                f"{where}: unknown field {key!r}; expected one of {', '.join(sorted(known))}"
            )
        low, high, unit = _BOUNDS[key]
        out[key] = check_range(
            value, f"{where}.{key}", low=low, high=high, unit=unit,
            low_open=key in _OPEN_LOW, error=ProfileError,
        )  # fmt: skip
    return out


@dataclass(frozen=True)
class ArmProfile:
    """A named actuator model for the whole arm: ``servo`` for every joint, ``joints`` the
    per-joint changes (the fields that differ), both at ``measured_at_v`` volts; the model gets
    them scaled to ``supply_v`` (:meth:`joint`)."""

    name: str
    description: str = ""
    supply_v: float = 12.0
    measured_at_v: float = 12.0
    scale_with_supply: bool = True
    servo: ServoParams = field(default_factory=ServoParams)
    joints: dict[str, dict[str, float]] = field(default_factory=dict)
    source: str = ""
    uncertainty: dict[str, float] = field(default_factory=dict)
    static_friction: bool = False
    calibration: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def supply_scale(self) -> float:
        """How the torque-related values scale from ``measured_at_v`` to ``supply_v``."""
        if not self.scale_with_supply or self.supply_v == self.measured_at_v:
            return 1.0
        return _stall(self.supply_v) / _stall(self.measured_at_v)

    def joint(self, name: str, *, scaled: bool = True) -> ServoParams:
        """The servo of joint ``name`` (at ``supply_v`` when ``scaled``)."""
        p = replace(self.servo, **self.joints.get(name, {}))
        if not scaled:
            return p
        s = self.supply_scale
        return replace(
            p, kp_per_p=p.kp_per_p * s, torque_limit=p.torque_limit * s, damping=p.damping * s
        )

    def with_supply(self, volts: float) -> ArmProfile:
        """The same profile driven at ``volts`` (7.4 or 12)."""
        return replace(self, supply_v=_check_supply(volts, "supply_v"))


ArmLike = str | os.PathLike[str] | ArmProfile | None
"""An arm profile as every so101sim function takes it: a shipped name (``"sts3215"``,
``"official"``), a TOML path, an :class:`ArmProfile`, or None (:data:`PROFILE_DEFAULT`)."""


def _stall(volts: float) -> float:
    """Rated stall torque at ``volts``, interpolated linearly between the two versions."""
    (v0, t0), (v1, t1) = sorted(STALL_TORQUE_NM.items())
    return t0 + (t1 - t0) * (volts - v0) / (v1 - v0)


def _check_supply(value: object, what: str) -> float:
    return check_range(value, what, low=5.0, high=14.0, unit=" V", error=ProfileError)
