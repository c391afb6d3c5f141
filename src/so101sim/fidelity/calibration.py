"""A recording's units: LeRobot's range mode (−100..100 of each joint's calibrated range) made
degrees, with LeRobot's calibration JSON (exact) or a typical arm's calibration (a guess), and
where LeRobot keeps that JSON (:func:`lerobot_calibration_path`).

LeRobot 0.6 keeps a follower's calibration at
``$HF_LEROBOT_CALIBRATION/robots/so_follower/<id>.json``; ``HF_LEROBOT_CALIBRATION`` defaults to
``$HF_LEROBOT_HOME/calibration``, ``HF_LEROBOT_HOME`` to ``$HF_HOME/lerobot`` and ``HF_HOME`` to
``$XDG_CACHE_HOME/huggingface`` (``~/.cache/huggingface``). Older releases used
``robots/so101_follower/<id>.json``; both are looked for.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

import numpy as np

from ..errors import CalibrationError
from ..units import JOINT_NAMES
from .logdata import LogError, read_small

__all__ = [
    "RANGE_GUESS",
    "applied_calibration",
    "calibration_maps",
    "from_log",
    "lerobot_calibration_dir",
    "lerobot_calibration_path",
    "range_guess",
    "to_arm_units",
    "to_log",
]


def applied_calibration(
    cal: dict[str, dict[str, float]], degrees_guessed: bool
) -> dict[str, dict[str, float]]:
    """A profile's ``[calibration]`` where it applies: to readings whose degrees are a guess
    (range mode without LeRobot's calibration JSON), or are being fitted; exact degrees (a
    calibration JSON, or a degrees recording) are taken as given (``{}``)."""
    return cal if degrees_guessed else {}


def calibration_maps(cal: dict[str, dict[str, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Per joint (arm order) a reading's ``scale`` and ``offset`` from a profile's
    ``[calibration]`` (1 and 0 where it says nothing; the gripper always)."""
    scale, offset = np.ones(len(JOINT_NAMES)), np.zeros(len(JOINT_NAMES))
    for j, name in enumerate(JOINT_NAMES[:5]):
        scale[j] = cal.get(name, {}).get("scale", 1.0)
        offset[j] = cal.get(name, {}).get("offset", 0.0)
    return scale, offset


def from_log(values: np.ndarray, cal: dict[str, dict[str, float]]) -> np.ndarray:
    """Readings (arm units, ``(..., 6)``) made angles with a profile's ``[calibration]`` (a
    reading is ``scale`` × angle + ``offset``); the gripper as it is."""
    scale, offset = calibration_maps(cal)
    return (values - offset) / scale


def to_log(values: np.ndarray, cal: dict[str, dict[str, float]]) -> np.ndarray:
    """Angles (arm units) made readings: the inverse of :func:`from_log`."""
    scale, offset = calibration_maps(cal)
    return values * scale + offset


TICKS_PER_TURN = 4096
DEGREE_TICKS = 4095  # LeRobot's degrees: (ticks - middle) * 360 / 4095
PLACED_TICKS = 2047
"""What a servo reads at the pose the arm was placed in for ``lerobot-calibrate`` (LeRobot
writes its homing offset so that pose reads ``int(4095 / 2)``)."""
ROBOT_FOLDERS = ("so_follower", "so101_follower")
"""The folders under ``robots/`` where LeRobot keeps an SO-101 follower's calibration (0.6,
then older releases)."""


def lerobot_calibration_dir() -> Path:
    """LeRobot's calibration folder, from the same environment variables LeRobot reads."""
    if os.environ.get("HF_LEROBOT_CALIBRATION"):
        return Path(os.environ["HF_LEROBOT_CALIBRATION"]).expanduser()
    if os.environ.get("HF_LEROBOT_HOME"):
        return Path(os.environ["HF_LEROBOT_HOME"]).expanduser() / "calibration"
    hf_home = os.environ.get("HF_HOME") or str(
        Path(os.environ.get("XDG_CACHE_HOME") or "~/.cache") / "huggingface"
    )
    return Path(hf_home).expanduser() / "lerobot" / "calibration"


def lerobot_calibration_path(robot_id: str) -> Path:
    """The calibration JSON LeRobot wrote for the follower ``robot_id``.

    Raises:
        CalibrationError: the id is not a plain name, or no file of that id is there.
    """
    if not re.fullmatch(r"[A-Za-z0-9_.\-]{1,128}", robot_id or "") or robot_id in (".", ".."):
        raise CalibrationError(
            f"--robot-id {robot_id!r} is not a robot id; expected the name given to LeRobot as "
            "--robot.id (letters, digits, '_', '-', '.')"
        )
    root = lerobot_calibration_dir() / "robots"
    tried = [root / folder / f"{robot_id}.json" for folder in ROBOT_FOLDERS]
    for path in tried:
        if path.exists():
            return path
    raise CalibrationError(
        f"no LeRobot calibration for robot id {robot_id!r}: looked for {str(tried[0])!r} and "
        f"{str(tried[1])!r}; expected the id the follower was calibrated with (or give the file "
        "with --calibration)"
    )


GUESSED_CALIBRATION = (
    "the body joints look range-normalised (-100..100) and no --calibration was given"
)
"""How a warning about a range-mode recording's guessed calibration begins."""


