"""The preflight: simulate a motion headless and judge it before it runs on hardware.

Modules: :mod:`.check` (``preflight``, ``check_motion_file``), :mod:`.measure`, :mod:`.judge`,
:mod:`.rollout` (variants rolled out in C), :mod:`.accumulate` (their figures, block by
block), :mod:`.variants` (perturbed models),
:mod:`.robust` (``check --variants``), :mod:`.report` (its report), :mod:`.distributed` (the
variants over Ray), :mod:`.states` and :mod:`.screen` (the lab helpers' figures after a block).

May import: ``so101sim.recording`` (plots of robust runs), ``so101sim.motion``,
``so101sim.sim``, ``so101sim.kinematics``, ``so101sim.model``, ``so101sim.units`` and the base
modules.
"""

import sys
import types
import warnings

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


class _CallablePackage(types.ModuleType):
    """``so101sim.preflight`` was the function :func:`~.check.preflight` or this package
    depending on import order; it is the package now, and calling it still runs the function,
    with a DeprecationWarning, for one release."""

    def __call__(self, *args, **kwargs):
        warnings.warn(
            "calling so101sim.preflight(...) is deprecated: so101sim.preflight is the "
            "subpackage; call so101sim.preflight.preflight(...) instead",
            DeprecationWarning,
            stacklevel=2,
        )
        return preflight(*args, **kwargs)


sys.modules[__name__].__class__ = _CallablePackage

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
