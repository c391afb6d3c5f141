"""make_vec: N worlds stepped together are N single environments bit for bit (seeds,
randomisation, arm profile, LeRobot's 30 Hz's uneven step counts, auto-reset); Gymnasium's
vector conventions (autoreset mode, final_obs/final_info, masks, RecordEpisodeStatistics);
the batched kernel; the reach task and its expert; the GPU backend's refusals."""

import importlib.util

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from gymnasium.wrappers.vector import RecordEpisodeStatistics

from so101sim.envs import ReachEnv, evaluate_expert, make, make_vec
from so101sim.errors import ClosedError, MissingDependencyError, SettingError
from so101sim.sim.batched import WorldStepper


def _same(a: dict, b: dict) -> bool:
    return set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in a)


def _compare(task: str, n: int, steps: int, seed: int, **kwargs) -> int:
    """Step a vector env and n single envs with the same noisy actions; assert they agree
    bit for bit (auto-reset included); return how many episodes ended."""
    venv = make_vec(task, n, nthread=2, **kwargs)
    singles = [make(task, **kwargs) for _ in range(n)]
    obs, info = venv.reset(seed=seed)
    for i, env in enumerate(singles):
        o, inf = env.reset(seed=seed + i)
        assert _same({k: v[i] for k, v in obs.items()}, o)
        assert info["time"][i] == inf["time"]
    rng = np.random.default_rng(1)
    space = venv.single_action_space
    ended = 0
    for _ in range(steps):
        noise = rng.normal(0.0, 8.0, (n, 6))
        acts = np.clip(obs["agent_pos"] + noise, space.low, space.high).astype(np.float32)
        obs, rew, term, trunc, info = venv.step(acts)
        for i, env in enumerate(singles):
            o, r, te, tr, inf = env.step(acts[i])
            assert (r, te, tr) == (rew[i], term[i], trunc[i])
            if te or tr:
                ended += 1
                assert info["_final_obs"][i] and _same(info["final_obs"][i], o)
                assert info["final_info"]["is_success"][i] == inf["is_success"]
                o, inf = env.reset()
            else:
                assert not info.get("_final_obs", np.zeros(n, bool))[i]
            assert _same({k: v[i] for k, v in obs.items()}, o)
            assert info["is_success"][i] == inf["is_success"] and info["_is_success"][i]
    venv.close()
    for env in singles:
        env.close()
    return ended


def test_vector_env_is_single_envs_bit_for_bit_with_autoreset():
    # 30 Hz: 16 or 17 physics steps per env step, so worlds whose episodes restarted take
    # different counts in the same batch; 0.3 s episodes: several auto-resets
    ended = _compare("pick_cube", 3, 24, seed=7, control_hz=30.0, episode_seconds=0.3)
    assert ended >= 6


def test_vector_env_randomised_and_on_another_arm_is_single_envs():
    kw = {"randomize": {"preset": "light", "actuator_sigmas": 1.0}, "episode_seconds": 0.4}
    assert _compare("reach", 2, 14, seed=3, **kw) >= 2
    assert _compare("pick_cube", 2, 6, seed=5, arm="official", control="joint_delta") == 0


def test_gymnasium_vector_conventions_and_episode_statistics():
    venv = make_vec("reach", 2, episode_seconds=0.2)
    assert venv.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert venv.observation_space.shape is None  # a Dict space, batched
    assert venv.observation_space["agent_pos"].shape == (2, 6)
    assert venv.action_space.shape == (2, 6)
    stats = RecordEpisodeStatistics(venv)
    obs, _ = stats.reset(seed=0)
    assert obs["environment_state"].shape == (2, 13)
    returns = np.zeros(2)
    for _ in range(5):  # 0.2 s at 25 Hz: the episodes end on step 5 (index 4)
        obs, rew, _, trunc, info = stats.step(obs["agent_pos"])
        returns += rew
    assert trunc.all() and "episode" in info
    np.testing.assert_allclose(info["episode"]["r"], returns)
    np.testing.assert_array_equal(info["episode"]["l"], [5, 5])
    assert info["_episode"].all()
    stats.close()
    with pytest.raises(ClosedError):
        venv.step(obs["agent_pos"])


