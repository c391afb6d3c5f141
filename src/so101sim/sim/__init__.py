"""The simulation layer: a :class:`Simulation` of the arm that moves, holds and steps MuJoCo.

Modules: :mod:`.simulation` (``Simulation``), :mod:`.armstate` (its pose and targets in the
arm's units), :mod:`.moveplan` (planning a move, its ``shape``), :mod:`.results`
(``SegmentResult``), :mod:`.fastpath` (the robot's per-call reads and writes), :mod:`.stepping`
(the stepping kernel; :mod:`.batch`: many models at once; :mod:`.batched`: an environment's
worlds at once), :mod:`.divergence` (its divergence check), :mod:`.observers` (observers,
pacing), :mod:`.profiles` (the move shapes), :mod:`.limited` (the servo-limited ``limited``
shape).

May import: ``so101sim.kinematics`` (tip moves), ``so101sim.model``, ``so101sim.units`` and
the base modules.
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
