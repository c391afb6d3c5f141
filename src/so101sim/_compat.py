"""Old module paths, kept for one release: ``so101sim.simulation`` is ``so101sim.sim.simulation``.

The flat modules moved into subpackages (issue 21). :data:`MOVED` maps each old name to its new
one; :class:`MovedModuleFinder` (installed by ``so101sim/__init__``) imports the new module when
the old name is imported, warns once with a :class:`DeprecationWarning`, and returns the very same
module object, so ``so101sim.simulation.Simulation is so101sim.sim.Simulation``. It imports no
module of its own, and names not in the map are left to Python's own finders (they fail as
before). To be removed in the release after 0.1.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import ModuleType

MOVED: dict[str, str] = {
    "so101sim.cli_demo": "so101sim.cli.demo",
    "so101sim.cli_tools": "so101sim.cli.tools",
    "so101sim.distributed": "so101sim.preflight.distributed",
    "so101sim.framing": "so101sim.recording.framing",
    "so101sim.handin": "so101sim.lab.handin",
    "so101sim.modelcache": "so101sim.model.cache",
    "so101sim.modeltrim": "so101sim.model.trim",
    "so101sim.motionfile": "so101sim.motion.file",
    "so101sim.motionfile_lines": "so101sim.motion.lines",
    "so101sim.motionfile_tip": "so101sim.motion.tip",
    "so101sim.posefinder": "so101sim.viewer.posefinder",
    "so101sim.preflight_judge": "so101sim.preflight.judge",
    "so101sim.preflight_measure": "so101sim.preflight.measure",
    "so101sim.preflight_rollout": "so101sim.preflight.rollout",
    "so101sim.preflight_variants": "so101sim.preflight.robust",
    "so101sim.profiles": "so101sim.sim.profiles",
    "so101sim.robot_actions": "so101sim.robot.actions",
    "so101sim.robot_cameras": "so101sim.robot.cameras",
    "so101sim.robot_config": "so101sim.robot.config",
    "so101sim.robot_ee": "so101sim.robot.ee",
    "so101sim.robot_helpers": "so101sim.robot.helpers",
    "so101sim.robot_scene": "so101sim.robot.scene",
    "so101sim.robot_threads": "so101sim.robot.threads",
    "so101sim.runplan": "so101sim.cli.runplan",
    "so101sim.simclock": "so101sim.lab.simclock",
    "so101sim.simulation": "so101sim.sim.simulation",
    "so101sim.starter": "so101sim.lab.starter",
    "so101sim.stepping": "so101sim.sim.stepping",
    "so101sim.teleop": "so101sim.robot.teleop",
    "so101sim.teleop_calibration": "so101sim.robot.calibration",
    "so101sim.trajectory": "so101sim.sim.limited",
    "so101sim.variants": "so101sim.preflight.variants",
}
"""Old module name -> new module name (both absolute)."""


class _MovedLoader(importlib.abc.Loader):
    """Imports the new module and puts it in ``sys.modules`` under the old name, so that the
    import machinery hands back the new module itself (not a copy, its ``__spec__`` untouched)."""

    def __init__(self, new: str) -> None:
        self.new = new

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> None:
        return None  # a placeholder, replaced in exec_module

    def exec_module(self, module: ModuleType) -> None:
        old = module.__name__
        warnings.warn(
            f"{old} moved to {self.new}; import it from there ({old} goes in the next release)",
            DeprecationWarning,
            stacklevel=2,
        )
        sys.modules[old] = importlib.import_module(self.new)


class MovedModuleFinder(importlib.abc.MetaPathFinder):
    """Finds the old names of :data:`MOVED`, and nothing else."""

    def find_spec(
        self, fullname: str, path: object = None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        new = MOVED.get(fullname)
        if new is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, _MovedLoader(new))


def install() -> None:
    """Put the finder on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, MovedModuleFinder) for f in sys.meta_path):
        sys.meta_path.append(MovedModuleFinder())


__all__ = ["MOVED", "MovedModuleFinder", "install"]
