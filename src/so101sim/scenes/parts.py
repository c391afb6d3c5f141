"""Adding a scene's parts to an ``mujoco.MjSpec``: the table, the objects (free bodies), the
gripper's jaw pads and the contact settings.

Which geoms touch which (MuJoCo's contype/conaffinity bits: two geoms collide when one's
contype shares a bit with the other's conaffinity):

========================  =======  ===========  ==========================================
geom                      contype  conaffinity  touches
========================  =======  ===========  ==========================================
arm, floor, table         1        1            each other (as in the shipped scene)
objects                   2        3            the arm, the table, the floor, each other
jaw meshes (with objects) 4        1            the arm, the table and the floor, not objects
jaw pads                  2        2            objects only
========================  =======  ===========  ==========================================

The jaws' collision meshes are convex hulls (MuJoCo collides a mesh by its hull), and the hull
of each jaw fills most of the space between the fingers, so an object could never get between
them. In scenes with objects the jaws touch objects through thin box *pads* instead: each
pad's inner face lies on the envelope of its finger's toothed gripping face (measured from the
shipped meshes; see docs/tasks.md), so the fingers meet an object where the printed fingers do.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from ..errors import ModelError
from .objects import ContactSettings, SceneObject, Table

ARM_BITS = (1, 1)
OBJECT_BITS = (2, 3)
JAW_MESH_BITS = (4, 1)
PAD_BITS = (2, 2)

GRIPPER_BODY = "gripper"
JAW_BODY = "moving_jaw_so101_v1"
JAW_JOINT = "gripper"
TIP_SITE = "gripperframe"
JAW_MESHES = {GRIPPER_BODY: "wrist_roll_follower_so101_v1", JAW_BODY: "moving_jaw_so101_v1"}

# The pads' inner faces, in the tip site's frame (x along the fingers, out through the tips; z
# from the fixed jaw towards the moving one) with the gripper closed on its lower limit: a line
# (x0, z0) -> (x1, z1) in metres. The fixed finger's teeth step down from z = 0 at the tip
# (x = -6 mm) to z = -5.4 mm at x = -54 mm; the moving finger's from 2.1 mm at x = -2 mm to
# 15.6 mm at x = -54 mm (tilted by the 10° the closed jaw turns past parallel).
FIXED_PAD_FACE = ((-0.050, -0.00495), (0.002, 0.0))
MOVING_PAD_FACE = ((-0.050, 0.01456), (0.002, 0.00106))
PAD_HALF_WIDTH = 0.0085
PAD_THICKNESS = 0.003
CONTAINER_SEGMENTS = 16
"""A bowl's wall is this many flat segments."""
MESH_SIDES = 8
"""A ``mesh`` object's sides: an octagon, so a top-down grasp at any multiple of 90° from its
yaw closes across two flats, as on a cube."""
MESH_CHAMFER = 0.2
"""A ``mesh`` object's top edge is cut off by this share of its half width."""


def _mat(quat: np.ndarray) -> np.ndarray:
    m = np.empty(9)
    mujoco.mju_quat2Mat(m, np.asarray(quat, dtype=float))
    return m.reshape(3, 3)


def _quat(mat: np.ndarray) -> np.ndarray:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(mat, dtype=float).ravel())
    return q


def _pad_in_site(face: tuple[tuple[float, float], ...], solid: float):
    """Centre and rotation (site frame) of a pad whose inner face is the line ``face`` and
    whose body lies on the ``solid`` side (-1: towards -z, +1: towards +z)."""
    (x0, z0), (x1, z1) = face
    u = np.array([x1 - x0, 0.0, z1 - z0])
    length = float(np.linalg.norm(u))
    u /= length
    y = np.array([0.0, 1.0, 0.0])
    n = np.cross(u, y)  # the face's normal, pointing +z-ish
    centre = np.array([(x0 + x1) / 2, 0.0, (z0 + z1) / 2]) + solid * n * PAD_THICKNESS / 2
    return centre, np.column_stack([u, y, n]), length


def _body_frame(spec: mujoco.MjSpec, name: str) -> tuple[np.ndarray, np.ndarray]:
    body = spec.body(name)
    if body is None:
        raise ModelError(
            f"the model has no body {name!r}; scenes with objects need the SO-101 gripper "
            f"({GRIPPER_BODY!r} and {JAW_BODY!r})"
        )
    return np.array(body.pos, dtype=float), _mat(body.quat)


