"""A LeRobot SO-101 leader arm's calibration: LeRobot's JSON format, where it is found, and
turning raw servo positions (ticks) into the arm's units with LeRobot's formulas.

* body joints, degrees: ``(raw - (range_min + range_max) / 2) * 360 / 4095``;
* gripper, 0..100: linear over ``[range_min, range_max]``, clamped (``100 - x`` if
  ``drive_mode``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..errors import CalibrationError
from ..model.load import default_units
from ..motion.lines import UnreadableFileError, read_text_limited
from ..units import DEG_PER_RAD, GRIPPER, GRIPPER_INDEX, JOINT_NAMES
from ..validation import check_count, checked_path

TICKS_PER_TURN = 4096
MAX_TICK = TICKS_PER_TURN - 1  # 4095, LeRobot's max_res for the STS3215
MOTOR_IDS: dict[str, int] = {name: i + 1 for i, name in enumerate(JOINT_NAMES)}
"""Servo id of each joint on LeRobot's SO-101 (shoulder_pan 1 ... gripper 6)."""
LEADER_NAME = "so_leader"  # LeRobot's class name for the SO-101 leader (calibration folder)
MAX_CALIBRATION_BYTES = 64 * 1024
"""The largest calibration file read (LeRobot writes about 700 bytes)."""

CALIBRATION_FIELDS: dict[str, tuple[int, int]] = {
    "id": (0, 253),  # Feetech ids (254 is the broadcast id)
    "drive_mode": (0, 1),
    "homing_offset": (-2047, 2047),  # 11 bits and a sign bit in the servo
    "range_min": (0, MAX_TICK),
    "range_max": (0, MAX_TICK),
}
"""Each field of a motor's calibration, with the values the servo can hold."""


@dataclass(frozen=True)
class MotorCalibration:
    """One motor's calibration, as LeRobot stores it."""

    id: int
    drive_mode: int
    homing_offset: int
    range_min: int
    range_max: int


def default_calibration() -> dict[str, MotorCalibration]:
    """A calibration to use without a file, assuming the leader was calibrated by LeRobot.

    LeRobot's calibration makes the middle pose read 2047 on every servo, so body joints get
    the range 0..4095 (middle 2047.5). The gripper's range is a guess: the model's gripper
    range (−10°..100° from the middle) around 2047. Pass the real file for exact values.
    """
    units = default_units()
    g_lo = round(2047 + units.lower[GRIPPER_INDEX] * DEG_PER_RAD * MAX_TICK / 360)
    g_hi = round(2047 + units.upper[GRIPPER_INDEX] * DEG_PER_RAD * MAX_TICK / 360)
    out = {n: MotorCalibration(MOTOR_IDS[n], 0, 0, 0, MAX_TICK) for n in JOINT_NAMES}
    out[GRIPPER] = MotorCalibration(MOTOR_IDS[GRIPPER], 0, 0, g_lo, g_hi)
    return out


def parse_calibration(data: object) -> dict[str, MotorCalibration]:
    """Validate LeRobot's calibration dict ``{motor: {id, drive_mode, homing_offset,
    range_min, range_max}}`` for the six SO-101 motors.

    Raises:
        CalibrationError: a motor missing or unknown, a field missing, not an integer or out
            of what the servo holds (:data:`CALIBRATION_FIELDS`), or ``range_min >=
            range_max`` (LeRobot refuses equal ends too).
    """
    if not isinstance(data, Mapping):
        raise CalibrationError(
            f"a calibration must be a JSON object keyed by motor name ({', '.join(JOINT_NAMES)})"
        )
    unknown = sorted(set(data) - set(JOINT_NAMES))
    missing = [n for n in JOINT_NAMES if n not in data]
    if unknown or missing:
        raise CalibrationError(
            f"calibration motors do not match the SO-101's: unknown {unknown or 'none'}, "
            f"missing {missing or 'none'}; expected exactly {', '.join(JOINT_NAMES)}"
        )
    return {name: _parse_motor(name, data[name]) for name in JOINT_NAMES}


def _parse_motor(name: str, entry: object) -> MotorCalibration:
    """One motor's entry of a calibration dict, checked."""
    if not isinstance(entry, Mapping) or any(f not in entry for f in CALIBRATION_FIELDS):
        raise CalibrationError(
            f"calibration of {name!r} must hold the integers {', '.join(CALIBRATION_FIELDS)}"
        )
    values = {
        f: check_count(
            entry[f],
            f"calibration of {name!r}: {f}",
            minimum=lo,
            maximum=hi,
            expected=f"an integer from {lo} to {hi}, as LeRobot writes it",
            error=CalibrationError,
        )
        for f, (lo, hi) in CALIBRATION_FIELDS.items()
    }
    cal = MotorCalibration(**values)
    if not cal.range_min < cal.range_max:
        raise CalibrationError(
            f"calibration of {name!r}: range_min = {cal.range_min}, range_max = "
            f"{cal.range_max}; expected 0 <= range_min < range_max <= {MAX_TICK}"
        )
    return cal


