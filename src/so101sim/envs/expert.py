"""Scripted experts: a policy per task that reaches above the cube, comes down around it,
closes the gripper, lifts it and (for CubeToBowl) carries it over the bowl and lets go, all
planned with the kinematics module (top-down grasps, straight-line moves of the tip).

An expert reads the true object poses from the environment (``env.unwrapped``), so it works
whatever the observations hold, and answers in the environment's control mode
(:meth:`ActionMap.action_for`). Each phase is planned when it starts, from where the arm and
the cube are then; if the cube did not come up with the gripper, the expert tries again (up to
:data:`MAX_ATTEMPTS` times); if a phase cannot be planned (the cube was knocked out of reach),
it holds still for the rest of the episode.

>>> env = gymnasium.make("so101sim/PickCube-v0")
>>> expert = expert_for(env)
>>> obs, info = env.reset(seed=0); expert.reset()
>>> obs, reward, terminated, truncated, info = env.step(expert.act(obs))
"""

from __future__ import annotations

import logging
import math
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import SettingError, UnreachableError
from ..kinematics import quat_yaw
from .grasp import GRASP_Z_M, LIFT_Z_M
from .planning import (
    CLOSED_GRIPPER,
    OPEN_GRIPPER,
    ThroughSag,
    gripper_path,
    joint_path,
    line_path,
    pose_at,
    top_grasp,
)
from .reach import ReachExpert, ReachTask
from .scene_state import SceneState
from .tasks import CubeToBowlTask, PickCubeTask

log = logging.getLogger(__name__)

MAX_ATTEMPTS = 3
SAG_PHASES = frozenset({"lift", "check", "carry", "lower", "release", "retreat", "hold"})
"""The phases commanded through the servos' sag (:class:`~so101sim.envs.planning.ThroughSag`),
from the lift on: the default arm (a real STS3215 at P = 16) holds the cube a centimetre and
more below the planned lift. (Not before the grasp: the jaws come down on the cube as planned
without it, and aiming higher there while the arm still lags put a jaw on the cube's top.)"""
APPROACH_Z_M = 0.06
"""The tip's height above an object before coming down on it (metres)."""
PHASE_SECONDS = {
    "reach": 1.6,
    "descend": 0.8,
    "close": 0.5,
    "settle": 0.2,
    "lift": 0.8,
    "carry": 1.4,
    "lower": 0.4,
    "release": 0.4,
    "retreat": 0.6,
}
"""How long each phase takes (simulated seconds)."""


def _yaw(quat: np.ndarray) -> float:
    """The turn about the vertical (degrees) of a quaternion (w, x, y, z)."""
    return math.degrees(float(quat_yaw(quat)))


class ScriptedExpert:
    """The phases common to the tasks: reach, descend, close, lift (then hold)."""

    phases: tuple[str, ...] = ("reach", "descend", "close", "settle", "lift")
    sag_phases: frozenset[str] = SAG_PHASES
    """The phases commanded through the servos' sag."""

    def __init__(self, env: Any) -> None:
        inner = getattr(env, "unwrapped", env)
        if not isinstance(inner, SceneState) or not hasattr(inner, "actions"):
            raise SettingError(
                f"{env!r} is not an so101sim task environment; expected one, or a task on a "
                "simulation (so101sim.envs.tasks.sim_task)"
            )
        self.env: Any = inner  # So101TaskEnv or SimTask: control_hz, actions, the scene state
        self._through_sag = ThroughSag(inner.model)
        self.reset()

    def reset(self) -> None:
        """Forget the plan: call after each ``env.reset()``."""
        self._queue: deque[np.ndarray] = deque()
        self._phase = -1
        self.attempts = 0
        self._grasp = None
        self._last: np.ndarray | None = None

    @property
    def phase(self) -> str:
        """The phase now being followed ("hold" once the script is done)."""
        return self.phases[self._phase] if 0 <= self._phase < len(self.phases) else "hold"

    def act(self, observation: Any = None) -> np.ndarray:
        """The next action (in the environment's control mode)."""
        while not self._queue and self._phase < len(self.phases):
            self._phase += 1
            if self._phase < len(self.phases):
                try:
                    self._plan(self.phase)
                except UnreachableError as exc:  # e.g. the cube was knocked out of reach
                    log.debug("scripted expert gives up in %s: %s", self.phase, exc)
                    self._phase = len(self.phases)
        commanded = self.env.sim.commanded_array()
        target = (
            self._queue.popleft()
            if self._queue
            else (self._last if self._last is not None else commanded)
        )
        self._last = target  # where the arm should be; the plan goes on from there
        if self.phase in self.sag_phases:  # holding the cube up: aim where the sagging arm ends
            target = self._through_sag(target)
        return self.env.actions.action_for(target, commanded)

    # -- planning
    def _steps(self, phase: str) -> int:
        return max(1, round(PHASE_SECONDS[phase] * self.env.control_hz))

    def _start(self) -> np.ndarray:
        return self._last.copy() if self._last is not None else self.env.sim.commanded_array()

    def _plan(self, phase: str) -> None:
        getattr(self, f"_plan_{phase}")(self._steps(phase))

    def _push(self, rows: np.ndarray) -> None:
        self._queue.extend(np.asarray(rows, dtype=float))

    def _plan_reach(self, n: int) -> None:
        env = self.env
        name = getattr(env, "target", "cube")  # the object to pick up (lift: "object")
        cube = env.object_pose(name)
        start = self._start()
        spec = env.scene.object(name)
        self._grasp = top_grasp(env.model, cube[:2], _yaw(cube[3:]), spec.size[0], GRASP_Z_M, start)
        goal = pose_at(
            env.model, self._grasp.at_height(APPROACH_Z_M), self._grasp.roll, start, OPEN_GRIPPER
        )
        self._push(joint_path(start, goal, n))

    def _plan_descend(self, n: int) -> None:
        g = self._grasp
        self._push(line_path(self.env.model, self._start(), g.position, n, g.roll))

    def _plan_close(self, n: int) -> None:
        self._push(gripper_path(self._start(), CLOSED_GRIPPER, n))

    def _plan_settle(self, n: int) -> None:
        self._push(np.repeat(self._start()[None], n, axis=0))

    def _plan_lift(self, n: int) -> None:
        up = self._grasp.at_height(LIFT_Z_M)
        self._push(line_path(self.env.model, self._start(), up, n, self._grasp.roll))

    def _check_lifted(self) -> None:
        """After a lift that left the cube behind, open and start again from the reach."""
        env = self.env
        if env.grasped(getattr(env, "target", "cube")) or self.attempts + 1 >= MAX_ATTEMPTS:
            return
        self.attempts += 1
        self._push(gripper_path(self._start(), OPEN_GRIPPER, self._steps("release")))
        self._phase = self.phases.index("reach") - 1


