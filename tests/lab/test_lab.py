"""The lab handout's helpers, used the way a student's script uses them."""

import math

import mujoco
import numpy as np
import pytest

from so101sim.errors import DurationError, JointLimitError, JointNameError, JointValueError
from so101sim.lab import (
    convert_to_dictionary,
    convert_to_list,
    hold_position,
    move_to_pose,
    send_position_command,
    set_initial_pose,
)
from so101sim.model import scene_path
from so101sim.units import JOINT_NAMES, STARTING_POSE, ZERO_POSE


@pytest.fixture
def md():
    m = mujoco.MjModel.from_xml_path(str(scene_path()))  # as the student does it
    return m, mujoco.MjData(m)


def test_conversions_round_trip():
    pose = {"shoulder_pan": 12.5, "shoulder_lift": -98.0, "elbow_flex": 88.0,
            "wrist_flex": 60.0, "wrist_roll": -30.0, "gripper": 42.0}  # fmt: skip
    q = convert_to_list(pose)
    assert isinstance(q, list) and len(q) == 6
    assert q[0] == 12.5 * math.pi / 180
    back = convert_to_dictionary(q)
    assert list(back) == list(JOINT_NAMES)
    assert back == pytest.approx(pose, abs=1e-12)


def test_gripper_scale_corrects_the_handout(md):
    m, _ = md
    lo, hi = m.jnt_range[5]
    assert convert_to_list({**ZERO_POSE, "gripper": 0})[5] == pytest.approx(lo)
    assert convert_to_list({**ZERO_POSE, "gripper": 100})[5] == pytest.approx(hi)
    assert convert_to_dictionary([0, 0, 0, 0, 0, hi])["gripper"] == pytest.approx(100.0)
    # the handout's qpos*100/pi would call the open gripper ~55.6, not 100
    assert hi * 100 / math.pi == pytest.approx(55.6, abs=0.1)


def test_the_labs_motion_on_the_helpers(md):
    m, d = md
    set_initial_pose(d, STARTING_POSE)
    send_position_command(d, STARTING_POSE)
    r1 = move_to_pose(m, d, None, ZERO_POSE, 2.0)
    assert r1.steps == 1000
    assert all(abs(convert_to_dictionary(d.qpos)[n]) < 1.0 for n in JOINT_NAMES)
    hold_position(m, d, None, 2.0)
    assert all(abs(convert_to_dictionary(d.qpos)[n]) < 1.0 for n in JOINT_NAMES)
    move_to_pose(m, d, None, STARTING_POSE, 2.0)
    end = convert_to_dictionary(d.qpos)
    assert all(abs(end[n] - STARTING_POSE[n]) < 1.0 for n in JOINT_NAMES)
    assert d.time == pytest.approx(6.0)


def test_set_initial_pose_also_holds_it(md):
    m, d = md
    set_initial_pose(d, STARTING_POSE)
    np.testing.assert_allclose(d.ctrl, convert_to_list(STARTING_POSE))
    hold_position(m, d, None, 1.0)
    end = convert_to_dictionary(d.qpos)
    assert all(abs(end[n] - STARTING_POSE[n]) < 0.2 for n in JOINT_NAMES)


def test_hold_holds_the_commanded_target_not_the_sagging_pose(md):
    m, d = md
    set_initial_pose(d, ZERO_POSE)
    for _ in range(5):
        hold_position(m, d, None, 1.0)
    # the target is still exactly what was commanded, although gravity made the arm sag a bit
    np.testing.assert_array_equal(d.ctrl, convert_to_list(ZERO_POSE))
    sag = max(abs(v) for v in convert_to_dictionary(d.qpos).values())
    assert 0 < sag < 0.2


def test_handout_style_hold_creeps_and_ours_does_not(md):
    m, d = md
    set_initial_pose(d, ZERO_POSE)
    # the handout: each hold re-reads the measured pose and commands it
    for _ in range(20):
        pos = convert_to_dictionary(d.qpos.copy())
        send_position_command(d, pos)
        for _ in range(50):
            mujoco.mj_step(m, d)
    handout_drift = abs(convert_to_dictionary(d.qpos)["shoulder_lift"])
    d2 = mujoco.MjData(m)
    set_initial_pose(d2, ZERO_POSE)
    for _ in range(20):
        hold_position(m, d2, None, 0.1)
    ours = abs(convert_to_dictionary(d2.qpos)["shoulder_lift"])
    assert ours < handout_drift


