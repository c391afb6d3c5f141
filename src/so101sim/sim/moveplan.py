"""Planning one move of a :class:`~so101sim.sim.simulation.Simulation` before anything moves:
a joint-space move (:func:`plan_joint_move`) or a move of the gripper's tip
(:func:`plan_tip_move`), each checked whole and returned as ``(start, targets)`` in arm units.
Also the one place a move's shape is named (:func:`move_shape`: ``shape=``, with the old
``profile=`` accepted for one release)."""

from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from ..errors import DurationError, SettingError
from ..units import Pose, unit_warnings
from ..validation import check_choice
from .profiles import (
    MAX_MOVE_DURATION_S,
    Profile,
    duration_warning,
    fractions,
    get_profile,
    plan,
    steps_for,
)

Simulation = Any  # a so101sim.sim.simulation.Simulation (not imported: it imports this module)

log = logging.getLogger(__name__)

ShapeName = Literal["linear", "minimum_jerk", "limited"]
"""The built-in shapes of a move (:data:`so101sim.sim.profiles.PROFILES`)."""
Shape = ShapeName | str | Profile
"""A move's shape: a built-in name or a function ``(start, goal, n, dt) -> (n, 6)``."""
TipPath = Literal["line", "joint"]
"""How the tip goes to its goal: a straight line, or a joint-space move."""


def move_shape(shape: Shape | None, profile: Shape | None, default: Shape = "linear") -> Shape:
    """The shape of a move from ``shape=`` or the deprecated ``profile=`` (a DeprecationWarning:
    "profile" names the servos' model, the arm profile; a move's timing is its shape).

    Raises:
        SettingError: both are given.
    """
    if profile is None:
        return default if shape is None else shape
    if shape is not None:
        raise SettingError(
            "shape= and profile= both given; expected shape= only (profile= is its old name)"
        )
    warnings.warn(
        "profile= for a move's shape is deprecated and goes in the next release; use shape= "
        '(e.g. shape="minimum_jerk"): "profile" names the arm profile, the servos\' model',
        DeprecationWarning,
        stacklevel=3,
    )
    return profile


def plan_joint_move(
    sim: Simulation,
    target: Pose,
    duration: float,
    shape: Shape,
    clip: bool,
    *,
    steps: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Validate a joint-space move and compute its targets (see :meth:`Simulation.plan_move`).
    ``steps``: the move's physics steps where its duration was already checked (the motion
    planner checks each duration once, :func:`so101sim.motion.plan.plan_segments`); None:
    checked here."""
    goal = sim.units.pose_to_array(target, clip=clip)
    n = move_steps(sim, duration, steps)
    for warning in unit_warnings(goal):
        log.warning("%s", warning)
    if (w := duration_warning(float(duration), "move duration")) is not None:
        log.warning("%s", w)
    prof = get_profile(shape, sim.units)
    start = sim.commanded_array()
    return start, plan(start, goal, n, sim.timestep, prof)


def plan_tip_move(
    sim: Simulation,
    tip: Sequence[float],
    duration: float | None,
    *,
    pitch: float | None,
    roll: float | None,
    path: TipPath,
    shape: Shape,
    steps: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Plan a move of the tip (see :meth:`Simulation.move_to`): ``(start, targets)``.
    ``steps`` as for :func:`plan_joint_move`."""
    from ..kinematics import plan_line, solve_ik  # imported here: only tip moves need it
    from ..kinematics.paths import MAX_LINE_STEPS

    _ = sim.kinematics  # held here, so that the planner's calls share it
    check_choice(path, "path", ("line", "joint"))
    n = move_steps(sim, required_duration(duration), steps)
    if path == "line" and n > MAX_LINE_STEPS:  # a model with a very short timestep
        raise SettingError(
            f"a straight tip line of {duration:g} s is {n} physics steps of "
            f"{sim.timestep * 1000:g} ms; expected at most {MAX_LINE_STEPS} steps "
            f"({MAX_LINE_STEPS * sim.timestep:g} s with this model): split it into "
            "shorter lines, or use path='joint'"
        )
    start = sim.commanded_array()
    if path == "joint":
        goal = solve_ik(tip, pitch=pitch, roll=roll, initial=start, model=sim.model)
        prof = get_profile(shape, sim.units)
        return start, plan(start, goal.values, n, sim.timestep, prof)
    line = plan_line(start, tip, fractions(shape, n), pitch=pitch, roll=roll, model=sim.model)
    return start, line.targets


def move_steps(sim: Simulation, duration: float, steps: int | None) -> int:
    """The physics steps of a move: ``steps`` as given (its duration checked by the caller,
    the motion planner), or ``duration`` checked here (a move asked of the simulation)."""
    if steps is not None:
        return steps
    return steps_for(duration, sim.timestep, maximum=MAX_MOVE_DURATION_S)


def required_duration(duration: float | None) -> float:
    if duration is None:
        raise DurationError("duration is missing; expected the move's length in seconds > 0")
    return duration


__all__ = [
    "Shape",
    "ShapeName",
    "TipPath",
    "move_shape",
    "move_steps",
    "plan_joint_move",
    "plan_tip_move",
    "required_duration",
]
