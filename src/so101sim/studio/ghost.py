"""A ghost arm in the studio: a translucent copy of the arm, posed from other angles than the
drawn arm's (``so101sim compare --web``: the real arm's recording beside the sim's replay).

:class:`Ghost` draws each moving part of the arm (its visual geoms, merged per body in the
body's frame, as mjviser merges them) once, as a translucent mesh of one colour under
``/ghost/`` in the page's scene, and :meth:`Ghost.pose` moves those meshes to where the arm's
bodies are at a pose (the model's own forward kinematics on a scratch ``MjData``). The model is
not changed: the ghost is drawn by the page, not simulated.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from ..model import arm_index, arm_units

GHOST_COLOUR = (120, 190, 255)  # a light blue: the real arm
GHOST_OPACITY = 0.4


def arm_bodies(model: mujoco.MjModel) -> list[int]:
    """The bodies that move with the arm's six joints (each joint's body and the bodies fixed
    to it below), in the model's order: a scene's free objects are not among them."""
    index = arm_index(model)
    joints = {int(j) for j in range(model.njnt) if model.jnt_qposadr[j] in set(index.qpos)}
    roots = {int(model.jnt_bodyid[j]) for j in joints}
    out = []
    for b in range(1, model.nbody):
        own = range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
        if any(j not in joints for j in own):  # a free object, another mechanism
            continue
        a = b
        while a != 0 and a not in roots:
            a = int(model.body_parentid[a])
        if a in roots:
            out.append(b)
    return out


class Ghost:
    """The arm's moving parts drawn translucent on ``server``'s scene (a viser server), posed
    by :meth:`pose` (arm units: degrees, gripper 0-100)."""

    def __init__(
        self,
        server: Any,
        model: mujoco.MjModel,
        *,
        name: str = "/ghost",
        colour: tuple[int, int, int] = GHOST_COLOUR,
        opacity: float = GHOST_OPACITY,
    ) -> None:
        from mjviser.conversions import merge_geoms  # only where a studio runs

        self.model = model
        self._index = arm_index(model)
        self._units = arm_units(model)
        self._data = mujoco.MjData(model)
        self.handles: dict[int, Any] = {}
        with server.atomic():
            for b in arm_bodies(model):
                geoms = [
                    g
                    for g in range(model.ngeom)
                    if model.geom_bodyid[g] == b
                    and model.geom_group[g] < 3  # what the page shows of the arm itself
                    and model.geom_rgba[g, 3] > 0
                ]
                if not geoms:
                    continue
                mesh = merge_geoms(model, geoms)
                body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}"
                self.handles[b] = server.scene.add_mesh_simple(
                    f"{name}/{body}",
                    np.asarray(mesh.vertices, dtype=np.float32),
                    np.asarray(mesh.faces, dtype=np.uint32),
                    color=colour,
                    opacity=opacity,
                    cast_shadow=False,
                    receive_shadow=False,
                )
        self.angles: np.ndarray | None = None

    def pose(self, angles: np.ndarray) -> None:
        """Move the ghost to ``angles`` (arm units, :data:`~so101sim.units.JOINT_NAMES` order;
        clipped to the joints' limits)."""
        lo, hi = self._units.limits
        self.angles = np.clip(np.asarray(angles, dtype=float), lo, hi)
        d = self._data
        d.qpos[:] = self.model.qpos0
        d.qpos[self._index.qpos] = self._units.to_radians(self.angles)
        mujoco.mj_kinematics(self.model, d)
        for b, handle in self.handles.items():
            handle.position = d.xpos[b].copy()
            handle.wxyz = d.xquat[b].copy()

    def body_positions(self) -> dict[int, np.ndarray]:
        """Where each drawn part of the ghost is now (world frame, metres)."""
        return {b: np.asarray(h.position, dtype=float) for b, h in self.handles.items()}
