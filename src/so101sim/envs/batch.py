"""What a vector environment (:mod:`.worlds`) computes for all its worlds at once: the actions'
joint targets before the physics, the observations after it.

Bit for bit what each world's own code computes (:meth:`ActionMap.targets
<so101sim.envs.actions.ActionMap.targets>`, :meth:`Observations._observation
<so101sim.envs.observations.Observations._observation>`): the same elementwise operations, in
the same order, on arrays with one row per world instead of one world's array. Only where
every world has the same arm units, joint indices, action settings and observation space
(worlds of one task made with the same options; a randomised draw changes none of these);
otherwise, and for what a task computes on its own (``control="ee_delta"``'s inverse
kinematics, a task's own observation, camera images), each world's own code runs.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..scenes import object_qpos
from .base import So101TaskEnv
from .observations import MAX_JOINT_SPEED, Observations

_BATCHED_MODES = ("joint", "joint_delta")


def _same(values: list[Any]) -> bool:
    first = np.asarray(values[0])
    return all(np.array_equal(np.asarray(v), first) for v in values[1:])


def _object_index(env: So101TaskEnv) -> np.ndarray:
    """Where the objects' poses are in ``qpos``, in the order of ``environment_state``."""
    spans = [object_qpos(env.model, o.name) for o in env.scene.objects]
    return np.array([i for s in spans for i in range(s.start, s.stop)], dtype=np.intp)


class WorldBatch:
    """The worlds' shared constants, and the batched computations they allow."""

    def __init__(self, envs: list[So101TaskEnv]) -> None:
        e0 = envs[0]
        self.envs = envs
        self.sims = [e.sim for e in envs]
        self.datas = [e.sim.data for e in envs]
        self.units = e0.sim.units
        idx = e0.sim.index
        self.qpos, self.dof = np.asarray(idx.qpos), np.asarray(idx.dof)
        same_arm = (
            _same([e.sim.units.lower for e in envs])
            and _same([e.sim.units.upper for e in envs])
            and _same([e.sim.index.qpos for e in envs])
            and _same([e.sim.index.dof for e in envs])
        )
        a0 = e0.actions
        self.mode = a0.settings.mode
        self.act_shape = a0.space.shape
        self.batch_actions = (
            same_arm
            and self.mode in _BATCHED_MODES
            and all(e.actions.settings == a0.settings for e in envs)
            and _same([e.actions.space.low for e in envs])
            and _same([e.actions.space.high for e in envs])
        )
        space = e0.observation_space
        self.batch_observations = (
            same_arm
            and not e0.cameras
            and all(type(e)._observation is Observations._observation for e in envs)
            and all(e.observation_space == space for e in envs)
            and all(  # the bounds bit for bit (a Box's == allows a tolerance)
                _same([e.observation_space[k].low for e in envs])
                and _same([e.observation_space[k].high for e in envs])
                for k in space.spaces
            )
        )
        self.pos_low, self.pos_high = space["agent_pos"].low, space["agent_pos"].high
        self.velocities = e0.joint_velocities
        self.scale = self.units.scale
        self.objects = _object_index(e0) if e0.object_state else None
        # a task's own numbers after the objects' poses: each world's, taken on its thread
        self.extra = self.objects is not None and (
            type(e0)._extra_state is not Observations._extra_state
        )
        if self.objects is not None:
            box = space["environment_state"]
            n = len(self.objects)
            self.state_low, self.state_high = box.low[:n], box.high[:n]
            self.batch_observations = self.batch_observations and _same(
                [_object_index(e) for e in envs]
            )

    def valid_actions(self, actions: np.ndarray) -> np.ndarray | None:
        """The actions as floats, one row per world, if every row is valid (else None: each
        world's own check then says which is not and why)."""
        try:
            a = np.asarray(actions, dtype=float).reshape(len(self.envs), -1)
        except (TypeError, ValueError, OverflowError):
            return None
        if a.shape[1:] != self.act_shape or not np.isfinite(a).all():
            return None
        return a

    def command(self, a: np.ndarray) -> None:
        """Set every world's joint targets for its row of ``a`` (valid: :meth:`valid_actions`),
        as ``env.actions.targets`` and ``env.sim.command_array(check=False)`` set them."""
        commanded = None
        if self.mode == "joint_delta":  # from what each world commands now
            commanded = np.stack([sim.commanded_array() for sim in self.sims])
        q = self.units.to_radians(self.envs[0].actions.joint_targets(a, commanded))
        for sim, row in zip(self.sims, q, strict=True):
            sim.command_radians(row)

    def observe(self, out: dict[str, np.ndarray], extras: list[Any]) -> None:
        """Every world's observation, written into ``out`` (one row per world); ``extras``:
        each world's ``_extra_state()`` (if :attr:`extra`)."""
        qpos = np.array([d.qpos for d in self.datas])  # one row per world
        pos = self.units.from_radians(qpos[:, self.qpos])
        out["agent_pos"][:] = np.clip(pos, self.pos_low, self.pos_high).astype(np.float32)
        if self.velocities:
            vel = np.array([d.qvel for d in self.datas])[:, self.dof] / self.scale
            speed = np.clip(vel, -MAX_JOINT_SPEED, MAX_JOINT_SPEED)
            out["agent_vel"][:] = speed.astype(np.float32)
        if self.objects is not None:
            state = qpos[:, self.objects].astype(np.float32)
            poses = np.clip(state, self.state_low, self.state_high)
            if self.extra:
                n = len(self.objects)
                out["environment_state"][:, :n] = poses
                out["environment_state"][:, n:] = np.array(extras).astype(np.float32)
            else:
                out["environment_state"][:] = poses


__all__ = ["WorldBatch"]
