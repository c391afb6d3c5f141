"""The simulated SO-101 follower with LeRobot's robot interface."""

from __future__ import annotations

import contextlib
import logging
import math
import os
import subprocess
import sys
import textwrap
import threading
import time

import pytest

from so101sim.errors import (
    DeviceAlreadyConnectedError,
    DeviceNotConnectedError,
    DurationError,
    JointNameError,
    JointValueError,
    RobotConfigError,
    So101SimError,
)
from so101sim.model import arm_index, default_units, load_model
from so101sim.model.arm import gripper_full_range
from so101sim.robot import (
    GRIPPER_TORQUE_FRACTION,
    SO101SimFollower,
    SO101SimFollowerConfig,
    parse_action,
    relative_caps,
)
from so101sim.units import JOINT_NAMES, STARTING_POSE, ZERO_POSE

KEYS = [f"{n}.pos" for n in JOINT_NAMES]
GOAL = {f"{n}.pos": v for n, v in ZERO_POSE.items()}
NOT_CONNECTED = "SO101SimFollower is not connected. Run `.connect()` first."


def lerobot_style_script(robot, goal, *, move_s=1.0, hold_s=0.4, fps=50, settle_s=0.0):
    """A script as written for the real arm through LeRobot: connect, read the arm, send goals in
    a 50 Hz loop with time.sleep, read, disconnect. It knows nothing of the simulation, but
    for ``settle_s`` > 0 the test waits until that much simulated time has passed, and at least
    ``hold_s`` simulated seconds since the last goal was sent (however busy the machine, the
    arm had that long in simulated time), before the last reading."""
    robot.connect()
    obs = robot.get_observation()
    start = {k: obs[k] for k in robot.action_features}
    observations = [obs]
    n = round(move_s * fps)
    for i in range(1, n + 1):
        action = {k: start[k] + (goal[k] - start[k]) * i / n for k in start}
        robot.send_action(action)
        time.sleep(1 / fps)
        observations.append(robot.get_observation())
    settle_s = max(settle_s, robot.time + hold_s) if settle_s else 0.0
    for _ in range(round(hold_s * fps)):
        time.sleep(1 / fps)
        observations.append(robot.get_observation())
    deadline = time.monotonic() + 60  # a busy machine may hold the physics thread back
    while robot.time < settle_s and time.monotonic() < deadline:
        time.sleep(0.01)
    if settle_s:
        observations.append(robot.get_observation())
    robot.disconnect()
    return observations


def physics_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("so101sim-physics")]


# how close the default arm (sts3215: a real STS3215 at P = 16) ends to a goal: it sags under
# the arm's weight (2.3° at the shoulder at the zero pose) and stops inside its Coulomb
# friction's dead band (frictionloss / kp: 1.3°); the vendored ideal actuators end within 0.1°
REACH_DEG = 4.0


def lockstep(**kw) -> SO101SimFollower:
    kw.setdefault("lockstep_action_seconds", 0.0)
    return SO101SimFollower(SO101SimFollowerConfig(mode="lockstep", **kw))


# ---------------------------------------------------------------------------- time
def test_lerobot_script_reaches_goals_in_realtime_mode():
    robot = SO101SimFollower(SO101SimFollowerConfig(id="rt"))
    observations = lerobot_style_script(robot, GOAL, settle_s=1.4)  # simulated seconds
    final = observations[-1]
    # the first reading is the start pose, give or take what the physics, running on its own
    # from connect(), moved before the script read it (0.003° seen on a machine at load 11)
    start = {f"{n}.pos": v for n, v in STARTING_POSE.items()}
    assert observations[0] == pytest.approx(start, abs=0.5)
    for k in KEYS:
        assert abs(final[k] - GOAL[k]) < REACH_DEG, (k, final[k])
    # the arm moved while the script slept: the physics ran on its own
    assert robot.time >= 1.4
    assert not robot.is_connected
    assert physics_threads() == []


