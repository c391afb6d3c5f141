"""The simulation layer: a :class:`Simulation` of the arm that moves, holds and steps MuJoCo.

May import: the model layer (``so101sim.model``), ``so101sim.kinematics`` (tip moves) and the
base modules (errors, validation, units). Modules: :mod:`.simulation` (``Simulation``,
``SegmentResult``), :mod:`.stepping` (the stepping kernel), :mod:`.observers` (observers,
pacing), :mod:`.profiles` (the move profiles), :mod:`.limited` (the servo-limited
``limited`` profile).
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
