"""Objects' poses: reading and setting them in a compiled scene (:func:`object_pose`,
:func:`place_object`), and start poses drawn from a seed: each object with an ``x_range``,
``y_range`` or ``yaw_range`` gets a pose drawn uniformly within them, apart from the others;
the rest keep their nominal pose. The same seed gives the same poses.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace

import mujoco
import numpy as np

from ..errors import SettingError
from .objects import SceneObject

SEPARATION_GAP_M = 0.05
"""The free space kept between two objects' bounding circles when their poses are drawn, so
the open jaws can come down around one without touching the other (metres)."""
KEEP_OUT_GAP_M = 0.01
"""The free space kept between an object's bounding circle and a keep-out rectangle."""
MAX_DRAWS = 1000
"""Tries to find poses that keep the objects apart before giving up."""

Placement = tuple[float, float, float]
"""(x, y, yaw): metres in the base frame, degrees about the vertical."""
Rectangle = tuple[float, float, float, float]
"""(x_min, x_max, y_min, y_max): a patch of the table, metres in the base frame."""


def _draw(obj: SceneObject, rng: np.random.Generator) -> Placement:
    x = rng.uniform(*obj.x_range) if obj.x_range is not None else obj.pos[0]
    y = rng.uniform(*obj.y_range) if obj.y_range is not None else obj.pos[1]
    yaw = rng.uniform(*obj.yaw_range) if obj.yaw_range is not None else obj.yaw
    return float(x), float(y), float(yaw)


def _apart(obj: SceneObject, p: Placement, placed: list[tuple[SceneObject, Placement]]) -> bool:
    return all(
        math.hypot(p[0] - q[0], p[1] - q[1]) >= obj.radius + other.radius + SEPARATION_GAP_M
        for other, q in placed
    )


def _clear(obj: SceneObject, p: Placement, keep_out: Sequence[Rectangle]) -> bool:
    for x0, x1, y0, y1 in keep_out:
        dx, dy = max(x0 - p[0], 0.0, p[0] - x1), max(y0 - p[1], 0.0, p[1] - y1)
        if math.hypot(dx, dy) < obj.radius + KEEP_OUT_GAP_M:
            return False
    return True


def _draw_all(
    objects: Sequence[SceneObject], gen: np.random.Generator, keep_out: Sequence[Rectangle]
) -> dict[str, Placement] | None:
    """One try: a pose for every object, or None as soon as one lands too close."""
    done: list[tuple[SceneObject, Placement]] = []
    for obj in objects:
        p = _draw(obj, gen)
        drawn = obj.x_range is not None or obj.y_range is not None
        if not _apart(obj, p, done) or (drawn and not _clear(obj, p, keep_out)):
            return None
        done.append((obj, p))
    return {obj.name: p for obj, p in done}


def sample_placements(
    objects: Sequence[SceneObject],
    rng: np.random.Generator | int | None,
    keep_out: Sequence[Rectangle] = (),
) -> dict[str, Placement]:
    """A start pose for each object: drawn within its ranges (``rng``: a NumPy generator or a
    seed), at least :data:`SEPARATION_GAP_M` apart from the others and clear of the
    ``keep_out`` rectangles, or its nominal pose (objects without ranges).

    Raises:
        SettingError: no poses keeping the objects apart were found (ranges too small).
    """
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    objects = [o.validated() for o in objects]
    for _ in range(MAX_DRAWS):
        poses = _draw_all(objects, gen, keep_out)
        if poses is not None:
            return poses
    raise SettingError(
        f"no start poses keep the objects {', '.join(o.name for o in objects)} "
        f"{SEPARATION_GAP_M * 100:g} cm apart within their ranges and out of the keep-out "
        f"patches after {MAX_DRAWS} tries; expected wider x_range/y_range or fewer objects"
    )


def placed(
    objects: Sequence[SceneObject], poses: Mapping[str, Placement]
) -> tuple[SceneObject, ...]:
    """The objects moved to ``poses`` (those not named keep theirs)."""
    out = []
    for obj in objects:
        if obj.name in poses:
            x, y, yaw = poses[obj.name]
            obj = replace(obj, pos=(x, y), yaw=yaw)
        out.append(obj)
    return tuple(out)


def place_objects(
    model: mujoco.MjModel, data: mujoco.MjData, poses: Mapping[str, Placement]
) -> None:
    """Put each named object at rest at its pose on the table, then ``mj_forward``."""
    for name, (x, y, yaw) in poses.items():
        place_object(model, data, name, x, y, yaw)
    mujoco.mj_forward(model, data)


def _joint(model: mujoco.MjModel, name: str) -> int:
    jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_joint")
    if jid < 0 or model.jnt_type[jid] != mujoco.mjtJoint.mjJNT_FREE:
        raise SettingError(f"the model has no object {name!r} (a body with a free joint)")
    return int(jid)


def object_qpos(model: mujoco.MjModel, name: str) -> slice:
    """Where object ``name``'s pose (x, y, z, quaternion w, x, y, z) is in ``data.qpos``."""
    adr = int(model.jnt_qposadr[_joint(model, name)])
    return slice(adr, adr + 7)


def object_qvel(model: mujoco.MjModel, name: str) -> slice:
    """Where object ``name``'s velocity (linear, then angular) is in ``data.qvel``."""
    adr = int(model.jnt_dofadr[_joint(model, name)])
    return slice(adr, adr + 6)


def object_pose(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    """Object ``name``'s pose: (x, y, z, qw, qx, qy, qz), metres, in the world frame."""
    return data.qpos[object_qpos(model, name)].copy()


def place_object(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    name: str,
    x: float,
    y: float,
    yaw: float = 0.0,
    z: float | None = None,
) -> None:
    """Put object ``name`` at rest at (x, y) turned by ``yaw`` degrees; standing on the table
    (its nominal height) unless ``z`` is given. Call ``mj_forward`` afterwards."""
    q = object_qpos(model, name)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    z0 = float(model.body_pos[body][2]) if z is None else z
    a = math.radians(yaw) / 2
    data.qpos[q] = (x, y, z0, math.cos(a), 0.0, 0.0, math.sin(a))
    data.qvel[object_qvel(model, name)] = 0.0
