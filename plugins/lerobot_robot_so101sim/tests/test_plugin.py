"""The plugin in process, against the real LeRobot 0.6.1: discovery, the robot contract LeRobot's
code relies on (errors, tensors, keys, cameras, robot_type), lockstep time, the teleoperators
and shutting down at exit."""

from __future__ import annotations

import gc
import importlib.metadata
import subprocess
import sys
import textwrap
import time
from dataclasses import dataclass

import draccus
import lerobot_robot_so101sim as plugin
import numpy as np
import pytest
import torch
from lerobot.cameras import Camera, CameraConfig
from lerobot.robots import Robot, RobotConfig, make_robot_from_config
from lerobot.teleoperators import Teleoperator, TeleoperatorConfig, make_teleoperator_from_config
from lerobot.utils import errors as lerobot_errors
from lerobot.utils.import_utils import register_third_party_plugins
from lerobot_robot_so101sim import (
    SO101Sim,
    SO101SimConfig,
    SO101SimMotion,
    SO101SimMotionConfig,
)

from so101sim import errors as sim_errors
from so101sim.units import STARTING_POSE, ZERO_POSE

KEYS = [f"{j}.pos" for j in STARTING_POSE]
SMALL = "{front: {type: so101_sim, width: 64, height: 48}, wrist: {type: so101_sim, width: 32, height: 32}}"  # noqa: E501


@dataclass
class _Cli:
    robot: RobotConfig


def parse_robot(*args: str) -> RobotConfig:
    """A robot config parsed from command-line flags, as LeRobot's CLIs parse ``--robot.*``."""
    return draccus.parse(_Cli, args=[f"--robot.{a}" for a in args]).robot


def lockstep(**kw) -> SO101Sim:
    return make_robot_from_config(SO101SimConfig(mode="lockstep", **kw))  # type: ignore[return-value]


# ---------------------------------------------------------------------------- discovery
def test_lerobot_discovers_the_plugin_by_its_distribution_name():
    dist = importlib.metadata.distribution("lerobot_robot_so101sim")
    assert dist.metadata["Name"] == "lerobot_robot_so101sim" == plugin.__name__
    register_third_party_plugins()
    assert RobotConfig.get_choice_class("so101_sim") is SO101SimConfig
    assert TeleoperatorConfig.get_choice_class("so101_sim_motion") is SO101SimMotionConfig
    assert CameraConfig.get_choice_class("so101_sim") is plugin.SO101SimCameraConfig


def test_make_robot_from_config_builds_a_lerobot_robot_named_so101_sim():
    cfg = parse_robot("type=so101_sim", "id=sim_arm", "port=/dev/ttyACM0")  # port: ignored
    assert cfg.type == "so101_sim"
    robot = make_robot_from_config(cfg)
    assert isinstance(robot, SO101Sim) and isinstance(robot, Robot)
    assert robot.name == robot.robot_type == "so101_sim"  # datasets' robot_type, --resume's check
    assert robot.id == "sim_arm" and str(robot) == "sim_arm SO101Sim"
    assert robot.is_calibrated and not robot.is_connected
    assert list(robot.action_features) == KEYS  # the real follower's keys
    assert robot.observation_features == dict.fromkeys(KEYS, float)
    assert robot.cameras == {}


# ---------------------------------------------------------------------------- errors
def test_connection_errors_are_lerobots_and_so101sims():
    robot = lockstep()
    for call in (robot.get_observation, lambda: robot.send_action({}), robot.disconnect):
        with pytest.raises(lerobot_errors.DeviceNotConnectedError) as info:
            call()
        assert isinstance(info.value, sim_errors.DeviceNotConnectedError)
        assert "not connected" in str(info.value)
    robot.connect()
    with pytest.raises(lerobot_errors.DeviceAlreadyConnectedError) as info:
        robot.connect()
    assert isinstance(info.value, sim_errors.DeviceAlreadyConnectedError)
    robot.disconnect()
    with pytest.raises(sim_errors.DeviceNotConnectedError):
        robot.disconnect()


def test_bad_config_fails_when_made_naming_the_field():
    with pytest.raises(sim_errors.RobotConfigError, match="mode"):
        SO101SimConfig(mode="fast")
    with pytest.raises(sim_errors.RobotConfigError, match="fps"):
        SO101SimConfig(fps=0)
    from lerobot.cameras.opencv import OpenCVCameraConfig

    webcam = OpenCVCameraConfig(index_or_path=0, fps=30, width=640, height=480)
    with pytest.raises(sim_errors.RobotConfigError, match=r"'opencv'.*so101_sim"):
        SO101SimConfig(cameras={"cam": webcam})
    with pytest.raises(sim_errors.RobotConfigError, match="pos and lookat"):
        SO101SimConfig(cameras={"top": plugin.SO101SimCameraConfig()})
    # from the command line, draccus raises its own error caused by ours (both are shown)
    with pytest.raises(draccus.utils.ParsingError) as info:
        parse_robot("type=so101_sim", "cameras={front: {type: so101_sim, width: 10}}")
    assert isinstance(info.value.__cause__, sim_errors.RobotConfigError)
    assert "camera 'front' width" in str(info.value.__cause__)