def load_calibration(path: str | Path) -> dict[str, MotorCalibration]:
    """Read a LeRobot calibration JSON file (e.g. ``~/.cache/huggingface/lerobot/calibration/
    teleoperators/so_leader/<id>.json``): a regular file of UTF-8 text, at most
    :data:`MAX_CALIBRATION_BYTES`.

    Raises:
        CalibrationError: the file is missing, unreadable, not a regular file, too large, not
            UTF-8 text, not JSON, or not a valid SO-101 calibration.
    """
    # empty, or a name or path too long for the file system: one line, not an OSError
    p = checked_path(path, "calibration file", error=CalibrationError)
    expected = "expected LeRobot's calibration JSON for the leader arm"
    try:
        text = read_text_limited(p, MAX_CALIBRATION_BYTES)
    except UnreadableFileError as exc:
        raise CalibrationError(
            f"cannot read the calibration file {str(p)!r} ({exc}); {expected}"
        ) from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CalibrationError(f"calibration file {str(p)!r} is not valid JSON: {exc}") from None
    except (RecursionError, ValueError) as exc:  # nested too deep, an integer too long
        reason = "it nests too deep" if isinstance(exc, RecursionError) else str(exc)
        raise CalibrationError(
            f"calibration file {str(p)!r} cannot be read as JSON: {reason}; {expected}"
        ) from None
    return parse_calibration(data)


def lerobot_calibration_path(leader_id: str) -> Path:
    """Where LeRobot keeps the leader calibration for ``leader_id`` (honours
    ``HF_LEROBOT_CALIBRATION``, ``HF_LEROBOT_HOME`` and ``HF_HOME`` as LeRobot does)."""
    root = os.environ.get("HF_LEROBOT_CALIBRATION")
    if root is None:
        home = os.environ.get("HF_LEROBOT_HOME")
        if home is None:
            hf = os.environ.get("HF_HOME", str(Path("~/.cache/huggingface")))
            home = str(Path(hf) / "lerobot")
        root = str(Path(home) / "calibration")
    return Path(root).expanduser() / "teleoperators" / LEADER_NAME / f"{leader_id}.json"


def ticks_to_pose(
    raw: Mapping[str, int | float], calibration: Mapping[str, MotorCalibration]
) -> dict[str, float]:
    """Raw servo positions -> the arm's units (LeRobot's normalisation in degrees mode).

    Body joints: ``(raw - (min + max) / 2) * 360 / 4095`` degrees (not clamped, as LeRobot);
    gripper: ``(clamp(raw, min, max) - min) / (max - min) * 100`` (``100 - x`` if
    ``drive_mode``). Returns ``{joint name: value}`` for the joints in ``raw``.
    """
    out: dict[str, float] = {}
    for name, value in raw.items():
        cal = calibration[name]
        lo, hi = cal.range_min, cal.range_max
        if name == GRIPPER:
            b = min(hi, max(lo, value))
            norm = (b - lo) / (hi - lo) * 100.0
            out[name] = 100.0 - norm if cal.drive_mode else norm
        else:
            out[name] = (value - (lo + hi) / 2.0) * 360.0 / MAX_TICK
    return out


# ---------------------------------------------------------------------------- finding a calibration
@dataclass(frozen=True)
class FoundCalibration:
    """The leader calibration to use and where it came from (``source`` None: no file was
    found, so :func:`default_calibration` is used)."""

    motors: dict[str, MotorCalibration]
    source: str | Path | None

    @property
    def note(self) -> str:
        """For the user: the file used, or that there is none and what is assumed instead."""
        if self.source is not None:
            return f"calibration: {self.source}"
        return (
            "no calibration file: assuming LeRobot's calibration (middle = 2047 ticks) and "
            "guessing the gripper's range; pass --calibration for exact values"
        )


def find_calibration(
    path: str | Path | None = None, leader_id: str | None = None
) -> FoundCalibration:
    """The calibration at ``path``; else LeRobot's file for ``leader_id`` if it exists; else
    :func:`default_calibration` (LeRobot's middle = 2047 ticks, the gripper's range guessed).

    Raises:
        CalibrationError: the file at ``path`` (or LeRobot's file) cannot be read or is invalid;
            ``path`` or ``leader_id`` is empty.
    """
    if path is not None:  # an empty path is refused, not taken for "none given"
        return FoundCalibration(load_calibration(path), path)
    if leader_id is not None and not str(leader_id).strip():
        raise CalibrationError(
            "the leader id is empty; expected the id whose LeRobot calibration file to use "
            "(as given to lerobot-calibrate --teleop.id)"
        )
    if leader_id and lerobot_calibration_path(leader_id).is_file():
        found = lerobot_calibration_path(leader_id)
        return FoundCalibration(load_calibration(found), found)
    return FoundCalibration(default_calibration(), None)