def to_arm_units(
    act: np.ndarray,
    obs: np.ndarray,
    mode: str,
    calibration: str | Path | None,
    warnings: list[str],
) -> tuple[np.ndarray, np.ndarray, bool, np.ndarray | None]:
    """Commands and measurements (``(n, 6)`` each, as recorded) in arm units (degrees, the
    gripper 0–100), by ``mode`` (``auto``, ``degrees``, ``range``; module docstring), whether
    the body joints' degrees are a guess (range mode without a calibration JSON:
    :data:`RANGE_GUESS`), and in range mode where the ends of the calibration sweep (−100 and
    100: the follower's stops) lie in arm units (``(2, 6)``, NaN for the gripper; None in
    degrees)."""
    body = np.abs(np.concatenate([act[:, :5], obs[:, :5]]))
    beyond = bool(body.max(initial=0.0) > 100.0 + 1e-6)
    if mode == "range" and beyond:
        raise LogError(
            "units = range, but a body joint reads beyond ±100; expected range-mode data "
            "(-100..100), or units = degrees"
        )
    if calibration is not None and beyond:
        raise LogError(
            "a body joint reads beyond ±100, so the recording is in degrees, but a calibration "
            "was given; expected range-mode data (-100..100) with --calibration / --robot-id, "
            "or degrees without"
        )
    if mode == "degrees" or (mode == "auto" and beyond):
        return act, obs, False, None
    if mode == "auto" and calibration is None:
        warnings.append(
            "every body joint reads within ±100: taken as LeRobot's range mode (-100..100); "
            "if the follower recorded degrees (use_degrees=True) give --units degrees"
        )
    if calibration is not None:
        scale, offset = calibration_of(Path(calibration).expanduser())
    else:
        scale, offset = range_guess()
        warnings.append(
            f"{GUESSED_CALIBRATION}: "
            "mapped with a typical SO-101's calibration (approximate, a few degrees per joint; "
            "give LeRobot's calibration JSON (--calibration or --robot-id) for exact degrees, or "
            "let `so101sim fit` estimate each joint's offset and scale)"
        )
    act, obs = act.copy(), obs.copy()
    for values in (act, obs):
        values[:, :5] = values[:, :5] * scale + offset
    ends = np.full((2, len(JOINT_NAMES)), np.nan)
    ends[:, :5] = np.sort(np.stack([-100.0 * scale + offset, 100.0 * scale + offset]), axis=0)
    return act, obs, calibration is None, ends


RANGE_GUESS: dict[str, tuple[float, float]] = {
    "shoulder_pan": (1.13, 0.0),
    "shoulder_lift": (1.033, -2.6),
    "elbow_flex": (0.969, -5.7),
    "wrist_flex": (1.015, -4.0),
    "wrist_roll": (360.0 / 200.0 * (TICKS_PER_TURN - 1) / TICKS_PER_TURN, 0.0),
}
"""A typical SO-101 follower's range mode: joint angle (degrees, the model's zero being the
pose LeRobot's calibration asks the arm to be placed in) = ``scale`` · reading + ``offset``, per
body joint. From 20 public LeRobot calibration files of real followers (docs/fidelity.md,
"Range mode without a calibration file"): ``scale`` is the mean swept range / 200, ``offset``
the mean distance of the swept range's middle from the placed pose (pan's +0.6 taken as 0).
wrist_roll is exact: LeRobot ≥ 0.4 does not sweep it and writes 0..4095, one turn."""


def range_guess() -> tuple[np.ndarray, np.ndarray]:
    """Per body joint (arm order) the ``scale`` and ``offset`` of :data:`RANGE_GUESS`."""
    pairs = [RANGE_GUESS[name] for name in JOINT_NAMES[:5]]
    return np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])


def calibration_of(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Each body joint's ``scale`` (degrees per range unit) and ``offset`` (degrees) from
    LeRobot's calibration JSON: a range value v is ticks ``min + (v + 100) / 200 · (max − min)``
    (v negated for a motor with ``drive_mode`` 1), and the angle is ticks from
    :data:`PLACED_TICKS` (the pose the arm was placed in when calibrated: the model's zero)
    times 360/4095, so ``± v · (max − min) / 200 · 360 / 4095 + ((min + max) / 2 − 2047) ·
    360 / 4095``. (LeRobot's own ``use_degrees`` counts from the swept range's middle instead,
    dropping the second term.)"""
    what = "calibration file"
    if not path.exists():
        raise CalibrationError(
            f"calibration file {str(path)!r} does not exist; expected LeRobot's calibration "
            "JSON (e.g. ~/.cache/huggingface/lerobot/calibration/robots/so_follower/<id>.json)"
        )
    try:
        cal = json.loads(read_small(path, what, CalibrationError))
    except ValueError as exc:
        raise CalibrationError(f"calibration file {str(path)!r} cannot be read: {exc}") from exc
    scale, offset = np.empty(5), np.empty(5)
    for i, name in enumerate(JOINT_NAMES[:5]):
        m = cal.get(name) if isinstance(cal, dict) else None
        try:
            lo, hi = float(m["range_min"]), float(m["range_max"])  # type: ignore[index]
            flip = int(m.get("drive_mode", 0) or 0)  # type: ignore[union-attr]
        except (TypeError, KeyError, ValueError, AttributeError):
            raise CalibrationError(
                f"calibration file {str(path)!r} has no range_min/range_max for {name!r}; "
                "expected LeRobot's calibration JSON with every motor"
            ) from None
        if not (0 <= lo < hi <= TICKS_PER_TURN) or not math.isfinite(hi) or flip not in (0, 1):
            raise CalibrationError(
                f"calibration file {str(path)!r}: {name} range {lo}..{hi} (drive_mode {flip}) is "
                f"invalid; expected 0 <= range_min < range_max <= {TICKS_PER_TURN}, drive_mode "
                "0 or 1"
            )
        scale[i] = (-1.0 if flip else 1.0) * (hi - lo) / 200.0 * 360.0 / DEGREE_TICKS
        offset[i] = ((lo + hi) / 2.0 - PLACED_TICKS) * 360.0 / DEGREE_TICKS
    return scale, offset
