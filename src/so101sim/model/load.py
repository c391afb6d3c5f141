"""The SO-101 model: where its files are, loading it once per process, and finding its joints.

The official model (TheRobotStudio/SO-ARM100, ``Simulation/SO101``, Apache-2.0) ships inside
the package under ``so101sim/data/so101_official``; nothing is downloaded. ``scene.xml`` is the
arm on a floor with lights, exactly the file the lab handout opens.
"""

from __future__ import annotations

import logging
import threading
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np

from ..errors import ModelError
from ..units import JOINT_NAMES, ArmUnits
from ..validation import check_input_file
from .cache import load_or_compile

log = logging.getLogger(__name__)

_lock = threading.Lock()
_cache: dict[tuple[str, int, bool, str], mujoco.MjModel] = {}
# how each cached model's MjSpec is made (its file, with its arm profile applied): the model's
# sensor twin (model/twin.py) is compiled from the same spec
_spec_fns: dict[tuple[str, int, bool, str], Callable[[], mujoco.MjSpec]] = {}


def model_dir() -> Path:
    """The folder of the shipped model (``scene.xml``, ``so101_new_calib.xml``, ``assets/``)."""
    return Path(str(resources.files("so101sim") / "data" / "so101_official"))


def scene_path() -> Path:
    """Path of the shipped ``scene.xml`` (the arm, a floor and lights)."""
    return model_dir() / "scene.xml"


def load_model(
    path: str | Path | None = None, *, physics_only: bool = False, arm: object = None
) -> mujoco.MjModel:
    """Compile an MJCF model with an arm profile, once per process per file and profile (and
    once per content across processes: the compiled model is cached on disk, see
    :mod:`so101sim.model.cache`).

    With no argument, loads the shipped ``scene.xml`` with the default arm profile
    (:data:`so101sim.model.arm.PROFILE_DEFAULT`, ``"sts3215"``: the servo model that predicts a
    real STS3215 best, see docs/fidelity.md). Later calls with the same file (same
    modification time) and profile return the same compiled :class:`mujoco.MjModel`, so treat
    it as read-only; use ``copy.copy(model)`` for a private copy you want to change.

    ``arm``: an arm profile (a name such as ``"sts3215"`` or ``"official"``, a TOML path, or an
    :class:`~so101sim.model.arm.ArmProfile`) applied to the servos with ``MjSpec`` at load
    (:func:`so101sim.model.arm.apply_profile`, the one place a profile is applied); None is
    the default profile. ``arm="official"`` is the file's own actuators, exactly (the model is
    compiled from the file as it is).

    ``physics_only=True``: for runs that never draw and never cast rays (``so101sim run
    --headless``): the model without its visual geoms, its collision meshes as their convex
    hulls (:mod:`so101sim.model.trim`), the same physics in about a quarter of the memory and
    load time. Do not cast rays at it (so101sim's renderers draw the full model of the same
    file instead). When it cannot be made (the disk cache is off, or the model's physics may read
    what is dropped: flexes, signed-distance fields, plugins, rangefinders), this is the full
    model.

    Raises:
        ModelError: the file does not exist, does not compile, or lacks the SO-101 joints.
        ProfileError: ``arm`` names no profile or holds invalid values.
    """
    from .arm import apply_profile, load_profile, profile_key

    prof = load_profile(arm)  # type: ignore[arg-type]
    if path is None:
        p = scene_path()
    else:  # empty, too long, missing, a folder, a device: one line saying so, no OSError
        expected = f"an MJCF file such as the shipped {str(scene_path())!r}"
        p = check_input_file(path, "model file", expected=expected, error=ModelError)
    p = p.resolve()
    variant = profile_key(prof)  # "" for the file's own actuators (official)
    key = (str(p), p.stat().st_mtime_ns, physics_only, variant)

    def spec_fn() -> mujoco.MjSpec:
        spec = mujoco.MjSpec.from_file(str(p))
        if variant:
            apply_profile(spec, prof)
        return spec

    def compile_fn() -> mujoco.MjModel:
        if not variant:
            return mujoco.MjModel.from_xml_path(str(p))
        return spec_fn().compile()

    with _lock:
        model = _cache.get(key)
        if model is None:
            try:
                model = load_or_compile(
                    p, compile_fn, variant=variant, physics_only=physics_only, spec_fn=spec_fn
                )
            except (ValueError, mujoco.FatalError) as exc:
                raise ModelError(f"model file {str(p)!r} does not compile: {exc}") from exc
            arm_index(model)  # fail now, not at the first command, if joints are missing
            _cache[key] = model
            _spec_fns[key] = spec_fn
            log.debug("compiled %s with arm profile %s (nq=%d)", p, prof.name, model.nq)
    return model


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


def loaded_models() -> list[tuple[Path, mujoco.MjModel]]:
    """``(file, model)`` for every model :func:`load_model` has compiled in this process (the
    full ones: a physics-only model has nothing to draw)."""
    with _lock:
        return [
            (Path(p), model) for (p, _mtime, physics, _arm), model in _cache.items() if not physics
        ]


def model_spec(model: mujoco.MjModel) -> Callable[[], mujoco.MjSpec] | None:
    """How ``model``'s MjSpec is made (its file, with the arm profile :func:`load_model`
    applied), if :func:`load_model` compiled it; else None. Each call of the result makes a
    fresh spec."""
    with _lock:
        for key, cached in _cache.items():
            if cached is model:
                return _spec_fns.get(key)
    return None


def loaded_specs() -> list[tuple[Callable[[], mujoco.MjSpec], mujoco.MjModel]]:
    """``(spec maker, model)`` for every full model :func:`load_model` has compiled in this
    process (see :func:`model_spec`)."""
    with _lock:
        return [(_spec_fns[k], m) for k, m in _cache.items() if not k[2] and k in _spec_fns]


def model_source(model: mujoco.MjModel) -> Path | None:
    """The MJCF file ``model`` was compiled from by :func:`load_model`, or None if it was built
    another way (or is a copy)."""
    with _lock:
        for (path, _mtime, _physics, _arm), cached in _cache.items():
            if cached is model:
                return Path(path)
    return None
