"""The plugin's configurations, registered with LeRobot's draccus registries on import.

- ``--robot.type=so101_sim``: :class:`SO101SimConfig` (the simulated SO-101 follower);
- ``--robot.cameras='{front: {type: so101_sim}}'``: :class:`SO101SimCameraConfig` (a camera of
  that robot's scene; the dict key names it: ``front`` and ``wrist`` are presets);
- ``--teleop.type=so101_sim_motion``: :class:`SO101SimMotionConfig` (plays a motion file);
- ``--teleop.type=so101_sim_expert``: :class:`SO101SimExpertConfig` (a task's scripted expert
  on the ``so101_sim`` robot's scene).

LeRobot finds each device class by name, ``FooConfig`` -> ``Foo``, in this module's package.
Every value is checked when the config is made (so a bad command line fails before anything
connects), by so101sim's own checks.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from lerobot.cameras import CameraConfig
from lerobot.robots import RobotConfig
from lerobot.teleoperators import TeleoperatorConfig

from so101sim import load_motion
from so101sim.errors import RobotConfigError
from so101sim.model import arm_units, load_model
from so101sim.robot import RobotMode, SO101SimFollowerConfig
from so101sim.units import STARTING_POSE
from so101sim.validation import check_choice, check_count, check_range

ROBOT_TYPE = "so101_sim"
"""``--robot.type``, and the robot's ``name``: the ``robot_type`` stored in its datasets."""
CAMERA_TYPE = "so101_sim"
MOTION_TELEOP_TYPE = "so101_sim_motion"
EXPERT_TELEOP_TYPE = "so101_sim_expert"
EXPERT_TASKS = {
    "pick_cube": 8.0,
    "cube_to_bowl": 12.0,
    "lift_cylinder": 8.0,
    "lift_sphere": 8.0,
    "lift_mesh": 8.0,
    "push": 10.0,
    "stack": 12.0,
}
"""The scripted experts' tasks (each also a ``--robot.scene`` preset) and their time limits
(seconds, those of ``so101sim/PickCube-v0`` and ``so101sim/CubeToBowl-v0``)."""
MAX_EPISODE_S = 3600.0
MAX_FPS = 1000


def check_fps(value: object, what: str = "fps") -> int:
    """A control rate: a whole number of frames per second from 1 to :data:`MAX_FPS`."""
    fps = check_range(value, what, low=1, high=MAX_FPS, unit=" Hz", error=RobotConfigError)
    if fps != int(fps):
        raise RobotConfigError(f"{what} = {value!r} is invalid; expected a whole number of Hz")
    return int(fps)


@CameraConfig.register_subclass(CAMERA_TYPE)
@dataclass(kw_only=True)
class SO101SimCameraConfig(CameraConfig):
    """A simulated camera of the ``so101_sim`` robot. Its name (the key in
    ``--robot.cameras``) picks a preset (``front``, ``wrist``) whose fields given here
    change it; any other name needs ``pos`` and ``lookat``.

    ``pos``/``lookat``/``up``: metres (3 numbers) in the frame of ``body`` (``world`` or
    ``gripper``); ``fovy``: vertical field of view in degrees; ``quality``: ``auto`` (draft
    meshes when OpenGL renders on the CPU, full ones on a GPU), ``draft`` or ``full``.
    """

    fps: int | None = 30
    width: int | None = 640
    height: int | None = 480
    pos: list[float] | None = None
    lookat: list[float] | None = None
    up: list[float] | None = None
    fovy: float | None = None
    body: str | None = None
    quality: str = "auto"

    def sim_settings(self) -> dict[str, Any]:
        """The fields given, as so101sim's camera settings (``so101sim.robot.cameras``)."""
        names = ("fps", "width", "height", "pos", "lookat", "up", "fovy", "body", "quality")
        return {n: getattr(self, n) for n in names if getattr(self, n) is not None}


