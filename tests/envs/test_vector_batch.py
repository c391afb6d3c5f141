"""make_vec's fast paths: the targets and observations of all the worlds at once
(envs/batch.py), each world's reward and info on the thread that stepped it (the
WorldStepper's ``after``), and the paths world by world where those do not apply (end-effector
control, a task's own observation, camera images), all bit for bit N single environments."""

import threading

import mujoco
import numpy as np
import pytest
from test_vector import _compare, _same

from so101sim.envs import make, make_vec
from so101sim.errors import SimulationDivergedError
from so101sim.sim.batched import WorldStepper


def test_the_batched_paths_are_taken_where_they_apply():
    def flags(task, **kw):
        venv = make_vec(task, 2, **kw)
        got = (venv._batch.batch_actions, venv._batch.batch_observations, venv._after is None)
        venv.close()
        return got

    assert flags("pick_cube") == (True, True, False)
    assert flags("pick_cube", control="joint_delta", joint_velocities=False) == (True, True, False)
    assert flags("reach") == (True, True, False)  # its goal and tip taken world by world
    assert flags("look_at") == (True, True, False)
    assert flags("reach", randomize="light") == (True, True, False)  # a model per world
    assert flags("pick_cube", control="ee_delta") == (False, True, False)
    assert flags("pick_cube", cameras=["front"], image_size=(32, 32)) == (True, False, True)


@pytest.mark.parametrize("control", ["joint", "joint_delta"])
def test_batched_targets_are_each_worlds_own_beyond_the_bounds_too(control):
    n = 3
    venv = make_vec("pick_cube", n, control=control)
    singles = [make("pick_cube", control=control).unwrapped for _ in range(n)]
    obs, _ = venv.reset(seed=11)
    for i, env in enumerate(singles):
        env.reset(seed=11 + i)
    space = venv.single_action_space
    rng = np.random.default_rng(0)
    for _ in range(4):  # actions well outside the space: clipped as a single env clips them
        acts = rng.uniform(space.low - 40, space.high + 40, (n, 6)).astype(np.float32)
        obs, rew, *_ = venv.step(acts)
        for i, env in enumerate(singles):
            o, r, *_ = env.step(acts[i])
            assert np.array_equal(venv.envs[i].sim.data.ctrl, env.sim.data.ctrl)
            assert _same({k: v[i] for k, v in obs.items()}, o) and r == rew[i]
    venv.close()


def test_the_world_by_world_paths_are_single_envs():
    # ee_delta: inverse kinematics per world, in the main thread
    assert _compare("pick_cube", 2, 4, seed=2, control="ee_delta", episode_seconds=0.12) >= 2


def test_camera_images_are_drawn_world_by_world_as_single_envs():
    # every world's whole finish in the main thread (the renderer's context), the frames too
    kw = {"cameras": ["front"], "image_size": (32, 48), "episode_seconds": 0.12}
    venv = make_vec("pick_cube", 2, **kw)
    singles = [make("pick_cube", **kw) for _ in range(2)]
    obs, _ = venv.reset(seed=6)
    for i, env in enumerate(singles):
        env.reset(seed=6 + i)
    for step in range(3):  # 0.12 s at 25 Hz: the episodes end (and restart) on step 3
        acts = obs["agent_pos"] + np.float32(3.0 * (step % 2))
        obs, rew, term, trunc, _ = venv.step(acts)
        for i, env in enumerate(singles):
            o, r, te, tr, _ = env.step(acts[i])
            if te or tr:
                o, _ = env.reset()
            assert (r, te, tr) == (rew[i], term[i], trunc[i])
            assert np.array_equal(obs["pixels"]["front"][i], o["pixels"]["front"])
            assert np.array_equal(obs["agent_pos"][i], o["agent_pos"])
    assert trunc.all()
    venv.close()
    for env in singles:
        env.close()


def test_after_runs_on_the_stepping_thread_right_after_each_world():
    env = make("pick_cube").unwrapped
    m = env.model
    datas = [mujoco.MjData(m) for _ in range(5)]
    seen: dict[int, tuple[float, str]] = {}

    def after(i):
        seen[i] = (datas[i].time, threading.current_thread().name)

    with WorldStepper([m] * 5, datas, nthread=2) as stepper:
        stepper.advance([3, 0, 5, 2, 1], after)
    dt = m.opt.timestep
    assert sorted(seen) == [0, 1, 2, 3, 4]  # a world stepped 0 times still gets its after
    for i, k in enumerate([3, 0, 5, 2, 1]):
        assert seen[i][0] == pytest.approx(k * dt)


def test_every_world_is_stepped_and_the_lowest_failure_raised():
    env = make("pick_cube").unwrapped
    m = env.model
    datas = [mujoco.MjData(m) for _ in range(4)]

    def after(i):
        if i in (1, 3):
            raise ValueError(f"after failed in world {i}")

    with WorldStepper([m] * 4, datas, nthread=2) as stepper:
        with pytest.raises(ValueError, match="world 1"):
            stepper.advance(4, after)
        assert all(d.time == pytest.approx(4 * m.opt.timestep) for d in datas)
        datas[2].qvel[:] = 1e12  # world 2 blows up; the others still step
        with pytest.raises(SimulationDivergedError, match="world 2"):
            stepper.advance(3)
        for i in (0, 1, 3):
            assert datas[i].time == pytest.approx(7 * m.opt.timestep)
