"""Helpers written once against LeRobot's robot interface (so101sim.robot.helpers)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fakes import FakeClock

from so101sim.errors import DurationError, JointNameError, JointValueError, RateError
from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
from so101sim.robot.helpers import (
    MOTOR_KEYS,
    Clock,
    WallClock,
    check_fps,
    clock_for,
    hold_robot,
    move_robot_to,
    sleep_until,
    wait_seconds,
)
from so101sim.units import STARTING_POSE, ZERO_POSE


class FakeArm:
    """Stands in for LeRobot's SO101Follower: no ``clock`` attribute, instant motors, each call
    costing ``call_cost`` seconds on the fake clock."""

    def __init__(self, clock: FakeClock, call_cost: float = 0.0) -> None:
        self.clock_ = clock
        self.call_cost = call_cost
        self.pos = {f"{n}.pos": v for n, v in STARTING_POSE.items()}
        self.sent: list[dict[str, float]] = []

    def get_observation(self) -> dict[str, float]:
        self.clock_.t += self.call_cost
        return dict(self.pos)

    def send_action(self, action: dict[str, float]) -> dict[str, float]:
        self.clock_.t += self.call_cost
        self.sent.append(dict(action))
        self.pos.update(action)
        return dict(action)


def test_clock_for_picks_the_robots_clock_or_the_wall_clock():
    arm = FakeArm(FakeClock())
    assert isinstance(clock_for(arm), WallClock)  # LeRobot's robots have no clock
    robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
    assert clock_for(robot) is robot.clock
    assert isinstance(robot.clock, Clock)


def test_move_sends_a_straight_line_at_fps_and_ends_exactly_at_the_target():
    clock = FakeClock()
    arm = FakeArm(clock)
    rec = move_robot_to(arm, {"shoulder_pan": 30.0, "gripper.pos": 50}, 0.5, fps=20, clock=clock)
    assert rec.actions_sent == len(arm.sent) == 10
    assert all(set(a) == {"shoulder_pan.pos", "gripper.pos"} for a in arm.sent)
    pan = [a["shoulder_pan.pos"] for a in arm.sent]
    assert pan == pytest.approx(np.linspace(3.0, 30.0, 10).tolist())
    assert arm.sent[-1] == {"shoulder_pan.pos": 30.0, "gripper.pos": 50.0}
    assert rec.target == {"shoulder_pan.pos": 30.0, "gripper.pos": 50.0}
    assert rec.final_error == {"shoulder_pan.pos": 0.0, "gripper.pos": 0.0}
    assert rec.end_time - rec.start_time == pytest.approx(0.5)
    assert rec.observed.shape == (10, 6)


def test_waits_go_to_absolute_deadlines_whatever_the_calls_cost():
    clock = FakeClock()
    arm = FakeArm(clock, call_cost=0.004)
    rec = move_robot_to(arm, ZERO_POSE, 1.0, fps=50, clock=clock)
    # 50 ticks of 20 ms: each tick's calls cost 8 ms, the sleeps make up the rest exactly
    assert rec.times - rec.times[0] == pytest.approx(np.arange(50) * 0.02 + np.r_[0, [0.004] * 49])
    assert clock.sleeps == pytest.approx([0.02 - 0.004] + [0.02 - 0.008] * 49)
    hold = hold_robot(arm, 0.2, fps=50, clock=clock)
    assert hold.actions_sent == 0 and hold.target == {}
    assert len(arm.sent) == 50  # the hold sent nothing
    assert hold.end_time - hold.start_time == pytest.approx(0.2 + 0.004)


def test_bad_input_raises_before_anything_is_sent():
    clock = FakeClock()
    arm = FakeArm(clock)
    with pytest.raises(JointNameError):
        move_robot_to(arm, {"elbow": 0.0}, 1.0, clock=clock)
    with pytest.raises(JointValueError):
        move_robot_to(arm, {"elbow_flex": math.nan}, 1.0, clock=clock)
    for bad in (0, -1.0, math.inf, "2"):
        with pytest.raises(DurationError):
            move_robot_to(arm, ZERO_POSE, bad, clock=clock)
        with pytest.raises(DurationError):
            hold_robot(arm, bad, clock=clock)
    for bad in (0, -5, math.nan, True, "50"):
        with pytest.raises(RateError):
            move_robot_to(arm, ZERO_POSE, 1.0, fps=bad, clock=clock)
    assert arm.sent == []
    assert clock.sleeps == []
    assert check_fps(np.float32(30)) == 30.0


def test_sleep_until_and_wait_seconds():
    clock = FakeClock()
    sleep_until(clock, clock.now() - 1)
    assert clock.sleeps == []
    sleep_until(clock, clock.now() + 0.25)
    assert clock.sleeps == [pytest.approx(0.25)]
    robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
    with robot:
        t0 = robot.time
        wait_seconds(robot, 0.1)
        assert robot.time == pytest.approx(t0 + 0.1)
        with pytest.raises(DurationError):
            wait_seconds(robot, -1)


def lab_motion(robot):
    """The lab's motion, written as for the real arm."""
    a = move_robot_to(robot, ZERO_POSE, 1.0)
    b = hold_robot(robot, 0.5)
    c = move_robot_to(robot, STARTING_POSE, 1.0)
    d = hold_robot(robot, 0.3)
    return a, b, c, d


def test_lab_motion_on_the_lockstep_sim_is_deterministic_and_reaches_its_targets():
    def run():
        robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
        with robot:
            t0 = robot.time
            records = lab_motion(robot)
            return robot.time - t0, records

    elapsed, (to_zero, hold, _, rest) = run()
    elapsed2, records2 = run()
    # simulated time is the clock of record: 1 + 0.5 + 1 + 0.3 s
    assert elapsed == pytest.approx(2.8)
    assert elapsed2 == elapsed
    assert np.array_equal(hold.observed, records2[1].observed)
    # the default arm (sts3215, a real STS3215 at P = 16) holds the arm out a few degrees low
    # (its weight against an 11 N·m/rad servo) and stops inside its friction's dead band
    assert all(abs(v - ZERO_POSE[k[:-4]]) < 3.5 for k, v in hold.reached.items())
    # holding sends nothing, and the arm does not creep: it settles, it does not drift away
    assert hold.actions_sent == 0
    err = np.abs(hold.observed - np.array(list(ZERO_POSE.values())))
    assert err[-1].max() <= err[0].max()
    assert err[-1].max() < 3.5
    assert all(abs(v - STARTING_POSE[k[:-4]]) < 7.0 for k, v in rest.reached.items())
    assert list(to_zero.reached) == list(MOTOR_KEYS)


def test_same_helpers_drive_the_realtime_sim():
    robot = SO101SimFollower(SO101SimFollowerConfig(initial_pose=ZERO_POSE))
    with robot:
        target = {"shoulder_pan": 20.0, "wrist_flex": -15.0, "gripper": 30.0}
        rec = move_robot_to(robot, target, 0.4)
        hold_robot(robot, 0.3)
        obs = robot.get_observation()
    assert rec.actions_sent == 20
    for name, value in target.items():  # within the default servo's sag and dead band
        assert abs(obs[f"{name}.pos"] - value) < 3.0, name
