"""Look at (``so101sim/LookAt-v0``): turn the arm so that the wrist camera looks straight at the
cube (the ``pick_cube`` scene preset: the cube drawn per episode; the randomisation's
distractors join it).

Judged geometrically, without drawing an image: the cube's centre projected through the wrist
camera (its pose and field of view as compiled: the environment always has the ``wrist``
camera, drawn only when ``cameras`` names it, so the ``camera_m``/``camera_fovy_deg``
randomisation is judged as drawn) lands ``r`` from the image's centre, in units of half the
image's height (r = 1: the top or bottom edge). Success: the cube in front of the lens and
r <= :data:`LOOK_SUCCESS`. Dense reward: 1 - tanh(2 r) (0 behind the lens); 1 on success. The
observation's ``environment_state`` is the cube's pose (7) and the projection (u, v) (2): u to
the right, v up, in the same units (0, 0 while the cube is behind the lens).

The scripted expert (:class:`LookAtExpert`) solves for the pose (damped least squares on the
projection, from a pose with the tip 12 cm above the cube), moves there in a minimum-jerk
joint move through the servos' sag, then corrects from the measured projection every 0.2 s.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces

from ..kinematics import solve_ik
from ..model.load import arm_index, arm_units
from ..scenes import camera
from ..units import GRIPPER_INDEX
from .base import Evaluation, So101TaskEnv
from .expert import EXPERTS
from .planning import ThroughSag, joint_path

LOOK_SUCCESS = 0.1
"""How near the image's centre the cube's centre must be seen (half image heights)."""
LOOK_SCALE = 2.0
"""1/(half image heights) in the reward's tanh."""
LOOK_CAMERA = "wrist"
LOOK_FROM_M = 0.12
"""The expert's first guess: the tip this high above the cube, pointing down."""


def projection(model: mujoco.MjModel, data: mujoco.MjData, cam: int, point: np.ndarray):
    """Where ``point`` (world frame) is seen by camera ``cam``: (u, v) in half image heights
    from the image's centre (u right, v up), or None behind the lens. ``data`` must have its
    camera poses computed (``mj_kinematics`` + ``mj_camlight``, or a step)."""
    rot = data.cam_xmat[cam].reshape(3, 3)
    p = rot.T @ (np.asarray(point, dtype=float) - data.cam_xpos[cam])
    depth = -p[2]  # MuJoCo cameras look along their -z axis
    if depth <= 1e-6:
        return None
    scale = math.tan(math.radians(float(model.cam_fovy[cam])) / 2) * depth
    return np.array([p[0] / scale, p[1] / scale])


class LookAtTask:
    """The look-at task's success test (mixed into :class:`LookAtEnv`)."""

    task = "look_at"
    task_description = "Look at the red cube with the wrist camera."
    target = "cube"

    def _setup_camera(self) -> None:
        self._cam = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, LOOK_CAMERA)

    def seen_at(self) -> np.ndarray | None:
        """The target's projection in the wrist camera now (see :func:`projection`)."""
        point = self.object_pose(self.target)[:3]
        return projection(self.model, self.sim.data, self._cam, point)

    def evaluate(self) -> Evaluation:
        uv = self.seen_at()
        r = math.inf if uv is None else float(np.hypot(*uv))
        success = r <= LOOK_SUCCESS
        shaped = 1.0 - math.tanh(LOOK_SCALE * r)  # 0 behind the lens (r infinite)
        dense = 1.0 if success else shaped
        return Evaluation(success, dense, {"image_offset": min(r, 1e3)})


class LookAtEnv(LookAtTask, So101TaskEnv):
    """Look at the cube with the wrist camera (see the module's text)."""

    scene_name = "pick_cube"
    default_episode_seconds = 4.0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._setup_camera()
        self.observation_space = self._observation_space()

    def _camera_specs(self) -> list:
        specs = super()._camera_specs()
        if LOOK_CAMERA not in {s.name for s in specs}:
            specs.append(camera(LOOK_CAMERA))  # judged through it; drawn only if named
        return specs

    def _observation_space(self) -> spaces.Dict:
        space = super()._observation_space()
        if self.object_state:
            box = space["environment_state"]
            far = np.full(2, 1e3, dtype=np.float32)
            space.spaces["environment_state"] = spaces.Box(
                np.r_[box.low, -far], np.r_[box.high, far], dtype=np.float32
            )
        return space

    def _extra_state(self) -> np.ndarray:
        """Where the wrist camera sees the cube (0, 0 behind the lens), after the objects'
        poses in ``environment_state``."""
        uv = self.seen_at()
        return np.zeros(2) if uv is None else np.clip(uv, -1e3, 1e3)


