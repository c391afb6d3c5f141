"""Arm profiles: the actuator model of the SO-101's servos, named and loaded from TOML, and
applied to the model at load with :class:`mujoco.MjSpec` (the official files stay unchanged).

A profile describes one Feetech STS3215 as LeRobot drives it (firmware P = 16, I = 0, D = 32,
a goal position written every control tick), in MuJoCo's own terms:

* ``kp``: the position actuator's stiffness, ``kp_per_p`` N·m/rad per firmware P unit times
  ``firmware_p``. The servo's firmware computes a PWM duty from the position error times P; the
  duty times the supply voltage, through the motor's winding, is a torque;
* ``torque_limit``: the actuator's ``forcerange`` (the firmware's largest duty, and the stall
  torque at the supply);
* ``damping``: the motor's back-EMF, kt²/R, as *joint* damping: it brakes the joint outside the
  duty clamp (as a DC motor does), where an actuator ``kv`` would be clipped with the drive;
* ``viscous``, ``frictionloss`` (Coulomb), ``armature`` (the rotor's inertia through the
  1:345 gearbox): joint properties; ``drive_frictionloss``: Coulomb friction added while the
  servo drives (the firmware's dead zone around the goal and the gear train under the motor's
  load hold the joint; a servo with its torque off swings freer);
* ``delay_s``: the time from a goal written on the bus to the motor acting on it (and the
  position read back), MuJoCo 4's actuator ``delay`` with a history of ``nsample`` samples;
* ``max_velocity``: the fastest the firmware moves its internal goal toward the written one
  (rad/s; 0: it jumps), MuJoCo 4's PID actuator with ``slewmax`` (kp only, no I or D);
* ``smoothing_s``: the firmware's goal smoothing, as a first-order filter of that time
  constant on the delayed goal (MuJoCo's ``<position timeconst>``: ``filterexact`` dynamics);
* ``offset``: a calibration offset (rad) per joint: the servo holds ``goal - offset``;
* ``kv``: an actuator velocity gain (only the vendored model uses one).

A profile may carry an ``[uncertainty]`` table: a standard deviation (at ``measured_at_v``,
in the field's own unit) for some of :data:`UNCERTAIN_FIELDS`, e.g. a fit's standard errors.
Domain randomisation (``scenes.randomize``, family ``actuator_sigmas``) draws each joint's
servo from it (:func:`draw_servo_deltas`); it does not change the model the profile loads.

Values are given at ``measured_at_v`` volts; the profile's ``supply_v`` (7.4 V for the
standard SO-101, 12 V for the "pro" kit) scales the torque-related ones (``kp_per_p``,
``torque_limit``, ``damping``) by the ratio of the two servo versions' rated stall torques
(:data:`STALL_TORQUE_NM`). The friction, armature and delay do not depend on the supply.

Shipped profiles (``so101sim/data/arms``): ``official`` (the vendored model's values),
``sts3215`` (fitted on a real STS3215 pendulum bench at 12 V, driven at 7.4 V) and
``sts3215-12v`` (the same fit at 12 V). :func:`load_profile` takes a name or a TOML path.

Long on purpose: a profile's fields, its TOML (loading and writing) and how it is applied
are one format and read best side by side (a field added in one place needs the others).
"""

from __future__ import annotations

import hashlib
import math
import os
import tomllib
from dataclasses import dataclass, field, fields, replace
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..errors import ProfileError
from ..units import JOINT_NAMES
from ..validation import check_range

__all__ = [
    "STALL_TORQUE_NM",
    "UNCERTAIN_FIELDS",
    "UNCERTAIN_LIMIT",
    "ArmLike",
    "ArmProfile",
    "ProfileError",
    "ServoParams",
    "apply_profile",
    "draw_servo_deltas",
    "fill_delay_history",
    "gripper_full_range",
    "load_profile",
    "profile_from_toml",
    "profile_key",
    "profile_names",
    "profile_toml",
]

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
    "armature": (0.0, 1.0, " kg·m²"),
    "delay_s": (0.0, 0.5, " s"),
    "smoothing_s": (0.0, 0.5, " s"),
    "max_velocity": (0.0, 1000.0, " rad/s"),
    "offset": (-0.2, 0.2, " rad"),
    "torque_scale": (0.0, 1.0, ""),
}
_OPEN_LOW = {"torque_limit", "torque_scale"}

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
UNCERTAIN_LIMIT: dict[str, float] = {}
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


