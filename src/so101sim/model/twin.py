"""A model's contact twin: the same model compiled again from its MJCF file with one
``contact`` sensor added (MuJoCo's ``mjSENS_CONTACT``, ``data="found"``, matching every
contact) and one ``actuatorfrc`` sensor per actuator, so a block stepped in C
(``mujoco.rollout``) reports, per step, how many contacts the step found and the force each
actuator applied, at no Python cost.

Sensors read the state; they do not change it: the twin's physics is the model's, bit for
bit (checked once per model when the twin is made: every array of the two compiled models
but the sensors', the file paths' and those synced below must be equal, else there is no
twin). Only a model
:func:`~so101sim.model.load.load_model` compiled from a file has one (its source is known), or
a model equal to one (a copy of it, or the same file compiled by the user: found by a cheap
signature, then checked whole); for any other model :func:`contact_twin` returns None and
callers fall back to their own means. The fields a user may change after loading
(:data:`_SYNCED`: gains, limits, masses, geometry, friction, margins, the options) are copied
into the twin before each use; a change to any other field after the twin was made is not
seen by it.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass

import mujoco
import numpy as np

from ..errors import So101SimError
from .build import Addition, ModelRecipe, build, built_models, recipe, recipe_of

_SYNCED = (
    "actuator_gainprm", "actuator_biasprm", "actuator_forcerange", "actuator_ctrlrange",
    "actuator_forcelimited", "actuator_ctrllimited", "actuator_gear", "dof_damping",
    "dof_armature", "dof_frictionloss", "jnt_range", "jnt_limited", "jnt_stiffness",
    "qpos_spring", "body_mass", "body_inertia", "body_pos", "body_quat", "body_ipos",
    "body_iquat", "body_gravcomp", "geom_size", "geom_pos", "geom_quat", "geom_rbound",
    "geom_aabb", "geom_friction", "geom_margin", "geom_gap", "geom_contype",
    "geom_conaffinity", "geom_solref", "geom_solimp", "geom_solmix", "geom_priority",
    "geom_condim", "jnt_pos", "jnt_axis", "pair_margin", "pair_gap", "eq_active0",
    "actuator_dynprm", "actuator_dyntype", "actuator_gaintype", "actuator_biastype",
    "actuator_actlimited", "actuator_actrange", "dof_solref", "dof_solimp", "jnt_solref",
    "jnt_solimp", "jnt_margin", "eq_data", "eq_solref", "eq_solimp", "geom_rgba",
)  # fmt: skip
"""Model fields a user may change after load: copied into the twin before each use."""
_OPT = (
    "timestep", "gravity", "wind", "magnetic", "density", "viscosity", "integrator",
    "cone", "jacobian", "solver", "iterations", "ls_iterations", "tolerance", "ls_tolerance",
    "impratio", "o_margin", "o_solref", "o_solimp", "o_friction", "disableflags",
    "enableflags", "noslip_iterations", "noslip_tolerance",
)  # fmt: skip
_IGNORED = ("sensor_", "name_", "names", "mesh_pathadr", "paths", "text_", "tuple_")


@dataclass
class Twin:
    """The twin of one model on one thread: its compiled model, its scratch data, and where
    in ``sensordata`` the contact count is."""

    model: mujoco.MjModel
    data: mujoco.MjData
    found: int  # sensordata column of the contact count
    forces: np.ndarray  # sensordata columns of each actuator's force, actuator order
    views: list[tuple[np.ndarray, np.ndarray]]  # (twin field, model field) pairs to sync

    def sync(self, m: mujoco.MjModel) -> None:
        for mine, theirs in self.views:
            np.copyto(mine, theirs)
        o, src = self.model.opt, m.opt
        for name in _OPT:
            value = getattr(src, name)
            if isinstance(value, np.ndarray):
                getattr(o, name)[:] = value
            else:
                setattr(o, name, value)


_local = threading.local()
_none: weakref.WeakKeyDictionary[mujoco.MjModel, bool] = weakref.WeakKeyDictionary()


def contact_twin(m: mujoco.MjModel) -> Twin | None:
    """``m``'s contact twin on this thread (made once per model and thread, synced with ``m``
    each call), or None where ``m`` has none (see the module)."""
    table = getattr(_local, "twins", None)
    if table is None:
        table = _local.twins = weakref.WeakKeyDictionary()
    twin = table.get(m)
    if twin is None:
        if m in _none:
            return None
        twin = _make(m)
        if twin is None:
            _none[m] = True
            return None
        table[m] = twin
    twin.sync(m)
    return twin


def _make(m: mujoco.MjModel) -> Twin | None:
    """The twin of ``m``: its recipe (its file with its arm profile) with the twin's sensors
    added, built by the model builder (cached on disk like any model), or, for a model so101sim
    did not build (a user's own copy or compile), the recipe of the first built model with
    ``m``'s signature (the shipped scene with the default profile and as the file has it
    first)."""
    own = recipe_of(m)
    candidates = [own] if own is not None else []
    if own is None:
        sig = _signature(m)
        for arm in (None, "official"):  # the shipped scene: the default arm, then the file's
            shipped = recipe(arm=arm)
            if _signature(build(shipped)) == sig:
                candidates.append(shipped)
        candidates += [r for r, lm in built_models() if _signature(lm) == sig]
    for r in candidates:
        twin = _from_recipe(m, r)
        if twin is not None:
            return twin
    return None


def _signature(m: mujoco.MjModel) -> tuple:
    """A cheap look at a model's structure: two models that differ here differ."""
    return (
        m.nq, m.nv, m.nu, m.nbody, m.ngeom, m.nmesh, m.body_parentid.tobytes(),
        m.geom_type.tobytes(), m.geom_dataid.tobytes(),
    )  # fmt: skip