class LookAtExpert:
    """Look-at's scripted expert (see the module's text)."""

    MOVE_SECONDS = 1.2
    CORRECT_SECONDS = 0.2
    ITERATIONS = 30

    def __init__(self, env: Any) -> None:
        self.env = getattr(env, "unwrapped", env)
        m = self.env.model
        self._through_sag = ThroughSag(m)
        self._scratch = mujoco.MjData(m)
        self._qpos = arm_index(m).qpos
        self._units = arm_units(m)
        self.attempts = 0
        self.reset()

    def reset(self) -> None:
        self._queue: list[np.ndarray] = []
        self._goal: np.ndarray | None = None
        self._command: np.ndarray | None = None
        self._wait = 0

    @property
    def phase(self) -> str:
        return "look" if self._queue else "correct"

    def _seen(self, pose: np.ndarray, point: np.ndarray) -> np.ndarray | None:
        m, d = self.env.model, self._scratch
        d.qpos[self._qpos] = self._units.to_radians(pose)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)
        return projection(m, d, self.env._cam, point)

    def solve(self, pose: np.ndarray, point: np.ndarray) -> np.ndarray:
        """The pose near ``pose`` (arm units) whose wrist camera sees ``point`` at the image's
        centre: damped least squares over pan, shoulder lift, elbow and wrist flex."""
        pose = np.asarray(pose, dtype=float).copy()
        lower, upper = self._units.limits
        joints = list(range(4))  # pan, shoulder lift, elbow, wrist flex
        for _ in range(self.ITERATIONS):
            uv = self._seen(pose, point)
            if uv is None:
                return pose
            if np.hypot(*uv) < 0.01:
                break
            jac = np.empty((2, len(joints)))
            for k, j in enumerate(joints):
                step = pose.copy()
                step[j] += 0.5
                seen = self._seen(step, point)
                jac[:, k] = (seen - uv) / 0.5 if seen is not None else 0.0
            delta = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(2), -uv)
            pose[joints] += np.clip(delta, -10.0, 10.0)
            pose = np.clip(pose, lower, upper)
        return pose

    def act(self, observation: Any = None) -> np.ndarray:
        env = self.env
        commanded = env.sim.commanded_array()
        point = env.object_pose(env.target)[:3]
        if self._goal is None:
            start = commanded.copy()
            above = point + np.array([0.0, 0.0, LOOK_FROM_M])
            guess = solve_ik(above, pitch=-90.0, initial=start, closest=True, model=env.model)
            first = np.asarray(guess.values, dtype=float)
            first[GRIPPER_INDEX] = start[GRIPPER_INDEX]
            self._goal = self.solve(first, point)
            self._command = self._through_sag(self._goal)
            n = max(1, round(self.MOVE_SECONDS * env.control_hz))
            self._queue = list(joint_path(start, self._command, n))
        target = self._queue.pop(0) if self._queue else self._correct(point)
        return env.actions.action_for(target, commanded)

    def _correct(self, point: np.ndarray) -> np.ndarray:
        """Every 0.2 s: solve again from the measured pose and move the command by the
        difference (the servos' sag and dead band, learned from where the arm stands)."""
        self._wait -= 1
        if self._wait > 0:
            return self._command
        self._wait = max(1, round(self.CORRECT_SECONDS * self.env.control_hz))
        measured = self.env.sim.pose_array()
        seen = self._seen(measured, point)
        if seen is not None and np.hypot(*seen) < 0.5 * LOOK_SUCCESS:
            return self._command
        want = self.solve(measured, point)
        lower, upper = self._units.limits
        self._command = np.clip(self._command + (want - measured), lower, upper)
        self._command[GRIPPER_INDEX] = self._goal[GRIPPER_INDEX]
        return self._command


EXPERTS[LookAtTask] = LookAtExpert

__all__ = ["LOOK_SUCCESS", "LookAtEnv", "LookAtExpert", "LookAtTask", "projection"]
