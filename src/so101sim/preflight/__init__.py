"""The preflight: simulate a motion headless and judge it before it runs on hardware.

Modules: :mod:`.check` (``preflight``, ``check_motion_file``), :mod:`.measure`, :mod:`.judge`,
:mod:`.rollout` (variants rolled out in C), :mod:`.variants` (perturbed models),
:mod:`.robust` (``check --variants``), :mod:`.report` (its report), :mod:`.distributed` (the
variants over Ray), :mod:`.states` and :mod:`.screen` (the lab helpers' figures after a block).

May import: ``so101sim.recording`` (plots of robust runs), ``so101sim.motion``,
``so101sim.sim``, ``so101sim.kinematics``, ``so101sim.model``, ``so101sim.units`` and the base
modules.
"""

from .check import (
    Contact,
    Finding,
    JointCheck,
    PreflightReport,
    StepCheck,
    Thresholds,
    check_motion_file,
    describe,
    format_report,
    preflight,
)

__all__ = [
    "Contact",
    "Finding",
    "JointCheck",
    "PreflightReport",
    "StepCheck",
    "Thresholds",
    "check_motion_file",
    "describe",
    "format_report",
    "preflight",
]
