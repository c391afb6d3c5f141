"""Where the SO-101 model's files are and where its joints live in a compiled model: the
shipped model's folder and ``scene.xml``, :func:`arm_index` (the six joints and their
actuators), :func:`arm_units` and :func:`default_units`."""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np

from ..errors import ModelError
from ..units import JOINT_NAMES, ArmUnits


def model_dir() -> Path:
    """The folder of the shipped model (``scene.xml``, ``so101_new_calib.xml``, ``assets/``)."""
    return Path(str(resources.files("so101sim") / "data" / "so101_official"))


def scene_path() -> Path:
    """Path of the shipped ``scene.xml`` (the arm, a floor and lights)."""
    return model_dir() / "scene.xml"


@dataclass(frozen=True)
class ArmIndex:
    """Where the six SO-101 joints live in a model's arrays, in :data:`JOINT_NAMES` order."""

    qpos: np.ndarray  # indices into data.qpos
    dof: np.ndarray  # indices into data.qvel
    actuator: np.ndarray  # indices into data.ctrl
    lower: np.ndarray  # joint lower limits, rad
    upper: np.ndarray  # joint upper limits, rad


_index_cache: weakref.WeakKeyDictionary[mujoco.MjModel, ArmIndex] = weakref.WeakKeyDictionary()


def arm_index(model: mujoco.MjModel) -> ArmIndex:
    """Find the six SO-101 joints and their position actuators in ``model`` (cached per model).

    Raises:
        ModelError: a joint or its actuator is missing.
    """
    cached = _index_cache.get(model)
    if cached is not None:
        return cached
    qpos, dof, act, lower, upper = [], [], [], [], []
    for name in JOINT_NAMES:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise ModelError(
                f"model has no joint named {name!r}; an SO-101 model needs the joints "
                f"{', '.join(JOINT_NAMES)}"
            )
        aid = next(
            (a for a in range(model.nu) if model.actuator_trnid[a, 0] == jid),
            -1,
        )
        if aid < 0:
            raise ModelError(f"model has no actuator driving the joint {name!r}")
        qpos.append(model.jnt_qposadr[jid])
        dof.append(model.jnt_dofadr[jid])
        act.append(aid)
        lower.append(model.jnt_range[jid, 0])
        upper.append(model.jnt_range[jid, 1])
    index = ArmIndex(
        qpos=np.array(qpos),
        dof=np.array(dof),
        actuator=np.array(act),
        lower=np.array(lower),
        upper=np.array(upper),
    )
    _index_cache[model] = index
    return index


@lru_cache(maxsize=1)
def default_units() -> ArmUnits:
    """Units for the shipped model, read from its joint ranges (parsed, not compiled): for code
    that has no model at hand. Where a model is known, use :func:`arm_units` of that model."""
    spec = mujoco.MjSpec.from_file(str(model_dir() / "so101_new_calib.xml"))
    ranges = {j.name: np.array(j.range, dtype=float) for j in spec.joints}
    lower = np.array([ranges[n][0] for n in JOINT_NAMES])
    upper = np.array([ranges[n][1] for n in JOINT_NAMES])
    return ArmUnits(lower=lower, upper=upper)


def arm_units(model: mujoco.MjModel) -> ArmUnits:
    """The arm-unit conversions for ``model``'s joint limits."""
    idx = arm_index(model)
    return ArmUnits(lower=idx.lower, upper=idx.upper)