def test_lerobot_script_in_lockstep_is_bit_identical_and_reaches_goals():
    def run():
        cfg = SO101SimFollowerConfig(
            mode="lockstep", lockstep_action_seconds=0.01, lockstep_observation_seconds=0.01
        )
        robot = SO101SimFollower(cfg)
        observations = lerobot_style_script(robot, GOAL, move_s=0.6, hold_s=0.2, fps=50)
        return robot, observations

    r1, obs1 = run()
    _, obs2 = run()
    assert obs1 == obs2  # exact equality of every float
    # 1 + 30 reads and 30 sends in the move, 10 reads in the hold, 10 ms each
    assert r1.time == pytest.approx(0.01 * (31 + 30 + 10))
    for k in KEYS:
        # 0.2 s after a 0.6 s move the default servo is still settling (5.3° at the elbow)
        assert abs(obs1[-1][k] - GOAL[k]) < 2 * REACH_DEG, k
    assert physics_threads() == []


def test_step_advances_simulated_time_in_whole_physics_steps():
    robot = lockstep()
    robot.connect()
    t0 = robot.time
    assert robot.step(0.1) == pytest.approx(t0 + 0.1)
    assert robot.step(0) == pytest.approx(t0 + 0.1)
    robot.send_action({"shoulder_pan.pos": 10.0})
    before = robot.get_observation()["shoulder_pan.pos"]
    robot.step(0.5)
    after = robot.get_observation()["shoulder_pan.pos"]
    assert before == pytest.approx(0.0, abs=1e-6)  # no time passed: the goal has not acted yet
    assert after == pytest.approx(10.0, abs=1.5)  # the friction's dead band: 1.3°
    robot.disconnect()


def test_lockstep_action_seconds_advances_time_per_send():
    robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
    with robot:
        t0 = robot.time
        robot.get_observation()
        assert robot.time == t0
        for _ in range(5):
            robot.send_action({"gripper.pos": 10.0})
        assert robot.time == pytest.approx(t0 + 5 * 0.02)


def test_step_errors():
    robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
    with pytest.raises(DeviceNotConnectedError):
        robot.step(0.1)
    with robot:
        for bad in (-0.1, math.nan, math.inf, "1", True):
            with pytest.raises(DurationError):
                robot.step(bad)
    realtime = SO101SimFollower()
    with realtime, pytest.raises(RobotConfigError, match="only in lockstep mode"):
        realtime.step(0.1)


# ---------------------------------------------------------------------------- interface
def test_feature_dicts_are_exactly_the_six_pos_keys():
    robot = SO101SimFollower()
    for features in (robot.observation_features, robot.action_features):
        assert list(features) == KEYS
        assert all(v is float for v in features.values())
    with robot:
        assert list(robot.get_observation()) == KEYS


def test_interface_attributes():
    robot = SO101SimFollower(SO101SimFollowerConfig(id="my_arm"))
    assert robot.config_class is SO101SimFollowerConfig
    assert robot.name == "so101_sim_follower"
    assert robot.id == "my_arm"
    assert str(robot) == "my_arm SO101SimFollower"
    assert robot.is_calibrated is True
    assert robot.is_connected is False
    robot.calibrate()  # nothing to do, must not fail
    robot.connect(calibrate=False)
    assert robot.is_connected
    robot.disconnect()
    assert not robot.is_connected


def test_context_manager_connects_and_disconnects_even_on_error():
    robot = SO101SimFollower()
    with pytest.raises(RuntimeError, match="boom"), robot as r:
        assert r is robot and robot.is_connected
        assert len(physics_threads()) == 1
        raise RuntimeError("boom")
    assert not robot.is_connected
    assert physics_threads() == []


def test_disconnect_stops_the_physics_thread_and_reconnect_restarts_it():
    before = set(threading.enumerate())
    robot = SO101SimFollower()
    robot.connect()
    assert len(physics_threads()) == 1
    robot.disconnect()
    assert set(threading.enumerate()) == before
    robot.connect()
    assert len(physics_threads()) == 1
    robot.disconnect()
    assert set(threading.enumerate()) == before


