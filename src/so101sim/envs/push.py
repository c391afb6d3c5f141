"""Push (``so101sim/Push-v0``): push the 2.5 cm cube across the table onto a mark, a 4 cm
green disc that touches nothing (the ``push`` scene preset; both drawn per episode, at least
8.8 cm apart).

Success: the cube's centre within :data:`PUSH_SUCCESS_M` of the mark's centre (horizontally)
and the cube on the table (its centre within :data:`ON_TABLE_M` of its start height: pushed,
not carried). Dense reward: (reach + 2 push) / 3, reach = 1 - tanh(10 d) for the distance d
from the point between the jaws to the cube, push = 1 - tanh(5 m) for the cube's distance m
from the mark; 1 on success. The observation's ``environment_state`` holds the cube's and
the mark's poses (14 numbers).

The scripted expert (:class:`PushExpert`) cages the cube between the open jaws: the tool
pointing down and turned so that the jaws close along the line from the cube to the mark, the
fixed jaw comes down just behind the cube, waits for the arm to settle there (pushing while the
arm still sank wedged the cube against the table), then moves in a straight line until the cube's
centre would be on the mark's centre (the jaws' closing axis kept along the line: the tool's
roll turned against the pan), and lifts away; if the cube is not on the mark it
plans the push again from where the cube is (up to three pushes).
"""

from __future__ import annotations

import math

import numpy as np

from ..sim.profiles import fractions
from .base import Evaluation, So101TaskEnv
from .expert import APPROACH_Z_M, EXPERTS, MAX_ATTEMPTS, ScriptedExpert
from .planning import joint_path, line_path, pose_at, top_grasp
from .scene_state import SceneState, SimTask
from .tasks import REACH_SCALE, SIM_TASKS

PUSH_SUCCESS_M = 0.02
"""How near the mark's centre the cube's centre must come (metres, horizontally)."""
ON_TABLE_M = 0.005
"""The cube counts as on the table while its centre is within this of its start height."""
PUSH_SCALE = 5.0
"""1/m in the push reward's tanh."""
PUSH_GRIPPER = 70.0
"""The gripper's opening while pushing: the moving jaw then stands 49 mm from the fixed one,
beyond a 2.5 cm cube's far corner whatever its turn."""
CORNER_CLEARANCE_M = 0.005
"""How far outside the cube's corners (whatever its turn) the fixed jaw comes down: with the
gripper at :data:`PUSH_GRIPPER` the moving jaw then clears the far corners by 7 mm."""
PUSH_Z_M = 0.009
"""The tip's height while pushing (as for a grasp: the jaws' ends clear the table)."""
PUSH_SPEED_M_S = 0.08
"""How fast the expert pushes (metres per simulated second)."""
PUSH_OVERSHOOT_M = 0.006
"""The push is planned this far past the mark: the cube ends 7-9 mm short of the plan (the
servos trail it), so the plan aims beyond."""
WAYPOINT_M = 0.02
"""The push's poses are solved this far apart along its line (metres)."""
PUSH_PHASES = {"reach": 1.6, "descend": 0.8, "settle": 0.4, "push": 0.8, "retreat": 0.5}
"""Each phase's length (simulated seconds; the push at least this, longer for long pushes)."""


class PushTask(SceneState):
    """Push the cube onto the mark: the success test (see the module's text)."""

    scene_name = "push"
    task = "push"
    task_description = "Push the red cube onto the green mark."

    def mark_distance(self) -> float:
        """The cube's horizontal distance from the mark's centre (metres)."""
        return float(np.linalg.norm(self.object_pose("cube")[:2] - self.object_pose("mark")[:2]))

    def evaluate(self) -> Evaluation:
        cube = self.object_pose("cube")
        offset = self.mark_distance()
        on_table = abs(float(cube[2] - self.start_pose("cube")[2])) <= ON_TABLE_M
        success = bool(offset <= PUSH_SUCCESS_M and on_table)
        distance = float(np.linalg.norm(self.grip_centre() - cube[:3]))
        reach = 1.0 - math.tanh(REACH_SCALE * distance)
        push = 1.0 - math.tanh(PUSH_SCALE * offset)
        dense = 1.0 if success else (reach + 2.0 * push) / 3.0
        details = {"cube_to_mark_m": offset, "reach_distance_m": distance}
        return Evaluation(success=success, dense=dense, details=details)


