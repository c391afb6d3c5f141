"""Fidelity: the twin held against real servos and real arms.

* :class:`ServoBench` / :class:`BenchBatch` (:mod:`.bench`): the STS3215 pendulum bench in
  MuJoCo, built from an arm profile (:mod:`so101sim.armprofile`) by the arm's own actuator code;
* :mod:`.benchdata`, :mod:`.benchfit`, :mod:`.bam`: the public bench runs, their scores, the
  profile's fit, and Rhoban's BAM M1 model for comparison;
* :func:`compare` (:mod:`.compare`) and :func:`fit` (:mod:`.fit`): a real arm's recording (a
  LeRobot dataset or a so101sim CSV log) replayed in the sim, and the profile fitted to it.

scipy and pyarrow are optional (``pip install 'so101sim[fidelity]'``); what needs them says so.
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "ServoBench": "bench",
    "BenchBatch": "bench",
    "BenchRun": "benchdata",
    "load_bench_runs": "benchdata",
    "split_runs": "benchdata",
    "simulate_runs": "benchfit",
    "fit_bench": "benchfit",
    "compare": "compare",
    "CompareResult": "compare",
    "read_log": "logs",
    "ArmLog": "logs",
    "fit": "fit",
    "FitResult": "fit",
    "MissingDependencyError": "deps",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module 'so101sim.fidelity' has no attribute {name!r}")
    return getattr(importlib.import_module(f".{mod}", __name__), name)


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
