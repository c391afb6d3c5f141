"""The scripted-expert teleoperator (``--teleop.type=so101_sim_expert``) in process and in
LeRobot's own record loop: takes that start from new placements, aligned with LeRobot's
episodes (``lerobot-record`` itself: test_expert_record.py)."""

from __future__ import annotations

import numpy as np
import pytest
from lerobot.robots import make_robot_from_config
from lerobot.teleoperators import TeleoperatorConfig, make_teleoperator_from_config
from lerobot.utils import errors as lerobot_errors
from lerobot.utils.import_utils import register_third_party_plugins
from lerobot_robot_so101sim import SO101SimConfig, SO101SimExpert, SO101SimExpertConfig

from so101sim import errors as sim_errors
from so101sim.units import STARTING_POSE

FPS = 30
EPISODE_S = 8  # the expert lifts the cube at call ~107: a loop at 14 Hz still gets there
FRAMES = EPISODE_S * FPS
EPISODES = 5
KEYS = [f"{j}.pos" for j in STARTING_POSE]
START = np.array(list(STARTING_POSE.values()))
REPO_ID = "local/so101_sim_expert"


def robot(mode: str = "lockstep"):
    return make_robot_from_config(SO101SimConfig(mode=mode, scene="pick_cube"))


def expert(**kw) -> SO101SimExpert:
    config = SO101SimExpertConfig(task="pick_cube", episode_time_s=EPISODE_S, **kw)
    return make_teleoperator_from_config(config)  # type: ignore[return-value]


def state(obs: dict) -> np.ndarray:
    return np.array([obs[k] for k in KEYS])


# ---------------------------------------------------------------------------- in process
def test_the_expert_teleoperator_is_registered_and_checks_its_fields():
    register_third_party_plugins()
    assert TeleoperatorConfig.get_choice_class("so101_sim_expert") is SO101SimExpertConfig
    assert SO101SimExpertConfig().episode_time_s == 8.0
    assert SO101SimExpertConfig(task="cube_to_bowl").episode_time_s == 12.0
    assert SO101SimExpertConfig(episode_time_s=5, reset_time_s=1, fps=10).take_calls == 60
    with pytest.raises(sim_errors.RobotConfigError, match="pick_cube, cube_to_bowl"):
        SO101SimExpertConfig(task="juggle")
    with pytest.raises(sim_errors.RobotConfigError, match="seed"):
        SO101SimExpertConfig(seed=-1)
    with pytest.raises(sim_errors.RobotConfigError, match="episode_time_s"):
        SO101SimExpertConfig(episode_time_s=0)


def test_takes_start_anew_before_their_first_observation_and_pick_the_cube():
    """As lerobot-record does it: the teleoperator connects first, then the robot; each loop
    observes, asks the teleoperator, sends the action. Two takes of 5 s."""
    teleop, arm = expert(seed=10), robot()
    teleop.connect()
    arm.connect()
    try:
        firsts, actions = [], []
        for k in range(2 * FRAMES):
            obs = arm.get_observation()
            if k % FRAMES == 0:
                firsts.append(state(obs))
            action = teleop.get_action()
            actions.append([action[key] for key in KEYS])
            arm.send_action(action)
    finally:
        teleop.disconnect()
        arm.disconnect()
    takes = teleop.takes
    assert [(t.index, t.seed, t.calls) for t in takes] == [(0, 10, FRAMES), (1, 11, FRAMES)]
    assert all(t.success and not t.cut_short and t.attempts == 0 for t in takes)
    assert all(t.details["cube_rise_m"] > 0.03 for t in takes)
    assert takes[0].placements != takes[1].placements
    for first in firsts:  # the arm back at its start pose when each take's first frame is taken
        np.testing.assert_allclose(first, START, atol=0.5)
    a = np.array(actions)
    assert np.abs(a[:FRAMES] - a[FRAMES:]).max() > 5  # another placement, another demonstration


def test_the_expert_finds_a_robot_connected_before_it_and_says_what_is_missing():
    arm = robot()
    arm.connect()
    try:
        teleop = expert()
        teleop.connect()
        arm.get_observation()  # the first take's reset is made here
        teleop.get_action()
        assert teleop.takes[0].placements["cube"][:2] != pytest.approx((0.19, 0.08))
        teleop.disconnect()
    finally:
        arm.disconnect()
    lonely = expert()
    lonely.connect()
    with pytest.raises(lerobot_errors.DeviceNotConnectedError, match=r"--robot\.scene=pick_cube"):
        lonely.get_action()
    realtime = robot(mode="realtime")
    realtime.connect()
    try:
        with pytest.raises(sim_errors.RobotConfigError, match=r"--robot\.mode=lockstep"):
            lonely.get_action()
    finally:
        realtime.disconnect()
        lonely.disconnect()
    with pytest.raises(lerobot_errors.DeviceNotConnectedError):
        lonely.get_action()


