"""The env plugin against the real LeRobot: discovery, the config's contract (features, gym
id, kwargs), ``make_env``, a rollout of a tiny ACT policy through LeRobot's own eval loop, and
the same features as the robot plugin's datasets."""

from __future__ import annotations

import importlib.metadata
from dataclasses import dataclass

import draccus
import gymnasium as gym
import lerobot_env_so101sim as plugin
import numpy as np
import pytest
from build_tiny_act import build
from lerobot.envs.configs import EnvConfig
from lerobot.envs.factory import make_env, make_env_pre_post_processors
from lerobot.envs.utils import env_to_policy_features
from lerobot.utils.import_utils import register_third_party_plugins
from lerobot_env_so101sim import SO101SimCubeToBowlEnv, SO101SimPickCubeEnv

from so101sim.errors import SettingError
from so101sim.units import JOINT_NAMES

SMALL = {"observation_height": 48, "observation_width": 64}


@dataclass
class _Cli:
    env: EnvConfig


def parse_env(*args: str) -> EnvConfig:
    """An env config parsed from command-line flags, as ``lerobot-eval`` parses ``--env.*``."""
    return draccus.parse(_Cli, args=[f"--env.{a}" for a in args]).env


def test_lerobot_discovers_the_plugin_by_its_distribution_name():
    dist = importlib.metadata.distribution("lerobot_env_so101sim")
    assert dist.metadata["Name"] == "lerobot_env_so101sim" == plugin.__name__
    register_third_party_plugins()
    assert EnvConfig.get_choice_class("so101sim_pick_cube") is SO101SimPickCubeEnv
    assert EnvConfig.get_choice_class("so101sim_cube_to_bowl") is SO101SimCubeToBowlEnv


def test_the_config_names_the_gym_env_and_the_policys_features():
    cfg = parse_env("type=so101sim_cube_to_bowl", "observation_height=48", "fps=25")
    assert cfg.type == "so101sim_cube_to_bowl" and cfg.gym_id == "so101sim/CubeToBowl-v0"
    assert cfg.gym_id in gym.registry
    features = env_to_policy_features(cfg)
    assert features["observation.state"].shape == (6,)
    assert features["action"].shape == (6,)
    assert features["observation.images.front"].shape == (3, 48, 640)
    assert set(features) == {
        "observation.state",
        "action",
        "observation.images.front",
        "observation.images.wrist",
    }
    kwargs = cfg.gym_kwargs
    assert kwargs["control"] == "joint" and kwargs["control_hz"] == 25.0
    assert kwargs["image_size"] == (48, 640) and kwargs["cameras"] == ["front", "wrist"]
    with_state = SO101SimCubeToBowlEnv(object_state=True)
    assert env_to_policy_features(with_state)["observation.environment_state"].shape == (14,)


def test_bad_values_fail_when_the_config_is_made():
    with pytest.raises(SettingError, match="unknown camera 'top'"):
        SO101SimPickCubeEnv(cameras=["top"])
    with pytest.raises(SettingError, match="unknown task 'Juggle-v0'"):
        SO101SimPickCubeEnv(task="Juggle-v0")
    with pytest.raises(SettingError, match="observation_width"):
        SO101SimPickCubeEnv(observation_width=63)
    with pytest.raises(draccus.utils.ParsingError) as info:
        parse_env("type=so101sim_pick_cube", "fps=0")
    assert isinstance(info.value.__cause__, SettingError)


def test_env_arm_goes_to_the_environment_and_an_unknown_one_fails_at_once():
    assert "arm" not in SO101SimPickCubeEnv().gym_kwargs  # the default profile
    cfg = parse_env("type=so101sim_pick_cube", "arm=official")
    assert cfg.gym_kwargs["arm"] == "official"
    env = gym.make(cfg.gym_id, **{**cfg.gym_kwargs, "cameras": []})
    try:
        assert env.unwrapped.arm.name == "official"
        assert env.unwrapped.model.actuator_gainprm[0, 0] > 900
    finally:
        env.close()
    with pytest.raises(SettingError, match="official, sts3215, sts3215-12v"):
        SO101SimPickCubeEnv(arm="sts9999")


