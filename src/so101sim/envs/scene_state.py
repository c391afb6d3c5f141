"""What the tasks and their scripted experts read of a table-top scene being simulated.

:class:`SceneState` holds a compiled scene (``model``, its :class:`~so101sim.scenes.TableScene`)
and the :class:`~so101sim.sim.simulation.Simulation` that steps it, and reads from them the
objects' poses (now and at the start of the episode), the jaws' contacts and the point
between the jaws. The environments (:class:`so101sim.envs.So101TaskEnv`) are scene states; so
is :class:`SimTask`, a task on a simulation that something else steps (the simulated
follower of :mod:`so101sim.robot` in a scene preset, driven by a scripted expert: see
:mod:`so101sim.robot.scene`), so the same success test and the same expert serve both.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import SettingError
from ..scenes import TableScene, object_qpos
from ..sim.simulation import Simulation
from ..validation import check_range
from .actions import ActionMap, ControlSettings

GRIP_OFFSET_M = 0.014
"""From the tip (on the fixed jaw's face) to the middle of a 2.5 cm grasp, along the tool's z
axis: the point the dense rewards bring to the object."""


class SceneState:
    """The state of a table-top scene's simulation that tasks and experts read (see the
    module's text). ``model`` must have been compiled from ``scene`` (jaw pads and objects)."""

    def __init__(self, model: mujoco.MjModel, sim: Simulation, scene: TableScene) -> None:
        self.model = model
        self.sim = sim
        self.scene = scene
        self._start: dict[str, np.ndarray] = {}
        self._pads = [_geom(model, n) for n in ("fixed_jaw_pad", "moving_jaw_pad")]
        self._qpos = {o.name: object_qpos(model, o.name) for o in scene.objects}
        self._bodies = {
            o.name: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, o.name)
            for o in scene.objects
        }
        self._tip_site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "gripperframe")
        self._geom_body: list[int] = model.geom_bodyid.tolist()  # the body of each geom

    def remember_start(self) -> None:
        """Take the objects' poses now as the episode's start poses (:meth:`start_pose`)."""
        self._start = {o.name: self.object_pose(o.name) for o in self.scene.objects}

    def object_pose(self, name: str) -> np.ndarray:
        """Object ``name``'s pose now: (x, y, z, qw, qx, qy, qz)."""
        return self.sim.data.qpos[self._qpos[name]].copy()

    def start_pose(self, name: str) -> np.ndarray:
        """Object ``name``'s pose at the start of the episode."""
        return self._start[name]

    def grip_centre(self) -> np.ndarray:
        """The point between the jaws a 2.5 cm object is held at (metres, world frame)."""
        d = self.sim.data
        rot = d.site_xmat[self._tip_site].reshape(3, 3)
        return d.site_xpos[self._tip_site] + GRIP_OFFSET_M * rot[:, 2]

    def touching(self, name: str) -> tuple[bool, bool]:
        """Whether the fixed and the moving jaw's pads touch object ``name``."""
        d = self.sim.data
        n = d.ncon
        if n == 0:
            return False, False
        # a few contacts: plain Python over them is cheaper than numpy's calls (a vector env
        # asks this of every world every step)
        body, target = self._geom_body, self._bodies[name]
        fixed, moving = self._pads
        on_fixed = on_moving = False
        for a, b in d.contact.geom[:n].tolist():
            if body[a] == target or body[b] == target:
                on_fixed = on_fixed or fixed in (a, b)
                on_moving = on_moving or moving in (a, b)
        return on_fixed, on_moving

    def grasped(self, name: str) -> bool:
        """Both jaws' pads touch object ``name``."""
        return all(self.touching(name))


class SimTask(SceneState):
    """A task's scene state on a simulation that something else steps, at ``control_hz``
    actions per simulated second, with absolute joint targets as actions (what a scripted
    expert needs besides the state: ``control_hz`` and ``actions``). The task's success test
    comes from the task's class (:class:`so101sim.envs.tasks.PickCubeTask`, ...): see
    :func:`so101sim.envs.tasks.sim_task`."""

    def __init__(
        self, model: mujoco.MjModel, sim: Simulation, scene: TableScene, control_hz: float
    ) -> None:
        super().__init__(model, sim, scene)
        self.control_hz = check_range(control_hz, "control_hz", low=1.0, high=500.0, unit=" Hz")
        self.actions = ActionMap(model, sim.units, ControlSettings("joint"))
        self.remember_start()


def _geom(model: mujoco.MjModel, name: str) -> int:
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
    if gid < 0:
        raise SettingError(f"the scene has no geom {name!r}; expected a scene with objects")
    return int(gid)


__all__ = ["GRIP_OFFSET_M", "SceneState", "SimTask"]
