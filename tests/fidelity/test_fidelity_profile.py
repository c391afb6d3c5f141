"""Arm profiles: loading by name and path, their bounds, and what they do to the model."""

from __future__ import annotations

import numpy as np
import pytest

from so101sim.model import load_model
from so101sim.model.arm import (
    STALL_TORQUE_NM,
    ProfileError,
    load_profile,
    profile_names,
    profile_toml,
)
from so101sim.sim import Simulation
from so101sim.units import JOINT_NAMES, ZERO_POSE


def test_shipped_profiles_load_by_name():
    assert {"official", "sts3215", "sts3215-12v"} <= set(profile_names())
    for name in profile_names():
        prof = load_profile(name)
        assert prof.name == name
        for j in JOINT_NAMES:
            assert prof.joint(j).kp > 0


def test_official_profile_reproduces_the_vendored_model():
    import mujoco

    from so101sim.model import scene_path

    plain = mujoco.MjModel.from_xml_path(str(scene_path()))  # the file, as it is
    official = load_model(arm="official")
    for f in ("dof_damping", "dof_frictionloss", "dof_armature", "actuator_gainprm",
              "actuator_biasprm", "actuator_forcerange", "actuator_ctrlrange"):  # fmt: skip
        np.testing.assert_allclose(getattr(official, f), getattr(plain, f), err_msg=f)
    assert not official.actuator_delay.any()


def test_sts3215_profile_is_soft_delayed_and_scaled_to_7v4():
    prof = load_profile("sts3215")
    at12 = load_profile("sts3215-12v")
    assert prof.supply_v == 7.4 and at12.supply_v == 12.0
    ratio = STALL_TORQUE_NM[7.4] / STALL_TORQUE_NM[12.0]
    lift, lift12 = prof.joint("shoulder_lift"), at12.joint("shoulder_lift")
    assert lift.kp == pytest.approx(lift12.kp * ratio)
    assert lift.torque_limit == pytest.approx(lift12.torque_limit * ratio)
    assert lift.damping == pytest.approx(lift12.damping * ratio)
    assert lift.frictionloss == lift12.frictionloss and lift.delay_s == lift12.delay_s
    assert 5 < lift12.kp < 40  # about 1 N·m/rad per P unit at P = 16, not the vendored 998
    assert prof.joint("gripper").force_limit == pytest.approx(lift.force_limit * 0.5)
    m = load_model(arm="sts3215")
    assert np.allclose(m.actuator_delay, lift.delay_s) and (m.actuator_history[:, 0] > 2).all()
    # back-EMF is joint damping, not actuator kv
    assert not m.actuator_biasprm[:, 2].any()
    assert np.allclose(m.dof_damping[:6], lift.joint_damping)


def test_a_profile_file_round_trips(tmp_path):
    prof = load_profile("sts3215")
    path = tmp_path / "arm.toml"
    path.write_text(profile_toml(prof, comment="a test"))
    again = load_profile(path)
    for j in JOINT_NAMES:
        assert again.joint(j) == prof.joint(j)
    assert load_profile(str(path)).supply_v == prof.supply_v


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[servo]\nkp_per_p = -1\n", "kp_per_p"),
        ("[servo]\ndelay_s = 5\n", "delay_s"),
        ("[servo]\nstiffness = 1\n", "unknown field 'stiffness'"),
        ("[joints.elbow]\nkp_per_p = 1\n", "names no joint"),
        ("supply_v = 48\n", "supply_v"),
        ("colour = 'red'\n", "unknown field 'colour'"),
        ("[servo\n", "not valid TOML"),
        ('extends = "nope"\n', "not a shipped profile"),
        ("[servo]\nkp_per_p = 'high'\n", "not a number"),
    ],
)
def test_bad_profiles_say_what_is_wrong(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ProfileError, match=match):
        load_profile(path)


def test_unknown_names_and_missing_files_are_refused(tmp_path):
    with pytest.raises(ProfileError, match=r"unknown arm profile 'sts9999'.*official"):
        load_profile("sts9999")
    with pytest.raises(ProfileError, match="does not exist"):
        load_profile(tmp_path / "missing.toml")


def test_simulation_with_a_profile_starts_still_and_sags_under_gravity():
    """The delay's history is filled at set_pose (no lurch toward 0 at the start), and the soft
    fitted servo sags under the arm's weight where the vendored one barely does."""
    sim = Simulation(arm="sts3215")
    start = sim.pose_array()
    np.testing.assert_allclose(sim.data.act, sim.data.ctrl)  # the slewed goal starts there too
    sim.step(150, trace=False)  # 0.3 s: it settles under its weight, nothing more
    assert np.abs(sim.pose_array() - start).max() < 2.0
    sags = {}
    for arm in ("official", "sts3215"):
        s = Simulation(arm=arm)
        s.move_to(ZERO_POSE, 2.0)
        s.hold(1.0)
        sags[arm] = abs(s.pose()["shoulder_lift"])
    assert sags["sts3215"] > 5 * sags["official"]
    assert sags["sts3215"] > 0.5  # degrees: a real P = 16 servo holding the arm out sags


def test_arm_with_a_compiled_model_is_refused():
    with pytest.raises(Exception, match="arm= applies when so101sim loads the model"):
        Simulation(load_model(), arm="sts3215")
