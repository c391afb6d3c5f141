"""The one stepping kernel (sim.stepping: step_block, advance_unobserved): every user of MuJoCo's
stepping goes through it, and gets the same physics bit for bit as MuJoCo's own loop."""

from __future__ import annotations

import contextlib

import mujoco
import numpy as np
import pytest

from so101sim.errors import SimulationDivergedError
from so101sim.sim import stepping
from so101sim.units import STARTING_POSE, ZERO_POSE


def _raw_loop(m, d, ctrl_rows):
    for row in ctrl_rows:
        d.ctrl[:] = row
        mujoco.mj_step(m, d)


def test_step_block_is_mujocos_loop_bit_for_bit_with_and_without_rollout():
    from so101sim import Simulation

    for k in (10, 300):  # under and over the rollout threshold
        a, b = Simulation(), Simulation()
        rows = np.repeat(b.data.ctrl[None], k, axis=0)
        rows[:, :6] += np.linspace(0, 0.3, k)[:, None]
        states = stepping.step_block(a.model, a.data, rows)
        _raw_loop(b.model, b.data, rows)
        assert np.array_equal(a.data.qpos, b.data.qpos)
        assert np.array_equal(a.data.qvel, b.data.qvel)
        assert np.array_equal(states[-1, 1 : 1 + a.model.nq], b.data.qpos)


def test_the_environment_steps_through_the_kernel_same_physics(monkeypatch):
    from so101sim.envs import PickCubeEnv, base

    calls = []
    real = base.advance_unobserved
    monkeypatch.setattr(
        base, "advance_unobserved", lambda *a, **k: calls.append(a[3]) or real(*a, **k)
    )
    env = PickCubeEnv()
    obs, _ = env.reset(seed=0)
    ref = mujoco.MjData(env.model)
    mujoco.mj_setState(
        env.model, ref, _state(env.model, env.sim.data), mujoco.mjtState.mjSTATE_INTEGRATION
    )
    ref.qacc_warmstart[:] = env.sim.data.qacc_warmstart
    action = obs["agent_pos"] + 3.0
    env.step(action)
    assert calls  # the kernel took the steps
    ref.ctrl[:] = env.sim.data.ctrl  # the targets the action set
    mujoco.mj_step(env.model, ref, nstep=calls[0])
    assert np.array_equal(ref.qpos, env.sim.data.qpos)
    env.close()


def _state(m, d):
    s = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(m, d, s, mujoco.mjtState.mjSTATE_INTEGRATION)
    return s


def test_the_pose_finder_steps_through_the_kernel_same_physics(monkeypatch):
    from so101sim.viewer import posefinder

    m, d = posefinder.pose_scene()
    d.qvel[:6] = 0.3
    ref = mujoco.MjData(m)
    mujoco.mj_setState(m, ref, _state(m, d), mujoco.mjtState.mjSTATE_INTEGRATION)
    ref.qacc_warmstart[:] = d.qacc_warmstart
    calls = []
    real = posefinder.advance_unobserved
    monkeypatch.setattr(
        posefinder, "advance_unobserved", lambda *a, **k: calls.append(a[3]) or real(*a, **k)
    )

    class Viewer:
        runs = 0

        def is_running(self):
            self.runs += 1
            return self.runs <= 5

        def sync(self):
            pass

        def lock(self):
            return contextlib.nullcontext()

    list(posefinder.watch_poses(Viewer(), m, d, pacer=stepping.Pacer(1000, sleep=lambda s: 0)))
    assert len(calls) == 5
    mujoco.mj_step(m, ref, nstep=sum(calls))
    assert np.array_equal(ref.qpos, d.qpos)


def test_the_robust_preflight_rolls_out_through_the_kernel_same_physics(monkeypatch):
    from so101sim.model import scene_path
    from so101sim.motion import Move
    from so101sim.preflight import rollout
    from so101sim.preflight.judge import Thresholds
    from so101sim.preflight.variants import sample_variants

    base = rollout.sensor_model(scene_path())
    plan = rollout.plan_motion(base, [Move(ZERO_POSE, 0.5)], STARTING_POSE)
    worker = rollout.Worker(base, plan, Thresholds())
    v = sample_variants(1, 3)[0]
    blocks = []
    real = rollout.step_block
    monkeypatch.setattr(
        rollout, "step_block", lambda *a, **k: blocks.append(len(a[2])) or real(*a, **k)
    )
    worker.measure(v)
    assert blocks == [len(plan.targets)]
    end = worker.d.qpos.copy()
    offset, _ = worker._start(v)  # the same variant, stepped by MuJoCo's own loop
    rows = np.zeros((len(plan.targets), base.nu))
    rows[:, worker.idx.actuator] = plan.targets - offset
    _raw_loop(worker.m, worker.d, rows)
    assert np.array_equal(end, worker.d.qpos)


def test_the_lockstep_robot_holds_through_the_kernel(monkeypatch):
    from so101sim import Simulation
    from so101sim.robot import threads

    calls = []
    real = threads.advance_unobserved
    monkeypatch.setattr(
        threads, "advance_unobserved", lambda *a, **k: calls.append(a[3]) or real(*a, **k)
    )
    sim, ref = Simulation(), Simulation()
    sim.command(ZERO_POSE)
    ref.command(ZERO_POSE)
    threads.RobotThreads(sim, "test", 1.0).advance(0.1)
    assert calls == [50]
    mujoco.mj_step(ref.model, ref.data, nstep=50)
    assert np.array_equal(sim.data.qpos, ref.data.qpos)


def test_one_divergence_check_with_the_callers_advice():
    import copy

    from so101sim import Simulation
    from so101sim.model import load_model

    m = copy.copy(load_model())
    m.actuator_gainprm[:, 0] = 1e9  # absurd gains: the explicit integrator blows up
    m.actuator_biasprm[:, 1] = -1e9
    m.actuator_forcerange[:] = [-1e12, 1e12]
    for fast in (True, False):
        sim = Simulation(m)
        sim.command(ZERO_POSE)
        with pytest.raises(SimulationDivergedError, match=r"diverged at t = .*s\. do this") as info:
            if fast:
                stepping.advance_unobserved(m, sim.data, None, 500, advice="do this")
            else:
                rows = np.repeat(sim.data.ctrl[None], 500, axis=0)
                stepping.step_block(m, sim.data, rows, advice="do this")
        assert np.isfinite(sim.data.qpos).all()
        assert f"{sim.time + sim.timestep:.3f} s" in str(info.value)