def add_jaw_pads(spec: mujoco.MjSpec, contact: ContactSettings) -> None:
    """Give the jaws pads that touch objects, and keep their hull meshes off objects."""
    site = spec.site(TIP_SITE)
    joint = spec.joint(JAW_JOINT)
    if site is None or joint is None:
        raise ModelError(f"the model has no {TIP_SITE!r} site or {JAW_JOINT!r} joint")
    p_site, r_site = np.array(site.pos, dtype=float), _mat(site.quat)
    p_jaw, r_jaw0 = _body_frame(spec, JAW_BODY)
    _body_frame(spec, GRIPPER_BODY)
    closed = float(joint.range[0])
    c, s = math.cos(closed), math.sin(closed)
    r_jaw = r_jaw0 @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    for body, face, solid in ((GRIPPER_BODY, FIXED_PAD_FACE, -1.0), (JAW_BODY, MOVING_PAD_FACE, 1)):
        centre, rot, length = _pad_in_site(face, solid)
        pos, mat = p_site + r_site @ centre, r_site @ rot  # in the gripper's frame
        if body == JAW_BODY:
            pos, mat = r_jaw.T @ (pos - p_jaw), r_jaw.T @ mat
        geom = spec.body(body).add_geom(
            name=f"{'fixed' if body == GRIPPER_BODY else 'moving'}_jaw_pad",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[length / 2, PAD_HALF_WIDTH, PAD_THICKNESS / 2],
            pos=pos.tolist(),
            quat=_quat(mat).tolist(),
            group=3,
            mass=0.0,
            rgba=[0.2, 0.8, 0.2, 0.5],
        )
        _contact(geom, contact, contact.pad_friction, PAD_BITS)
        for g in spec.body(body).geoms:
            if g.meshname == JAW_MESHES[body] and (g.contype or g.conaffinity):
                g.contype, g.conaffinity = JAW_MESH_BITS


def _contact(geom, contact: ContactSettings, friction: float, bits: tuple[int, int]) -> None:
    geom.contype, geom.conaffinity = bits
    geom.condim = contact.condim
    geom.friction = [friction, contact.torsional, contact.rolling]
    geom.solref = list(contact.solref)
    geom.solimp = [*contact.solimp, *(0.5, 2.0)[: 5 - len(contact.solimp)]]


def set_options(spec: mujoco.MjSpec, contact: ContactSettings) -> None:
    """The solver options a scene with objects uses (cone, impratio, no-slip iterations)."""
    cone = mujoco.mjtCone
    spec.option.cone = cone.mjCONE_ELLIPTIC if contact.cone == "elliptic" else cone.mjCONE_PYRAMIDAL
    spec.option.impratio = contact.impratio
    spec.option.noslip_iterations = contact.noslip_iterations


def add_table(spec: mujoco.MjSpec, table: Table, contact: ContactSettings) -> None:
    """A table whose top is z = 0 under the arm; the floor moves down to its legs' end."""
    if table.surface != "table":
        return
    floor = spec.geom("floor")
    if floor is not None:
        floor.pos = [0.0, 0.0, -table.height]
    thick = 0.03
    top = spec.worldbody.add_body(name="table", pos=[*table.center, 0.0])
    geom = top.add_geom(
        name="table_top",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[table.size[0] / 2, table.size[1] / 2, thick / 2],
        pos=[0.0, 0.0, -thick / 2],
        rgba=list(table.rgba),
    )
    _contact(geom, contact, table.friction, ARM_BITS)
    leg = (table.height - thick) / 2
    inset = (table.size[0] / 2 - 0.04, table.size[1] / 2 - 0.04)
    for sx in (-1, 1):
        for sy in (-1, 1):
            top.add_geom(
                type=mujoco.mjtGeom.mjGEOM_BOX,
                size=[0.02, 0.02, leg],
                pos=[sx * inset[0], sy * inset[1], -thick - leg],
                rgba=[c * 0.8 for c in table.rgba[:3]] + [1.0],
                contype=0,
                conaffinity=0,
            )


