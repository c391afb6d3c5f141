"""Kinematics of the SO-101: where the tip is, the pose that puts it somewhere, straight-line
moves of the tip and the reachable workspace, all in the arm's units.

Positions are metres in the base frame (the ``baseframe`` site: x forward, y left, z up), the
tip is the ``gripperframe`` site, poses are dicts in degrees (gripper 0-100). It needs only the
model (no simulation state), so the simulation and everything above it can call it. See
docs/kinematics.md.

* :func:`tip_pose` (forward kinematics) -> :class:`TipPose`; :func:`tip_positions` for many;
* :func:`solve_ik` (inverse kinematics) -> :class:`IKResult`;
* :func:`plan_line` (a straight-line move of the tip) -> :class:`LinePlan`;
  :func:`line_deviation` (how far a run's tip strayed from a line) -> :class:`LineDeviation`;
* :func:`is_reachable`, :func:`sample_workspace`, :func:`plot_workspace`;
* :func:`planar_arm`: the chain's numbers (link lengths, axes) read from the model.

May import: ``so101sim.model``, ``so101sim.units`` and the base modules.
"""

from .core import (
    BASE_SITE,
    TIP_SITE,
    Kinematics,
    TipPose,
    for_model,
    quat_yaw,
    tip_pose,
    tip_positions,
)
from .geometry import PlanarArm, planar_arm
from .ik import ORIENTATION_WEIGHT, IKResult, solve_ik
from .paths import LineDeviation, LinePlan, line_deviation, plan_line
from .workspace import WorkspaceSamples, is_reachable, plot_workspace, sample_workspace

__all__ = [
    "BASE_SITE",
    "ORIENTATION_WEIGHT",
    "TIP_SITE",
    "IKResult",
    "Kinematics",
    "LineDeviation",
    "LinePlan",
    "PlanarArm",
    "TipPose",
    "WorkspaceSamples",
    "for_model",
    "is_reachable",
    "line_deviation",
    "plan_line",
    "planar_arm",
    "plot_workspace",
    "quat_yaw",
    "sample_workspace",
    "solve_ik",
    "tip_pose",
    "tip_positions",
]