def test_make_env_gives_the_observations_lerobot_maps_to_the_policys_inputs():
    cfg = SO101SimPickCubeEnv(**SMALL, episode_length=5)
    vec = make_env(cfg, n_envs=1)["so101sim_pick_cube"][0]
    try:
        obs, _ = vec.reset(seed=[0])
        assert obs["agent_pos"].shape == (1, 6) and obs["agent_pos"].dtype == np.float32
        assert obs["pixels"]["front"].shape == (1, 48, 64, 3)
        assert obs["pixels"]["wrist"].dtype == np.uint8
        assert vec.call("_max_episode_steps") == (5,)
        assert vec.call("task_description") == ("Pick up the red cube.",)
        for _ in range(5):
            obs, _, terminated, truncated, _ = vec.step(obs["agent_pos"])
        assert truncated[0] and not terminated[0]
    finally:
        vec.close()


def test_a_tiny_act_policy_runs_through_lerobots_rollout(tmp_path):
    from lerobot.scripts.lerobot_eval import rollout

    cfg = SO101SimPickCubeEnv(**SMALL, episode_length=12)
    policy, pre, post = build(cfg, tmp_path / "policy")
    assert (tmp_path / "policy" / "config.json").is_file()
    env_pre, env_post = make_env_pre_post_processors(cfg, policy.config)
    vec = make_env(cfg, n_envs=1)["so101sim_pick_cube"][0]
    try:
        policy.eval()
        out = rollout(vec, policy, env_pre, env_post, pre, post, seeds=[3])
    finally:
        vec.close()
    assert out["action"].shape == (1, 12, 6)
    assert bool(out["done"][0, -1]) and np.isfinite(out["action"].numpy()).all()


def test_the_features_are_those_the_robot_plugin_records():
    robot_plugin = pytest.importorskip("lerobot_robot_so101sim")
    from lerobot.robots import make_robot_from_config
    from lerobot.utils.feature_utils import hw_to_dataset_features

    cams = {n: robot_plugin.SO101SimCameraConfig(width=64, height=48) for n in ("front", "wrist")}
    robot = make_robot_from_config(robot_plugin.SO101SimConfig(mode="lockstep", cameras=cams))
    recorded = hw_to_dataset_features(robot.observation_features, "observation")
    recorded.update(hw_to_dataset_features(robot.action_features, "action"))
    env = env_to_policy_features(SO101SimPickCubeEnv(**SMALL))
    assert set(recorded) == set(env)
    assert recorded["observation.state"]["names"] == [f"{j}.pos" for j in JOINT_NAMES]
    assert recorded["action"]["names"] == [f"{j}.pos" for j in JOINT_NAMES]
    for cam in ("front", "wrist"):
        h, w, c = recorded[f"observation.images.{cam}"]["shape"]
        assert env[f"observation.images.{cam}"].shape == (c, h, w)


# ---------------------------------------------------------------------------- the policy's inputs
def test_the_env_takes_the_policys_cameras_sizes_and_state_and_refuses_a_mismatch(tmp_path):
    """Given a policy (--env.policy_path; lerobot-eval's --policy.path the same way), the env
    observes what it was trained on: its cameras, image size and environment state; a setting
    given that differs is refused, naming the setting to change."""
    policy = tmp_path / "policy"
    build(SO101SimPickCubeEnv(observation_height=96, observation_width=96, cameras=["wrist"],
                              object_state=True), policy)  # fmt: skip
    cfg = parse_env("type=so101sim_pick_cube", f"policy_path={policy}")
    assert cfg.cameras == ["wrist"] and (cfg.observation_height, cfg.observation_width) == (96, 96)
    assert cfg.object_state is True
    assert set(cfg.features_map.values()) == {
        "action", "observation.state", "observation.environment_state", "observation.images.wrist"
    }  # fmt: skip
    vec = make_env(cfg, n_envs=1)["so101sim_pick_cube"][0]
    try:
        obs, _ = vec.reset(seed=[0])
        declared = {k for k in cfg.features if k != "action"}
        flat = {f"pixels/{c}" for c in obs.get("pixels", {})} | (set(obs) - {"pixels"})
        assert flat == declared  # exactly the declared features: no agent_vel
        assert obs["pixels"]["wrist"].shape == (1, 96, 96, 3)
    finally:
        vec.close()
    for flag, setting in (
        ("observation_height=480", "--env.observation_height=96"),
        ("cameras=[front,wrist]", "--env.cameras=['wrist']"),
        ("object_state=false", "--env.object_state=true"),
    ):
        with pytest.raises(draccus.utils.ParsingError) as info:
            parse_env("type=so101sim_pick_cube", f"policy_path={policy}", flag)
        assert isinstance(info.value.__cause__, SettingError)
        assert setting in str(info.value.__cause__), str(info.value.__cause__)
    with pytest.raises(SettingError, match="--rename_map"):
        SO101SimPickCubeEnv().match_policy({"observation.images.top": cfg.features["pixels/wrist"]})
    with pytest.raises(SettingError, match="six joint positions"):
        SO101SimPickCubeEnv().match_policy({"observation.state": type(cfg.features["action"])(
            type=cfg.features["action"].type, shape=(7,))})  # fmt: skip
    # without a policy: the defaults, as before
    plain = parse_env("type=so101sim_pick_cube")
    assert plain.cameras == ["front", "wrist"] and plain.observation_height == 480
    assert plain.object_state is False