def test_seeds_per_world_and_bad_settings():
    venv = make_vec("reach", 2)
    a, _ = venv.reset(seed=[4, 9])
    b, _ = venv.reset(seed=4)  # world 1 gets 5
    assert np.array_equal(a["environment_state"][0], b["environment_state"][0])
    assert not np.array_equal(a["environment_state"][1], b["environment_state"][1])
    with pytest.raises(SettingError, match="one seed per world"):
        venv.reset(seed=[1, 2, 3])
    with pytest.raises(SettingError, match="one row per world"):
        venv.step(np.zeros((3, 6)))
    with pytest.raises(SettingError, match="world 1"):
        venv.step(np.array([[0.0] * 6, [np.nan] * 6]))
    venv.close()
    with pytest.raises(SettingError, match="num_envs"):
        make_vec("reach", 0)
    with pytest.raises(SettingError, match="backend"):
        make_vec("reach", 2, backend="tpu")
    with pytest.raises(SettingError, match="human"):
        make_vec("reach", 2, render_mode="human")


def test_batch_stepper_matches_mj_step_and_checks_divergence():
    env = make("pick_cube").unwrapped
    m = env.model
    datas = [mujoco.MjData(m) for _ in range(3)]
    ref = [mujoco.MjData(m) for _ in range(3)]
    for i, (d, r) in enumerate(zip(datas, ref, strict=True)):
        d.ctrl[:] = r.ctrl[:] = 0.1 * i
    with WorldStepper([m] * 3, datas, nthread=2) as stepper:
        stepper.advance([5, 0, 17])
        for r, k in zip(ref, [5, 0, 17], strict=True):
            if k:
                mujoco.mj_step(m, r, nstep=k)
        for d, r in zip(datas, ref, strict=True):
            assert np.array_equal(d.qpos, r.qpos) and np.array_equal(
                d.qacc_warmstart, r.qacc_warmstart
            )
            assert d.ncon == r.ncon
        datas[1].qvel[:] = 1e12  # blows up
        with pytest.raises(Exception, match="world 1"):
            stepper.advance(3)
    with pytest.raises(ClosedError):
        stepper.advance(1)


def test_reach_task_expert_and_registration():
    env = gym.make("so101sim/Reach-v0")
    assert isinstance(env.unwrapped, ReachEnv)
    obs, info = env.reset(seed=0, options={"goal": (0.2, 0.0, 0.1)})
    np.testing.assert_allclose(obs["environment_state"][7:10], [0.2, 0.0, 0.1], atol=1e-6)
    assert not info["is_success"] and info["goal_distance_m"] > 0.05
    with pytest.raises(SettingError, match="goal"):
        env.reset(options={"goal": (0.2, "x")})
    env.close()
    score = evaluate_expert("reach", range(4))
    assert score.success_rate == 1.0


def test_warp_backend_refuses_cleanly():
    with pytest.raises(SettingError, match="reach"):
        make_vec("pick_cube", 2, backend="warp")
    with pytest.raises(SettingError, match="randomi"):
        make_vec("reach", 2, backend="warp", randomize="light")
    if importlib.util.find_spec("mujoco_warp") is None:
        with pytest.raises(MissingDependencyError, match="not installed"):
            make_vec("reach", 2, backend="warp", arm="official")
    else:
        import warp

        warp.config.quiet = True
        warp.init()
        if not warp.is_cuda_available():
            with pytest.raises(MissingDependencyError, match="CUDA device"):
                make_vec("reach", 2, backend="warp", arm="official")


def test_warp_backend_refuses_the_missing_package(monkeypatch):
    import builtins

    real = builtins.__import__

    def no_warp(name, globals=None, locals=None, fromlist=(), level=0):
        if level == 0 and name in ("warp", "mujoco_warp"):
            raise ImportError(f"No module named {name!r}", name=name)
        return real(name, globals, locals, fromlist, level)

    monkeypatch.setattr(builtins, "__import__", no_warp)
    with pytest.raises(MissingDependencyError, match="so101sim\\[warp\\]"):
        make_vec("reach", 2, backend="warp", arm="official")


@pytest.mark.parametrize("task", ["push", "look_at"])
def test_vector_env_of_the_newer_tasks_is_single_envs(task):
    # push (a mark that touches nothing), look_at (the wrist camera's projection in the state)
    assert _compare(task, 2, 8, seed=4, episode_seconds=0.2) >= 2