def _add_sensors(spec: mujoco.MjSpec) -> None:
    """The twin's sensors: one contact count, one force per actuator (named if unnamed)."""
    spec.add_sensor(
        name="so101sim_contacts",
        type=mujoco.mjtSensor.mjSENS_CONTACT,
        intprm=[1, 0, 1],  # data="found", no reduction, one match slot
    )
    for a, act in enumerate(spec.actuators):  # each actuator's force (actuatorfrc)
        if not act.name:
            act.name = f"so101sim_actuator_{a}"
        spec.add_sensor(
            name=f"so101sim_force_{a}",
            type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
            objtype=mujoco.mjtObj.mjOBJ_ACTUATOR,
            objname=act.name,
        )


TWIN_SENSORS = Addition("twin1", _add_sensors)


def _from_recipe(m: mujoco.MjModel, r: ModelRecipe) -> Twin | None:
    try:
        tw = build(r.with_additions(TWIN_SENSORS))
    except (ValueError, mujoco.FatalError, So101SimError):
        return None
    if not _same_physics(m, tw):
        return None
    views = [(getattr(tw, n), getattr(m, n)) for n in _SYNCED if hasattr(m, n)]
    first = m.nsensor  # the added sensors come after the model's own
    forces = tw.sensor_adr[first + 1 : first + 1 + m.nu].copy()
    if not np.array_equal(tw.sensor_objid[first + 1 : first + 1 + m.nu], np.arange(m.nu)):
        return None
    twin = Twin(tw, mujoco.MjData(tw), int(tw.sensor_adr[first]), forces, views)
    twin.sync(m)
    return twin


def _same_physics(m: mujoco.MjModel, tw: mujoco.MjModel) -> bool:
    """Whether every array of the two models but the sensors' (and names and paths) is equal,
    or one the twin copies from the model before each use (:data:`_SYNCED`, the options):
    the same physics."""
    if tw.nsensor != m.nsensor + 1 + m.nu:
        return False
    for name in dir(m):
        if name.startswith("_") or name.startswith(_IGNORED) or name in _SYNCED:
            continue
        a = getattr(m, name)
        if not isinstance(a, np.ndarray):
            continue
        b = getattr(tw, name)
        if a.shape != b.shape or not np.array_equal(a, b, equal_nan=True):
            return False
    return all(np.array_equal(getattr(m.opt, n), getattr(tw.opt, n)) for n in _OPT)


__all__ = ["Twin", "contact_twin"]
