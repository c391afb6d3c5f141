"""Configuration of the simulated follower: :class:`SO101SimFollowerConfig` and its checks.

Every field is checked when the config is made, so a bad value fails at the line that wrote
it (a :class:`~so101sim.errors.RobotConfigError` naming the field and the valid values), not
later in ``connect()`` or in the physics thread.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np

from ..errors import CameraError, JointNameError, RobotConfigError, So101SimError
from ..model.arm import load_profile
from ..scenes import SCENE_PRESETS, randomization
from ..sim.stepping import MAX_PLAYBACK_SPEED, MIN_PLAYBACK_SPEED
from ..units import JOINT_NAMES, STARTING_POSE, normalize_joint_name, parse_pose
from ..validation import (
    MAX_DURATION_S,
    check_choice,
    check_positive,
    check_range,
    is_real,
)
from ..viewer import VIEWER_QUALITIES, ViewerQuality
from .cameras import parse_cameras

RobotMode = Literal["realtime", "lockstep"]
"""How the follower's simulated time advances: in the background at ``speed`` x real time, or
only through ``step()`` and the fixed amounts of the config (deterministic)."""
MODES: tuple[str, ...] = get_args(RobotMode)
GRIPPER_TORQUE_FRACTION = 0.5
"""Share of the actuator's force range the gripper may use: LeRobot's ``configure()`` writes
``Max_Torque_Limit = 500`` (of 1000) to the real gripper (with ``Protection_Current = 250`` and
``Overload_Torque = 25``), so the simulated gripper gets 50 % of the model's force range."""


def relative_caps(max_relative_target: object) -> np.ndarray | None:
    """``max_relative_target`` as six caps in :data:`JOINT_NAMES` order (``inf``: uncapped),
    or None when there is no cap.

    Accepts a positive number (int or float: LeRobot rejects an int, this does not) applying to
    every joint, or a dict from joint name (``"elbow_flex"`` or ``"elbow_flex.pos"``) to a
    positive number; joints a dict leaves out are not capped.

    Raises:
        RobotConfigError: a cap that is not a finite number > 0, or a dict key that is not one
            of the six joints (the message lists them).
    """
    if max_relative_target is None:
        return None
    caps = np.full(len(JOINT_NAMES), math.inf)
    if isinstance(max_relative_target, Mapping):
        for key, value in max_relative_target.items():
            i = JOINT_NAMES.index(_cap_joint(key))
            caps[i] = check_positive(value, f"max_relative_target[{key!r}]", error=RobotConfigError)
        return caps
    if is_real(max_relative_target):
        caps[:] = check_positive(max_relative_target, "max_relative_target", error=RobotConfigError)
        return caps
    raise RobotConfigError(
        f"max_relative_target = {max_relative_target!r} is invalid; expected None, a number > 0 "
        f"(degrees; 0..100 units for the gripper), or a dict from joint name to such a number"
    )


def _cap_joint(key: object) -> str:
    try:
        return normalize_joint_name(key)
    except JointNameError:
        raise RobotConfigError(
            f"max_relative_target has an unknown joint {key!r}; valid keys are "
            f"{', '.join(JOINT_NAMES)} (or the same with '.pos')"
        ) from None


def _check_seconds(value: object, what: str) -> float:
    """Lockstep seconds: a finite number >= 0, at most a day."""
    return check_positive(
        value,
        what,
        allow_zero=True,
        maximum=MAX_DURATION_S,
        unit=" s",
        error=RobotConfigError,
    )


RANDOMIZE_CHOICES = ("none", "light", "full")
"""The domain randomisation presets (:data:`so101sim.scenes.RANDOMIZE_PRESETS`)."""


