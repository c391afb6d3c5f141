"""A geared servo holds: Coulomb friction that holds a load below it (no creep), and lets go
above it (issue 32, point 1); a profile that says nothing of its servo is refused by name
(issue 30)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from so101sim.errors import ProfileError
from so101sim.fidelity import ServoBench
from so101sim.model.arm import load_profile, profile_from_toml, profile_key, profile_toml
from so101sim.model.load import load_model
from so101sim.sim.simulation import Simulation

HORIZONTAL = np.pi / 2  # the bench's pendulum hangs at 0


def _held():
    """The shipped servo with friction that holds (``static_friction = true``)."""
    return replace(load_profile("sts3215"), static_friction=True)


def _let_go(profile, mass: float, seconds: float = 10.0) -> np.ndarray:
    """The pendulum of ``mass`` kg at 0.10 m, started still and horizontal, the servo's torque
    off (only the gear train's friction holds it): its angle every 5 ms of simulated time."""
    bench = ServoBench(mass, 0.10, 16, profile)
    t = np.arange(0.0, seconds, 0.005)
    goal = np.full_like(t, HORIZONTAL)
    return bench.simulate(t, goal, initial=HORIZONTAL, torque_enabled=np.zeros(len(t), bool))


def _load(mass: float) -> float:
    """The gravity torque (N·m) of the bench pendulum held horizontal (its arm's own mass too)."""
    bench = ServoBench(mass, 0.10, 16, _held())
    return float((mass * 0.10 + bench.rig.arm_mass * 0.05) * 9.81)


def test_a_load_below_the_static_friction_does_not_move_the_joint_over_10_s():
    prof = _held()
    friction = prof.servo.frictionloss  # the mechanical friction: the servo is off
    assert _load(0.02) < 0.8 * friction
    q = _let_go(prof, 0.02)
    assert np.abs(q - HORIZONTAL).max() < 1e-6  # not a creep: still, for 10 s


def test_a_load_above_the_static_friction_moves_the_joint():
    prof = _held()
    assert _load(0.3) > 2 * prof.servo.frictionloss
    q = _let_go(prof, 0.3, seconds=2.0)
    assert HORIZONTAL - q.min() > 0.5  # it falls


def test_soft_friction_would_creep_under_the_same_load():
    soft = replace(load_profile("sts3215"), static_friction=False)
    q = _let_go(soft, 0.02)
    assert abs(q[-1] - HORIZONTAL) > 1e-3  # MuJoCo's soft friction slips under any load


def test_the_arm_holds_a_pose_without_creeping():
    drift = {}
    for hold in (False, True):
        sim = Simulation(arm=replace(load_profile("sts3215"), static_friction=hold))
        sim.set_pose(
            {"shoulder_pan": 0, "shoulder_lift": -30, "elbow_flex": 40, "wrist_flex": 60,
             "wrist_roll": 0, "gripper": 10}
        )  # fmt: skip
        sim.hold(2.0)
        before = sim.pose_array().copy()
        sim.hold(8.0)  # simulated seconds
        drift[hold] = np.abs(sim.pose_array() - before).max()
    assert drift[True] < 0.01  # degrees, between 2 s and 10 s of a hold
    assert drift[False] > 10 * max(drift[True], 0.01)


def test_static_friction_is_in_the_model_and_its_cache_key(tmp_path):
    path = tmp_path / "held.toml"
    path.write_text('extends = "sts3215"\nstatic_friction = true\n')
    assert load_model(arm=path).opt.noslip_iterations > 0
    assert load_model(arm="sts3215").opt.noslip_iterations == 0  # shipped soft (docs)
    assert load_model(arm="official").opt.noslip_iterations == 0
    assert profile_key(path) != profile_key("sts3215")
    back = profile_from_toml(profile_toml(load_profile(path)))
    assert back.static_friction and profile_key(back) == profile_key(path)


@pytest.mark.parametrize(
    "text, missing",
    [
        ("", "kp_per_p"),
        ('name = "mine"', "torque_limit"),
        ('name = "mine"\n[servo]\nkp_per_p = 1.0\n', "armature"),
    ],
)
def test_a_profile_that_does_not_say_what_its_servo_is_is_refused_by_name(text, missing):
    with pytest.raises(ProfileError, match=missing) as err:
        profile_from_toml(text)
    assert "extends" in str(err.value)


def test_a_profile_that_extends_a_shipped_one_needs_only_what_differs(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text('extends = "sts3215"\nname = "mine"\n[servo]\ndamping = 1.0\n')
    prof = load_profile(path)
    assert (
        prof.servo.damping == 1.0 and prof.servo.kp_per_p == load_profile("sts3215").servo.kp_per_p
    )
    with pytest.raises(ProfileError, match="static_friction"):
        profile_from_toml('extends = "sts3215"\nstatic_friction = 1\n')


def test_an_unnamed_profile_that_extends_one_is_named_after_its_file_in_every_output(tmp_path):
    from so101sim.model.build import servo_model

    path = tmp_path / "my_arm.toml"
    path.write_text('extends = "sts3215"\n[joints.elbow_flex]\nkp_per_p = 1.2\n')
    prof = load_profile(path)
    assert prof.name == "my_arm"
    assert prof.description.startswith("sts3215 changed by my_arm.toml")
    words = servo_model(load_model(arm=path))
    assert words.startswith("my_arm (sts3215 changed by my_arm.toml"), words
    # one that adds only a [calibration] runs sts3215's servos: it keeps that name, and the
    # default model (the same model) is still named sts3215 after it was loaded
    cal = tmp_path / "my_cal.toml"
    cal.write_text('extends = "sts3215"\n[calibration.elbow_flex]\noffset = 2.0\n')
    assert load_profile(cal).name == "sts3215" and load_profile(cal).calibration
    load_model(arm=cal)
    assert servo_model(load_model()).startswith("sts3215 ("), servo_model(load_model())