# ---------------------------------------------------------------------------- loading
def _arms_dir() -> Path:
    return Path(str(resources.files("so101sim") / "data" / "arms"))


def profile_names() -> list[str]:
    """The shipped profiles' names."""
    return sorted(p.stem for p in _arms_dir().glob("*.toml"))


def load_profile(profile: ArmLike = None) -> ArmProfile:
    """A profile by name (``"official"``, ``"sts3215"``, ``"sts3215-12v"``), by TOML path, or
    as given; None is :data:`PROFILE_DEFAULT`.

    Raises:
        ProfileError: unknown name, missing or unreadable file, invalid TOML, unknown field or
            a value out of bounds.
    """
    if isinstance(profile, ArmProfile):
        return profile
    if profile is None:
        profile = PROFILE_DEFAULT
    text = os.fspath(profile) if isinstance(profile, os.PathLike) else str(profile)
    if isinstance(profile, os.PathLike) or text.endswith(".toml") or "/" in text or "\\" in text:
        path = Path(text).expanduser()
        if not path.is_file():
            raise ProfileError(
                f"arm profile file {text!r} does not exist; expected a TOML file such as one "
                f"written by `so101sim fit`, or a shipped name ({', '.join(profile_names())})"
            )
        return _from_file(path, set())
    if text not in profile_names():
        raise ProfileError(
            f"unknown arm profile {text!r}; valid profiles are {', '.join(profile_names())} "
            "or the path of a TOML file"
        )
    return _from_file(_arms_dir() / f"{text}.toml", set())


def profile_from_toml(text: str, where: str = "arm profile") -> ArmProfile:
    """A profile from TOML text (e.g. :func:`profile_toml`'s), checked as a file is.

    Raises:
        ProfileError: invalid TOML, an unknown field or a value out of its bounds.
    """
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(f"{where} is not valid TOML ({exc})") from exc
    return _from_dict(raw, where, set())


def _from_file(path: Path, seen: set[str]) -> ArmProfile:
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ProfileError(f"arm profile {str(path)!r} cannot be read: {exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(
            f"arm profile {str(path)!r} is not valid TOML ({exc}); expected the format of "
            "so101sim/data/arms/sts3215.toml"
        ) from exc
    return _from_dict(raw, str(path), seen | {str(path.resolve())})


def _from_dict(raw: dict[str, Any], where: str, seen: set[str]) -> ArmProfile:
    top = {"name", "description", "extends", "supply_v", "measured_at_v", "scale_with_supply"}
    unknown = set(raw) - top - {"servo", "joints", "uncertainty"}
    if unknown:
        raise ProfileError(
            f"{where}: unknown field {sorted(unknown)[0]!r}; expected {', '.join(sorted(top))}, "
            "[servo], [joints.<joint>] and [uncertainty]"
        )
    base: ArmProfile | None = None
    if "extends" in raw:
        parent = raw["extends"]
        if not isinstance(parent, str) or parent not in profile_names():
            raise ProfileError(
                f"{where}: extends = {parent!r} is not a shipped profile; expected one of "
                f"{', '.join(profile_names())}"
            )
        ppath = _arms_dir() / f"{parent}.toml"
        if str(ppath.resolve()) in seen:
            raise ProfileError(f"{where}: extends {parent!r} in a cycle; expected a chain")
        base = _from_file(ppath, seen)
    servo_raw = raw.get("servo", {})
    joints_raw = raw.get("joints", {})
    if not isinstance(servo_raw, dict) or not isinstance(joints_raw, dict):
        raise ProfileError(f"{where}: [servo] and [joints] must be tables")
    servo = replace(base.servo if base else ServoParams(), **_check_params(servo_raw, "servo"))
    joints = {k: dict(v) for k, v in (base.joints if base else {}).items()}
    for name, table in joints_raw.items():
        if name not in JOINT_NAMES:
            raise ProfileError(
                f"{where}: [joints.{name}] names no joint; expected one of {', '.join(JOINT_NAMES)}"
            )
        if not isinstance(table, dict):
            raise ProfileError(f"{where}: joints.{name} must be a table")
        joints.setdefault(name, {}).update(_check_params(table, f"joints.{name}"))
    name = raw.get("name", base.name if base else Path(where).stem)
    desc = raw.get("description", base.description if base else "")
    scale = raw.get("scale_with_supply", base.scale_with_supply if base else True)
    if not isinstance(name, str) or not isinstance(desc, str) or not isinstance(scale, bool):
        raise ProfileError(
            f"{where}: name and description must be strings, scale_with_supply a boolean"
        )
    supply = _check_supply(raw.get("supply_v", base.supply_v if base else 12.0), "supply_v")
    measured = _check_supply(
        raw.get("measured_at_v", base.measured_at_v if base else supply), "measured_at_v"
    )
    uncertainty = dict(base.uncertainty) if base else {}
    uncertainty.update(_check_uncertainty(raw.get("uncertainty", {}), where))
    return ArmProfile(
        name=name, description=desc, supply_v=supply, measured_at_v=measured,
        scale_with_supply=scale, servo=servo, joints=joints, source=where,
        uncertainty=uncertainty,
    )  # fmt: skip