class PickCubeExpert(ScriptedExpert):
    """Reach above the cube, come down around it, close, lift it and hold it up."""

    phases = ("reach", "descend", "close", "settle", "lift", "check")

    def _plan_check(self, n: int) -> None:
        self._check_lifted()

    def _steps(self, phase: str) -> int:
        return 0 if phase == "check" else super()._steps(phase)


class CubeToBowlExpert(ScriptedExpert):
    """Pick up the cube, carry it over the bowl at the lift height, lower it, open, retreat."""

    phases = (
        "reach",
        "descend",
        "close",
        "settle",
        "lift",
        "check",
        "carry",
        "lower",
        "release",
        "retreat",
    )

    def _steps(self, phase: str) -> int:
        return 0 if phase == "check" else super()._steps(phase)

    def _plan_check(self, n: int) -> None:
        self._check_lifted()

    def _drop_point(self, z: float) -> np.ndarray:
        env = self.env
        bowl = env.object_pose("bowl")
        width = env.scene.object("cube").size[0]
        g = top_grasp(
            env.model, bowl[:2], 0.0, width, z, self._start(), symmetry=None, roll=self._grasp.roll
        )
        return g.position

    def _plan_carry(self, n: int) -> None:
        target = self._drop_point(LIFT_Z_M)
        self._push(line_path(self.env.model, self._start(), target, n, self._grasp.roll))

    def _plan_lower(self, n: int) -> None:
        bowl = self.env.scene.object("bowl")
        target = self._drop_point(bowl.height + 0.012)
        self._push(line_path(self.env.model, self._start(), target, n, self._grasp.roll))

    def _plan_release(self, n: int) -> None:
        self._push(gripper_path(self._start(), OPEN_GRIPPER, n))

    def _plan_retreat(self, n: int) -> None:
        target = self._drop_point(LIFT_Z_M)
        self._push(line_path(self.env.model, self._start(), target, n, self._grasp.roll))


EXPERTS: dict[type, Callable[[Any], ScriptedExpert]] = {
    PickCubeTask: PickCubeExpert,
    CubeToBowlTask: CubeToBowlExpert,
    ReachTask: ReachExpert,
}


def expert_for(env: Any) -> ScriptedExpert:
    """The scripted expert of ``env``'s task (a Gymnasium env, wrapped or not, or a task on a
    simulation stepped elsewhere: :func:`so101sim.envs.tasks.sim_task`)."""
    inner = getattr(env, "unwrapped", env)
    for cls, make in EXPERTS.items():
        if isinstance(inner, cls):
            return make(env)
    raise SettingError(
        f"no scripted expert for {type(inner).__name__}; experts exist for "
        f"{', '.join(c.__name__ for c in EXPERTS)}"
    )
