"""A LeRobot-style robot on the simulation: ``SO101SimFollower`` and the leader-arm teleop.

Modules: :mod:`.follower`,
:mod:`.config`, :mod:`.actions`, :mod:`.cameras`, :mod:`.threads`, :mod:`.scene`, :mod:`.ee`
(end-effector actions), :mod:`.helpers`, :mod:`.teleop`, :mod:`.calibration` (the leader's),
:mod:`.policycheck` (``so101sim policy-check``).

May import: ``so101sim.recording``, ``so101sim.viewer``, ``so101sim.scenes``,
``so101sim.motion``, ``so101sim.sim``, ``so101sim.kinematics``, ``so101sim.model``,
``so101sim.units`` and the base modules; never LeRobot itself (the plugins in ``plugins/``
wrap it).
"""

from .cameras import SimCamera
from .config import RobotMode
from .follower import (
    GRIPPER_TORQUE_FRACTION,
    MODES,
    VIEWER_QUALITIES,
    SO101SimFollower,
    SO101SimFollowerConfig,
    parse_action,
    relative_caps,
)
from .helpers import MOTOR_KEYS
from .policycheck import check_policy, training_fps
from .scene import RobotScene, find_follower, robot_scene, scene_resets, when_connected

__all__ = [
    "GRIPPER_TORQUE_FRACTION",
    "MODES",
    "MOTOR_KEYS",
    "VIEWER_QUALITIES",
    "RobotMode",
    "RobotScene",
    "SO101SimFollower",
    "SO101SimFollowerConfig",
    "SimCamera",
    "check_policy",
    "find_follower",
    "parse_action",
    "relative_caps",
    "robot_scene",
    "scene_resets",
    "training_fps",
    "when_connected",
]
