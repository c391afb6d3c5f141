"""The one divergence check of every stepping path (:mod:`so101sim.sim.stepping` calls it after
each block): a block diverged when MuJoCo warned of a bad acceleration, velocity or position
(and reset the data), when its time went back, or when a joint angle is not finite. The data is
then put back to the last good state and :class:`~so101sim.errors.SimulationDivergedError`
says when and why.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import SimulationDivergedError

_STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS
_DIVERGENCE_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQPOS,
)


def _first_bad_step(states: np.ndarray, t0: float, dt: float, qpos_cols: np.ndarray) -> int | None:
    """Index of the first step of a block whose state is not a continuation of the run: time
    that went back (MuJoCo reset the data after a bad acceleration) or a NaN/inf joint angle."""
    k = len(states)
    expected = t0 + dt * np.arange(1, k + 1)
    bad = (states[:, 0] < expected - 0.5 * dt) | ~np.isfinite(states[:, qpos_cols]).all(axis=1)
    hits = np.flatnonzero(bad)
    return int(hits[0]) if hits.size else None


ADVICE = "Expected stable physics: check the model's gains, timestep and targets"
"""The end of a divergence message: what to do about it (a caller may give its own)."""


def _check_divergence(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    states: np.ndarray,
    start_state: np.ndarray,
    qpos_cols: np.ndarray,
    advice: str = ADVICE,
) -> None:
    """THE divergence check of every stepping path (:func:`step_block`; :func:`advance_unobserved`
    steps a diverged block again to come here). Raise SimulationDivergedError if the block of
    ``states`` (FULLPHYSICS, one row per step) diverged, after putting ``d`` back to the last
    good state (the state when it happened); ``advice`` ends the message."""
    warned = [w for w in _DIVERGENCE_WARNINGS if d.warning[w].number > 0]
    t0, dt = float(start_state[0]), float(m.opt.timestep)
    i = _first_bad_step(states, t0, dt, qpos_cols)
    if i is None and not warned:
        return
    if i is None:  # warned without a visible jump (MuJoCo reset on the last step)
        i = len(states) - 1
    good = states[i - 1] if i > 0 else start_state
    mujoco.mj_setState(m, d, good, _STATE_SPEC)
    mujoco.mj_forward(m, d)
    when = float(good[0]) + dt
    if warned:
        w = warned[0]
        cause = (
            f"MuJoCo warned {mujoco.mjtWarning(w).name} (index {d.warning[w].lastinfo}) and "
            "would have reset the state"
        )
    else:
        cause = "the joint angles hold NaN or inf"
    for w in warned:
        d.warning[w].number = 0
    raise SimulationDivergedError(
        f"the simulation diverged at t = {when:.3f} s: {cause}; the state is left as it was "
        f"at t = {float(good[0]):.3f} s. {advice}"
    )


def _warnings(d: mujoco.MjData) -> int:
    return sum(d.warning[w].number for w in _DIVERGENCE_WARNINGS)


__all__ = ["ADVICE"]
