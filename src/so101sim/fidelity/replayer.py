"""Replaying recorded episodes on a batch of arms, one parameter set each: what ``so101sim fit``
evaluates (:mod:`so101sim.fidelity.fit`). Each episode starts from its first measured pose and
gets its commands at its own times, as :func:`~so101sim.fidelity.compare.compare` replays it,
with the arm reaching the recording's stops (:mod:`so101sim.fidelity.stops`); every batch entry
steps in one :class:`~so101sim.sim.stepping.BatchStepper` call per frame."""

from __future__ import annotations

import copy
import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np

from ..model.arm import ArmProfile, ServoParams, fill_delay_history, write_servo
from ..model.build import Addition, build, recipe
from ..model.load import arm_index, arm_units
from ..model.loadfriction import add_load_friction_slots
from ..sim.stepping import BatchStepper
from ..units import JOINT_NAMES, ArmUnits
from ..validation import check_count
from .fitparams import MAX_DELAY_S
from .logs import Episode
from .stops import stop_limits, widen_stops

__all__ = ["MAX_THREADS", "ArmReplayer", "replay_model"]

MAX_THREADS = 256  # threads for the parallel rollouts (one MjData each)
_ADVICE = "expected servo parameters within their bounds (a replay diverged)"

Calibration = tuple[np.ndarray, np.ndarray]  # per joint: the reading's scale and offset


def replay_model(base: ArmProfile, model_path: str | Path | None) -> mujoco.MjModel:
    """The model a fit replays on: ``base`` applied with the longest delay a fit considers (so
    any delay up to it can be written in place) and a load-friction slot on every joint (so
    any ``load_friction`` can be; a slot at 0 steps as a joint without one)."""
    wide = replace(base, servo=replace(base.servo, delay_s=MAX_DELAY_S),
                   joints={j: {k: v for k, v in d.items() if k != "delay_s"}
                           for j, d in base.joints.items()})  # fmt: skip
    # the model builder's, a one-off (not cached); the batch's copies are what the fit writes into
    slots = Addition(None, add_load_friction_slots)
    return build(recipe(model_path, arm=wide, keep=False, additions=(slots,)))


class ArmReplayer:
    """Replays recorded episodes on a batch of arms (one parameter set each), all in one
    :class:`~so101sim.sim.stepping.BatchStepper` call per frame.

    ``base``: the starting profile (its values where a batch entry does not say otherwise)."""

    def __init__(
        self,
        episodes: Sequence[Episode],
        base: ArmProfile,
        *,
        model_path: str | Path | None = None,
        threads: int | None = None,
        stops: np.ndarray | None = None,
    ) -> None:
        self.episodes = list(episodes)
        self.base = base
        self.stops = stops  # the recording's stops (readings): the replayed arm reaches them
        self.model = replay_model(base, model_path)
        self.index = arm_index(self.model)
        self.units: ArmUnits = arm_units(self.model)
        self.threads = check_count(
            threads or min(8, os.cpu_count() or 1), "threads", minimum=1, maximum=MAX_THREADS
        )
        self._models: list[mujoco.MjModel] = []

    def _batch_models(self, n: int) -> list[mujoco.MjModel]:
        while len(self._models) < n:
            self._models.append(copy.copy(self.model))
        return self._models[:n]

    def replay(
        self,
        servos: Sequence[dict[str, ServoParams]],
        calibrations: Sequence[Calibration] | None = None,
    ) -> np.ndarray:
        """For each batch entry (joint -> servo; a reading's calibration, identity by default),
        the predicted readings (arm units) of every episode, concatenated: ``(nbatch, frames,
        6)``."""
        models = self._batch_models(len(servos))
        idx = self.index
        one = (np.ones(len(JOINT_NAMES)), np.zeros(len(JOINT_NAMES)))
        cals = list(calibrations) if calibrations is not None else [one] * len(servos)
        limits = [stop_limits(self.units, self.stops, *c) for c in cals]
        for m, joints, (lo, hi) in zip(models, servos, limits, strict=True):
            for j, name in enumerate(JOINT_NAMES):
                write_servo(m, int(idx.actuator[j]), int(idx.dof[j]), joints[name])
            widen_stops(m, idx, self.units.to_radians(lo), self.units.to_radians(hi))
        offsets = np.array([[s[n].offset for n in JOINT_NAMES] for s in servos])
        scale = np.array([c[0] for c in cals])[:, None, :]
        shift = np.array([c[1] for c in cals])[:, None, :]
        lims = np.array(limits)[:, :, None, :]  # (n, 2, 1, 6): each entry's limits
        datas = [mujoco.MjData(self.model) for _ in range(self.threads)]
        out = []
        with BatchStepper(self.threads) as pool:
            for ep in self.episodes:
                out.append(self._episode(pool, models, datas, ep, offsets, scale, shift, lims))
        return np.concatenate(out, axis=1)

    def _episode(self, pool, models, datas, ep: Episode, offsets, scale, shift, lims) -> np.ndarray:
        m = self.model
        idx, units = self.index, self.units
        lo, hi = lims[:, 0], lims[:, 1]
        n = len(models)
        meas = (ep.measured[None] - shift) / scale  # (n, frames, 6): the angles read
        cmd = units.to_radians(np.clip((ep.command[None] - shift) / scale, lo, hi))
        start = units.to_radians(np.clip(meas[:, 0], lo[:, 0], hi[:, 0]))
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        states = np.empty((n, mujoco.mj_stateSize(m, spec)))
        d = datas[0]
        for b, model in enumerate(models):
            mujoco.mj_resetData(model, d)
            d.qpos[idx.qpos] = start[b] - offsets[b]
            d.ctrl[idx.actuator] = start[b]
            mujoco.mj_forward(model, d)
            fill_delay_history(model, d)
            mujoco.mj_getState(model, d, states[b], spec)
        dt = m.opt.timestep
        marks = np.round(ep.times / dt).astype(int)
        frames = len(ep.times)
        qadr = 1 + idx.qpos  # state = [time, qpos, ...]
        pred = np.empty((n, frames, len(JOINT_NAMES)))
        control = np.zeros((n, 1, m.nu))
        for k in range(frames):
            pred[:, k] = units.from_radians(states[:, qadr] + offsets)
            if k + 1 == frames:
                break
            steps = int(marks[k + 1] - marks[k])
            if steps <= 0:
                continue
            control[:, 0, :] = 0.0
            control[:, 0, idx.actuator] = cmd[:, k]
            states = pool.step(models, datas, states, control, steps, _ADVICE)
        return pred * scale + shift
