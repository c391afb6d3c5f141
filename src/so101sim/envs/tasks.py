"""The tasks: pick up the cube (``so101sim/PickCube-v0``), put the cube in the bowl
(``so101sim/CubeToBowl-v0``). What counts as success, and the dense rewards (0..1, and 1 on
success):

* **PickCube**: success when both jaws hold the cube and its centre is at least
  :data:`LIFT_SUCCESS_M` above where it started. Dense reward: (reach + grasp + 2 lift) / 4,
  reach = 1 - tanh(10 d) for the distance d (metres) from the point between the jaws to the
  cube, grasp = 1 while both jaws touch it, lift = the share of :data:`LIFT_SUCCESS_M` risen
  while grasped.
* **CubeToBowl**: success when the cube is inside the bowl (its centre within the bowl's
  inner radius less half the cube, below the rim), the jaws have let go of it and it has
  settled (slower than :data:`SETTLED_SPEED`). Dense reward: (reach + grasp + carry + inside)
  / 5, carry = 1 - tanh(5 h) for the horizontal distance h from the cube to the bowl's centre
  while the cube is held up or in the bowl, inside = 1 once it is in the bowl.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from ..errors import SettingError
from ..scenes import SCENE_PRESETS, TableScene, object_qvel
from ..sim.simulation import Simulation
from .base import Evaluation, So101TaskEnv
from .scene_state import SceneState, SimTask

LIFT_SUCCESS_M = 0.03
"""How high the cube's centre must rise for PickCube to succeed (metres)."""
REACH_SCALE = 10.0
"""1/m in the reach reward's tanh."""
CARRY_SCALE = 5.0
"""1/m in the carry reward's tanh."""
SETTLED_SPEED = 0.05
"""The cube counts as in the bowl once it moves slower than this (m/s)."""


class PickCubeTask(SceneState):
    """Pick up the 2.5 cm cube and hold it at least 3 cm above the table: the success test,
    for the environment and for a simulation stepped elsewhere (:func:`sim_task`)."""

    scene_name = "pick_cube"
    task = "pick_cube"
    task_description = "Pick up the red cube."

    target = "cube"
    """The object to pick up."""

    def evaluate(self) -> Evaluation:
        name = self.target
        cube = self.object_pose(name)
        rise = float(cube[2] - self.start_pose(name)[2])
        grasped = self.grasped(name)
        distance = float(np.linalg.norm(self.grip_centre() - cube[:3]))
        reach = 1.0 - math.tanh(REACH_SCALE * distance)
        lift = float(np.clip(rise / LIFT_SUCCESS_M, 0.0, 1.0)) if grasped else 0.0
        success = grasped and rise >= LIFT_SUCCESS_M
        dense = 1.0 if success else (reach + float(grasped) + 2.0 * lift) / 4.0
        details = {f"{name}_rise_m": rise, "grasped": float(grasped), "reach_distance_m": distance}
        return Evaluation(success=success, dense=dense, details=details)


class CubeToBowlTask(SceneState):
    """Pick up the cube and put it in the bowl: the success test (see :class:`PickCubeTask`)."""

    scene_name = "cube_to_bowl"
    task = "cube_to_bowl"
    task_description = "Put the red cube in the blue bowl."

    @property
    def _cube_dofs(self) -> slice:
        return object_qvel(self.model, "cube")

    def evaluate(self) -> Evaluation:
        cube = self.object_pose("cube")
        bowl = self.object_pose("bowl")
        spec_cube = self.scene.object("cube")
        spec_bowl = self.scene.object("bowl")
        half = spec_cube.size[0] / 2
        inner = spec_bowl.size[0] / 2 - spec_bowl.wall
        bottom = bowl[2] - spec_bowl.height / 2
        offset = float(np.linalg.norm(cube[:2] - bowl[:2]))
        inside = offset <= inner - half and cube[2] - bottom <= spec_bowl.height
        touching = self.touching("cube")
        grasped = all(touching)
        speed = float(np.linalg.norm(self.sim.data.qvel[self._cube_dofs][:3]))
        success = bool(inside and not any(touching) and speed < SETTLED_SPEED)
        distance = float(np.linalg.norm(self.grip_centre() - cube[:3]))
        reach = 1.0 - math.tanh(REACH_SCALE * distance)
        lifted = cube[2] - self.start_pose("cube")[2] > 0.01
        carry = 1.0 - math.tanh(CARRY_SCALE * offset) if (grasped and lifted) or inside else 0.0
        dense = 1.0 if success else (reach + float(grasped) + carry + float(inside)) / 5.0
        details = {"cube_to_bowl_m": offset, "grasped": float(grasped), "in_bowl": float(inside)}
        return Evaluation(success=success, dense=dense, details=details)


