"""The lab: the handout's helpers on ``(m, d)``, the hand-in recorder and the starter files.

Modules:
:mod:`.helpers` (``move_to_pose``, ``hold_position``, ...), :mod:`.handin` (``so101sim record``),
:mod:`.recviewer` (the recording viewer ``record`` returns), :mod:`.arming` (``record --arm``:
the script's model run with a profile), :mod:`.simclock` (simulated time for scripts),
:mod:`.starter` (``so101sim examples``), :mod:`.grade` (``so101sim grade``: :mod:`.gradelog`
reads a log, :mod:`.gradevideo` checks the video, :mod:`.gradefolder` grades a folder,
:mod:`.gradereport` says it).

May import: ``so101sim.preflight``, ``so101sim.recording``, ``so101sim.viewer``,
``so101sim.motion``, ``so101sim.sim``, ``so101sim.kinematics``, ``so101sim.model``,
``so101sim.units`` and the base modules.
"""

from typing import TYPE_CHECKING

from .._lazy import lazy_names

# The helpers load on first use (they import MuJoCo); so101sim.lab.starter and .simclock do not.
if TYPE_CHECKING:
    from .helpers import (
        convert_to_dictionary,
        convert_to_list,
        hold_position,
        move_to_pose,
        send_position_command,
        set_initial_pose,
    )

__getattr__, __dir__ = lazy_names(__name__)
