"""Planning a top-down grasp with the kinematics module: where the tip goes so that the jaws
close on an object's faces, and the joint targets of the moves between (used by the scripted
experts and the grasp measurements).

The SO-101 has a fixed jaw and a moving one. The tip site (``gripperframe``) lies on the fixed
jaw's gripping face; the tool's z axis points from it towards the moving jaw. To pinch an
object of width ``w`` the tip goes ``w / 2 + clearance`` from the object's centre against that
axis, pointing straight down (pitch -90°), turned about the vertical (the tool's roll) so that
the jaws close across two opposite faces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from ..kinematics import plan_line, solve_ik, tip_pose
from ..model.load import arm_index, arm_units
from ..sim.profiles import fractions
from ..units import GRIPPER_INDEX

GRASP_PITCH = -90.0
"""Top-down grasps: the tool points straight down."""
JAW_CLEARANCE_M = 0.0015
"""How far the fixed jaw's face stays from the object's face as it comes down (metres)."""
OPEN_GRIPPER = 35.0
"""The gripper opening (0-100) the jaws approach with: at least 35 mm between the fingers,
room to spare around a 2.5 cm cube, not so much that the moving jaw sweeps far."""
CLOSED_GRIPPER = 0.0
"""The grip command: fully closed; the jaws stop on the object and squeeze it with the
gripper's force limit."""


@dataclass(frozen=True)
class Grasp:
    """A top-down grasp: the tip ``position`` (metres, base frame) when the jaws are around the
    object, and the tool's ``roll`` (degrees) that puts them across its faces."""

    position: np.ndarray
    roll: float

    def at_height(self, z: float) -> np.ndarray:
        """The grasp's position moved to height ``z``."""
        p = self.position.copy()
        p[2] = z
        return p


def _closing_axis(model: mujoco.MjModel, target: np.ndarray, roll: float, initial: np.ndarray):
    ik = solve_ik(target, pitch=GRASP_PITCH, roll=roll, initial=initial, model=model)
    return tip_pose(ik.values, model).rotation[:, 2]


def top_grasp(
    model: mujoco.MjModel,
    centre: np.ndarray,
    yaw: float,
    width: float,
    z: float,
    initial: np.ndarray,
    *,
    symmetry: float | None = 90.0,
    roll: float = 0.0,
) -> Grasp:
    """The top-down grasp of an object whose centre is at ``centre`` (x, y), turned by ``yaw``
    degrees (its faces' normals at ``yaw + k * symmetry``; None: any direction will do, and the
    tool keeps ``roll``), ``width`` metres across, with the tip at height ``z``. ``initial``
    (arm units) warm-starts the IK."""
    c = np.array([centre[0], centre[1], z], dtype=float)
    position = c
    for _ in range(3):  # the tip is off the centre, which turns the arm a little: iterate
        axis = _closing_axis(model, position, roll, initial)
        if symmetry is not None:
            heading = math.degrees(math.atan2(axis[1], axis[0]))
            roll += (yaw - heading + symmetry / 2) % symmetry - symmetry / 2
            axis = _closing_axis(model, position, roll, initial)
        position = c - axis * (width / 2 + JAW_CLEARANCE_M)
        position[2] = z
    return Grasp(position=position, roll=float(roll))


def joint_path(start: np.ndarray, goal: np.ndarray, n: int) -> np.ndarray:
    """``n`` targets (arm units) from ``start`` to ``goal`` with a minimum-jerk timing."""
    f = fractions("minimum_jerk", n)[:, None]
    return np.asarray(start, dtype=float) + f * (np.asarray(goal, dtype=float) - start)


def line_path(
    model: mujoco.MjModel,
    start: np.ndarray,
    tip: np.ndarray,
    n: int,
    roll: float,
    *,
    pitch: float = GRASP_PITCH,
) -> np.ndarray:
    """``n`` targets (arm units) moving the tip along a straight line to ``tip`` with a
    minimum-jerk timing, the gripper kept."""
    plan = plan_line(start, tip, fractions("minimum_jerk", n), pitch=pitch, roll=roll, model=model)
    return plan.targets


def pose_at(
    model: mujoco.MjModel, tip: np.ndarray, roll: float, initial: np.ndarray, gripper: float
) -> np.ndarray:
    """The pose (arm units) with the tip at ``tip`` pointing down with ``roll``, the gripper at
    ``gripper``."""
    ik = solve_ik(tip, pitch=GRASP_PITCH, roll=roll, initial=initial, model=model)
    values = ik.values.copy()
    values[GRIPPER_INDEX] = gripper
    return values


def gripper_path(start: np.ndarray, value: float, n: int) -> np.ndarray:
    """``n`` targets that move only the gripper from its value in ``start`` to ``value``."""
    goal = np.asarray(start, dtype=float).copy()
    goal[GRIPPER_INDEX] = value
    return joint_path(start, goal, n)


class ThroughSag:
    """Joint targets that end where they are meant to on servos that sag under the arm's
    weight: each body joint's target moved by the gravity torque on it at that pose over its
    servo's stiffness (``-actuator_biasprm[1]``, N·m/rad), as a person commanding a real
    P = 16 arm learns to aim a little high. On the default arm profile (``sts3215``, 11 N·m/rad)
    it is a few degrees; on the vendored ideal actuators (998 N·m/rad) next to nothing. The
    gripper is left as asked. Coulomb friction (the servo's dead band, about 1°) is not
    compensated: it has no one sign.

    The stiffness and the masses are read from the model at each call, so a model changed
    after this was made (an environment's physical randomisation at each reset) is aimed
    through as it is now: the same targets whatever episodes the environment ran before.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)  # scratch: the pose is written, the physics not stepped
        idx = arm_index(model)
        self.units = arm_units(model)
        self.qpos, self.dof, self.actuator = idx.qpos, idx.dof, idx.actuator
        self._arm = np.arange(len(idx.qpos)) != GRIPPER_INDEX
        self._force = np.zeros(model.nv)

    @property
    def kp(self) -> np.ndarray:
        """Each joint's servo stiffness now (N·m/rad, from ``-actuator_biasprm[1]``)."""
        return -self.model.actuator_biasprm[self.actuator, 1]

    def __call__(self, target: np.ndarray) -> np.ndarray:
        """``target`` (arm units, six values) as the command that holds the arm there."""
        q = self.units.to_radians(np.asarray(target, dtype=float))
        m, d = self.model, self.data
        d.qpos[self.qpos] = q
        d.qvel[:] = 0.0
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_rne(m, d, 0, self._force)  # gravity alone: the joints are still
        kp = self.kp
        body = self._arm & (kp > 0)
        shift = np.where(body, self._force[self.dof] / np.where(body, kp, 1.0), 0.0)
        lower, upper = self.units.limits
        return np.clip(self.units.from_radians(q + shift), lower, upper)
