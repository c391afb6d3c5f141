"""Fidelity: the twin held against real servos and real arms.

* :class:`ServoBench` / :class:`BenchBatch` (:mod:`.bench`): the STS3215 pendulum bench in
  MuJoCo, built from an arm profile (:mod:`so101sim.model.arm`) by the arm's own actuator code;
* :mod:`.benchdata`, :mod:`.benchfit`, :mod:`.bam`: the public bench runs, their scores, the
  profile's fit, and Rhoban's BAM M1 model for comparison;
* :func:`compare` (:mod:`.compare`) and :func:`fit` (:mod:`.fit`, :mod:`.fitparams`): a real
  arm's recording (a LeRobot dataset or a so101sim CSV log) replayed in the sim, where it is
  wrong (:mod:`.windows`; ``--plot``: :mod:`.plot`), and the profile fitted to it; the
  recordings are read by :mod:`.logs` (:mod:`.logdata`, :mod:`.lerobotlog`, :mod:`.csvlog`,
  :mod:`.calibration`), trusting nothing in them.

scipy and pyarrow are optional (``pip install 'so101sim[fidelity]'``); what needs them says so.

May import: ``so101sim.recording`` (writing a replay's outputs), ``so101sim.motion``,
``so101sim.sim``, ``so101sim.kinematics``, ``so101sim.model``, ``so101sim.units`` and the base
modules.
"""

from __future__ import annotations

# Imported eagerly (MuJoCo and NumPy only; scipy and pyarrow stay lazy), so that the functions
# ``compare`` and ``fit`` are what ``so101sim.fidelity.compare``/``.fit`` name, not the modules of
# the same name.
from .bam import BamM1, load_m1, simulate_m1
from .bench import BenchBatch, BenchRig, ServoBench
from .benchdata import BenchRun, load_bench_runs, split_runs
from .benchfit import BenchFit, fit_bench, per_run_errors, simulate_runs, summarize
from .compare import CompareResult, compare
from .deps import MissingDependencyError
from .fit import FitResult, fit
from .logs import ArmLog, Episode, LogError, read_log

__all__ = [
    "ArmLog",
    "BamM1",
    "BenchBatch",
    "BenchFit",
    "BenchRig",
    "BenchRun",
    "CompareResult",
    "Episode",
    "FitResult",
    "LogError",
    "MissingDependencyError",
    "ServoBench",
    "compare",
    "fit",
    "fit_bench",
    "load_bench_runs",
    "load_m1",
    "per_run_errors",
    "read_log",
    "simulate_m1",
    "simulate_runs",
    "split_runs",
    "summarize",
]