class PickCubeEnv(PickCubeTask, So101TaskEnv):
    """Pick up the 2.5 cm cube and hold it at least 3 cm above the table."""

    default_episode_seconds = 8.0


class CubeToBowlEnv(CubeToBowlTask, So101TaskEnv):
    """Pick up the cube and put it in the bowl."""

    default_episode_seconds = 12.0


class LiftCylinderEnv(PickCubeEnv):
    """Lift the 2.5 cm cylinder standing on the table 3 cm (the pick test on another shape)."""

    scene_name = "lift_cylinder"
    task = "lift_cylinder"
    task_description = "Pick up the orange cylinder."
    target = "object"


class LiftSphereEnv(PickCubeEnv):
    """Lift the 2.8 cm ball 3 cm (the pick test on another shape)."""

    scene_name = "lift_sphere"
    task = "lift_sphere"
    task_description = "Pick up the green ball."
    target = "object"


class LiftMeshEnv(PickCubeEnv):
    """Lift the 2.5 cm octagonal mesh 3 cm (a convex mesh made at load time; the pick test
    on another shape)."""

    scene_name = "lift_mesh"
    task = "lift_mesh"
    task_description = "Pick up the purple nut."
    target = "object"


class PickCubeSimTask(PickCubeTask, SimTask):
    """PickCube on a simulation stepped elsewhere (:func:`sim_task`)."""


class CubeToBowlSimTask(CubeToBowlTask, SimTask):
    """CubeToBowl on a simulation stepped elsewhere (:func:`sim_task`)."""


class LiftCylinderSimTask(PickCubeSimTask):
    """Lift the cylinder on a simulation stepped elsewhere (:func:`sim_task`)."""

    scene_name = task = "lift_cylinder"
    target = "object"


class LiftSphereSimTask(PickCubeSimTask):
    """Lift the ball on a simulation stepped elsewhere (:func:`sim_task`)."""

    scene_name = task = "lift_sphere"
    target = "object"


class LiftMeshSimTask(PickCubeSimTask):
    """Lift the mesh on a simulation stepped elsewhere (:func:`sim_task`)."""

    scene_name = task = "lift_mesh"
    target = "object"


SIM_TASKS: dict[str, type[SimTask]] = {
    "pick_cube": PickCubeSimTask,
    "cube_to_bowl": CubeToBowlSimTask,
    "lift_cylinder": LiftCylinderSimTask,
    "lift_sphere": LiftSphereSimTask,
    "lift_mesh": LiftMeshSimTask,
}
"""The tasks by name (each is also its scene preset's name)."""


def sim_task(
    task: str, model: mujoco.MjModel, sim: Simulation, scene: TableScene, control_hz: float
) -> SimTask:
    """Task ``task`` (``pick_cube``, ``cube_to_bowl``) on ``sim``, a simulation of ``model``
    compiled from ``scene`` that something else steps (e.g. the simulated follower in that
    scene preset) ``control_hz`` times a simulated second: its ``evaluate()`` says whether the
    task succeeded, and :func:`so101sim.envs.expert_for` gives its scripted expert. The
    objects' poses now are the episode's start poses (``remember_start()`` takes them anew).

    Raises:
        SettingError: an unknown task (the message lists them), or a scene without the task's
            objects.
    """
    cls = SIM_TASKS.get(task)
    if cls is None:
        raise SettingError(f"task = {task!r} is unknown; expected one of {', '.join(SIM_TASKS)}")
    needed = {o.name for o in SCENE_PRESETS[task].objects}
    missing = sorted(needed - {o.name for o in scene.objects})
    if missing:
        raise SettingError(
            f"task {task!r} needs the object(s) {', '.join(missing)} in its scene; expected the "
            f"{task!r} scene preset"
        )
    return cls(model, sim, scene, control_hz)
