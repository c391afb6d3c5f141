"""A physics-only copy of a model, built with ``mujoco.MjSpec``: the same physics in a fraction
of the memory, for runs that never draw and never cast rays (``so101sim run --headless``).

Most of the SO-101's compiled model (66 of 67 MB) is there to draw it and to cast rays at it:
the triangles of its 13 meshes (~322k faces) and a bounding-volume tree over them. MuJoCo's
physics needs neither: it collides meshes through their convex hulls. :func:`physics_only`
edits a copy of the model's spec, through MuJoCo's public API only:

* **visual geoms dropped**: a geom that collides with nothing (``contype = conaffinity = 0``),
  has no name (nothing can refer to it) and sits on a body whose inertia is given (it adds no
  mass) only draws;
* **collision meshes as their convex hulls**: each mesh still used gets the vertices of its
  hull (the full model's ``mesh_polyvert``, put back in the asset's frame with ``mesh_pos`` and
  ``mesh_quat``) and no faces, from which MuJoCo builds the same hull;
* a custom text element (:data:`MARK`) says what it is (:func:`is_physics_only`).

It is then checked against the full model (bodies, masses, inertias, joints, DOFs, actuators,
options and the colliding geoms' kinds) and, when anything differs, not used. The physics is the
same bit for bit until a mesh touches something (the lab motion, any motion in free space);
with contacts, the same contacts at the same steps, and only rounding differs (a hull's frame
sits at its own centre rather than the mesh's), which 12 s of the arm slamming into the floor
and itself grows to a few milliradians (``tests/model/test_modeltrim.py``).

Models whose physics may read meshes in other ways are not trimmed (:func:`why_not`: flexes,
signed-distance fields, plugins, ray-casting sensors such as rangefinders). Do not render a
physics-only model or cast rays at it yourself (``mj_ray``, ``mjv_select``): its visual geoms
are gone. so101sim's renderers draw the full model of the same file instead.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import mujoco
import numpy as np

log = logging.getLogger(__name__)

VERSION = 2
"""Part of a physics-only cache entry's name: raised when what is trimmed changes."""

MARK = "so101sim_physics_only"
"""The name of the custom text element that marks a physics-only model."""

# Arrays that must be equal in the full and the physics-only model (what the dynamics read,
# besides the meshes' own shapes).
_SAME = (
    "body_parentid", "body_jntnum", "body_dofnum", "body_pos", "body_quat", "body_ipos",
    "body_iquat", "body_mass", "body_inertia", "jnt_type", "jnt_qposadr", "jnt_dofadr",
    "jnt_axis", "jnt_pos", "jnt_range", "jnt_limited", "jnt_stiffness", "dof_damping",
    "dof_armature", "dof_frictionloss", "actuator_trnid", "actuator_gainprm",
    "actuator_biasprm", "actuator_ctrlrange", "actuator_forcerange", "qpos0",
)  # fmt: skip


def _visual_only(geom: mujoco.MjsGeom, inertia_given: set[str]) -> bool:
    return (
        geom.contype == 0
        and geom.conaffinity == 0
        and not geom.name
        and geom.parent.name in inertia_given
    )


def _hull_vertices(full: mujoco.MjModel, mesh_id: int) -> np.ndarray:
    """The vertices of mesh ``mesh_id``'s convex hull, in the asset's frame (before scaling)."""
    start, count = full.mesh_polyadr[mesh_id], full.mesh_polynum[mesh_id]
    ids: set[int] = set()
    for p in range(start, start + count):
        a, n = full.mesh_polyvertadr[p], full.mesh_polyvertnum[p]
        ids.update(full.mesh_polyvert[a : a + n].tolist())
    first = full.mesh_vertadr[mesh_id]
    vertices = full.mesh_vert[first + np.array(sorted(ids))].astype(float)
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, full.mesh_quat[mesh_id])
    return vertices @ rotation.reshape(3, 3).T + full.mesh_pos[mesh_id]


def _edited(spec: mujoco.MjSpec, full: mujoco.MjModel) -> mujoco.MjSpec:
    """A copy of ``spec`` without visual geoms, its meshes replaced by their hulls."""
    spec = spec.copy()
    infer = spec.compiler.inertiafromgeom == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE
    given = set() if infer else {b.name for b in spec.bodies if b.explicitinertial}
    for geom in [g for g in spec.geoms if _visual_only(g, given)]:
        spec.delete(geom)
    used = {g.meshname for g in spec.geoms if g.type == mujoco.mjtGeom.mjGEOM_MESH}
    for mesh in list(spec.meshes):
        name, scale, inertia = mesh.name, np.asarray(mesh.scale, dtype=float), mesh.inertia
        if name in used and (np.any(mesh.refpos) or not np.array_equal(mesh.refquat, [1, 0, 0, 0])):
            raise ValueError(f"mesh {name!r} has a reference frame")
        spec.delete(mesh)  # a new mesh of the same name: nothing of the old one's data is kept
        if name not in used:
            continue
        mesh_id = mujoco.mj_name2id(full, mujoco.mjtObj.mjOBJ_MESH, name)
        if mesh_id < 0 or full.mesh_polynum[mesh_id] == 0:
            raise ValueError(f"mesh {name!r} has no convex hull in the full model")
        vertices = _hull_vertices(full, mesh_id) / scale
        spec.add_mesh(name=name, scale=scale, inertia=inertia, uservert=vertices.ravel().tolist())
    spec.add_text(name=MARK, data="meshes are their convex hulls; visual geoms dropped")
    return spec


