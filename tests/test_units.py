import math

import numpy as np
import pytest

from so101sim.errors import JointLimitError, JointNameError, JointValueError
from so101sim.model import default_units
from so101sim.units import (
    JOINT_NAMES,
    STARTING_POSE,
    ZERO_POSE,
    format_pose,
    normalize_joint_name,
    parse_pose,
    to_lerobot,
)

U = default_units()


def test_joint_names_are_the_real_arms_in_order():
    assert JOINT_NAMES == (
        "shoulder_pan",
        "shoulder_lift",
        "elbow_flex",
        "wrist_flex",
        "wrist_roll",
        "gripper",
    )


def test_degrees_use_exact_pi():
    q = U.to_radians(np.array([90.0, -45.0, 180.0, 1.0, 0.0, 0.0]))
    assert q[0] == math.pi / 2
    assert q[1] == -math.pi / 4
    assert q[2] == math.pi
    assert U.from_radians(np.array([math.pi, 0, 0, 0, 0, U.lower[5]]))[0] == 180.0


def test_gripper_0_and_100_land_on_the_joint_limits():
    lo, hi = U.lower[5], U.upper[5]
    q0 = U.to_radians(np.array([0, 0, 0, 0, 0, 0.0]))
    q100 = U.to_radians(np.array([0, 0, 0, 0, 0, 100.0]))
    assert q0[5] == pytest.approx(lo, abs=1e-15)
    assert q100[5] == pytest.approx(hi, abs=1e-15)
    # the shipped gripper joint spans -10°..100°
    assert math.degrees(lo) == pytest.approx(-10.0, abs=1e-4)
    assert math.degrees(hi) == pytest.approx(100.0, abs=1e-4)
    # linear in between
    q50 = U.to_radians(np.array([0, 0, 0, 0, 0, 50.0]))
    assert q50[5] == pytest.approx((lo + hi) / 2)


def test_round_trip_arrays_and_batches():
    rng = np.random.default_rng(0)
    lo, hi = U.limits
    values = rng.uniform(lo, hi, size=(100, 6))
    back = U.from_radians(U.to_radians(values))
    np.testing.assert_allclose(back, values, rtol=0, atol=1e-12)


def test_limits_in_arm_units():
    lim = U.limits_dict()
    assert lim["gripper"] == pytest.approx((0.0, 100.0))
    assert lim["shoulder_pan"] == pytest.approx((-110.0, 110.0), abs=1e-4)
    assert lim["shoulder_lift"] == pytest.approx((-100.0, 100.0), abs=1e-4)


def test_lerobot_keys_are_accepted_and_produced():
    pose = {f"{n}.pos": 1.0 for n in JOINT_NAMES}
    np.testing.assert_array_equal(U.pose_to_array(pose), np.ones(6))
    assert to_lerobot(ZERO_POSE) == {f"{n}.pos": 0.0 for n in JOINT_NAMES}
    assert normalize_joint_name("gripper.pos") == "gripper"


def test_unknown_joint_lists_the_six_names():
    with pytest.raises(JointNameError) as e:
        U.pose_to_array({**ZERO_POSE, "elbow": 3.0})
    msg = str(e.value)
    assert "'elbow'" in msg
    for n in JOINT_NAMES:
        assert n in msg


def test_missing_joint_is_named():
    pose = dict(ZERO_POSE)
    del pose["wrist_roll"]
    with pytest.raises(JointNameError, match="missing wrist_roll"):
        U.pose_to_array(pose)
    # with a base, missing joints keep the base's value
    base = np.arange(6.0)
    assert U.pose_to_array(pose, base=base)[4] == 4.0


def test_duplicate_joint_is_rejected():
    with pytest.raises(JointNameError, match="twice"):
        parse_pose({**ZERO_POSE, "gripper.pos": 1.0})


def test_not_a_dict():
    with pytest.raises(JointNameError, match="dict keyed by joint name"):
        U.pose_to_array([0, 0, 0, 0, 0, 0])


