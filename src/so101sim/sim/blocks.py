"""The rows of one block of the stepping kernel (:mod:`.stepping`): ``k`` steps from a state,
one row of controls each, every step's state kept, in C through ``mujoco.rollout`` on the
calling thread, or in a plain ``mj_step`` loop (a few steps, contact counts after each step,
or a model with load friction, :mod:`so101sim.model.loadfriction`), the same physics bit for
bit; and the same on a model's contact twin (:mod:`so101sim.model.twin`). No exit gate and no
divergence check here: :func:`so101sim.sim.stepping.step_block` wraps these and is what the
rest of so101sim calls."""

from __future__ import annotations

import threading

import mujoco
import numpy as np
from mujoco import rollout as _rollout

from ..model.loadfriction import LoadFriction, step_index
from ..model.twin import Twin
from .divergence import _DIVERGENCE_WARNINGS, _STATE_SPEC

ROLLOUT_MIN_STEPS = 48
"""Below this many steps, a Python loop costs less than rollout's per-call setup."""

_local = threading.local()


def rollout_runner() -> _rollout.Rollout:
    """This thread's rollout runner (no thread pool: it steps on the calling thread)."""
    r = getattr(_local, "runner", None)
    if r is None:
        r = _local.runner = _rollout.Rollout(nthread=0)
    return r


def step_rows(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    ctrl_full: np.ndarray,
    s0: np.ndarray,
    sensordata: np.ndarray | None = None,
    counts: np.ndarray | None = None,
    forces: np.ndarray | None = None,
    loaded: LoadFriction | None = None,
) -> np.ndarray:
    """Take ``len(ctrl_full)`` steps from the state ``s0`` (that of ``d``), applying row i of
    ``ctrl_full`` (all actuators) during step i; return the state after each step
    (FULLPHYSICS layout), and fill ``sensordata`` (one row per step) if given, ``counts``
    and ``forces`` (each step's ``ncon`` and ``actuator_force``; the loop only) if given.
    ``loaded``: the model's load friction, set in the loop (:mod:`so101sim.model.loadfriction`)."""
    k = len(ctrl_full)
    states = np.empty((k, len(s0)))
    if k >= ROLLOUT_MIN_STEPS and counts is None and loaded is None:
        rollout_runner().rollout(
            [m],
            [d],
            s0[None],
            np.ascontiguousarray(ctrl_full[None]),
            control_spec=mujoco.mjtState.mjSTATE_CTRL.value,
            skip_checks=True,
            nstep=k,
            initial_warmstart=d.qacc_warmstart[None].copy(),
            state=states[None],
            sensordata=(
                np.empty((1, k, m.nsensordata)) if sensordata is None else sensordata[None]
            ),
        )
        # rollout leaves d holding the last step's result; make ctrl match it, as a loop would.
        d.ctrl[:] = ctrl_full[-1]
    else:
        first = 0
        if loaded is not None:
            first = step_index(d.time, m.opt.timestep)
            loaded.restore(m, d)
        for i in range(k):
            if loaded is not None and (first + i) % loaded.stride == 0:
                loaded.update(m, d)
            d.ctrl[:] = ctrl_full[i]
            mujoco.mj_step(m, d)
            mujoco.mj_getState(m, d, states[i], _STATE_SPEC)
            if sensordata is not None:
                sensordata[i] = d.sensordata
            if counts is not None:
                counts[i] = d.ncon
            if forces is not None:
                forces[i] = d.actuator_force
    return states


def step_rows_on_twin(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    twin: Twin,
    ctrl_full: np.ndarray,
    s0: np.ndarray,
    counts: np.ndarray,
    forces: np.ndarray | None,
) -> np.ndarray:
    """:func:`step_rows` on ``m``'s contact twin (:mod:`so101sim.model.twin`), filling
    ``counts`` with each step's contact count (and ``forces`` with its actuator forces): all
    steps but the last in C on the twin (the same physics, bit for bit), from ``d``'s whole
    state; the last one on ``(m, d)`` itself from the state and warm start before it, so
    ``d`` ends exactly as a plain block leaves it
    (its contacts, forces and sensors those of the last step)."""
    k = len(ctrl_full)
    tm, td = twin.model, twin.data
    full = mujoco.mjtState.mjSTATE_INTEGRATION
    buf = np.empty(mujoco.mj_stateSize(m, full))
    mujoco.mj_getState(m, d, buf, full)  # mocap, applied forces, equality flags, user data
    mujoco.mj_setState(tm, td, buf, full)
    for w in _DIVERGENCE_WARNINGS:
        td.warning[w].number = 0
    states = np.empty((k, len(s0)))
    sensordata = np.empty((1, k - 1, tm.nsensordata))
    rollout_runner().rollout(
        [tm],
        [td],
        s0[None],
        np.ascontiguousarray(ctrl_full[None, : k - 1]),
        control_spec=mujoco.mjtState.mjSTATE_CTRL.value,
        skip_checks=True,
        nstep=k - 1,
        initial_warmstart=d.qacc_warmstart[None].copy(),
        state=states[None, : k - 1],
        sensordata=sensordata,
    )
    counts[: k - 1] = sensordata[0, :, twin.found]
    if forces is not None:
        forces[: k - 1] = sensordata[0][:, twin.forces]
    mujoco.mj_setState(m, d, states[k - 2], _STATE_SPEC)
    d.qacc_warmstart[:] = td.qacc_warmstart
    for w in _DIVERGENCE_WARNINGS:
        d.warning[w].number += td.warning[w].number
    d.ctrl[:] = ctrl_full[-1]
    mujoco.mj_step(m, d)
    mujoco.mj_getState(m, d, states[k - 1], _STATE_SPEC)
    counts[k - 1] = d.ncon
    if forces is not None:
        forces[k - 1] = d.actuator_force
    return states