def test_physics_is_frozen_after_disconnect():
    robot = lockstep()
    robot.connect()
    robot.send_action({"shoulder_pan.pos": 20.0})
    robot.step(0.05)
    robot.disconnect()
    t = robot.time
    pose = robot.simulation.pose()
    robot.connect()  # the arm is where it was, still driven to its goal
    assert robot.time == t
    assert robot.get_observation()["shoulder_pan.pos"] == pose["shoulder_pan"]
    assert robot.goal()["shoulder_pan.pos"] == 20.0
    robot.disconnect()


def test_connection_errors_have_lerobots_messages_and_kinds():
    robot = SO101SimFollower()
    for call in (
        robot.get_observation,
        lambda: robot.send_action(GOAL),
        robot.disconnect,
    ):
        with pytest.raises(DeviceNotConnectedError) as info:
            call()
        assert str(info.value) == NOT_CONNECTED
        assert isinstance(info.value, ConnectionError)
        assert isinstance(info.value, So101SimError)
    with robot:
        with pytest.raises(DeviceAlreadyConnectedError) as info:
            robot.connect()
        assert str(info.value) == "SO101SimFollower is already connected."
        assert isinstance(info.value, ConnectionError)
    assert "connect()" in str(DeviceNotConnectedError())
    assert "twice" in str(DeviceAlreadyConnectedError())


def test_action_after_disconnect_raises_and_keeps_the_goal():
    robot = lockstep()
    robot.connect()
    robot.send_action({"elbow_flex.pos": 50.0})
    robot.disconnect()
    with pytest.raises(DeviceNotConnectedError):
        robot.send_action({"elbow_flex.pos": 10.0})
    assert robot.goal()["elbow_flex.pos"] == 50.0


# ---------------------------------------------------------------------------- actions
def test_send_action_returns_what_was_sent_and_allows_partial_actions():
    robot = lockstep()
    with robot:
        before = robot.goal()
        sent = robot.send_action({"gripper.pos": 40, "wrist_roll.pos": -15.5})
        assert sent == {"gripper.pos": 40.0, "wrist_roll.pos": -15.5}
        after = robot.goal()
        assert after["gripper.pos"] == 40.0 and after["wrist_roll.pos"] == -15.5
        for k in KEYS[:4]:
            assert after[k] == before[k]
        assert robot.send_action({}) == {}


@pytest.mark.parametrize(
    "bad",
    [
        {"shoulder_pann.pos": 1.0},
        {"shoulder_pan": 1.0},  # LeRobot silently drops keys without ".pos"; we refuse
        {"shoulder_pan.vel": 1.0},
        {3: 1.0},
    ],
)
def test_unknown_action_keys_list_the_valid_ones_and_change_nothing(bad):
    robot = lockstep()
    with robot:
        before = robot.goal()
        action = {"elbow_flex.pos": 0.0, **bad}
        with pytest.raises(JointNameError) as info:
            robot.send_action(action)
        for k in KEYS:
            assert k in str(info.value)
        assert robot.goal() == before


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, "10", None, True, [1.0]])
def test_bad_action_values_raise_and_change_nothing(value):
    robot = lockstep()
    with robot:
        before = robot.goal()
        with pytest.raises(JointValueError, match=r"gripper\.pos"):
            robot.send_action({"elbow_flex.pos": 0.0, "gripper.pos": value})
        assert robot.goal() == before


def test_action_must_be_a_dict():
    with pytest.raises(JointNameError, match="dict"):
        parse_action([1, 2, 3, 4, 5, 6])


def test_numpy_values_are_accepted():
    np = pytest.importorskip("numpy")
    robot = lockstep()
    with robot:
        sent = robot.send_action({"shoulder_pan.pos": np.float32(5.0), "gripper.pos": np.int64(3)})
        assert sent == {"shoulder_pan.pos": 5.0, "gripper.pos": 3.0}


# ---------------------------------------------------------------------------- safety
CLAMP_MSG = "Relative goal position magnitude had to be clamped to be safe."


