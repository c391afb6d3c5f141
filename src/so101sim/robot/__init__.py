"""A LeRobot-style robot on the simulation: ``SO101SimFollower`` and the leader-arm teleop.

An app layer: may import the output layers (``so101sim.recording``, ``so101sim.viewer``,
``so101sim.scenes``), ``so101sim.sim``, ``so101sim.kinematics``, ``so101sim.model`` and the base
modules; never LeRobot itself (the plugins in ``plugins/`` wrap it). Modules: :mod:`.follower`,
:mod:`.config`, :mod:`.actions`, :mod:`.cameras`, :mod:`.threads`, :mod:`.scene`, :mod:`.ee`
(end-effector actions), :mod:`.helpers`, :mod:`.teleop`, :mod:`.calibration` (the leader's),
:mod:`.policycheck` (``so101sim policy-check``).
"""

from .follower import (
    GRIPPER_TORQUE_FRACTION,
    MODES,
    VIEWER_QUALITIES,
    SO101SimFollower,
    SO101SimFollowerConfig,
    parse_action,
    relative_caps,
)

__all__ = [
    "GRIPPER_TORQUE_FRACTION",
    "MODES",
    "VIEWER_QUALITIES",
    "SO101SimFollower",
    "SO101SimFollowerConfig",
    "parse_action",
    "relative_caps",
]
