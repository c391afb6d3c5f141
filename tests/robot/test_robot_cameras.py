"""The simulated follower's cameras (so101sim.robot.cameras): configured by name, frames in
get_observation() and observation_features, rendered off the physics lock on one thread."""

from __future__ import annotations

import importlib
import sys
import threading
import time

import numpy as np
import pytest

from so101sim.errors import (
    CameraError,
    DeviceNotConnectedError,
    RenderBackendError,
    RobotConfigError,
)
from so101sim.recording import frames
from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
from so101sim.robot.cameras import CAMERA_KEYS, parse_cameras, scene_model
from so101sim.scenes import PRESET_CAMERAS, camera, camera_names
from so101sim.units import JOINT_NAMES

SMALL = {"front": {"width": 64, "height": 48}, "wrist": {"width": 32, "height": 32}}


def lockstep(**kw) -> SO101SimFollower:
    return SO101SimFollower(SO101SimFollowerConfig(mode="lockstep", **kw))


def render_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "so101sim-cameras"]


# ---------------------------------------------------------------------------- configuration
def test_cameras_are_presets_changed_by_the_keys_given_or_cameras_of_ones_own():
    cams = parse_cameras(
        {
            "front": {},
            "wrist": {"width": 224, "height": 224, "quality": "draft"},
            "top": {"pos": [0.3, 0.0, 0.6], "lookat": (0.1, 0, 0), "fovy": 40},
            "side": camera("ignored", pos=(0, -0.5, 0.2), lookat=(0.1, 0, 0.1)),
            "front2": PRESET_CAMERAS["front"],
        }
    )
    assert cams["front"].spec == PRESET_CAMERAS["front"] and cams["front"].quality == "auto"
    assert (cams["wrist"].spec.width, cams["wrist"].spec.body) == (224, "gripper")
    assert cams["wrist"].quality == "draft"
    assert cams["top"].spec.pos == (0.3, 0.0, 0.6) and cams["top"].spec.fovy == 40
    assert cams["side"].spec.name == "side" and cams["front2"].spec.name == "front2"
    assert parse_cameras(None) == {} == parse_cameras({})
    assert parse_cameras({"wrist": None})["wrist"].spec == PRESET_CAMERAS["wrist"]
    assert "quality" in CAMERA_KEYS and "pos" in CAMERA_KEYS and "name" not in CAMERA_KEYS


@pytest.mark.parametrize(
    "cameras, match",
    [
        ({"front": {"colour": True}}, "unknown setting 'colour'"),
        ({"front": {"width": 641}}, "camera 'front'.*even"),
        ({"front": {"quality": "best"}}, "auto, draft, full"),
        ({"top": {}}, "give its pos and lookat"),
        ({"front": {"pos": 3}}, "3 numbers"),
        ({"front": object()}, "expected a dict"),
        (["front"], "expected a dict from camera name"),
        ({"front": {"width": 10**6}}, "width"),
    ],
)
def test_bad_cameras_are_refused_when_the_config_is_made(cameras, match):
    with pytest.raises(CameraError, match=match):
        parse_cameras(cameras)
    with pytest.raises(RobotConfigError, match="cameras: "):
        SO101SimFollowerConfig(cameras=cameras)


def test_the_scene_gets_the_cameras_and_a_follower_without_any_gets_a_private_model():
    m = scene_model(SMALL, None)
    assert {"front", "wrist"} <= set(camera_names(m))
    assert scene_model({}, None) is not scene_model({}, None)


# ---------------------------------------------------------------------------- the follower
def test_frames_in_observations_and_their_shapes_in_observation_features():
    robot = lockstep(cameras=SMALL)
    features = robot.observation_features
    assert features["front"] == (48, 64, 3) and features["wrist"] == (32, 32, 3)
    assert list(features)[:6] == list(robot.action_features)  # the joints come first
    assert set(robot.cameras) == {"front", "wrist"} and not robot.cameras["front"].is_connected
    with robot:
        obs = robot.get_observation()
        for name, shape in features.items():
            if isinstance(shape, tuple):
                assert obs[name].shape == shape and obs[name].dtype == np.uint8
                assert obs[name].std() > 3  # a picture, not a blank frame
        again = robot.get_observation()
        assert again["front"] is not obs["front"]  # each observation owns its frames
        np.testing.assert_array_equal(again["front"], obs["front"])  # lockstep: nothing moved
        cam = robot.cameras["wrist"]
        assert (cam.width, cam.height, cam.fps) == (32, 32, 30.0) and cam.is_connected
        np.testing.assert_array_equal(cam.read(), obs["wrist"])
        last = cam.async_read()
        np.testing.assert_array_equal(last, obs["wrist"])
        assert cam.read_latest() is last  # the last frame rendered, young enough
    assert not robot.cameras["front"].is_connected and not render_threads()
    with pytest.raises(DeviceNotConnectedError):
        robot.cameras["front"].read()