def test_max_relative_target_int_cap_clamps_and_warns(caplog):
    robot = lockstep(max_relative_target=5)  # an int: LeRobot raises TypeError(5)
    with robot, caplog.at_level(logging.WARNING, logger="so101sim.robot"):
        present = robot.get_observation()
        sent = robot.send_action(
            {"shoulder_pan.pos": 30.0, "elbow_flex.pos": present["elbow_flex.pos"] - 2}
        )
        assert sent["shoulder_pan.pos"] == pytest.approx(present["shoulder_pan.pos"] + 5)
        assert sent["elbow_flex.pos"] == pytest.approx(present["elbow_flex.pos"] - 2)
        assert robot.goal()["shoulder_pan.pos"] == sent["shoulder_pan.pos"]
    assert CLAMP_MSG in caplog.text
    assert "shoulder_pan" in caplog.text and "elbow_flex" not in caplog.text


def test_max_relative_target_float_cap_is_relative_to_the_present_position():
    robot = lockstep(max_relative_target=2.5)
    with robot:
        robot.send_action({"shoulder_pan.pos": 2.5})
        robot.step(0.5)
        present = robot.get_observation()["shoulder_pan.pos"]
        sent = robot.send_action({"shoulder_pan.pos": -40.0})
        assert sent["shoulder_pan.pos"] == pytest.approx(present - 2.5)


def test_max_relative_target_dict_caps_per_joint(caplog):
    caps = {"shoulder_pan": 3, "elbow_flex.pos": 4.0}
    robot = lockstep(max_relative_target=caps)
    with robot, caplog.at_level(logging.WARNING, logger="so101sim.robot"):
        p = robot.get_observation()
        sent = robot.send_action(
            {"shoulder_pan.pos": 20.0, "elbow_flex.pos": 0.0, "wrist_roll.pos": 30.0}
        )
    assert sent["shoulder_pan.pos"] == pytest.approx(p["shoulder_pan.pos"] + 3)
    assert sent["elbow_flex.pos"] == pytest.approx(p["elbow_flex.pos"] - 4)
    assert sent["wrist_roll.pos"] == 30.0  # not in the dict: not capped
    assert CLAMP_MSG in caplog.text


@pytest.mark.parametrize(
    "cap", [0, -1.0, math.nan, math.inf, True, "5", [5], {"elbow": 5}, {"elbow_flex": 0}]
)
def test_bad_max_relative_target_is_refused(cap):
    with pytest.raises(RobotConfigError) as info:
        SO101SimFollowerConfig(max_relative_target=cap)
    if isinstance(cap, dict) and "elbow" in cap:
        for n in JOINT_NAMES:
            assert n in str(info.value)


def test_relative_caps_layout():
    assert relative_caps(None) is None
    assert list(relative_caps(4)) == [4.0] * 6
    caps = relative_caps({"gripper.pos": 10})
    assert caps[-1] == 10.0 and all(math.isinf(c) for c in caps[:-1])


def test_goals_beyond_the_limits_are_clipped_with_a_warning(caplog):
    hi = default_units().limits[1]
    robot = lockstep()
    with robot, caplog.at_level(logging.WARNING, logger="so101sim.robot"):
        sent = robot.send_action({"shoulder_pan.pos": 500.0, "gripper.pos": -20.0})
        assert sent["shoulder_pan.pos"] == pytest.approx(hi[0])
        assert sent["gripper.pos"] == pytest.approx(0.0)
        assert robot.goal()["shoulder_pan.pos"] == pytest.approx(hi[0])
    assert "clipped to the limits" in caplog.text
    assert "500" in caplog.text


def test_clamp_then_clip():
    hi = default_units().limits[1]
    robot = lockstep(max_relative_target=1000.0, initial_pose={"shoulder_pan": 100.0})
    with robot:
        sent = robot.send_action({"shoulder_pan.pos": 400.0})
    assert sent["shoulder_pan.pos"] == pytest.approx(hi[0])