class PushEnv(PushTask, So101TaskEnv):
    """Push the cube onto the mark (see the module's text)."""

    default_episode_seconds = 10.0


class PushSimTask(PushTask, SimTask):
    """Push on a simulation stepped elsewhere (:func:`so101sim.envs.sim_task`)."""


class PushExpert(ScriptedExpert):
    """Cage the cube between the open jaws and push it onto the mark (see the module's
    text)."""

    phases = ("reach", "descend", "settle", "push", "retreat", "check")
    sag_phases = frozenset({"descend", "settle", "push", "retreat", "check", "hold"})

    def _steps(self, phase: str) -> int:
        return 0 if phase == "check" else max(1, round(PUSH_PHASES[phase] * self.env.control_hz))

    def reset(self) -> None:
        super().reset()
        self._end = np.zeros(3)
        self._end_roll = 0.0

    def _heading(self) -> float:
        env = self.env
        d = env.object_pose("mark")[:2] - env.object_pose("cube")[:2]
        return math.degrees(math.atan2(d[1], d[0]))

    def _plan_reach(self, n: int) -> None:
        env = self.env
        cube = env.object_pose("cube")
        start = self._start()
        width = env.scene.object("cube").radius * 2 + 2 * CORNER_CLEARANCE_M
        self._grasp = top_grasp(
            env.model, cube[:2], self._heading(), width, PUSH_Z_M, start, symmetry=360.0
        )
        above = self._grasp.at_height(APPROACH_Z_M)
        goal = pose_at(env.model, above, self._grasp.roll, start, PUSH_GRIPPER)
        self._push(joint_path(start, goal, n))

    def _plan_descend(self, n: int) -> None:
        g = self._grasp
        self._push(line_path(self.env.model, self._start(), g.position, n, g.roll))

    def _plan_push(self, n: int) -> None:
        """A straight push from behind the cube to where its near face is on the mark's centre,
        the jaws' closing axis kept along the line (the tool's roll turned against the pan),
        so the cube stays caged: poses solved every :data:`WAYPOINT_M`, joined in joint
        space, timed by a minimum-jerk profile."""
        env = self.env
        start = self._start()
        cube = env.object_pose("cube")[:2]
        mark = env.object_pose("mark")[:2]
        half = env.scene.object("cube").size[0] / 2
        heading = self._heading()
        line = mark - cube
        length = float(np.linalg.norm(line))
        k = max(2, math.ceil(length / WAYPOINT_M))
        poses, pose = [start], start
        over = 1.0 + PUSH_OVERSHOOT_M / max(length, 1e-6)
        for f in np.linspace(0.0, over, k + 1)[1:]:
            g = top_grasp(
                env.model, cube + f * line, heading, 2 * half, PUSH_Z_M, pose, symmetry=360.0
            )
            pose = pose_at(env.model, g.position, g.roll, pose, PUSH_GRIPPER)
            poses.append(pose)
        self._end, self._end_roll = g.position, g.roll
        n = max(n, round(length / PUSH_SPEED_M_S * env.control_hz))
        at = fractions("minimum_jerk", n) * k
        rows = np.array(poses)
        self._push(np.array([np.interp(at, np.arange(k + 1), rows[:, j]) for j in range(6)]).T)

    def _plan_retreat(self, n: int) -> None:
        up = self._end.copy()
        up[2] = APPROACH_Z_M
        self._push(line_path(self.env.model, self._start(), up, n, self._end_roll))

    def _plan_check(self, n: int) -> None:
        """Not on the mark: push again from where the cube is now."""
        if self.env.mark_distance() <= 0.75 * PUSH_SUCCESS_M or self.attempts + 1 >= MAX_ATTEMPTS:
            return
        self.attempts += 1
        self._phase = self.phases.index("reach") - 1


SIM_TASKS["push"] = PushSimTask
EXPERTS[PushTask] = PushExpert

__all__ = ["PUSH_SUCCESS_M", "PushEnv", "PushExpert", "PushSimTask", "PushTask"]
