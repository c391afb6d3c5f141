"""The stepping kernel for many models at once (``so101sim fit``'s batches): the same physics
as ``mj_step``, and a diverged entry named."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from so101sim.errors import SimulationDivergedError
from so101sim.sim.stepping import BatchStepper

PENDULUM = """<mujoco><option timestep="0.002"/><worldbody><body pos="0 0 1">
<joint name="j" type="hinge" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 0.3 0 0"
size="0.02" mass="0.5"/></body></worldbody><actuator><position joint="j" kp="5"/></actuator>
</mujoco>"""


def _state(m, d):
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    out = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, out, spec)
    return out


def test_a_batch_steps_as_mj_step_does():
    m = mujoco.MjModel.from_xml_string(PENDULUM)
    d = mujoco.MjData(m)
    d.qpos[0] = 0.3
    start = _state(m, d)
    control = np.array([[[0.1]], [[-0.2]]])
    with BatchStepper(2) as pool:
        got = pool.step([m, m], [mujoco.MjData(m), mujoco.MjData(m)], np.stack([start] * 2),
                        control, 50)  # fmt: skip
    for b in range(2):
        mujoco.mj_setState(m, d, start, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        d.ctrl[0] = control[b, 0, 0]
        mujoco.mj_step(m, d, nstep=50)  # the reference, in the test
        np.testing.assert_allclose(got[b], _state(m, d), atol=1e-12)


def test_a_diverged_entry_is_named():
    m = mujoco.MjModel.from_xml_string(PENDULUM)
    d = mujoco.MjData(m)
    start = np.stack([_state(m, d)] * 2)
    start[1, 1] = np.nan  # entry 1's angle
    with BatchStepper(1) as pool, pytest.raises(SimulationDivergedError, match="batch entry 1"):
        pool.step([m, m], [mujoco.MjData(m)], start, np.zeros((2, 1, 1)), 10, "check it")