def test_gripper_effort_is_bounded_on_a_private_model_copy():
    shared = load_model()
    g = arm_index(shared).actuator[JOINT_NAMES.index("gripper")]
    full = gripper_full_range(None)  # the profile's gripper torque limit, before LeRobot's 50 %
    own = shared.actuator_forcerange[g].copy()
    robot = lockstep()
    with robot:
        m = robot.simulation.model
        assert m is not shared
        assert list(m.actuator_forcerange[g]) == pytest.approx(list(full * GRIPPER_TORQUE_FRACTION))
        assert m.actuator_forcelimited[g]
        # other joints keep their full range, and the shared model is untouched
        assert list(m.actuator_forcerange[0]) == list(shared.actuator_forcerange[0])
    assert list(shared.actuator_forcerange[g]) == list(own)
    robot2 = lockstep(gripper_torque_fraction=0.25)
    with robot2:
        assert robot2.simulation.model.actuator_forcerange[g][1] == pytest.approx(full[1] / 4)
    # the bound acts: a gripper commanded far away never pushes harder than the bound
    with robot:
        robot.send_action({"gripper.pos": 100.0})
        # the default servo acts 27 ms after the goal is written and slews its goal toward
        # it: after 0.1 s the error asks for more than the bound
        robot.step(0.1)
        force = robot.simulation.data.actuator_force[g]
        assert abs(force) == pytest.approx(full[1] * GRIPPER_TORQUE_FRACTION)


# ---------------------------------------------------------------------------- configuration
@pytest.mark.parametrize(
    "kw, match",
    [
        ({"use_degrees": False}, "use_degrees"),
        ({"cameras": {"front": object()}}, "cameras"),
        ({"mode": "fast"}, "realtime, lockstep"),
        ({"speed": 0}, "speed"),
        ({"lockstep_action_seconds": -1}, "lockstep_action_seconds"),
        ({"gripper_torque_fraction": 1.5}, "gripper_torque_fraction"),
        ({"initial_pose": {"elbow": 0.0}}, "initial_pose"),
    ],
)
def test_bad_config_is_refused(kw, match):
    with pytest.raises(RobotConfigError, match=match):
        SO101SimFollowerConfig(**kw)


def test_initial_pose_is_partial_over_the_starting_pose():
    robot = lockstep(initial_pose={"shoulder_pan.pos": 30.0})
    with robot:
        obs = robot.get_observation()
    assert obs["shoulder_pan.pos"] == pytest.approx(30.0)
    assert obs["elbow_flex.pos"] == pytest.approx(STARTING_POSE["elbow_flex"])


@pytest.mark.slow
@pytest.mark.viewer
def test_viewer_is_synced_and_closed_with_the_robot(xvfb):
    code = textwrap.dedent(
        """
        import threading, time
        from so101sim import SO101SimFollower, SO101SimFollowerConfig

        before = set(threading.enumerate())
        robot = SO101SimFollower(SO101SimFollowerConfig(viewer=True))
        with robot:
            assert robot.viewer_open
            t0 = robot.time
            robot.send_action({"shoulder_pan.pos": 10.0})
            deadline = time.monotonic() + 60  # however busy the machine: wait on simulated time
            while robot.time - t0 < 0.3 and time.monotonic() < deadline:
                time.sleep(0.01)
            assert robot.time - t0 >= 0.3, robot.time - t0
            pan = robot.get_observation()["shoulder_pan.pos"]
        assert not robot.viewer_open
        assert set(threading.enumerate()) == before  # physics and viewer threads both ended
        print("pan", round(pan, 1))
        """
    )
    env = {**os.environ, "DISPLAY": xvfb}
    env.pop("MUJOCO_GL", None)
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert abs(float(out.stdout.split()[-1]) - 10.0) <= 1.0


class StuckViewer:
    """Stands for MuJoCo's passive viewer on a machine where drawing a frame takes 30 s."""

    def __init__(self) -> None:
        self.drawing = threading.Event()
        self.release = threading.Event()
        self.frames_drawn = 0

    def lock(self):
        return contextlib.nullcontext()

    def sync(self, state_only: bool = False) -> None:
        self.drawing.set()
        self.release.wait(30)
        self.frames_drawn += 1

    def is_running(self) -> bool:
        return not self.release.is_set()

    def close(self) -> None:
        self.release.set()


