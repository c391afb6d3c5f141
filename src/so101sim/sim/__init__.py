"""The simulation layer: a :class:`Simulation` of the arm that moves, holds and steps MuJoCo.

Modules: :mod:`.simulation` (``Simulation``, ``SegmentResult``), :mod:`.stepping` (the stepping
kernel; :mod:`.batch`: many models at once), :mod:`.divergence` (its divergence check),
:mod:`.observers` (observers, pacing),
:mod:`.profiles` (the move profiles), :mod:`.limited` (the servo-limited ``limited`` profile).

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
