"""The motion layer: segments (moves and holds) run on a simulation, and motion files (TOML).

Modules: :mod:`.moves` (``Move``, ``Hold``: a motion as data), :mod:`.plan` (a motion planned
once: ``plan_segments``, ``run_plan``), :mod:`.segments` (``run_motion`` and the ``(m, d)``
functions), :mod:`.file` (``load_motion``), :mod:`.reader` (a motion file's settings and poses),
:mod:`.lines` (reading a file, line numbers in its errors), :mod:`.tip` (straight tip moves).

May import: ``so101sim.sim``, ``so101sim.kinematics``, ``so101sim.model``, ``so101sim.units``
and the base modules.
"""

from .plan import PlannedMotion, PlannedSegment, plan_segments, run_plan
from .segments import (
    LAB_MOTION,
    PROFILES,
    STARTING_POSE,
    Hold,
    Move,
    Profile,
    RunResult,
    Segment,
    SegmentResult,
    commanded_path,
    get_profile,
    hold,
    move,
    plan_move,
    run_motion,
    run_segments,
    steps_for,
    validate_segments,
)

__all__ = [
    "LAB_MOTION",
    "PROFILES",
    "STARTING_POSE",
    "Hold",
    "Move",
    "PlannedMotion",
    "PlannedSegment",
    "Profile",
    "RunResult",
    "Segment",
    "SegmentResult",
    "commanded_path",
    "get_profile",
    "hold",
    "move",
    "plan_move",
    "plan_segments",
    "run_motion",
    "run_plan",
    "run_segments",
    "steps_for",
    "validate_segments",
]