def test_the_physics_never_waits_for_the_viewers_drawing(monkeypatch):
    import so101sim.viewer

    stuck = StuckViewer()

    @contextlib.contextmanager
    def open_stuck_viewer(m, d, *, mirror=False, **kw):
        import mujoco

        shown = so101sim.viewer.MirroredViewer(stuck, m, mujoco.MjData(m), d) if mirror else stuck
        yield shown
        shown.close()

    monkeypatch.setattr(so101sim.viewer, "open_viewer", open_stuck_viewer)
    robot = SO101SimFollower(SO101SimFollowerConfig(viewer=True))
    with robot:
        assert stuck.drawing.wait(60)  # the viewer is drawing its first frame, forever
        t0 = robot.time
        robot.send_action({"shoulder_pan.pos": 10.0})
        deadline = time.monotonic() + 60  # however busy the machine: wait on simulated time
        while robot.time - t0 < 0.3 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert robot.time - t0 >= 0.3  # the physics went on
        assert stuck.frames_drawn == 0  # while the first frame was still being drawn
        assert robot.get_observation()["shoulder_pan.pos"] == pytest.approx(10.0, abs=1.0)
    assert physics_threads() == []


def test_physics_that_falls_behind_real_time_is_said_once(monkeypatch, caplog):
    import so101sim.robot.threads as threads

    calls = [0]

    def jumping_clock() -> float:  # the wall clock jumps 2 s ahead once: a stalled machine
        calls[0] += 1
        return time.perf_counter() + (2.0 if calls[0] > 20 else 0.0)

    real_pacer = threads.Pacer

    def pacer(speed, **kw):
        return real_pacer(speed, clock=jumping_clock, **kw)

    monkeypatch.setattr(threads, "Pacer", pacer)
    with caplog.at_level("WARNING", logger="so101sim"), SO101SimFollower() as robot:
        t0 = robot.time
        deadline = time.monotonic() + 60  # however busy the machine: wait on simulated time
        while robot.time - t0 < 0.5 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert robot.time - t0 >= 0.5  # the physics went on after the stall
    said = [r.getMessage() for r in caplog.records if "fell behind real time" in r.message]
    assert len(said) == 1, said
    assert "behind the wall clock" in said[0] and "mode='lockstep'" in said[0]


def test_gripper_reading_is_clamped_to_0_100_as_lerobot_does(caplog):
    robot = lockstep()
    sim = robot.simulation
    with robot:
        with robot.lock:
            sim.data.qpos[sim.index.qpos[-1]] = sim.units.lower[-1] - 0.01  # past the stop
        assert robot.get_observation()["gripper.pos"] == 0.0
        with caplog.at_level(logging.WARNING, logger="so101sim.robot"):
            sent = robot.send_action({"gripper.pos": -1e-6})  # noise-level: clipped silently
        assert sent == {"gripper.pos": 0.0}
    assert caplog.text == ""


# ---------------------------------------------------------------------------- huge numbers
def test_huge_numbers_give_clear_bounded_errors_and_change_nothing():
    with pytest.raises(RobotConfigError, match=r"lockstep_action_seconds .*<= 86400 s"):
        SO101SimFollowerConfig(mode="lockstep", lockstep_action_seconds=1e9)
    with pytest.raises(RobotConfigError, match=r"lockstep_observation_seconds .*<= 86400 s"):
        SO101SimFollowerConfig(mode="lockstep", lockstep_observation_seconds=10**400)
    robot = lockstep()
    with robot:
        t0, goal = robot.time, robot.goal()
        for seconds in (1e9, 10**400):
            with pytest.raises(DurationError, match="at most 86400 s"):
                robot.step(seconds)
        for value in (10**400, -(10**400)):
            with pytest.raises(JointValueError, match=r"shoulder_pan\.pos.*too large"):
                robot.send_action({"shoulder_pan.pos": value})
        assert robot.time == t0 and robot.goal() == goal