def _parts(obj: SceneObject) -> list[tuple[int, list[float], list[float], float]]:
    """The object's geoms: (type, size, pos, yaw about z in radians), body frame at its centre."""
    box, cyl = mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_CYLINDER
    sphere = mujoco.mjtGeom.mjGEOM_SPHERE
    h = obj.height / 2
    if obj.shape == "box":
        return [(box, [s / 2 for s in obj.size], [0.0, 0.0, 0.0], 0.0)]
    if obj.shape == "cylinder":
        return [(cyl, [obj.size[0] / 2, h], [0.0, 0.0, 0.0], 0.0)]
    if obj.shape == "sphere":
        return [(sphere, [obj.size[0] / 2], [0.0, 0.0, 0.0], 0.0)]
    w = obj.wall
    wall_h = h - w / 2  # half height of a wall standing on the floor
    wall_z = w / 2
    if obj.shape == "open_box":
        sx, sy = obj.size[0] / 2, obj.size[1] / 2
        return [
            (box, [sx, sy, w / 2], [0.0, 0.0, -h + w / 2], 0.0),
            (box, [w / 2, sy, wall_h], [sx - w / 2, 0.0, wall_z], 0.0),
            (box, [w / 2, sy, wall_h], [-sx + w / 2, 0.0, wall_z], 0.0),
            (box, [sx - w, w / 2, wall_h], [0.0, sy - w / 2, wall_z], 0.0),
            (box, [sx - w, w / 2, wall_h], [0.0, -sy + w / 2, wall_z], 0.0),
        ]
    r = obj.size[0] / 2
    n = CONTAINER_SEGMENTS
    half_len = (r - w) * math.tan(math.pi / n) + w / 2  # segments overlap at the corners
    parts = [(cyl, [r, w / 2], [0.0, 0.0, -h + w / 2], 0.0)]
    for i in range(n):
        a = 2 * math.pi * i / n
        rc = r - w / 2
        centre = [rc * math.cos(a), rc * math.sin(a), wall_z]
        parts.append((box, [w / 2, half_len, wall_h], centre, a))
    return parts


def mesh_vertices(width: float, height: float) -> np.ndarray:
    """The vertices (metres, centred) of a ``mesh`` object: an octagonal prism ``width`` across
    its flats (a face's normal along x) and ``height`` tall, its top edge chamfered (MuJoCo
    collides and draws the convex hull of these points)."""
    r = width / 2 / math.cos(math.pi / MESH_SIDES)  # across the corners
    c = MESH_CHAMFER * width / 2
    h = height / 2
    angles = [math.pi / MESH_SIDES + 2 * math.pi * k / MESH_SIDES for k in range(MESH_SIDES)]
    rings = ((r, -h), (r, h - c), (r - c / math.cos(math.pi / MESH_SIDES), h))
    return np.array([(rr * math.cos(a), rr * math.sin(a), z) for rr, z in rings for a in angles])


def _volume(kind: int, size: list[float]) -> float:
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return 8 * size[0] * size[1] * size[2]
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return math.pi * size[0] ** 2 * 2 * size[1]
    return 4 / 3 * math.pi * size[0] ** 3


def add_object(spec: mujoco.MjSpec, obj: SceneObject, contact: ContactSettings) -> None:
    """A free body at the object's nominal pose, standing on z = 0."""
    yaw = math.radians(obj.yaw)
    body = spec.worldbody.add_body(
        name=obj.name,
        pos=[obj.pos[0], obj.pos[1], obj.height / 2],
        quat=[math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)],
    )
    body.add_freejoint(name=f"{obj.name}_joint")
    if obj.shape == "mark":  # a goal: touches nothing, gravity compensated so it stays put
        body.gravcomp = 1.0
        body.add_geom(
            name=obj.name,
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            size=[obj.size[0] / 2, obj.height / 2],
            rgba=list(obj.rgba),
            mass=obj.mass,
            contype=0,
            conaffinity=0,
        )
        return
    if obj.shape == "mesh":
        mesh = spec.add_mesh(name=f"{obj.name}_mesh")
        mesh.uservert = mesh_vertices(obj.size[0], obj.height).ravel().tolist()
        geom = body.add_geom(
            name=obj.name,
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=mesh.name,
            rgba=list(obj.rgba),
            mass=obj.mass,
        )
        _contact(geom, contact, obj.friction, OBJECT_BITS)
        return
    parts = _parts(obj)
    total = sum(_volume(k, s) for k, s, _, _ in parts)
    for i, (kind, size, pos, a) in enumerate(parts):
        geom = body.add_geom(
            name=obj.name if len(parts) == 1 else f"{obj.name}_{i}",
            type=kind,
            size=size,
            pos=pos,
            quat=[math.cos(a / 2), 0.0, 0.0, math.sin(a / 2)],
            rgba=list(obj.rgba),
            mass=obj.mass * _volume(kind, size) / total,
        )
        _contact(geom, contact, obj.friction, OBJECT_BITS)
