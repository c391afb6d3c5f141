"""The replayed arm's joint stops: where a real follower's joints end, when a recording says.

The official model's joint limits come from the CAD; real SO-101 followers sweep further. In
range mode LeRobot's −100 and 100 are the ends of the follower's calibration sweep (its
mechanical stops), and the 20 public calibration files behind
:data:`~so101sim.fidelity.calibration.RANGE_GUESS` sweep shoulder_lift about 207° and
wrist_flex about 203° where the model allows 200° and 190°. A real arm resting folded against
its stops then reads a few degrees past the model's limits, where the replayed sim cannot
follow: on a real recording most of shoulder_lift's error came from such frames
(docs/fidelity.md, "The real arm's stops"). So ``compare`` and ``fit`` replay an arm whose body
joints reach the recording's stops: the model's limits widened (never narrowed) to the angles of
the sweep's ends, through the calibration the recording is read with. Nothing else changes: the
arm's own limits (poses, motions, the lab) stay the model's.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np

from ..model.index import ArmIndex, arm_index
from ..units import JOINT_NAMES, ArmUnits

__all__ = ["stop_limits", "widen_stops", "with_stops"]

BODY = len(JOINT_NAMES) - 1  # the gripper keeps its range (its units are a share of it)


def stop_limits(
    units: ArmUnits,
    stops: np.ndarray | None,
    scale: np.ndarray | None = None,
    offset: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) joint limits (arm units) of the replayed arm: ``units``' limits, each body
    joint's widened to cover the recording's ``stops`` (readings, ``(2, 6)``, NaN where
    unknown) read as angles through a reading's ``scale`` and ``offset`` (a reading is
    ``scale`` · angle + ``offset``: a profile's ``[calibration]``; identity by default)."""
    lo, hi = (np.array(v, dtype=float) for v in units.limits)
    if stops is None:
        return lo, hi
    s = np.ones(len(JOINT_NAMES)) if scale is None else np.asarray(scale, dtype=float)
    o = np.zeros(len(JOINT_NAMES)) if offset is None else np.asarray(offset, dtype=float)
    ends = np.sort((np.asarray(stops, dtype=float) - o) / s, axis=0)
    for j in range(BODY):
        if np.isfinite(ends[:, j]).all():
            lo[j] = min(lo[j], ends[0, j])
            hi[j] = max(hi[j], ends[1, j])
    return lo, hi


def widen_stops(
    model: mujoco.MjModel, index: ArmIndex, lower: np.ndarray, upper: np.ndarray
) -> None:
    """Set ``model``'s body joints' ranges and their position actuators' control ranges to
    ``lower``/``upper`` (radians, arm order), in place: a private copy of the model ``index``
    was found in (a loaded model is shared; the copy's own :func:`arm_index` must not be
    asked before this, it would keep the old limits)."""
    for j, name in enumerate(JOINT_NAMES[:BODY]):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        model.jnt_range[jid] = (lower[j], upper[j])
        a = int(index.actuator[j])
        if model.actuator_ctrllimited[a]:
            model.actuator_ctrlrange[a] = (lower[j], upper[j])


def with_stops(model: mujoco.MjModel, lower: np.ndarray, upper: np.ndarray) -> mujoco.MjModel:
    """``model`` itself when ``lower``/``upper`` (arm units) are its own limits, else a copy
    whose body joints reach them (:func:`widen_stops`)."""
    idx = arm_index(model)
    units = ArmUnits(lower=idx.lower, upper=idx.upper)
    own_lo, own_hi = units.limits
    if np.allclose(lower, own_lo) and np.allclose(upper, own_hi):
        return model
    out = copy.copy(model)
    widen_stops(out, idx, units.to_radians(lower), units.to_radians(upper))
    return out
