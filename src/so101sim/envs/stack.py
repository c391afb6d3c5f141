"""Stack (``so101sim/Stack-v0``): put the red 2.5 cm cube on the blue 3 cm block (the
``stack`` scene preset; both drawn per episode, apart).

Success: the cube rests on the block's top (its centre within :data:`STACK_OFFSET_M` of the
block's centre horizontally, its bottom within :data:`STACK_HEIGHT_M` of the block's top),
the jaws have let go of it, it has settled (slower than
:data:`~so101sim.envs.tasks.SETTLED_SPEED`) and the block still stands where it was (moved
less than :data:`BLOCK_MOVED_M`). The sizes are read from the compiled model, so the
``object_size`` randomisation is judged with the sizes it drew. Dense reward: (reach + grasp +
carry + on_block) / 5 as for CubeToBowl (carry = 1 - tanh(5 h) for the horizontal distance h
from the cube to the block while the cube is held up or on the block); 1 on success. The
observation's ``environment_state`` holds the cube's and the block's poses (14 numbers).

The scripted expert (:class:`StackExpert`) picks the cube as the pick expert does, carries it
over the block at the lift height, lowers it until it is 4 mm above the block's top (the
tip placed so that the cube, where it sits in the jaws, is over the block's centre), opens
and lifts away (the bowl expert's script with the block as the target).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from ..scenes import object_qvel
from .base import Evaluation, So101TaskEnv
from .expert import EXPERTS, CubeToBowlExpert
from .grasp import GRASP_Z_M
from .planning import line_path, top_grasp
from .scene_state import SceneState, SimTask
from .tasks import CARRY_SCALE, REACH_SCALE, SETTLED_SPEED, SIM_TASKS

STACK_OFFSET_M = 0.012
"""How near the block's centre the cube's centre must be, horizontally (metres)."""
STACK_HEIGHT_M = 0.004
"""How far the cube's bottom may be from the block's top (metres)."""
BLOCK_MOVED_M = 0.02
"""The block counts as standing where it was while it moved less than this (metres)."""
DROP_GAP_M = 0.004
"""The expert lets go of the cube this far above the block's top (metres)."""


class StackTask(SceneState):
    """Put the cube on the block: the success test (see the module's text)."""

    scene_name = "stack"
    task = "stack"
    task_description = "Stack the red cube on the blue block."

    def half_height(self, name: str) -> float:
        """Half the height of box object ``name`` as compiled (metres)."""
        gid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, name)
        return float(self.model.geom_size[gid][2])

    def evaluate(self) -> Evaluation:
        cube = self.object_pose("cube")
        block = self.object_pose("block")
        offset = float(np.linalg.norm(cube[:2] - block[:2]))
        gap = (cube[2] - self.half_height("cube")) - (block[2] + self.half_height("block"))
        on_block = offset <= STACK_OFFSET_M and abs(float(gap)) <= STACK_HEIGHT_M
        moved = float(np.linalg.norm(block[:3] - self.start_pose("block")[:3]))
        touching = self.touching("cube")
        grasped = all(touching)
        speed = float(np.linalg.norm(self.sim.data.qvel[object_qvel(self.model, "cube")][:3]))
        success = bool(
            on_block and not any(touching) and speed < SETTLED_SPEED and moved < BLOCK_MOVED_M
        )
        distance = float(np.linalg.norm(self.grip_centre() - cube[:3]))
        reach = 1.0 - math.tanh(REACH_SCALE * distance)
        lifted = cube[2] - self.start_pose("cube")[2] > 0.01
        carry = 1.0 - math.tanh(CARRY_SCALE * offset) if (grasped and lifted) or on_block else 0.0
        dense = 1.0 if success else (reach + float(grasped) + carry + float(on_block)) / 5.0
        details = {
            "cube_to_block_m": offset,
            "grasped": float(grasped),
            "on_block": float(on_block),
            "block_moved_m": moved,
        }
        return Evaluation(success=success, dense=dense, details=details)


class StackEnv(StackTask, So101TaskEnv):
    """Put the cube on the block (see the module's text)."""

    default_episode_seconds = 12.0


class StackSimTask(StackTask, SimTask):
    """Stack on a simulation stepped elsewhere (:func:`so101sim.envs.sim_task`)."""


class StackExpert(CubeToBowlExpert):
    """Pick up the cube, carry it over the block, lower it onto it, open, retreat."""

    def _drop_point(self, z: float) -> np.ndarray:
        env = self.env
        block = env.object_pose("block")
        width = env.scene.object("cube").size[0]
        g = top_grasp(
            env.model, block[:2], 0.0, width, z, self._start(), symmetry=None, roll=self._grasp.roll
        )
        return g.position

    def _plan_lower(self, n: int) -> None:
        """Down onto the block, the cube's centre (as it sits in the hand now, measured) over
        the block's: the carry aims the tip, and the cube is rarely exactly where the grasp
        was planned in the jaws."""
        env = self.env
        # the tip holds the cube as it held it on the table (GRASP_Z_M up from its bottom)
        tip_z = 2 * env.half_height("block") + DROP_GAP_M + GRASP_Z_M
        target = self._drop_point(tip_z)
        in_hand = env.object_pose("cube")[:2] - env.sim.data.site_xpos[env._tip_site][:2]
        target[:2] = env.object_pose("block")[:2] - in_hand
        self._push(line_path(env.model, self._start(), target, n, self._grasp.roll))


SIM_TASKS["stack"] = StackSimTask
EXPERTS[StackTask] = StackExpert

__all__ = ["StackEnv", "StackExpert", "StackSimTask", "StackTask"]
