"""Writes into a compiled model and its data at run time: a delayed actuator's history filled
with the current command (:func:`fill_delay_history`), a servo's parameters written in place
for sweeps and fits (:func:`write_servo`)."""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import ProfileError
from .loadfriction import write_load_friction
from .servo import ServoParams

_GOAL_STATE_DYN = (int(mujoco.mjtDyn.mjDYN_FILTEREXACT), int(mujoco.mjtDyn.mjDYN_PID))
"""Actuator dynamics whose state is the goal the servo acts on (filtered or slew-limited)."""


def fill_delay_history(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Fill every delayed actuator's history (and a smoothed one's filter state) with its
    current ``data.ctrl``, so that a pose set now is commanded from the start (not the zeros
    of a fresh history)."""
    for a in range(model.nu):
        adr = int(model.actuator_actadr[a])
        dyn = int(model.actuator_dyntype[a])
        if adr >= 0 and dyn in _GOAL_STATE_DYN:
            data.act[adr] = data.ctrl[a]
    if not model.nhistory:
        return
    for a in range(model.nu):
        n = int(model.actuator_history[a, 0])
        if n > 0:
            values = np.full((n, 1), float(data.ctrl[a]))
            times = data.time + model.opt.timestep * (np.arange(n, dtype=float) - n)
            mujoco.mj_initCtrlHistory(model, data, a, times.reshape(n, 1), values)


def write_servo(model: mujoco.MjModel, actuator: int, dof: int, params: ServoParams) -> None:
    """Write ``params`` into a compiled ``model`` in place (actuator ``actuator`` driving the
    degree of freedom ``dof``): what :func:`apply_servo` does to a spec, for parameter sweeps
    and fits. The delay must lie within the history the model was compiled with.

    Raises:
        ProfileError: the delay is beyond the actuator's history, or a ``load_friction`` > 0
            on a model compiled without load friction.
    """
    n = int(model.actuator_history[actuator, 0])
    reach = max(n - 2, 0) * model.opt.timestep
    if params.delay_s > reach + 1e-12:
        raise ProfileError(
            f"delay_s = {params.delay_s} s is beyond actuator {actuator}'s history "
            f"({reach:.4f} s); expected a model compiled with a longer delay"
        )
    kp = params.kp
    pid = int(model.actuator_dyntype[actuator]) == int(mujoco.mjtDyn.mjDYN_PID)
    if pid != (params.max_velocity > 0):
        raise ProfileError(
            "max_velocity > 0 needs a model compiled with a slew-limited goal (and 0 one "
            "without); expected the profile's max_velocity when the model was made"
        )
    if pid:
        model.actuator_dynprm[actuator, 1] = params.max_velocity
    model.actuator_gainprm[actuator, 0] = 0.0 if pid else kp
    model.actuator_biasprm[actuator, :3] = [-kp * params.offset, -kp, -params.kv]
    model.actuator_forcerange[actuator] = [-params.force_limit, params.force_limit]
    model.actuator_delay[actuator] = params.delay_s
    if params.smoothing_s > 0:
        if int(model.actuator_dyntype[actuator]) != int(mujoco.mjtDyn.mjDYN_FILTEREXACT):
            raise ProfileError(
                "smoothing_s > 0 needs a model compiled with smoothing; expected the profile's "
                "smoothing when the model was made"
            )
        model.actuator_dynprm[actuator, 0] = params.smoothing_s
    model.dof_damping[dof] = params.joint_damping
    model.dof_frictionloss[dof] = params.joint_frictionloss
    model.dof_armature[dof] = params.armature
    write_load_friction(model, dof, params.load_friction)