def test_wilson_interval_and_the_randomize_option():
    from lerobot_env_so101sim.evaluate import wilson_interval

    assert wilson_interval(0, 2) == (0.0, pytest.approx(0.6576, abs=1e-4))
    low, high = wilson_interval(40, 50)
    assert low == pytest.approx(0.6697, abs=1e-4) and high == pytest.approx(0.8876, abs=1e-4)
    assert wilson_interval(0, 0) == (0.0, 1.0)
    cfg = parse_env("type=so101sim_pick_cube", "randomize=light")
    assert cfg.gym_kwargs["randomize"] == "light"
    assert "randomize" not in parse_env("type=so101sim_pick_cube").gym_kwargs
    with pytest.raises(draccus.utils.ParsingError):
        parse_env("type=so101sim_pick_cube", "randomize=heavy")


@pytest.mark.parametrize("task", ["push", "stack", "look_at", "lift_mesh", "reach"])
def test_every_task_has_an_env_type_with_its_state_size(task):
    from lerobot_env_so101sim.configs import state_size

    cfg = parse_env(f"type=so101sim_{task}", "object_state=true", "cameras=[]")
    assert cfg.gym_id in gym.registry
    env = gym.make(cfg.gym_id, **cfg.gym_kwargs)
    obs, _ = env.reset(seed=0)
    assert obs["environment_state"].shape == (state_size(cfg.task),)
    env.close()


def test_a_camera_file_gives_the_policy_a_camera_of_your_own(tmp_path):
    """``--env.camera_file``: a camera the presets lack (a policy trained on a dataset recorded
    with that camera file) renders where the file puts it, under its name."""
    rig = tmp_path / "rig.toml"
    rig.write_text("[top]\npos = [0.2, 0.0, 0.8]\nlookat = [0.2, 0.0, 0.0]\nfovy = 60\n")
    with pytest.raises(SettingError, match="unknown camera 'top'"):
        SO101SimPickCubeEnv(cameras=["top"])
    cfg = parse_env("type=so101sim_pick_cube", f"camera_file={rig}", "cameras=[top,wrist]")
    assert set(env_to_policy_features(cfg)) >= {"observation.images.top"}
    top, wrist = cfg.gym_kwargs["cameras"]
    assert top.name == "top" and top.pos == (0.2, 0.0, 0.8) and wrist == "wrist"
    env = gym.make(cfg.gym_id, **{**cfg.gym_kwargs, "image_size": (48, 64)})
    try:
        obs, _ = env.reset(seed=0)
        assert obs["pixels"]["top"].shape == (48, 64, 3)
    finally:
        env.close()
    bad = tmp_path / "bad.toml"
    bad.write_text("[top]\npos = [0.2, 0.0, 0.8]\n")  # no lookat
    with pytest.raises(draccus.utils.ParsingError) as info:
        parse_env("type=so101sim_pick_cube", f"camera_file={bad}")
    assert "lookat" in str(info.value.__cause__)
