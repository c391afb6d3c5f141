"""The environments' observations (see :mod:`.base`): their space and their values, read
from the simulation after each control period."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from ..errors import SettingError
from ..units import JOINT_NAMES, LIMIT_TOLERANCE
from ..validation import check_count

MAX_JOINT_SPEED = 1e4
"""Joint speeds in ``agent_vel`` are clipped to this (arm units per second)."""
MAX_DISTANCE_M = 10.0
"""Object positions in ``environment_state`` are clipped to this (metres)."""


class Observations:
    """The observation space and values of an :class:`~so101sim.envs.So101TaskEnv` (a mixin:
    it reads the environment's ``sim``, ``scene``, ``cameras`` and settings)."""

    def _observation_space(self) -> spaces.Dict:
        lower, upper = self.sim.units.limits
        tol = LIMIT_TOLERANCE
        n = len(JOINT_NAMES)
        items: dict[str, spaces.Space] = {
            "agent_pos": spaces.Box(
                (lower - tol).astype(np.float32),
                (upper + tol).astype(np.float32),
                dtype=np.float32,
            ),
        }
        if self.joint_velocities:
            fastest = MAX_JOINT_SPEED
            items["agent_vel"] = spaces.Box(-fastest, fastest, (n,), dtype=np.float32)
        if self.object_state:
            k = len(self.scene.objects)
            bound = np.tile(np.r_[np.full(3, MAX_DISTANCE_M), np.ones(4)], k).astype(np.float32)
            items["environment_state"] = spaces.Box(-bound, bound, dtype=np.float32)
        if self.cameras:
            h, w = self.image_size
            items["pixels"] = spaces.Dict(
                {c: spaces.Box(0, 255, (h, w, 3), dtype=np.uint8) for c in self.cameras}
            )
        return spaces.Dict(items)

    def _observation(self) -> dict[str, Any]:
        sim = self.sim
        space = self.observation_space["agent_pos"]
        pos = np.clip(sim.pose_array(), space.low, space.high).astype(np.float32)
        obs: dict[str, Any] = {"agent_pos": pos}
        if self.joint_velocities:
            vel = sim.data.qvel[sim.index.dof] / self._scale
            obs["agent_vel"] = np.clip(vel, -MAX_JOINT_SPEED, MAX_JOINT_SPEED).astype(np.float32)
        if self.object_state:
            poses = [self.object_pose(o.name) for o in self.scene.objects]
            state = np.concatenate(poses).astype(np.float32)
            space = self.observation_space["environment_state"]
            obs["environment_state"] = np.clip(
                state, space.low[: len(state)], space.high[: len(state)]
            )
            extra = self._extra_state()
            if extra is not None:  # a task's own numbers after the objects' poses
                obs["environment_state"] = np.r_[obs["environment_state"], extra].astype(np.float32)
        if self.cameras:
            obs["pixels"] = {
                c: self._renderer(c, self.image_size).render(sim.data).copy() for c in self.cameras
            }
        return obs

    def _extra_state(self) -> np.ndarray | None:
        """What a task adds to ``environment_state`` after the objects' poses (floats; None:
        nothing)."""
        return None


def check_size(value: object, what: str) -> tuple[int, int]:
    try:
        h, w = value  # type: ignore[misc]
    except (TypeError, ValueError):
        raise SettingError(f"{what} = {value!r}; expected (height, width) in pixels") from None
    dims = tuple(
        check_count(v, what, minimum=16, maximum=4096, even=True, unit=" pixels") for v in (h, w)
    )
    return dims  # type: ignore[return-value]


__all__ = ["MAX_DISTANCE_M", "MAX_JOINT_SPEED", "Observations", "check_size"]
