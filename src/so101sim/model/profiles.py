"""Arm profiles by name or TOML file (:func:`load_profile`), checked field by field, and written
back (:func:`profile_toml`); the key a profile's values give a compiled model
(:func:`profile_key`)."""

from __future__ import annotations

import hashlib
import os
import tomllib
from dataclasses import fields, replace
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ProfileError
from ..units import JOINT_NAMES
from ..validation import check_range
from .servo import (
    _BOUNDS,
    CALIBRATION_BOUNDS,
    OFFICIAL,
    PROFILE_DEFAULT,
    REQUIRED_FIELDS,
    UNCERTAIN_FIELDS,
    UNCERTAIN_LIMIT,
    ArmLike,
    ArmProfile,
    ServoParams,
    _check_params,
    _check_supply,
)


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
    return _from_dict(raw, str(path), seen | {str(path.resolve())}, file=path)


def _from_dict(
    raw: dict[str, Any], where: str, seen: set[str], file: Path | None = None
) -> ArmProfile:
    top = {"name", "description", "extends", "supply_v", "measured_at_v", "scale_with_supply",
           "static_friction"}  # fmt: skip
    unknown = set(raw) - top - {"servo", "joints", "uncertainty", "calibration"}
    if unknown:
        raise ProfileError(
            f"{where}: unknown field {sorted(unknown)[0]!r}; expected {', '.join(sorted(top))}, "
            "[servo], [joints.<joint>], [uncertainty] and [calibration.<joint>]"
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
    hold = raw.get("static_friction", base.static_friction if base else False)
    if not isinstance(name, str) or not isinstance(desc, str) or not isinstance(scale, bool):
        raise ProfileError(
            f"{where}: name and description must be strings, scale_with_supply a boolean"
        )
    if not isinstance(hold, bool):
        raise ProfileError(f"{where}: static_friction = {hold!r}; expected true or false")
    supply = _check_supply(raw.get("supply_v", base.supply_v if base else 12.0), "supply_v")
    measured = _check_supply(
        raw.get("measured_at_v", base.measured_at_v if base else supply), "measured_at_v"
    )
    uncertainty = dict(base.uncertainty) if base else {}
    uncertainty.update(_check_uncertainty(raw.get("uncertainty", {}), where))
    if base is None:  # a profile of its own must say what its servo is: nothing assumed
        missing = [k for k in REQUIRED_FIELDS if k not in servo_raw]
        if missing:
            raise ProfileError(
                f"{where}: [servo] lacks {', '.join(missing)}; expected every one of "
                f'{", ".join(REQUIRED_FIELDS)}, or extends = "{PROFILE_DEFAULT}" to start from '
                "a shipped profile and change only what differs"
            )
    prof = ArmProfile(
        name=name, description=desc, supply_v=supply, measured_at_v=measured,
        scale_with_supply=scale, servo=servo, joints=joints, source=where,
        uncertainty=uncertainty, static_friction=hold,
        calibration=_check_calibration(raw.get("calibration", {}), where),
    )  # fmt: skip
    # A file that extends a profile, changes its servos and does not name itself is named after
    # the file: every output's "servo model:" line names it, not the parent. One that changes
    # only [calibration] or [uncertainty] builds the parent's model, and keeps its name.
    renamed = base is not None and file is not None and "name" not in raw
    if renamed and _values_toml(prof) != _values_toml(base):
        changed = f"{base.name} changed by {file.name}"
        about = f"{changed}: {base.description}" if base.description else changed
        prof = replace(prof, name=file.stem, description=raw.get("description", about))
    return prof


def _check_calibration(table: object, where: str) -> dict[str, dict[str, float]]:
    if not isinstance(table, dict) or not all(isinstance(v, dict) for v in table.values()):
        raise ProfileError(f"{where}: [calibration] must hold a table per body joint")
    out: dict[str, dict[str, float]] = {}
    for joint, values in table.items():
        if joint not in JOINT_NAMES[:5]:
            raise ProfileError(
                f"{where}: [calibration.{joint}] names no body joint; expected one of "
                f"{', '.join(JOINT_NAMES[:5])}"
            )
        for key, value in values.items():
            if key not in CALIBRATION_BOUNDS:
                raise ProfileError(
                    f"{where}: calibration.{joint}.{key} is unknown; expected "
                    f"{', '.join(CALIBRATION_BOUNDS)}"
                )
            low, high = CALIBRATION_BOUNDS[key]
            out.setdefault(joint, {})[key] = check_range(
                value, f"{where}: calibration.{joint}.{key}", low=low, high=high,
                error=ProfileError,
            )  # fmt: skip
    return out


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
    """``profile`` as TOML text that :func:`load_profile` reads back to the same values
    (written by ``tomli-w``: every string escaped as TOML says)."""
    import tomli_w  # imported here: only writing a profile needs it

    data: dict[str, Any] = {
        "name": profile.name,
        "description": profile.description,
        "supply_v": float(profile.supply_v),
        "measured_at_v": float(profile.measured_at_v),
        "scale_with_supply": bool(profile.scale_with_supply),
        "static_friction": bool(profile.static_friction),
        "servo": {f.name: float(getattr(profile.servo, f.name)) for f in fields(ServoParams)},
    }
    joints = {
        joint: {k: float(v) for k, v in profile.joints[joint].items()}
        for joint in JOINT_NAMES
        if profile.joints.get(joint)
    }
    if joints:
        data["joints"] = joints
    if profile.uncertainty:
        data["uncertainty"] = {k: float(v) for k, v in profile.uncertainty.items()}
    if profile.calibration:
        data["calibration"] = {
            joint: {k: float(v) for k, v in values.items()}
            for joint, values in profile.calibration.items()
        }
    head = "".join(f"# {c}\n" if c else "#\n" for c in comment.splitlines()) if comment else ""
    return head + tomli_w.dumps(data)


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
    return profile_toml(
        replace(profile, name="", description="", source="", uncertainty={}, calibration={})
    )


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