@RobotConfig.register_subclass(ROBOT_TYPE)
@dataclass(kw_only=True)
class SO101SimConfig(RobotConfig):
    """The simulated SO-101 follower (``--robot.type=so101_sim``).

    The first fields are those of LeRobot's ``so101_follower`` that mean something to a
    simulated arm (``port`` is accepted and ignored, so a real arm's command line runs with
    only ``--robot.type`` changed); the rest are the simulation's.
    """

    port: str | None = None
    """Ignored (there is no serial port): accepted so a real follower's flags still parse."""
    disable_torque_on_disconnect: bool = True
    max_relative_target: float | dict[str, float] | None = None
    cameras: dict[str, CameraConfig] = field(default_factory=dict)
    use_degrees: bool = True
    mode: RobotMode = "realtime"
    """``realtime`` (default): the physics runs on its own at ``speed`` x real time, as a real
    arm moves while the loop waits. ``lockstep``: simulated time advances only with the loop,
    exactly ``1/fps`` per ``send_action``, so it matches the dataset's timestamps however
    slowly the machine renders."""
    fps: int = 30
    """Lockstep: the rate of the loop driving the robot (``--fps`` / ``--dataset.fps``)."""
    speed: float = 1.0
    viewer: bool = False
    model: str | None = None
    arm: str | None = None
    """The arm profile (``--robot.arm=``): the servos' model, ``sts3215`` (None: the default,
    fitted on a real STS3215: it sags under load and lags as the real arm does), ``official``
    (the vendored model's ideal position actuators), ``sts3215-12v``, or a TOML file written
    by ``so101sim fit``."""
    scene: str | None = None
    """A table-top scene preset (``pick_cube``, ``cube_to_bowl``): its table and objects are
    added to the simulated arm's scene. None: the arm alone."""
    initial_pose: dict[str, float] = field(default_factory=lambda: dict(STARTING_POSE))
    gripper_torque_fraction: float = 0.5
    randomize: str = "none"
    """Domain randomisation of the ``scene`` at each new take: ``none``, ``light`` or ``full``
    (so101sim's presets), or one with families changed (``light,textures=0.5``); the same draws
    as ``gym.make(..., randomize=...)`` for the same seed."""
    environment_state: bool = False
    """Also observe the scene's objects: ``"environment_state"`` in each observation, each
    object's position (m) and quaternion (w, x, y, z), 7 numbers per object, float32, as the
    env plugin's ``observation.environment_state``. Needs ``scene``. (``lerobot-record`` 0.6
    stores every non-image feature of a robot in ``observation.state``, so it cannot record it
    as a separate feature: ``so101sim dataset --environment-state`` does.)"""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.fps = check_fps(self.fps)
        if not isinstance(self.environment_state, bool):
            raise RobotConfigError(
                f"environment_state is {self.environment_state!r}; expected true or false"
            )
        if self.environment_state and self.scene is None:
            raise RobotConfigError(
                "environment_state needs a scene with objects; expected --robot.scene=pick_cube "
                "or cube_to_bowl with --robot.environment_state=true"
            )
        self.follower_config()  # every field checked now, by so101sim

    def follower_config(self) -> SO101SimFollowerConfig:
        """The so101sim follower's config. In lockstep mode the plugin advances time itself
        (exactly ``1/fps`` per action, without rounding drift), so the follower advances none.

        Raises:
            RobotConfigError: a value so101sim cannot use (the message names the field).
        """
        for name, cam in self.cameras.items():
            if not isinstance(cam, SO101SimCameraConfig):
                raise RobotConfigError(
                    f"camera {name!r} has type {getattr(cam, 'type', cam)!r}; the simulated "
                    f"robot's cameras render its scene: use type {CAMERA_TYPE!r}"
                )
        return SO101SimFollowerConfig(
            id=self.id,
            max_relative_target=self.max_relative_target,
            disable_torque_on_disconnect=self.disable_torque_on_disconnect,
            use_degrees=self.use_degrees,
            cameras={n: c.sim_settings() for n, c in self.cameras.items()},  # type: ignore[attr-defined]
            model=self.model,
            arm=self.arm,
            scene=self.scene,
            viewer=self.viewer,
            mode=self.mode,
            initial_pose=dict(self.initial_pose),
            speed=self.speed,
            lockstep_action_seconds=0.0,
            lockstep_observation_seconds=0.0,
            gripper_torque_fraction=self.gripper_torque_fraction,
            randomize=self.randomize,
        )


