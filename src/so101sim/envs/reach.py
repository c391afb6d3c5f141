"""Reach (``so101sim/Reach-v0``): bring the tip (the ``gripperframe`` site, between the jaws'
fingertips) to a target point in the air, drawn per episode.

The target is where the tip is at a pose drawn from the episode's generator (after the cube's
placement, before the randomisation): pan ±60°, shoulder lift -60..30°, elbow -40..80°,
wrist flex -40..80°, kept if the tip is 4-25 cm above the table and at least 12 cm from the
pan axis, so every target is reachable. The pick_cube scene's cube stays on the table as a
thing to avoid (and the randomisation's distractors join it).

Success: the tip within :data:`REACH_SUCCESS_M` of the target. Dense reward: 1 - tanh(10 d)
for the distance d (metres); 1 on success. The observation's ``environment_state`` is the
cube's pose (7), the target (x, y, z) and the tip's position now (x, y, z): 13 numbers.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from ..errors import SettingError
from ..kinematics import solve_ik
from ..model.load import arm_index, arm_units
from .base import Evaluation, So101TaskEnv
from .observations import MAX_DISTANCE_M
from .planning import ThroughSag, joint_path

REACH_SUCCESS_M = 0.02
"""How near the target the tip must come (metres)."""
REACH_SCALE = 10.0
"""1/m in the reward's tanh."""
GOAL_JOINTS_DEG = ((-60.0, 60.0), (-60.0, 30.0), (-40.0, 80.0), (-40.0, 80.0))
"""The ranges the target's pose is drawn from (pan, shoulder lift, elbow, wrist flex)."""
GOAL_HEIGHT_M = (0.04, 0.25)
GOAL_MIN_RADIUS_M = 0.12
_MAX_DRAWS = 1000


class ReachTask:
    """The reach task's target and success test (mixed into :class:`ReachEnv`)."""

    task = "reach"
    task_description = "Move the gripper's tip to the target."
    goal = np.zeros(3)

    def _setup_goal(self) -> None:
        self._tip = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, "gripperframe")
        self._scratch = mujoco.MjData(self.model)
        self._arm_qpos = arm_index(self.model).qpos
        self._units = arm_units(self.model)
        self.goal = np.zeros(3)

    def draw_goal(self, rng: np.random.Generator) -> np.ndarray:
        """A reachable target point (metres, world frame) drawn from ``rng``."""
        d = self._scratch
        for _ in range(_MAX_DRAWS):
            body = [rng.uniform(lo, hi) for lo, hi in GOAL_JOINTS_DEG]
            pose = np.array([*body, 0.0, 0.0])
            d.qpos[self._arm_qpos] = self._units.to_radians(pose)
            mujoco.mj_kinematics(self.model, d)
            tip = d.site_xpos[self._tip].copy()
            low, high = GOAL_HEIGHT_M
            if low <= tip[2] <= high and math.hypot(tip[0], tip[1]) >= GOAL_MIN_RADIUS_M:
                return tip
        return tip  # not reached in practice: about a third of the draws are kept

    def tip(self) -> np.ndarray:
        """The tip's position now (metres, world frame)."""
        return self.sim.data.site_xpos[self._tip].copy()

    def evaluate(self) -> Evaluation:
        distance = float(np.linalg.norm(self.tip() - self.goal))
        success = distance <= REACH_SUCCESS_M
        dense = 1.0 if success else 1.0 - math.tanh(REACH_SCALE * distance)
        return Evaluation(success, dense, {"goal_distance_m": distance})


class ReachEnv(ReachTask, So101TaskEnv):
    """Bring the tip to a target point (see the module's text)."""

    scene_name = "pick_cube"
    default_episode_seconds = 4.0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._setup_goal()
        self.observation_space = self._observation_space()

    def _observation_space(self) -> spaces.Dict:
        space = super()._observation_space()
        if self.object_state:
            box = space["environment_state"]
            far = np.full(6, MAX_DISTANCE_M, dtype=np.float32)
            space.spaces["environment_state"] = spaces.Box(
                np.r_[box.low, -far], np.r_[box.high, far], dtype=np.float32
            )
        return space

    def _extra_state(self) -> np.ndarray:
        """The target and the tip, after the objects' poses in ``environment_state``."""
        return np.r_[self.goal, self.tip()]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        """As :meth:`So101TaskEnv.reset`, then a new target (``options={"goal": (x, y, z)}``
        sets it)."""
        super().reset(seed=seed, options=options)
        goal = (options or {}).get("goal")
        if goal is None:
            self.goal = self.draw_goal(self.np_random)
        else:
            self.goal = _goal(goal)
        return self._observation(), self._info(self.evaluate())


class ReachExpert:
    """Reach's scripted expert: the pose that puts the tip on the target (inverse kinematics
    from the arm's pose now), aimed through the servos' sag, in a minimum-jerk joint move of
    1.2 s, then held."""

    MOVE_SECONDS = 1.2

    def __init__(self, env: Any) -> None:
        self.env = getattr(env, "unwrapped", env)
        self._through_sag = ThroughSag(self.env.model)
        self.attempts = 0  # retries, as the other experts count them (none: one move)
        self.reset()

    def reset(self) -> None:
        self._queue: list[np.ndarray] = []
        self._goal: np.ndarray | None = None

    @property
    def phase(self) -> str:
        return "reach" if self._queue else "hold"

    def act(self, observation: Any = None) -> np.ndarray:
        env = self.env
        commanded = env.sim.commanded_array()
        if self._goal is None:
            start = commanded.copy()
            result = solve_ik(env.goal, initial=start, closest=True, model=env.model)
            goal = np.asarray(result.values, dtype=float)
            goal[-1] = start[-1]
            self._goal = self._through_sag(goal)
            n = max(1, round(self.MOVE_SECONDS * env.control_hz))
            self._queue = list(joint_path(start, self._goal, n))
        target = self._queue.pop(0) if self._queue else self._goal
        return env.actions.action_for(target, commanded)


def _goal(value: object) -> np.ndarray:
    try:
        goal = np.asarray(value, dtype=float).reshape(3)
    except (TypeError, ValueError):
        goal = np.full(3, np.nan)
    if not np.all(np.isfinite(goal)) or np.abs(goal).max() > MAX_DISTANCE_M:
        raise SettingError(
            f"goal = {value!r}; expected (x, y, z) in metres, each within ±{MAX_DISTANCE_M}"
        )
    return goal


__all__ = ["REACH_SUCCESS_M", "ReachEnv", "ReachExpert", "ReachTask"]
