"""The motion layer: segments (moves and holds) run on a simulation, and motion files (TOML).

May import: ``so101sim.sim``, ``so101sim.kinematics``, ``so101sim.model`` and the base modules.
Modules: :mod:`.segments` (``Move``, ``Hold``, ``run_motion``), :mod:`.file` (``load_motion``),
:mod:`.lines` (reading a file, line numbers in its errors), :mod:`.tip` (straight tip moves).
"""

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