def test_robot_scene_puts_the_presets_objects_in_the_robots_scene():
    import mujoco

    robot = make_robot_from_config(parse_robot("type=so101_sim", "scene=pick_cube"))
    model = robot.follower._sim.model
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "cube") >= 0
    with pytest.raises(draccus.utils.ParsingError) as info:
        parse_robot("type=so101_sim", "scene=juggle")
    assert isinstance(info.value.__cause__, sim_errors.RobotConfigError)
    assert "pick_cube, cube_to_bowl" in str(info.value.__cause__)


def test_environment_state_is_opt_in_and_is_what_the_env_observes():
    """--robot.environment_state=true: each observation holds the objects' poses as the env
    plugin's observation.environment_state (7 per object), read from the robot's own
    simulation; it needs a scene; off by default."""
    from so101sim.envs import CubeToBowlEnv
    from so101sim.robot.scene import robot_scene

    assert SO101SimConfig().environment_state is False
    with pytest.raises(draccus.utils.ParsingError) as info:
        parse_robot("type=so101_sim", "environment_state=true")
    assert "--robot.scene" in str(info.value.__cause__)
    robot = lockstep(scene="cube_to_bowl", environment_state=True)
    robot.connect()
    try:
        robot_scene(robot.follower).reset(5)
        obs = robot.get_observation()
        state = obs["environment_state"]
        assert state.dtype == np.float32 and state.shape == (14,)
        assert robot.environment_state_size == 14
        env = CubeToBowlEnv(object_state=True)
        expected, _ = env.reset(seed=5)
        np.testing.assert_allclose(state, expected["environment_state"], atol=1e-4)
        plain = lockstep(scene="pick_cube")
        plain.connect()
        assert "environment_state" not in plain.get_observation()
        assert plain.environment_state_size == 0
        plain.disconnect()
    finally:
        robot.disconnect()


def test_randomize_is_passed_to_the_follower_and_needs_a_scene():
    config = parse_robot("type=so101_sim", "scene=pick_cube", "randomize=light")
    assert config.follower_config().randomize == "light"
    assert SO101SimConfig().randomize == "none"
    with pytest.raises(draccus.utils.ParsingError) as info:
        parse_robot("type=so101_sim", "randomize=light")
    assert "needs a scene" in str(info.value.__cause__)


def test_robot_arm_picks_the_servos_model_and_names_the_profiles_when_wrong():
    robot = make_robot_from_config(parse_robot("type=so101_sim", "arm=official"))
    model = robot.follower._sim.model
    assert model.actuator_gainprm[0, 0] > 900  # the vendored ideal actuator, kp 998
    default = make_robot_from_config(parse_robot("type=so101_sim")).follower._sim.model
    assert -default.actuator_biasprm[0, 1] < 20  # sts3215: kp 11 N·m/rad at 7.4 V
    assert default.actuator_delay[0] > 0.02
    with pytest.raises(draccus.utils.ParsingError) as info:
        parse_robot("type=so101_sim", "arm=sts9999")
    assert isinstance(info.value.__cause__, sim_errors.RobotConfigError)
    assert "official, sts3215, sts3215-12v" in str(info.value.__cause__)


# ---------------------------------------------------------------------------- actions
def test_actions_accept_0d_tensors_and_numpy_scalars_and_ignore_other_keys():
    with lockstep() as robot:
        sent = robot.send_action(
            {
                "shoulder_pan.pos": torch.tensor(10.0),  # lerobot-replay sends these
                "elbow_flex.pos": np.float32(20.0),
                "wrist_flex.pos": np.array(30.0),
                "gripper.pos": torch.tensor(40.0, dtype=torch.float64),
                "shoulder_pan.vel": 1.0,  # ignored, as LeRobot's follower ignores it
                "task": "pick",
            }
        )
        assert sent == pytest.approx(
            {"shoulder_pan.pos": 10, "elbow_flex.pos": 20, "wrist_flex.pos": 30, "gripper.pos": 40}
        )
        assert all(type(v) is float for v in sent.values())
        with pytest.raises(sim_errors.JointValueError, match="shoulder_pan"):
            robot.send_action({"shoulder_pan.pos": torch.tensor([1.0, 2.0])})
        with pytest.raises(sim_errors.JointNameError, match=r"elbow\.pos"):
            robot.send_action({"elbow.pos": 1.0})


