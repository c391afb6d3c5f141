"""The simulation layer: a :class:`Simulation` of the arm that moves, holds and steps MuJoCo.

May import: the model layer (``so101sim.model``), ``so101sim.kinematics`` (tip moves) and the
base modules (errors, validation, units). Modules: :mod:`.simulation` (``Simulation``),
:mod:`.armstate` (its pose and targets in the arm's units), :mod:`.moveplan` (planning a move,
its ``shape``), :mod:`.results` (``SegmentResult``), :mod:`.fastpath` (the robot's per-call
reads and writes), :mod:`.stepping` (the stepping kernel), :mod:`.observers` (observers,
pacing), :mod:`.profiles` (the move shapes), :mod:`.limited` (the servo-limited ``limited``
shape).
"""

from .simulation import (
    TRACE_AUTO_STEPS,
    Observer,
    Pacer,
    SegmentResult,
    Simulation,
    Trace,
    ViewerObserver,
    advance,
    measured_radians,
)

__all__ = [
    "TRACE_AUTO_STEPS",
    "Observer",
    "Pacer",
    "SegmentResult",
    "Simulation",
    "Trace",
    "ViewerObserver",
    "advance",
    "measured_radians",
]