@TeleoperatorConfig.register_subclass(MOTION_TELEOP_TYPE)
@dataclass(kw_only=True)
class SO101SimMotionConfig(TeleoperatorConfig):
    """A teleoperator without hardware (``--teleop.type=so101_sim_motion``): it plays a TOML
    motion file (``so101sim run``'s format) as the leader arm's positions.

    Each ``get_action()`` moves the motion on by ``1/fps`` seconds: give the loop's rate
    (``--dataset.fps``, ``--fps``; 30 by default in both). With ``loop`` the motion starts
    again when it ends (a motion that ends where it starts, as the lab's does, loops
    smoothly); each pass (a "take") may be varied at random: every pose it moves to is offset
    by up to ``variation`` (degrees; gripper 0..100 units) per joint, drawn anew for each take
    from ``seed``.
    """

    motion: str | None = None
    """TOML motion file; default: the lab motion (rest -> zeros -> rest, 6 s)."""
    loop: bool = True
    fps: int = 30
    variation: float = 0.0
    seed: int | None = None
    model: str | None = None
    """MJCF file whose joint limits the motion is checked against (default: the shipped one)."""

    def __post_init__(self) -> None:
        self.fps = check_fps(self.fps)
        self.variation = check_range(
            self.variation, "variation", low=0.0, high=180.0, unit=" deg", error=RobotConfigError
        )
        if self.motion is not None:  # a bad file fails now, before anything connects
            load_motion(self.motion, units=arm_units(load_model(self.model)))


@TeleoperatorConfig.register_subclass(EXPERT_TELEOP_TYPE)
@dataclass(kw_only=True)
class SO101SimExpertConfig(TeleoperatorConfig):
    """A task's scripted expert as the teleoperator (``--teleop.type=so101_sim_expert``): it
    drives the ``so101_sim`` robot whose scene is the task's (``--robot.scene=<task>``,
    ``--robot.mode=lockstep``), planning from the objects' real poses in that robot's
    simulation.

    One *take* is one run of the expert from a new start: the arm at its start pose and the
    objects at poses drawn from ``seed + take`` (as ``so101sim/PickCube-v0``'s
    ``reset(seed=seed + take)`` draws them). A take lasts ``(episode_time_s + reset_time_s) *
    fps`` calls of ``get_action()``: give ``--dataset.episode_time_s``,
    ``--dataset.reset_time_s`` and ``--dataset.fps`` (the same numbers), and each recorded
    episode is one take.
    """

    task: str = "pick_cube"
    """``pick_cube`` or ``cube_to_bowl``: also the robot's ``--robot.scene``."""
    seed: int = 0
    """Take ``k`` draws its start from ``seed + k``."""
    fps: int = 30
    """The loop's rate (``--dataset.fps``): the expert moves on ``1/fps`` s per call."""
    episode_time_s: float | None = None
    """``--dataset.episode_time_s``; None: the task's time limit (8 s, 12 s)."""
    reset_time_s: float = 0.0
    """``--dataset.reset_time_s``: its calls belong to the take before it (the expert holds
    still). 0 is recommended."""

    def __post_init__(self) -> None:
        check_choice(self.task, "task", EXPERT_TASKS, error=RobotConfigError)
        self.seed = check_count(self.seed, "seed", maximum=2**62, error=RobotConfigError)
        self.fps = check_fps(self.fps)
        if self.episode_time_s is None:
            self.episode_time_s = EXPERT_TASKS[self.task]
        self.episode_time_s = check_range(
            self.episode_time_s, "episode_time_s", low=0.0, high=MAX_EPISODE_S, low_open=True,
            unit=" s", error=RobotConfigError,
        )  # fmt: skip
        self.reset_time_s = check_range(
            self.reset_time_s, "reset_time_s", low=0.0, high=MAX_EPISODE_S, unit=" s",
            error=RobotConfigError,
        )  # fmt: skip
        if self.take_calls < 1:
            raise RobotConfigError(
                f"episode_time_s + reset_time_s = {self.episode_time_s + self.reset_time_s:g} s "
                f"at {self.fps} fps is less than one frame; expected at least 1/fps"
            )

    @property
    def take_calls(self) -> int:
        """Calls of ``get_action()`` in one take: ``(episode_time_s + reset_time_s) * fps``."""
        return round((float(self.episode_time_s or 0.0) + self.reset_time_s) * self.fps)


__all__ = [
    "CAMERA_TYPE",
    "EXPERT_TASKS",
    "EXPERT_TELEOP_TYPE",
    "MOTION_TELEOP_TYPE",
    "ROBOT_TYPE",
    "SO101SimCameraConfig",
    "SO101SimConfig",
    "SO101SimExpertConfig",
    "SO101SimMotionConfig",
]