UNCERTAIN_LIMIT.update({k: _BOUNDS[k][1] - _BOUNDS[k][0] for k in UNCERTAIN_FIELDS})


def _check_uncertainty(table: object, where: str) -> dict[str, float]:
    if not isinstance(table, dict):
        raise ProfileError(f"{where}: [uncertainty] must be a table of standard deviations")
    out: dict[str, float] = {}
    for key, value in table.items():
        if key not in UNCERTAIN_FIELDS:
            raise ProfileError(
                f"{where}: [uncertainty] has {key!r}; expected some of "
                f"{', '.join(UNCERTAIN_FIELDS)}"
            )
        out[key] = check_range(
            value, f"{where}: uncertainty.{key}", low=0.0, high=UNCERTAIN_LIMIT[key],
            unit=_BOUNDS[key][2],
            error=ProfileError,
        )  # fmt: skip
    return out


def profile_toml(profile: ArmProfile, *, comment: str = "") -> str:
    """``profile`` as TOML text that :func:`load_profile` reads back to the same values."""
    lines = [f"# {c}" if c else "#" for c in comment.splitlines()] if comment else []
    lines += [
        f"name = {_q(profile.name)}",
        f"description = {_q(profile.description)}",
        f"supply_v = {profile.supply_v!r}",
        f"measured_at_v = {profile.measured_at_v!r}",
        f"scale_with_supply = {'true' if profile.scale_with_supply else 'false'}",
        "",
        "[servo]",
    ]
    lines += [f"{f.name} = {float(getattr(profile.servo, f.name))!r}" for f in fields(ServoParams)]
    for joint in JOINT_NAMES:
        values = profile.joints.get(joint)
        if values:
            lines += ["", f"[joints.{joint}]"]
            lines += [f"{k} = {float(v)!r}" for k, v in values.items()]
    if profile.uncertainty:
        lines += ["", "[uncertainty]"]
        lines += [f"{k} = {float(v)!r}" for k, v in profile.uncertainty.items()]
    return "\n".join(lines) + "\n"


def profile_key(profile: ArmLike) -> str:
    """A short key naming what ``profile`` does to a model: ``""`` when it is the vendored
    actuators (the shipped ``official`` values: the model file as it is), else ``"arm-"`` and
    a digest of its values (the model caches' key)."""
    prof = load_profile(profile)
    text = _values_toml(prof)
    if text == _official_values():
        return ""
    return "arm-" + hashlib.sha256(text.encode()).hexdigest()[:16]


def _values_toml(profile: ArmProfile) -> str:
    """The profile's values as the model gets them (name, description and source aside)."""
    return profile_toml(replace(profile, name="", description="", source="", uncertainty={}))


@lru_cache(maxsize=1)
def _official_values() -> str:
    return _values_toml(load_profile(OFFICIAL))


def gripper_full_range(profile: ArmLike) -> np.ndarray:
    """``[-limit, limit]`` (N·m): the gripper servo's torque limit at the profile's supply,
    before a firmware torque limit (the profile's ``torque_scale``). The follower and the
    environments give the gripper their ``gripper_torque_fraction`` of it (LeRobot's
    ``Max_Torque_Limit`` 500 of 1000), replacing the profile's own fraction."""
    p = load_profile(profile).joint("gripper")
    return np.array([-p.torque_limit, p.torque_limit])


