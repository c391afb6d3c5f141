"""The SO-101 model: where its files are, loading it once per process, and finding its joints.

The official model (TheRobotStudio/SO-ARM100, ``Simulation/SO101``, Apache-2.0) ships inside
the package under ``so101sim/data/so101_official``; nothing is downloaded. ``scene.xml`` is the
arm on a floor with lights, exactly the file the lab handout opens.
"""

from __future__ import annotations

from pathlib import Path

import mujoco

from .arm import ArmLike
from .build import build, built_models, recipe, recipe_of
from .index import ArmIndex, arm_index, arm_units, default_units, model_dir, scene_path

__all__ = [
    "ArmIndex",
    "arm_index",
    "arm_units",
    "default_units",
    "load_model",
    "loaded_models",
    "model_dir",
    "model_source",
    "scene_path",
]


def load_model(
    path: str | Path | None = None, *, physics_only: bool = False, arm: ArmLike = None
) -> mujoco.MjModel:
    """Compile an MJCF model with an arm profile, once per process per file and profile (and
    once per content across processes: the compiled model is cached on disk, see
    :mod:`so101sim.model.cache`): :func:`so101sim.model.build.build` of its recipe.

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
    return build(recipe(path, arm=arm, physics_only=physics_only))


def loaded_models() -> list[tuple[Path, mujoco.MjModel]]:
    """``(file, model)`` for every full model :func:`load_model` (or another caller of the
    model builder) has compiled and cached in this process (a physics-only model has nothing
    to draw)."""
    return [(r.path, m) for r, m in built_models() if not r.physics_only and r.path is not None]


def model_source(model: mujoco.MjModel) -> Path | None:
    """The MJCF file ``model`` was compiled from by :func:`load_model` (the model builder), or
    None if it was built another way (or is a copy)."""
    r = recipe_of(model)
    return r.path if r is not None else None