def test_a_loop_that_fell_behind_starts_the_next_take_at_lerobots_next_episode(monkeypatch):
    """LeRobot ends an episode after episode_time_s of wall-clock time: an observation that
    comes that long after the take's first one is the next episode's first (no reset period),
    and it already shows the next take's start."""
    import lerobot_robot_so101sim.expert as module

    clock = [100.0]
    monkeypatch.setattr(module.time, "perf_counter", lambda: clock[0])
    teleop, arm = expert(seed=3), robot()
    teleop.connect()
    arm.connect()
    try:
        for _ in range(10):
            arm.send_action(teleop.get_action())
            clock[0] += 1 / FPS
        clock[0] += EPISODE_S  # the loop fell behind; LeRobot saved the episode
        first = arm.get_observation()  # the next episode's first frame: the next take's start
        assert [(t.index, t.calls, t.cut_short) for t in teleop.takes] == [(0, 10, True)]
        np.testing.assert_allclose(state(first), START, atol=0.5)
        teleop.get_action()
        takes = [(t.index, t.calls, t.cut_short) for t in teleop.takes]
        assert takes == [(0, 10, True), (1, 1, False)]
        assert teleop.takes[1].seed == 4 and arm.follower.goal() == pytest.approx(
            {k: v for k, v in zip(KEYS, START, strict=True)}, abs=1.0
        )
    finally:
        teleop.disconnect()
        arm.disconnect()


# ---------------------------------------------------------------------------- lerobot-record
@pytest.mark.cli
# ---------------------------------------------------------------------------- LeRobot's loop
def test_takes_follow_lerobots_episodes_however_slow_the_loop(tmp_path):
    """LeRobot's own record_loop and dataset writer, three 8 s episodes, the second one slowed
    down by a sleep before every observation (under 5 Hz instead of 30; the others have twice
    the time the take needs, so a busy machine still records them whole): every episode starts
    at its take's start pose and holds that one take (no jump back to the start inside an
    episode, no take going on into the next); the slow one is marked failed with a message,
    the others hold a whole demonstration (the cube lifted)."""
    import time as wall

    from lerobot.datasets import LeRobotDataset
    from lerobot.processor import make_default_processors
    from lerobot.scripts.lerobot_record import record_loop
    from lerobot.utils.feature_utils import hw_to_dataset_features

    teleop_actions, robot_actions, observations = make_default_processors()
    config = SO101SimExpertConfig(task="pick_cube", episode_time_s=8.0, seed=7)
    teleop, arm = make_teleoperator_from_config(config), robot()
    features = {
        **hw_to_dataset_features(arm.action_features, "action", use_video=False),
        **hw_to_dataset_features(arm.observation_features, "observation", use_video=False),
    }
    dataset = LeRobotDataset.create(
        REPO_ID, FPS, root=tmp_path / "ds", robot_type=arm.name, features=features, use_videos=False
    )
    get_observation = arm.get_observation
    slow = [False]

    def observe():
        if slow[0]:
            wall.sleep(0.2)
        return get_observation()

    arm.get_observation = observe  # type: ignore[method-assign]
    events = {"exit_early": False, "rerecord_episode": False, "stop_recording": False}
    teleop.connect()
    arm.connect()
    try:
        for episode in range(3):
            slow[0] = episode == 1
            record_loop(
                robot=arm, events=events, fps=FPS, teleop_action_processor=teleop_actions,
                robot_action_processor=robot_actions, robot_observation_processor=observations,
                dataset=dataset, teleop=teleop, control_time_s=8.0, single_task="pick",
            )  # fmt: skip
            dataset.save_episode()
    finally:
        teleop.disconnect()
        arm.disconnect()
    dataset.finalize()
    takes = teleop.takes
    assert [t.episode for t in takes] == [0, 1, 2]
    assert [t.seed for t in takes] == [7, 8, 9]
    assert [t.failed for t in takes] == [False, True, False]
    assert teleop.failed_episodes == [1]
    assert "episode 1" in takes[1].message and "--dataset.episode_time_s" in takes[1].message
    loaded = LeRobotDataset(REPO_ID, root=tmp_path / "ds")
    index = np.asarray(loaded.hf_dataset["episode_index"])
    states = np.stack(loaded.hf_dataset["observation.state"]).astype(float)
    for episode, take in enumerate(takes):
        s = states[index == episode]
        assert len(s) == take.calls  # the take is the whole episode
        np.testing.assert_allclose(s[0], START, atol=0.5)  # from the start pose
        # the folded pose is never seen again once left: no snap back to the start inside
        left = np.flatnonzero(np.abs(s - START).max(axis=1) > 5.0)
        assert len(left) and not np.any(np.abs(s[left[0] :] - START).max(axis=1) < 1.0)
        assert np.abs(np.diff(s, axis=0)).max() < 15.0  # no jump between frames
    assert len(states[index == 1]) < 0.6 * len(states[index == 0])  # it was slow
    assert takes[0].success and takes[2].success and not takes[1].success
