"""LeRobot plugin for so101sim: LeRobot's own commands drive the simulated SO-101.

Installed, it is imported by LeRobot's ``register_third_party_plugins()`` (its distribution
name starts with ``lerobot_robot_`` and equals this package's name), which registers:

- ``--robot.type=so101_sim``: :class:`SO101Sim` (config :class:`SO101SimConfig`);
- ``--robot.cameras='{front: {type: so101_sim}, wrist: {type: so101_sim}}'``: simulated
  cameras (:class:`SO101SimCamera`, config :class:`SO101SimCameraConfig`);
- ``--teleop.type=so101_sim_motion``: :class:`SO101SimMotion`, a teleoperator that plays a
  motion file (config :class:`SO101SimMotionConfig`);
- ``--teleop.type=so101_sim_expert``: :class:`SO101SimExpert`, a task's scripted expert driving
  the ``so101_sim`` robot's scene (config :class:`SO101SimExpertConfig`).

LeRobot finds each device class in this package by its config's name (``FooConfig`` ->
``Foo``), so all of them are imported here.
"""

from .camera import SO101SimCamera
from .config_so101sim import (
    CAMERA_TYPE,
    EXPERT_TELEOP_TYPE,
    MOTION_TELEOP_TYPE,
    ROBOT_TYPE,
    SO101SimCameraConfig,
    SO101SimConfig,
    SO101SimExpertConfig,
    SO101SimMotionConfig,
)
from .errors import DeviceAlreadyConnectedError, DeviceNotConnectedError, SimCameraError
from .expert import SO101SimExpert, TakeRecord
from .motion import SO101SimMotion
from .robot import SO101Sim

__version__ = "0.1.0"

__all__ = [
    "CAMERA_TYPE",
    "EXPERT_TELEOP_TYPE",
    "MOTION_TELEOP_TYPE",
    "ROBOT_TYPE",
    "DeviceAlreadyConnectedError",
    "DeviceNotConnectedError",
    "SO101Sim",
    "SO101SimCamera",
    "SO101SimCameraConfig",
    "SO101SimConfig",
    "SO101SimExpert",
    "SO101SimExpertConfig",
    "SO101SimMotion",
    "SO101SimMotionConfig",
    "SimCameraError",
    "TakeRecord",
]