def test_before_any_command_hold_keeps_the_pose_it_finds(md):
    m, d = md
    q = convert_to_list({**ZERO_POSE, "elbow_flex": 30.0})
    d.qpos[:6] = q  # placed by hand, never commanded
    r = hold_position(m, d, None, 0.5)
    np.testing.assert_allclose(d.ctrl, q)
    assert r.target["elbow_flex"] == pytest.approx(30.0)


def test_bad_input_raises_and_leaves_the_data_alone(md):
    m, d = md
    set_initial_pose(d, STARTING_POSE)
    ctrl, qpos = d.ctrl.copy(), d.qpos.copy()
    with pytest.raises(JointNameError):
        send_position_command(d, {"shoulder": 0})
    with pytest.raises(JointValueError):
        move_to_pose(m, d, None, {**ZERO_POSE, "gripper": float("nan")}, 2.0)
    with pytest.raises(JointLimitError):
        move_to_pose(m, d, None, {**ZERO_POSE, "elbow_flex": 150}, 2.0)
    with pytest.raises(DurationError):
        move_to_pose(m, d, None, ZERO_POSE, 0)
    with pytest.raises(DurationError):
        hold_position(m, d, None, -1)
    with pytest.raises(JointNameError):
        set_initial_pose(d, {"elbow_flex": 0})
    np.testing.assert_array_equal(d.ctrl, ctrl)
    np.testing.assert_array_equal(d.qpos, qpos)
    assert d.time == 0.0


def test_a_command_written_straight_to_ctrl_is_held(md):
    m, d = md
    set_initial_pose(d, STARTING_POSE)
    d.ctrl[:] = convert_to_list(ZERO_POSE)  # as the handout's own send_position_command does
    hold_position(m, d, None, 2.0)
    np.testing.assert_allclose(d.ctrl, convert_to_list(ZERO_POSE))
    assert abs(convert_to_dictionary(d.qpos)["shoulder_lift"]) < 1.0


def test_convert_to_dictionary_says_what_it_needs():
    from so101sim.errors import JointValueError

    with pytest.raises(JointValueError, match="at least 6"):
        convert_to_dictionary([0, 0, 0])
    with pytest.raises(JointValueError, match="not a list of numbers"):
        convert_to_dictionary(["a", "b"])


def test_the_limit_errors_advice_works_on_the_lab_helpers(md):
    m, d = md
    set_initial_pose(d, STARTING_POSE)
    too_far = {**ZERO_POSE, "elbow_flex": 120.0}
    with pytest.raises(JointLimitError, match="clip=True") as info:
        move_to_pose(m, d, None, too_far, 0.5)
    assert info.value.joint == "elbow_flex" and info.value.value == 120.0
    r = move_to_pose(m, d, None, too_far, 0.5, clip=True)  # the advice is true here
    assert r.target["elbow_flex"] == pytest.approx(info.value.upper)
    send_position_command(d, too_far, clip=True)
    set_initial_pose(d, too_far, clip=True)


def test_the_lab_helpers_warn_when_a_run_goes_wrong(md, caplog):
    import logging

    m, d = md
    set_initial_pose(d, STARTING_POSE)
    with caplog.at_level(logging.WARNING, logger="so101sim"):
        move_to_pose(m, d, None, ZERO_POSE, 2.0)
        hold_position(m, d, None, 2.0)
        move_to_pose(m, d, None, STARTING_POSE, 2.0)
    assert caplog.text == ""  # the lab motion itself: no warning
    into_floor = {**ZERO_POSE, "shoulder_lift": 60.0, "elbow_flex": 60.0}
    with caplog.at_level(logging.WARNING, logger="so101sim"):
        move_to_pose(m, d, None, into_floor, 2.0)
    lines = [r.getMessage() for r in caplog.records]
    assert any("touches" in line and "floor" in line and "t = " in line for line in lines)
    assert any("lags its target" in line and "shoulder_lift" in line for line in lines)
    assert all("so101sim check" in line for line in lines)