def test_lockstep_advances_exactly_one_over_fps_per_action_without_drift():
    for fps in (30, 50, 15):
        with lockstep(fps=fps) as robot:
            t0 = robot.time
            for n in range(1, 3 * fps + 1):
                robot.get_observation()
                robot.send_action({"shoulder_pan.pos": 5.0})
                # within half a 2 ms physics step of n / fps, at every step (no drift)
                assert robot.time - t0 == pytest.approx(n / fps, abs=0.001 + 1e-9)
            assert robot.time - t0 == pytest.approx(3.0, abs=1e-9)


def test_realtime_is_the_default_and_the_arm_moves_while_the_loop_waits():
    robot = make_robot_from_config(SO101SimConfig())
    assert robot.config.mode == "realtime"
    with robot:
        t0 = robot.time
        robot.send_action({"shoulder_pan.pos": 30.0})
        give_up = time.monotonic() + 120  # only if the physics thread stopped
        while robot.time < t0 + 1.0:  # simulated time: the physics thread moves it
            assert time.monotonic() < give_up, "the physics thread does not advance"
            time.sleep(0.01)
        assert robot.get_observation()["shoulder_pan.pos"] > 20.0


# ---------------------------------------------------------------------------- cameras
def test_cameras_configured_the_lerobot_way_give_uint8_frames_of_their_size():
    top = "top: {type: so101_sim, width: 48, height: 32, pos: [0.3, 0.0, 0.6], lookat: [0.1, 0, 0]}"
    cfg = parse_robot("type=so101_sim", "mode=lockstep", "cameras=" + SMALL[:-1] + ", " + top + "}")
    robot = make_robot_from_config(cfg)
    assert len(robot.cameras) == 3  # lerobot-record sizes its image writer with this
    assert all(isinstance(c, Camera) for c in robot.cameras.values())
    features = robot.observation_features
    assert features["front"] == (48, 64, 3) and features["wrist"] == (32, 32, 3)
    assert features["top"] == (32, 48, 3)
    assert not robot.cameras["front"].is_connected
    with robot:
        assert all(c.is_connected for c in robot.cameras.values())
        obs = robot.get_observation()
        for name, shape in (("front", (48, 64, 3)), ("wrist", (32, 32, 3)), ("top", (32, 48, 3))):
            assert obs[name].shape == shape and obs[name].dtype == np.uint8
            assert obs[name].std() > 3  # not a blank frame
        frame = robot.cameras["front"].read()
        assert frame.shape == (48, 64, 3)
        np.testing.assert_array_equal(frame, obs["front"])  # nothing moved in lockstep
        assert robot.cameras["wrist"].read_latest().shape == (32, 32, 3)
        with pytest.raises(plugin.SimCameraError, match="with its robot"):
            robot.cameras["front"].disconnect()
    assert not robot.cameras["front"].is_connected
    with pytest.raises(lerobot_errors.DeviceNotConnectedError):
        robot.cameras["front"].read()


def test_the_wrist_camera_sees_the_gripper_move_and_the_front_camera_sees_the_arm():
    with lockstep(cameras=parse_robot("type=so101_sim", "cameras=" + SMALL).cameras) as robot:
        before = robot.get_observation()
        for _ in range(30):
            robot.send_action({"shoulder_pan.pos": 45.0, "wrist_flex.pos": 0.0})
        after = robot.get_observation()
    for name in ("front", "wrist"):
        diff = np.abs(before[name].astype(int) - after[name].astype(int)).mean()
        assert diff > 2, name


def test_a_so101_sim_camera_on_its_own_says_what_to_do():
    cam = plugin.SO101SimCamera(plugin.SO101SimCameraConfig())
    assert not cam.is_connected and cam.find_cameras() == []
    with pytest.raises(plugin.SimCameraError, match=r"--robot\.cameras"):
        cam.connect()


# ---------------------------------------------------------------------------- teleoperators
def motion_teleop(**kw) -> SO101SimMotion:
    cfg = SO101SimMotionConfig(**kw)
    teleop = make_teleoperator_from_config(cfg)
    assert isinstance(teleop, SO101SimMotion) and isinstance(teleop, Teleoperator)
    return teleop


def test_the_motion_teleoperator_plays_the_lab_motion_and_loops():
    teleop = motion_teleop()
    assert teleop.duration == pytest.approx(6.0)
    with pytest.raises(lerobot_errors.DeviceNotConnectedError):
        teleop.get_action()
    teleop.connect()
    actions = [teleop.get_action() for _ in range(6 * 30 + 31)]
    assert list(actions[0]) == KEYS == list(teleop.action_features)
    assert teleop.feedback_features == {}
    pose = {k: v for k, v in zip(STARTING_POSE, actions[0].values(), strict=True)}
    assert pose == pytest.approx(STARTING_POSE)
    assert list(actions[60].values()) == pytest.approx(list(ZERO_POSE.values()))  # 2 s: zeros
    assert list(actions[120].values()) == pytest.approx(list(ZERO_POSE.values()))  # held
    assert list(actions[180].values()) == pytest.approx(list(STARTING_POSE.values()))
    assert actions[210] == pytest.approx(actions[30])  # the second take repeats the first
    assert teleop.takes == 2
    teleop.disconnect()
    with pytest.raises(lerobot_errors.DeviceAlreadyConnectedError):
        teleop.connect()
        teleop.connect()