@dataclass(kw_only=True)
class SO101SimFollowerConfig:
    """Configuration of :class:`~so101sim.robot.SO101SimFollower`.

    The first fields are LeRobot's ``SO101FollowerConfig`` fields that mean something here
    (``port``, the PID coefficients and ``num_read_retries`` do not); the rest are the sim's.
    """

    id: str | None = None
    """Name of this arm, as in LeRobot (shown in logs and ``str(robot)``)."""
    max_relative_target: float | int | dict[str, float] | None = None
    """Largest step from the present position a goal may ask for: one number for every joint,
    or a dict per joint (degrees; gripper in 0..100 units). None: no cap."""
    disable_torque_on_disconnect: bool = True
    """Accepted for LeRobot compatibility. The sim's physics stops at ``disconnect()``, so the
    arm neither falls (torque off) nor holds (torque on); it freezes until the next connect."""
    use_degrees: bool = True
    """Body joints in degrees. Only True is supported (LeRobot's -100..100 mode is not)."""
    cameras: dict[str, Any] = field(default_factory=dict)
    """Simulated cameras by name: ``{}`` or None for a preset (``"front"``, ``"wrist"``), or
    a dict of :data:`~so101sim.robot.cameras.CAMERA_KEYS` (``width``, ``height``, ``fps``,
    ``pos``, ``lookat``, ``fovy``, ``body``, ``quality``...). Their frames are in
    ``get_observation()`` under the camera's name: see :mod:`so101sim.robot.cameras`."""
    model: str | Path | None = None
    """MJCF file to load instead of the shipped ``scene.xml``."""
    arm: str | None = None
    """The arm profile: the servos' actuator model (:mod:`so101sim.model.arm`), a shipped name
    (``"sts3215"``, ``"official"``, ``"sts3215-12v"``) or a TOML file (e.g. written by
    ``so101sim fit``). None: the default, ``"sts3215"`` (the model that predicts a real
    STS3215 best; ``"official"`` is the vendored model's ideal position actuators)."""
    scene: str | None = None
    """A table-top scene preset of :mod:`so101sim.scenes` (``"pick_cube"``,
    ``"cube_to_bowl"``): its table and objects (at their nominal poses) are added to the
    follower's model. None: the arm alone, as the shipped scene has it."""
    viewer: bool = False
    """Open MuJoCo's passive viewer at ``connect()`` (needs a display)."""
    viewer_quality: ViewerQuality = "auto"
    """What the viewer draws: ``"draft"`` (simplified meshes, no shadows: fast on a computer
    without a GPU), ``"full"`` (the model's meshes), or ``"auto"`` (draft when OpenGL renders on
    the CPU, e.g. in a VM, WSL or a remote desktop; full on a GPU)."""
    mode: RobotMode = "realtime"
    """``"realtime"``: physics runs in the background at ``speed`` × real time.
    ``"lockstep"``: simulated time advances only through ``step()`` and the fixed amounts
    below, deterministically."""
    initial_pose: dict[str, float] = field(default_factory=lambda: dict(STARTING_POSE))
    """Pose the arm starts in (joint names or LeRobot keys; joints left out take
    :data:`~so101sim.units.STARTING_POSE`'s value)."""
    speed: float = 1.0
    """Real-time mode: simulated seconds per wall-clock second (from
    :data:`~so101sim.sim.stepping.MIN_PLAYBACK_SPEED` to
    :data:`~so101sim.sim.stepping.MAX_PLAYBACK_SPEED`)."""
    lockstep_action_seconds: float = 0.02
    """Lockstep mode: simulated seconds each ``send_action`` advances (0.02: a 50 Hz loop)."""
    lockstep_observation_seconds: float = 0.0
    """Lockstep mode: simulated seconds each ``get_observation`` advances."""
    gripper_torque_fraction: float = GRIPPER_TORQUE_FRACTION
    """Share of the gripper actuator's force range the gripper may use (0 < f <= 1)."""
    randomize: str = "none"
    """Domain randomisation of the ``scene`` at each reset of a take
    (:mod:`so101sim.scenes.randomize`): ``"none"``, ``"light"`` or ``"full"``, or a preset with
    families changed (``"light,textures=0.5"``), drawn from the take's seed after the objects'
    start poses, as the environments draw it."""

    def __new__(cls, *args: Any, **kwargs: Any) -> SO101SimFollowerConfig:
        # Before the dataclass's __init__, so a field it lacks (a real arm's ``port``) is a
        # RobotConfigError naming the fields, not a bare TypeError.
        names = [f.name for f in fields(cls) if f.init]
        unknown = [key for key in kwargs if key not in names]
        if args or unknown:
            what = f"has no field {unknown[0]!r}" if unknown else "takes keyword arguments only"
            if "port" in unknown:
                what += " (the simulated arm has no serial port: leave it out)"
            raise RobotConfigError(f"{cls.__name__} {what}; its fields are {', '.join(names)}")
        return super().__new__(cls)

    def __post_init__(self) -> None:
        if self.use_degrees is not True:
            raise RobotConfigError(
                "use_degrees=False (LeRobot's -100..100 range for the body joints) is not "
                "supported by the simulated follower; it reports body joints in degrees only: "
                "set use_degrees=True"
            )
        try:  # cameras: checked here, built at connect (so101sim.robot.cameras)
            parse_cameras(self.cameras)
        except CameraError as exc:
            raise RobotConfigError(f"cameras: {exc}") from None
        check_choice(self.mode, "mode", MODES, error=RobotConfigError)
        if self.arm is not None:
            try:
                load_profile(self.arm)
            except So101SimError as exc:
                raise RobotConfigError(f"arm: {exc}") from None
        if self.scene is not None:
            check_choice(self.scene, "scene", SCENE_PRESETS, error=RobotConfigError)
        try:
            randomization(self.randomize)  # a preset, or a preset with families changed
        except So101SimError as exc:
            raise RobotConfigError(str(exc)) from None
        if self.randomize != "none" and self.scene is None:
            raise RobotConfigError(
                f"randomize={self.randomize!r} needs a scene; expected scene='pick_cube' or "
                f"'cube_to_bowl' (LeRobot: --robot.scene=...)"
            )
        check_choice(
            self.viewer_quality, "viewer_quality", VIEWER_QUALITIES, error=RobotConfigError
        )
        relative_caps(self.max_relative_target)
        try:
            parse_pose(self.initial_pose, partial=True)
        except So101SimError as exc:
            raise RobotConfigError(f"initial_pose is invalid: {exc}") from None
        # the range the physics thread's Pacer accepts (checked here, not in the thread)
        self.speed = check_range(
            self.speed,
            "speed",
            low=MIN_PLAYBACK_SPEED,
            high=MAX_PLAYBACK_SPEED,
            error=RobotConfigError,
        )
        self.lockstep_action_seconds = _check_seconds(
            self.lockstep_action_seconds, "lockstep_action_seconds"
        )
        self.lockstep_observation_seconds = _check_seconds(
            self.lockstep_observation_seconds, "lockstep_observation_seconds"
        )
        self.gripper_torque_fraction = check_range(
            self.gripper_torque_fraction,
            "gripper_torque_fraction",
            low=0.0,
            high=1.0,
            low_open=True,
            error=RobotConfigError,
        )


__all__ = [
    "GRIPPER_TORQUE_FRACTION",
    "MODES",
    "VIEWER_QUALITIES",
    "SO101SimFollowerConfig",
    "relative_caps",
]