def _q(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


# ---------------------------------------------------------------------------- applying
def delay_samples(delay_s: float, timestep: float) -> int:
    """History samples an actuator needs to delay its control by ``delay_s`` at ``timestep``."""
    return math.ceil(delay_s / timestep - 1e-9) + 2


def apply_servo(
    spec: mujoco.MjSpec, joint: str, actuator: Any, params: ServoParams, timestep: float
) -> None:
    """Write ``params`` onto ``joint`` (a joint name in ``spec``) and ``actuator`` (an
    ``MjsActuator`` driving it): a position actuator with ``kp``, ``kv``, ``forcerange``,
    ``delay``; the joint's damping, frictionloss and armature."""
    j = spec.joint(joint)
    j.damping = [params.joint_damping, 0.0, 0.0]  # MuJoCo 4: [linear, polynomial terms]
    j.frictionloss = params.joint_frictionloss
    j.armature = params.armature
    kp = params.kp
    if params.max_velocity > 0:  # a slew-limited goal: MuJoCo 4's PID actuator, P only
        if params.smoothing_s > 0:
            raise ProfileError("smoothing_s and max_velocity cannot be combined; expected one")
        actuator.set_to_pid(kp, 0.0, -1, -1, -1, params.max_velocity, 0, 1)  # position input only
        actuator.biasprm = np.r_[-kp * params.offset, -kp, -params.kv, np.zeros(7)]
        actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        actuator.forcerange = np.array([-params.force_limit, params.force_limit])
        _set_delay(actuator, params, timestep)
        return
    if params.smoothing_s > 0:  # the goal through a first-order filter (<position timeconst>)
        actuator.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
        actuator.dynprm = np.r_[params.smoothing_s, np.zeros(9)]
    else:
        actuator.dyntype = mujoco.mjtDyn.mjDYN_NONE
    actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
    actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    actuator.gainprm = np.r_[kp, np.zeros(9)]
    actuator.biasprm = np.r_[-kp * params.offset, -kp, -params.kv, np.zeros(7)]
    actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    actuator.forcerange = np.array([-params.force_limit, params.force_limit])
    _set_delay(actuator, params, timestep)


def _set_delay(actuator: Any, params: ServoParams, timestep: float) -> None:
    if params.delay_s > 0:
        actuator.delay = params.delay_s
        actuator.nsample = delay_samples(params.delay_s, timestep)
        actuator.interp = 1  # linear between the per-step samples (smooth in the delay)
    else:
        actuator.delay = 0.0
        actuator.nsample = 0


def apply_profile(spec: mujoco.MjSpec, profile: ArmLike) -> ArmProfile:
    """Apply ``profile`` to every SO-101 joint of ``spec`` and the actuator driving it; returns
    the profile. Joints the spec lacks are skipped (a scene may hold only part of the arm)."""
    prof = load_profile(profile)
    by_joint = {a.target: a for a in spec.actuators}
    timestep = float(spec.option.timestep)
    names = {j.name for j in spec.joints}
    for name in JOINT_NAMES:
        if name in names and name in by_joint:
            apply_servo(spec, name, by_joint[name], prof.joint(name), timestep)
    return prof


_GOAL_STATE_DYN = (int(mujoco.mjtDyn.mjDYN_FILTEREXACT), int(mujoco.mjtDyn.mjDYN_PID))
"""Actuator dynamics whose state is the goal the servo acts on (filtered or slew-limited)."""


def fill_delay_history(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Fill every delayed actuator's history (and a smoothed one's filter state) with its
    current ``data.ctrl``, so that a pose set now is commanded from the start (not the zeros
    of a fresh history)."""
    for a in range(model.nu):
        adr = int(model.actuator_actadr[a])
        dyn = int(model.actuator_dyntype[a])
        if adr >= 0 and dyn in _GOAL_STATE_DYN:
            data.act[adr] = data.ctrl[a]
    if not model.nhistory:
        return
    for a in range(model.nu):
        n = int(model.actuator_history[a, 0])
        if n > 0:
            values = np.full((n, 1), float(data.ctrl[a]))
            times = data.time + model.opt.timestep * (np.arange(n, dtype=float) - n)
            mujoco.mj_initCtrlHistory(model, data, a, times.reshape(n, 1), values)


def write_servo(model: mujoco.MjModel, actuator: int, dof: int, params: ServoParams) -> None:
    """Write ``params`` into a compiled ``model`` in place (actuator ``actuator`` driving the
    degree of freedom ``dof``): what :func:`apply_servo` does to a spec, for parameter sweeps
    and fits. The delay must lie within the history the model was compiled with.

    Raises:
        ProfileError: the delay is beyond the actuator's history.
    """
    n = int(model.actuator_history[actuator, 0])
    reach = max(n - 2, 0) * model.opt.timestep
    if params.delay_s > reach + 1e-12:
        raise ProfileError(
            f"delay_s = {params.delay_s} s is beyond actuator {actuator}'s history "
            f"({reach:.4f} s); expected a model compiled with a longer delay"
        )
    kp = params.kp
    pid = int(model.actuator_dyntype[actuator]) == int(mujoco.mjtDyn.mjDYN_PID)
    if pid != (params.max_velocity > 0):
        raise ProfileError(
            "max_velocity > 0 needs a model compiled with a slew-limited goal (and 0 one "
            "without); expected the profile's max_velocity when the model was made"
        )
    if pid:
        model.actuator_dynprm[actuator, 1] = params.max_velocity
    model.actuator_gainprm[actuator, 0] = 0.0 if pid else kp
    model.actuator_biasprm[actuator, :3] = [-kp * params.offset, -kp, -params.kv]
    model.actuator_forcerange[actuator] = [-params.force_limit, params.force_limit]
    model.actuator_delay[actuator] = params.delay_s
    if params.smoothing_s > 0:
        if int(model.actuator_dyntype[actuator]) != int(mujoco.mjtDyn.mjDYN_FILTEREXACT):
            raise ProfileError(
                "smoothing_s > 0 needs a model compiled with smoothing; expected the profile's "
                "smoothing when the model was made"
            )
        model.actuator_dynprm[actuator, 0] = params.smoothing_s
    model.dof_damping[dof] = params.joint_damping
    model.dof_frictionloss[dof] = params.joint_frictionloss
    model.dof_armature[dof] = params.armature


def draw_servo_deltas(
    profile: ArmLike,
    rng: np.random.Generator,
    sigmas: float = 1.0,
    joints: tuple[str, ...] = JOINT_NAMES,
) -> dict[str, dict[str, float]]:
    """One draw of each joint's servo from ``profile``'s ``[uncertainty]``: for each joint
    (in ``joints``' order) and each field of the table (in :data:`UNCERTAIN_FIELDS`' order), the
    drawn value minus the profile's own, at the profile's supply (``ArmProfile.joint``). Each
    field is drawn independently per joint as the value plus ``sigmas`` × its standard deviation
    × a standard normal number cut at ±:data:`MAX_SIGMAS`, kept inside the field's bounds. No
    table, or ``sigmas`` = 0: an empty dict per joint, and nothing drawn from ``rng``.

    Raises:
        ProfileError: ``sigmas`` outside 0 to :data:`MAX_SIGMAS`.
    """
    prof = load_profile(profile)
    k = check_range(sigmas, "actuator sigmas", low=0.0, high=MAX_SIGMAS, error=ProfileError)
    names = [n for n in UNCERTAIN_FIELDS if prof.uncertainty.get(n, 0.0) > 0]
    if not names or k == 0:
        return {j: {} for j in joints}
    z = np.clip(rng.standard_normal((len(joints), len(names))), -MAX_SIGMAS, MAX_SIGMAS)
    out: dict[str, dict[str, float]] = {}
    for i, joint in enumerate(joints):
        raw = prof.joint(joint, scaled=False)
        values = {}
        for f, name in enumerate(names):
            low, high, _ = _BOUNDS[name]
            v = getattr(raw, name) + k * prof.uncertainty[name] * z[i, f]
            floor = low + 1e-9 if name in _OPEN_LOW else low
            values[name] = float(np.clip(v, floor, high))
        drawn = replace(prof, joints={joint: {**prof.joints.get(joint, {}), **values}})
        new, old = drawn.joint(joint), prof.joint(joint)
        out[joint] = {n: getattr(new, n) - getattr(old, n) for n in names}
    return out