@pytest.mark.parametrize("bad", ["10", None, True, float("nan"), float("inf"), -math.inf, [1]])
def test_non_numeric_and_non_finite_values(bad):
    with pytest.raises(JointValueError, match="elbow_flex"):
        U.pose_to_array({**ZERO_POSE, "elbow_flex": bad})


def test_numpy_scalars_are_numbers():
    pose = {n: np.float32(1.5) for n in JOINT_NAMES}
    assert U.pose_to_array(pose)[0] == 1.5


def test_out_of_limits_names_joint_value_and_limits():
    with pytest.raises(JointLimitError) as e:
        U.pose_to_array({**ZERO_POSE, "shoulder_lift": 120.0})
    msg = str(e.value)
    assert "shoulder_lift" in msg and "120°" in msg and "-100°..100°" in msg and "clip" in msg
    with pytest.raises(JointLimitError, match=r"gripper = 101 .*0\.\.100"):
        U.pose_to_array({**ZERO_POSE, "gripper": 101.0})


def test_clip_is_an_explicit_opt_in():
    arr = U.pose_to_array({**ZERO_POSE, "shoulder_lift": 120.0, "gripper": -5}, clip=True)
    assert arr[1] == pytest.approx(100.0, abs=1e-4)
    assert arr[5] == 0.0


def test_limit_check_is_a_limit_error_and_a_value_error():
    assert issubclass(JointLimitError, JointValueError)
    assert issubclass(JointLimitError, ValueError)


def test_starting_pose_is_inside_the_limits():
    values = U.pose_to_array(STARTING_POSE)
    lo, hi = U.limits
    assert np.all(values >= lo) and np.all(values <= hi)


def test_format_pose_has_units_and_no_negative_zero():
    text = format_pose({**ZERO_POSE, "shoulder_pan": -0.0001, "gripper": 50})
    assert "shoulder_pan=0.00°" in text and "gripper=50.00" in text and "-0.00" not in text


def test_a_hair_past_a_limit_is_clipped_not_rejected():
    # a joint resting on its stop reads slightly past it; sending that back must work
    arr = U.pose_to_array({**ZERO_POSE, "gripper": -0.00002, "shoulder_lift": 100.3})
    assert arr[5] == 0.0
    assert arr[1] == pytest.approx(100.0, abs=1e-4)
    with pytest.raises(JointLimitError):
        U.pose_to_array({**ZERO_POSE, "shoulder_lift": 100.6})


def test_arm_units_per_degree_of_rotation():
    per = U.per_degree()
    assert per[:5] == pytest.approx(np.ones(5))
    # the gripper's 100 units span its 110° range
    assert per[5] == pytest.approx(100 / 110, rel=1e-6)


def test_zero_d_arrays_are_numbers_and_huge_ints_are_refused():
    units = default_units()
    pose = {n: np.float32(0.0) for n in JOINT_NAMES}
    pose["elbow_flex"] = np.array(12.5)  # 0-d array, as a tensor's .numpy() gives
    assert units.pose_to_array(pose)[2] == 12.5
    with pytest.raises(JointValueError, match="too large"):
        parse_pose({"elbow_flex": 10**400}, partial=True)
    for bad in (np.array([1.0, 2.0]), np.array(True), "3", None):
        with pytest.raises(JointValueError, match="not a number"):
            parse_pose({"elbow_flex": bad}, partial=True)


def test_an_integer_too_long_to_print_still_gives_the_error():
    from so101sim.validation import check_duration

    with pytest.raises(JointValueError, match="too large"):
        parse_pose({"elbow_flex": 10**5000}, partial=True)
    from so101sim.errors import DurationError

    with pytest.raises(DurationError, match="too large"):
        check_duration(10**5000)


def test_the_plain_float_conversions_are_bit_for_bit_the_array_ones():
    units = default_units()
    rng = np.random.default_rng(5)
    for q in rng.uniform(-7.0, 7.0, size=(2000, 6)):
        assert units.values_from_radians(q.tolist()) == units.from_radians(q).tolist()
        values = units.from_radians(q)
        radians = [units.joint_to_radians(i, v) for i, v in enumerate(values.tolist())]
        assert radians == units.to_radians(values).tolist()
