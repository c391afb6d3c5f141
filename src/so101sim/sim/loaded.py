"""The stepping kernel's steps of a model with load-dependent friction
(:mod:`so101sim.model.loadfriction`): ``mj_step(nstep)`` between the simulated times at which
the friction follows the servos' torque. :mod:`.stepping` (one arm) and :mod:`.batch` (a fit's
models) both step such a model here, so they step the same physics."""

from __future__ import annotations

import mujoco

from ..model.loadfriction import LoadFriction, step_index


def step_loaded(m: mujoco.MjModel, d: mujoco.MjData, loaded: LoadFriction, k: int) -> None:
    """``k`` steps holding ``d.ctrl`` (``mj_step(nstep)``) with the model's load friction
    updated at its simulated times, as :func:`~.stepping.step_block` sets it (the same physics)."""
    i = step_index(d.time, m.opt.timestep)
    end = i + k
    loaded.restore(m, d)
    while i < end:
        if i % loaded.stride == 0:
            loaded.update(m, d)
        j = min(end - i, loaded.stride - i % loaded.stride)
        mujoco.mj_step(m, d, nstep=j)
        i += j


__all__ = ["step_loaded"]