def test_the_motion_teleoperator_varies_each_take_within_bounds_reproducibly():
    def takes(seed: int) -> np.ndarray:
        teleop = motion_teleop(variation=5.0, seed=seed)
        teleop.connect()
        return np.array([list(teleop.get_action().values()) for _ in range(3 * 180)])

    a, b = takes(1), takes(1)
    np.testing.assert_array_equal(a, b)  # same seed: same takes
    zero = np.array(list(ZERO_POSE.values()))
    peaks = a[[60, 240, 420]]  # each take's "zero" pose
    assert np.all(np.abs(peaks - zero) <= 5.0 + 1e-9)
    assert np.abs(peaks[0] - peaks[1]).max() > 0.1  # the takes differ
    np.testing.assert_allclose(a[[0, 180, 360]], np.tile(list(STARTING_POSE.values()), (3, 1)))
    assert np.abs(takes(2)[60] - peaks[0]).max() > 0.1


def test_without_loop_the_motion_ends_and_stays_at_its_last_pose():
    teleop = motion_teleop(loop=False)
    teleop.connect()
    actions = [teleop.get_action() for _ in range(300)]
    assert actions[-1] == pytest.approx(actions[180]) and teleop.takes == 1


def test_a_bad_motion_file_fails_when_the_teleoperator_is_made(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('start = "rest"\n[[steps]]\nmove = "nowhere"\nduration = 1.0\n')
    with pytest.raises(sim_errors.MotionFileError, match=r"bad\.toml:3: unknown pose 'nowhere'"):
        SO101SimMotionConfig(motion=str(bad))


def test_a_so101_leader_arm_drives_the_sim_through_lerobots_record_loop(monkeypatch):
    """``--teleop.type=so101_leader --robot.type=so101_sim``: the leader's readings (degrees,
    gripper 0..100, as its bus returns them) are the sim's goals. The serial bus is faked."""
    from lerobot.processor import make_default_processors
    from lerobot.scripts.lerobot_record import record_loop
    from lerobot.teleoperators.so_leader import SO101Leader, SO101LeaderConfig

    leader = make_teleoperator_from_config(SO101LeaderConfig(port="/dev/null", id="leader"))
    assert isinstance(leader, SO101Leader)
    reading = dict(zip(STARTING_POSE, (20.0, -40.0, 30.0, 10.0, -15.0, 35.0), strict=True))
    monkeypatch.setattr(SO101Leader, "is_connected", property(lambda self: True))
    monkeypatch.setattr(leader.bus, "sync_read", lambda *a, **k: dict(reading))
    robot = lockstep()
    with robot:
        events = {"exit_early": False, "rerecord_episode": False, "stop_recording": False}
        record_loop(robot, events, 30, *make_default_processors(), teleop=leader, control_time_s=1)
        goal = robot.follower.goal()
        obs = robot.get_observation()
    assert list(goal.values()) == pytest.approx(list(reading.values()))
    assert obs["shoulder_pan.pos"] == pytest.approx(20.0, abs=3.0)  # it moved there


# ---------------------------------------------------------------------------- exit
EXIT_SCRIPT = """
import logging, sys
logging.basicConfig(level=logging.INFO, stream=sys.stdout, format="%(message)s")
from lerobot_robot_so101sim import SO101SimConfig
from lerobot.robots import make_robot_from_config
cfg = SO101SimConfig(id="left_on", cameras={{}})
robot = make_robot_from_config(cfg)
robot.connect()
print("connected", flush=True)
{ending}
"""


@pytest.mark.parametrize("ending", ["pass", "raise RuntimeError('boom')", "sys.exit(3)"])
def test_a_robot_left_connected_is_disconnected_at_interpreter_exit(ending):
    script = textwrap.dedent(EXIT_SCRIPT).format(ending=ending)
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert "connected" in done.stdout, done.stderr
    assert "left_on SO101SimFollower disconnected." in done.stdout, done.stdout + done.stderr
    assert done.returncode == {"pass": 0, "sys.exit(3)": 3}.get(ending, 1)


def test_a_dropped_robot_is_disconnected_by_the_garbage_collector():
    robot = make_robot_from_config(SO101SimConfig(cameras={}))
    robot.connect()
    follower = robot.follower
    del robot
    gc.collect()
    assert not follower.is_connected
