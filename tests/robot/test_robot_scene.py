"""The simulated follower's scene between takes (so101sim.robot.scene): the registry of
connected followers, resets drawn from a seed as the environments draw them, a reset asked
for and made before the next observation, and the scripted expert on the follower."""

from __future__ import annotations

import numpy as np
import pytest

from so101sim.envs import PickCubeEnv, expert_for, sim_task
from so101sim.errors import DeviceNotConnectedError, RobotConfigError, SettingError
from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
from so101sim.robot import scene as robot_scene
from so101sim.robot.helpers import MOTOR_KEYS
from so101sim.robot.scene import (
    RobotScene,
    connected_followers,
    draw_placements,
    find_follower,
    when_connected,
)
from so101sim.scenes import SCENE_PRESETS, object_pose
from so101sim.units import STARTING_POSE

FPS = 30


def follower(scene: str | None = "pick_cube", mode: str = "lockstep") -> SO101SimFollower:
    return SO101SimFollower(
        SO101SimFollowerConfig(scene=scene, mode=mode, lockstep_action_seconds=1 / FPS)
    )


def test_placements_drawn_from_a_seed_are_the_environments_for_that_seed():
    env = PickCubeEnv()
    try:
        for seed in (0, 1, 7):
            env.reset(seed=seed)
            x, y, _yaw = draw_placements(SCENE_PRESETS["pick_cube"], seed)["cube"]
            np.testing.assert_allclose(env.object_pose("cube")[:2], (x, y), atol=1e-12)
    finally:
        env.close()
    with pytest.raises(SettingError, match="seed"):
        draw_placements(SCENE_PRESETS["pick_cube"], -1)


def test_the_registry_holds_connected_followers_and_tells_listeners():
    seen: list[SO101SimFollower] = []
    stop = when_connected(seen.append)
    robot = follower()
    try:
        assert robot not in connected_followers()
        robot.connect()
        assert seen == [robot] and robot in connected_followers()
        assert find_follower("pick_cube", mode="lockstep") is robot
        with pytest.raises(RobotConfigError, match="expected 'realtime'"):
            find_follower("pick_cube", mode="realtime")
        with pytest.raises(DeviceNotConnectedError, match="scene 'cube_to_bowl'"):
            find_follower("cube_to_bowl")
    finally:
        stop()
        robot.disconnect()
    assert robot not in connected_followers()
    with pytest.raises(DeviceNotConnectedError, match=r"--robot\.scene=pick_cube"):
        find_follower("pick_cube")
    robot.connect()  # no listener any more
    robot.disconnect()
    assert seen == [robot]


def test_a_listener_that_fails_does_not_fail_connect(caplog):
    def broken(_follower):
        raise RuntimeError("boom")

    stop = when_connected(broken)
    robot = follower()
    try:
        robot.connect()
        assert robot.is_connected and "listener" in caplog.text
    finally:
        stop()
        robot.disconnect()


def test_reset_puts_the_arm_at_its_start_and_the_objects_where_the_seed_says():
    with follower() as robot:
        scene = robot_scene.robot_scene(robot)
        assert robot_scene.robot_scene(robot) is scene
        robot.send_action({"shoulder_lift.pos": 0.0, "elbow_flex.pos": 0.0})
        robot.step(1.0)
        before = robot.time
        poses = scene.reset(5)
        assert poses == draw_placements(scene.scene, 5) and scene.resets == 1
        assert robot.time == before  # simulated time goes on
        obs = robot.get_observation()
        for key, name in zip(MOTOR_KEYS, STARTING_POSE, strict=True):
            assert obs[key] == pytest.approx(STARTING_POSE[name], abs=1e-6)
        assert robot.goal() == pytest.approx({f"{n}.pos": v for n, v in STARTING_POSE.items()})
        sim = robot.simulation
        cube = object_pose(sim.model, sim.data, "cube")
        np.testing.assert_allclose(cube[:2], poses["cube"][:2], atol=1e-12)
        robot.step(0.5)  # the cube rests where it was put, the arm stays folded
        cube_later = object_pose(sim.model, sim.data, "cube")
        assert np.abs(cube_later[:3] - cube[:3]).max() < 1e-3


def test_a_reset_asked_for_is_made_before_the_next_observation():
    with follower() as robot:
        scene = robot_scene.robot_scene(robot)
        sim = robot.simulation
        nominal = object_pose(sim.model, sim.data, "cube")
        scene.request_reset(3)
        assert scene.pending == 3 and scene.resets == 0
        robot.step(0.1)
        assert np.allclose(object_pose(sim.model, sim.data, "cube"), nominal, atol=1e-3)
        robot.get_observation()
        assert scene.pending is None and scene.resets == 1
        assert scene.placements == draw_placements(scene.scene, 3)
        assert not scene.apply_pending()  # nothing left to do


def test_a_follower_without_a_scene_has_none_to_reset():
    robot = follower(scene=None)
    with pytest.raises(RobotConfigError, match="has no scene"):
        RobotScene(robot)


def test_sim_task_needs_its_objects():
    robot = follower()
    sim = robot.simulation
    with pytest.raises(SettingError, match="bowl"):
        sim_task("cube_to_bowl", sim.model, sim, robot_scene.robot_scene(robot).scene, FPS)
    with pytest.raises(SettingError, match="pick_cube, cube_to_bowl"):
        sim_task("juggle", sim.model, sim, robot_scene.robot_scene(robot).scene, FPS)


@pytest.mark.parametrize("seed", [0, 4])
def test_the_scripted_expert_picks_the_cube_on_the_follower(seed):
    with follower() as robot:
        scene = robot_scene.robot_scene(robot)
        scene.reset(seed)
        sim = robot.simulation
        task = sim_task("pick_cube", sim.model, sim, scene.scene, FPS)
        expert = expert_for(task)
        succeeded_at = None
        for k in range(5 * FPS):
            target = expert.act()
            robot.send_action(dict(zip(MOTOR_KEYS, map(float, target), strict=True)))
            if succeeded_at is None and task.evaluate().success:
                succeeded_at = k
        assert succeeded_at is not None and task.grasped("cube")
        assert task.object_pose("cube")[2] - task.start_pose("cube")[2] > 0.03


def test_the_observation_hook_runs_before_the_pending_reset_and_resets_are_counted():
    with follower() as robot:
        scene = robot_scene.robot_scene(robot)
        assert robot_scene.scene_resets(robot) == 0
        seen = []

        def hook() -> None:  # e.g. a teleoperator that ends its take and asks for a reset
            seen.append(scene.pending)
            scene.request_reset(5)

        scene.observation_hook = hook
        robot.get_observation()
        assert seen == [None]  # called first; the reset it asked for was made right after
        assert robot_scene.scene_resets(robot) == 1 and scene.pending is None
        assert scene.placements == draw_placements(scene.scene, 5)
    with follower(scene=None) as plain:
        assert robot_scene.scene_resets(plain) == 0  # no scene: never reset
