"""Reading the STS3215 pendulum bench's runs and splitting them into fit and validation.

Two layouts are read (neither is shipped: the data has no licence):

* the data set's own folder of JSON runs (kscalelabs/sysid,
  ``data/feetech/STS_3215_12V_20250317/processed/``): one file per run with ``mass``,
  ``length``, ``kp``, ``trajectory`` and ``entries`` (``timestamp``, ``goal_position``,
  ``position``, ``torque_enable``);
* a ``.npz`` holding ``meta`` (a JSON list of ``{name, mass, length, kp, trajectory}``) and per
  run ``t{i}``, ``g{i}``, ``p{i}``, ``e{i}``.

The split: runs are grouped by condition (mass, length, P, trajectory); in each group the run
whose file name sorts first is for fitting, the next for validation.
"""

from __future__ import annotations

import json
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SettingError

__all__ = ["BenchRun", "load_bench_runs", "split_runs"]

MAX_RUNS = 5000


@dataclass(frozen=True)
class BenchRun:
    """One run on the bench: times (s), goals and measured positions (rad), torque on."""

    name: str
    mass: float
    length: float
    kp: float
    trajectory: str
    t: np.ndarray
    goal: np.ndarray
    pos: np.ndarray
    enabled: np.ndarray

    @property
    def condition(self) -> tuple[float, float, float, str]:
        return (self.mass, self.length, self.kp, self.trajectory)


def _run(name: str, meta: dict, t, g, p, e) -> BenchRun:
    arrays = [np.asarray(a) for a in (t, g, p, e)]
    n = len(arrays[0])
    if n < 2 or any(len(a) != n for a in arrays):
        raise SettingError(f"bench run {name!r}: its columns differ in length or are empty")
    try:
        return BenchRun(
            name=name,
            mass=float(meta["mass"]),
            length=float(meta["length"]),
            kp=float(meta["kp"]),
            trajectory=str(meta["trajectory"]),
            t=arrays[0].astype(float),
            goal=arrays[1].astype(float),
            pos=arrays[2].astype(float),
            enabled=arrays[3].astype(bool),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise SettingError(
            f"bench run {name!r} lacks {exc}; expected mass, length, kp and trajectory"
        ) from exc


def load_bench_runs(path: str | Path) -> list[BenchRun]:
    """The runs in ``path``: a folder of the data set's JSON runs, or a ``.npz`` file.

    Raises:
        SettingError: the path does not exist, holds no runs, or a run is malformed.
    """
    p = Path(path).expanduser()
    if p.is_dir():
        files = sorted(p.glob("*.json"))
        if not files:
            raise SettingError(
                f"{str(p)!r} holds no .json runs; expected the data set's processed/ folder"
            )
        if len(files) > MAX_RUNS:
            raise SettingError(f"{str(p)!r} holds {len(files)} runs; at most {MAX_RUNS} read")
        runs = []
        for f in files:
            try:
                raw = json.loads(f.read_text(encoding="utf-8"))
                ent = raw["entries"]
                cols = [
                    [e["timestamp"] for e in ent],
                    [e["goal_position"] for e in ent],
                    [e["position"] for e in ent],
                    [bool(e.get("torque_enable", True)) for e in ent],
                ]
            except (OSError, ValueError, KeyError, TypeError) as exc:
                raise SettingError(f"bench run {str(f)!r} cannot be read: {exc}") from exc
            runs.append(_run(f.name, raw, *cols))
        return runs
    if p.is_file() and p.suffix == ".npz":
        try:
            with np.load(p, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                if len(meta) > MAX_RUNS:
                    raise SettingError(f"{str(p)!r} holds {len(meta)} runs; at most {MAX_RUNS}")
                return [
                    _run(m["name"], m, z[f"t{i}"], z[f"g{i}"], z[f"p{i}"], z[f"e{i}"])
                    for i, m in enumerate(meta)
                ]
        except (OSError, ValueError, KeyError) as exc:
            raise SettingError(f"bench file {str(p)!r} cannot be read: {exc}") from exc
    raise SettingError(
        f"bench data {str(p)!r} does not exist or is not a folder of JSON runs or an .npz file"
    )


def split_runs(runs: list[BenchRun]) -> tuple[list[BenchRun], list[BenchRun]]:
    """``(fit, validation)``: in each condition the run whose name sorts first is for fitting,
    the second for validation (a condition with one run gives only a fit run)."""
    groups: dict[tuple, list[BenchRun]] = defaultdict(list)
    for r in runs:
        groups[r.condition].append(r)
    fit, val = [], []
    for key in sorted(groups, key=str):
        g = sorted(groups[key], key=lambda r: r.name)
        fit.append(g[0])
        val.extend(g[1:2])
    return fit, val