def test_cameras_change_no_physics():
    plain, seen = lockstep(), lockstep(cameras=SMALL)
    with plain, seen:
        for i in range(20):
            a, b = plain.get_observation(), seen.get_observation()
            assert [a[k] for k in plain.action_features] == [b[k] for k in plain.action_features]
            for robot in (plain, seen):
                robot.send_action({"shoulder_pan.pos": 2.0 * i, "elbow_flex.pos": 30.0})
                robot.step(0.02)


def test_frames_show_the_state_the_joints_were_read_in_and_follow_the_arm():
    with lockstep(cameras=SMALL) as robot:
        first = robot.get_observation()
        robot.send_action({"shoulder_pan.pos": 45.0, "wrist_flex.pos": 0.0})
        robot.step(1.0)
        moved = robot.get_observation()
    for name in ("front", "wrist"):
        assert np.abs(first[name].astype(int) - moved[name].astype(int)).mean() > 2, name


def test_rendering_happens_off_the_physics_lock_on_one_thread_whoever_asks(monkeypatch):
    seen: list[tuple[str, bool]] = []
    render = frames.FrameRenderer.render

    def spy(self, d, caption=None):
        free = robot.lock.acquire(blocking=False)  # would fail if the caller held the lock
        if free:
            robot.lock.release()
        seen.append((threading.current_thread().name, free))
        return render(self, d, caption)

    monkeypatch.setattr(frames.FrameRenderer, "render", spy)
    robot = lockstep(cameras={"front": {"width": 32, "height": 32}})
    with robot:
        robot.get_observation()
        worker = threading.Thread(target=robot.get_observation)  # another thread asks too
        worker.start()
        worker.join()
        robot.cameras["front"].read()
    assert seen == [("so101sim-cameras", True)] * 3


def test_a_renderer_that_cannot_start_leaves_nothing_running(monkeypatch):
    def fail(self, model, settings=None):
        raise RenderBackendError("no OpenGL here; install Mesa's EGL")

    monkeypatch.setattr(frames.FrameRenderer, "__init__", fail)
    robot = lockstep(cameras={"front": {"width": 32, "height": 32}})
    with pytest.raises(RenderBackendError, match="EGL"):
        robot.connect()
    assert not robot.is_connected and not render_threads()


def test_realtime_frames_are_rendered_while_the_physics_runs():
    robot = SO101SimFollower(SO101SimFollowerConfig(cameras={"front": {"width": 32, "height": 32}}))
    with robot:
        t0 = robot.time
        robot.send_action({"shoulder_pan.pos": 30.0})
        for _ in range(3):
            obs = robot.get_observation()
            assert obs["front"].shape == (32, 32, 3)
        give_up = time.monotonic() + 120  # only if the physics thread stalled
        while robot.time < t0 + 0.1:  # the physics thread is not stalled by rendering
            assert time.monotonic() < give_up, "the physics thread does not advance"
            time.sleep(0.01)
    assert not render_threads()


# ---------------------------------------------------------------------------- __main__
def test_importing_so101sim_main_runs_no_cli(monkeypatch, capsys):
    """Tools that import every submodule (LeRobot's ``--robot.discover_packages_path``) must
    not start the CLI."""
    monkeypatch.setattr(sys, "argv", ["lerobot-record", "--help"])
    sys.modules.pop("so101sim.__main__", None)
    module = importlib.import_module("so101sim.__main__")
    assert callable(module.main) and capsys.readouterr().out == ""


def test_a_scene_preset_puts_its_objects_in_the_followers_model():
    import mujoco

    from so101sim.scenes import object_pose

    robot = lockstep(scene="cube_to_bowl", cameras={"front": {"width": 64, "height": 48}})
    model = robot._sim.model
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "cube") >= 0
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "bowl") >= 0
    with robot:
        start = object_pose(model, robot._sim.data, "cube").copy()
        for _ in range(25):  # 0.5 s of simulated time: the cube rests on the table
            robot.send_action({f"{j}.pos": v for j, v in robot._sim.pose().items()})
            obs = robot.get_observation()
        end = object_pose(model, robot._sim.data, "cube")
    assert obs["front"].shape == (48, 64, 3)
    np.testing.assert_allclose(end[:3], start[:3], atol=1e-3)
    assert set(k for k in obs if k.endswith(".pos")) == {f"{j}.pos" for j in JOINT_NAMES}


def test_without_a_scene_the_follower_has_the_plain_arm():
    from so101sim.model import load_model

    plain = SO101SimFollower(SO101SimFollowerConfig())._sim.model
    shipped = load_model()
    assert (plain.nbody, plain.ngeom, plain.njnt) == (shipped.nbody, shipped.ngeom, 6)
    assert plain.opt.cone == shipped.opt.cone and plain.opt.impratio == shipped.opt.impratio


def test_an_unknown_scene_is_refused_listing_the_presets():
    with pytest.raises(RobotConfigError, match=r"unknown scene 'juggle'.*pick_cube, cube_to_bowl"):
        SO101SimFollowerConfig(scene="juggle")