# ---------------------------------------------------------------------------- threads end
LEFT_CONNECTED = textwrap.dedent(
    """
    import atexit, sys, threading, time
    from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig

    def threads_at_exit():  # registered first, so it runs after the robot's own exit hook
        alive = [t.name for t in threading.enumerate() if t.name.startswith("so101sim")]
        print("alive at exit:", alive, flush=True)

    atexit.register(threads_at_exit)

    def teleoperate():
        # speed 1000: the physics thread is almost always inside MuJoCo when the script ends
        robot = SO101SimFollower(SO101SimFollowerConfig(speed=1000.0))
        robot.connect()
        robot.send_action({"shoulder_pan.pos": 10.0})
        time.sleep(0.02)
        if sys.argv[1] == "raise":  # LeRobot's teleoperate() when teleop.disconnect() raises
            raise RuntimeError("teleop.disconnect() failed")
        return robot

    robot = teleoperate()  # the script ends with the robot connected
    """
)


@pytest.mark.slow
def test_a_realtime_robot_left_connected_at_exit_stops_its_threads_and_exits_cleanly():
    # Before the fix about 8 runs in 10 of this script segfaulted at interpreter exit.
    for i in range(10):
        how = "raise" if i % 2 else "return"
        out = subprocess.run(
            [sys.executable, "-c", LEFT_CONNECTED, how],
            capture_output=True,
            text=True,
            timeout=120,
        )
        expected = 1 if how == "raise" else 0  # an uncaught exception exits with 1
        assert out.returncode == expected, (i, out.returncode, out.stderr[-2000:])
        assert "alive at exit: []" in out.stdout, (i, out.stdout)
        if how == "raise":
            assert out.stderr.rstrip().endswith("RuntimeError: teleop.disconnect() failed")


@pytest.mark.slow
@pytest.mark.viewer
def test_a_robot_with_its_viewer_left_connected_exits_cleanly(xvfb):
    code = LEFT_CONNECTED.replace("speed=1000.0", "speed=1000.0, viewer=True")
    env = {**os.environ, "DISPLAY": xvfb}
    env.pop("MUJOCO_GL", None)
    for how in ("return", "raise"):
        out = subprocess.run(
            [sys.executable, "-c", code, how], env=env, capture_output=True, text=True, timeout=120
        )
        assert out.returncode == (1 if how == "raise" else 0), out.stderr[-2000:]
        assert "alive at exit: []" in out.stdout, out.stdout


def test_dropped_connected_robots_stop_their_physics_threads_when_collected():
    import gc
    import weakref

    robots = [SO101SimFollower(SO101SimFollowerConfig(id=f"drop{i}")) for i in range(20)]
    for r in robots:
        r.connect()
    assert len(physics_threads()) == 20
    sims = [weakref.ref(r.simulation) for r in robots]
    del robots, r
    gc.collect()
    assert physics_threads() == []
    # nothing else kept them: not the threads, not the exit hooks (removed with the robots)
    assert [s for s in sims if s() is not None] == []


def test_a_disconnected_robot_leaves_nothing_behind():
    import gc
    import weakref

    before = set(threading.enumerate())
    for make in (SO101SimFollower, lockstep):
        robot = make()
        robot.connect()
        robot.disconnect()
        sim = weakref.ref(robot.simulation)
        del robot
        gc.collect()
        assert sim() is None  # no exit hook holds its simulation
    assert set(threading.enumerate()) == before


def test_a_config_field_the_sim_lacks_says_which_fields_exist():
    import dataclasses
    import pickle

    with pytest.raises(RobotConfigError) as info:
        SO101SimFollowerConfig(port="/dev/ttyACM0")  # a real arm's config
    message = str(info.value)
    assert "has no field 'port'" in message and "no serial port" in message
    assert "its fields are id, max_relative_target," in message and "speed" in message
    assert len(message.splitlines()) == 1
    with pytest.raises(RobotConfigError, match="has no field 'calibration_dir'; its fields"):
        SO101SimFollowerConfig(id="a", calibration_dir="/tmp")
    with pytest.raises(RobotConfigError, match="keyword arguments only"):
        SO101SimFollowerConfig("my_arm")
    config = SO101SimFollowerConfig(id="a", speed=2.0)  # still a plain dataclass
    assert dataclasses.replace(config, speed=3.0).speed == 3.0
    assert pickle.loads(pickle.dumps(config)) == config
