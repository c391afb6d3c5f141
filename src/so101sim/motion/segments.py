"""Motions: moves, holds and sequences of them, as data and as ``(model, data)`` functions.

A motion is a sequence of :data:`Segment` s (:class:`Move` and :class:`Hold`), each one
planned whole and then stepped by :class:`~so101sim.sim.simulation.Simulation`: a move of T
seconds is exactly ``round(T / timestep)`` physics steps of simulated time, its targets
computed at once by its shape (:mod:`so101sim.sim.profiles`) and replayed in C.

The ``(m, d)`` functions (:func:`move`, :func:`hold`, :func:`plan_move`, :func:`run_motion`)
are thin wrappers over :meth:`Simulation.attach`, for handout-style code that holds a bare
``MjModel``/``MjData``.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence

import mujoco
import numpy as np

from ..sim.moveplan import Shape, move_shape
from ..sim.profiles import PROFILES, Profile, get_profile, steps_for
from ..sim.simulation import Observer, SegmentResult, Simulation
from ..units import STARTING_POSE, Pose
from .moves import LAB_MOTION, Hold, Move, RunResult, Segment
from .plan import plan_segments, run_plan

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------- (m, d) functions
def plan_move(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    target: Pose,
    duration: float,
    *,
    shape: Shape | None = None,
    clip: bool = False,
    profile: Shape | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Validate a move and compute all its targets: ``(start, targets)`` in arm units
    (:meth:`Simulation.plan_move`). Nothing moves. ``shape``: ``"linear"`` (default),
    ``"minimum_jerk"``, ``"limited"`` or a function; ``profile=`` is its deprecated old name."""
    shape = move_shape(shape, profile)
    return Simulation.attach(m, d).plan_move(target, duration, shape=shape, clip=clip)


def move(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    target: Pose,
    duration: float,
    *,
    shape: Shape | None = None,
    observers: Sequence[Observer] = (),
    clip: bool = False,
    phase: str = "move",
    profile: Shape | None = None,
) -> SegmentResult:
    """Move the arm from its last commanded target to ``target`` over ``duration`` simulated
    seconds with ``shape`` (as :func:`plan_move`; ``profile=`` its deprecated old name), then
    return what happened (:meth:`Simulation.move_to`)."""
    shape = move_shape(shape, profile)
    return Simulation.attach(m, d).move_to(
        target, duration, shape=shape, observers=observers, clip=clip, phase=phase
    )


def hold(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    duration: float,
    *,
    observers: Sequence[Observer] = (),
    phase: str = "hold",
) -> SegmentResult:
    """Hold the last commanded target (the measured pose, before any command) for ``duration``
    simulated seconds (:meth:`Simulation.hold`)."""
    return Simulation.attach(m, d).hold(duration, observers=observers, phase=phase)


# ---------------------------------------------------------------------------- sequences


def validate_segments(
    m: mujoco.MjModel,
    segments: Sequence[Segment],
    *,
    clip: bool = False,
    start: np.ndarray | None = None,
) -> None:
    """Deprecated (kept for one release): :func:`~so101sim.motion.plan.plan_segments` plans
    and checks a motion, every segment (tip moves and the joint limits of ``limited`` moves
    included) from the start it plans for it; this calls it from ``start`` (the rest pose by
    default) and drops the plan."""
    warnings.warn(
        "validate_segments is deprecated; use so101sim.motion.plan_segments(model, segments, "
        "start), which plans and checks the motion once",
        DeprecationWarning,
        stacklevel=2,
    )
    first = STARTING_POSE if start is None else np.asarray(start, dtype=float)
    plan_segments(m, segments, first, clip=clip)


def commanded_path(
    model: mujoco.MjModel, segments: Sequence[Segment], start: Pose
) -> tuple[np.ndarray, np.ndarray]:
    """What a motion commands, step by step, without simulating it: ``(times, targets)``
    with ``targets`` (n, 6) in arm units, one row per physics step (the target applied during
    the step that ends at ``times[i]``). Planning depends only on the commanded targets, so
    this is exactly what :func:`run_segments` would command from the rest pose ``start``
    (:meth:`so101sim.motion.plan.PlannedMotion.path` of the same plan).
    """
    return plan_segments(model, segments, start).path()


def run_segments(
    sim: Simulation,
    segments: Sequence[Segment] = LAB_MOTION,
    *,
    viewer: object = None,
    observers: Sequence[Observer] = (),
    clip: bool = False,
    trace: bool | None = None,
) -> RunResult:
    """Run a sequence of moves and holds on ``sim``; stops early if an observer (a closed
    viewer) says so. The motion is planned once, whole (every segment checked), before the
    first segment runs (:func:`so101sim.motion.plan.plan_segments`). ``trace``: keep each
    segment's per-step arrays (None: for segments up to two minutes)."""
    plan = plan_segments(sim.model, segments, sim.commanded_array(), clip=clip)
    return run_plan(sim, plan, viewer=viewer, observers=observers, trace=trace)


def run_motion(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    segments: Sequence[Segment] = LAB_MOTION,
    *,
    observers: Sequence[Observer] = (),
    clip: bool = False,
    trace: bool | None = None,
) -> RunResult:
    """Run a sequence of moves and holds on ``(m, d)`` (:func:`run_segments`)."""
    return run_segments(
        Simulation.attach(m, d), segments, observers=observers, clip=clip, trace=trace
    )


__all__ = [
    "LAB_MOTION",
    "PROFILES",
    "STARTING_POSE",
    "Hold",
    "Move",
    "Profile",
    "RunResult",
    "Segment",
    "SegmentResult",
    "commanded_path",
    "get_profile",
    "hold",
    "move",
    "plan_move",
    "run_motion",
    "run_segments",
    "steps_for",
    "validate_segments",
]
