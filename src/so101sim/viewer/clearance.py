"""Whether a pose puts the arm into the floor or the table: the pose finders' warnings.

A pose is only a list of angles: the browser's pose finder draws it with physics off, so a
slider can put the tip below the floor, and a pose that is fine for the sliders would drive
the real arm into the table. :func:`pose_warnings` looks at the arm as ``d`` holds it
(positions computed: after ``mj_forward`` or ``mj_kinematics``) against the scene's fixed
geoms (the floor plane, a table, what else the scene fixed to the world):

* the tip (the ``gripperframe`` site) below a plane or inside a box;
* any part of the arm (its collision geoms) into one of them, by MuJoCo's own signed
  distance (``mj_geomDistance``).

Each finding deeper than ``tolerance`` is one sentence, the deepest per part.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..kinematics import TIP_SITE
from ..model.load import arm_index
from ..units import JOINT_NAMES

TOLERANCE = 0.001  # metres: deeper than this is worth a warning (contacts sink ~0.5 mm)
_PROBE = 0.05  # metres: the distance mj_geomDistance looks within


def _name(m: mujoco.MjModel, geom: int) -> str:
    name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, geom)
    if not name:
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[geom]))
    return f"the {name.replace('_', ' ')}" if name else "the scene"


def _collides(m: mujoco.MjModel, geom: int) -> bool:
    return bool(m.geom_contype[geom] or m.geom_conaffinity[geom])


def scene_geoms(m: mujoco.MjModel) -> tuple[list[int], list[int]]:
    """``(fixed, arm)``: the collidable geoms fixed to the world that are not the arm's (floor,
    table), and the collidable geoms of the arm's moving parts."""
    arm_index(m)  # a model without the SO-101's joints: ModelError naming them
    root = int(m.body_rootid[int(m.jnt_bodyid[m.joint(JOINT_NAMES[0]).id])])
    fixed, arm = [], []
    for g in range(m.ngeom):
        if not _collides(m, g):
            continue
        body = int(m.geom_bodyid[g])
        if int(m.body_rootid[body]) == root:
            if int(m.body_weldid[body]) != 0:
                arm.append(g)
        elif int(m.body_weldid[body]) == 0:
            fixed.append(g)
    return fixed, arm


def point_depth(m: mujoco.MjModel, d: mujoco.MjData, geom: int, p: np.ndarray) -> float:
    """How deep the point ``p`` is inside a fixed plane or box geom (metres; <= 0: outside,
    or a shape this does not judge)."""
    local = d.geom_xmat[geom].reshape(3, 3).T @ (np.asarray(p) - d.geom_xpos[geom])
    kind = int(m.geom_type[geom])
    if kind == mujoco.mjtGeom.mjGEOM_PLANE:
        return float(-local[2])
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        inside = m.geom_size[geom] - np.abs(local)
        return float(inside.min()) if (inside > 0).all() else 0.0
    return 0.0


def _where(m: mujoco.MjModel, geom: int) -> str:
    return "below" if int(m.geom_type[geom]) == mujoco.mjtGeom.mjGEOM_PLANE else "into"


def pose_warnings(
    m: mujoco.MjModel, d: mujoco.MjData, *, tolerance: float = TOLERANCE
) -> tuple[str, ...]:
    """The sentences that say where the arm, as ``d`` holds it, is in the floor or the table
    (empty when it is clear of them)."""
    fixed, arm = scene_geoms(m)
    out: list[str] = []
    tip = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, TIP_SITE)
    if tip >= 0:
        for g in fixed:
            depth = point_depth(m, d, g, d.site_xpos[tip])
            if depth > tolerance:
                out.append(f"the tip is {depth * 1000:.0f} mm {_where(m, g)} {_name(m, g)}")
    deepest: dict[int, tuple[float, int]] = {}
    fromto = np.zeros(6)
    for a in arm:
        body = int(m.geom_bodyid[a])
        for g in fixed:
            dist = mujoco.mj_geomDistance(m, d, a, g, _PROBE, fromto)
            if -dist > tolerance and -dist > deepest.get(body, (0.0, -1))[0]:
                deepest[body] = (-dist, g)
    for body, (depth, g) in deepest.items():
        part = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, body) or f"body {body}"
        out.append(f"{part} is {depth * 1000:.0f} mm {_where(m, g)} {_name(m, g)}")
    return tuple(out)


__all__ = ["TOLERANCE", "point_depth", "pose_warnings", "scene_geoms"]