def _differences(full: mujoco.MjModel, trimmed: mujoco.MjModel) -> list[str]:
    """What differs between the two models' physics (names), besides the meshes' shapes."""
    out = [
        n
        for n in ("nq", "nv", "nu", "nbody", "njnt", "neq", "ntendon", "nsensor", "npair")
        if getattr(full, n) != getattr(trimmed, n)
    ]
    if out:
        return out
    out = [n for n in _SAME if not np.array_equal(getattr(full, n), getattr(trimmed, n))]
    if str(full.opt) != str(trimmed.opt):
        out.append("opt")
    colliding = (full.geom_contype | full.geom_conaffinity) != 0
    kept = (trimmed.geom_contype | trimmed.geom_conaffinity) != 0
    if not np.array_equal(full.geom_type[colliding], trimmed.geom_type[kept]):
        out.append("the colliding geoms")
    return out


def physics_only(
    spec: mujoco.MjSpec,
    full: mujoco.MjModel | None = None,
    *,
    compile_spec: Callable[[mujoco.MjSpec], mujoco.MjModel],
) -> mujoco.MjModel | None:
    """The physics-only model of ``spec`` (unchanged: a copy is edited), whose full compiled
    model is ``full`` (compiled when None); None when the model may read what is dropped
    (:func:`why_not`) or the copy's physics would differ (the reason is logged at DEBUG).
    ``compile_spec``: the model builder's compile (:func:`so101sim.model.build.compile_spec`,
    the one place so101sim compiles a model)."""
    try:
        if full is None:
            full = compile_spec(spec.copy())
        reason = why_not(full)
        if reason is not None:
            raise ValueError(reason)
        trimmed = compile_spec(_edited(spec, full))
        differ = _differences(full, trimmed)
        if differ:
            raise ValueError(f"{', '.join(differ)} would differ")
    # anything unexpected (an asset the copy cannot find, a field another MuJoCo renamed):
    # keep the full model
    except Exception as exc:
        log.debug("physics-only model: not made (%s); keeping the full model", exc)
        return None
    return trimmed


# Sensors that never cast rays at meshes nor read their triangles or trees (an allow-list: a
# sensor type a later MuJoCo adds keeps the full model until it is known).
_SAFE_SENSORS = frozenset(
    {
        "ACCELEROMETER", "ACTUATORFRC", "ACTUATORPOS", "ACTUATORVEL", "BALLANGVEL", "BALLQUAT",
        "CAMPROJECTION", "CLOCK", "CONTACT", "E_KINETIC", "E_POTENTIAL", "FORCE",
        "FRAMEANGACC", "FRAMEANGVEL", "FRAMELINACC", "FRAMELINVEL", "FRAMEPOS", "FRAMEQUAT",
        "FRAMEXAXIS", "FRAMEYAXIS", "FRAMEZAXIS", "GEOMDIST", "GEOMFROMTO", "GEOMNORMAL",
        "GYRO", "INSIDESITE", "JOINTACTFRC", "JOINTLIMITFRC", "JOINTLIMITPOS", "JOINTLIMITVEL",
        "JOINTPOS", "JOINTVEL", "MAGNETOMETER", "SUBTREEANGMOM", "SUBTREECOM", "SUBTREELINVEL",
        "TENDONACTFRC", "TENDONLIMITFRC", "TENDONLIMITPOS", "TENDONLIMITVEL", "TENDONPOS",
        "TENDONVEL", "TORQUE", "TOUCH", "VELOCIMETER",
    }
)  # fmt: skip


def why_not(model: mujoco.MjModel) -> str | None:
    """Why ``model``'s physics may read more of its meshes than their hulls (then it is not
    trimmed), or None: flexes, signed-distance fields (octrees, SDF geoms), plugins, and sensors
    that cast rays (rangefinders) or are not known to be safe."""
    if model.nflex or model.nbvhdynamic:
        return "it has flex objects"
    if model.noct or (model.geom_type == mujoco.mjtGeom.mjGEOM_SDF).any():
        return "it has signed-distance-field geoms"
    if model.nplugin:
        return "it uses plugins"
    kinds = mujoco.mjtSensor
    safe = {
        int(getattr(kinds, f"mjSENS_{n}")) for n in _SAFE_SENSORS if hasattr(kinds, f"mjSENS_{n}")
    }
    for i, kind in enumerate(model.sensor_type.tolist()):
        if kind not in safe:
            return f"its sensor {i} ({mujoco.mjtSensor(kind).name}) may cast rays"
    return None


def is_physics_only(model: mujoco.MjModel) -> bool:
    """Whether ``model`` is a physics-only copy (marked with :data:`MARK`): nothing to draw."""
    return model.ntext > 0 and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, MARK) >= 0
