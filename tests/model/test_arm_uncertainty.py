"""An arm profile's ``[uncertainty]`` table and the servos drawn from it
(model/arm.py ``draw_servo_deltas``), what domain randomisation's ``actuator_sigmas`` uses."""

from __future__ import annotations

import numpy as np
import pytest

from so101sim.model.arm import (
    MAX_SIGMAS,
    ProfileError,
    draw_servo_deltas,
    load_profile,
    profile_key,
    profile_toml,
)
from so101sim.units import JOINT_NAMES

PROFILE = """
name = "wide"
extends = "sts3215"

[uncertainty]
kp_per_p = 0.1
delay_s = 0.004
frictionloss = 0.02
torque_limit = 0.0   # the shipped sts3215's other standard deviations: 0, not drawn
damping = 0.0
viscous = 0.0
drive_frictionloss = 0.0
armature = 0.0
max_velocity = 0.0
"""


def wide(tmp_path):
    path = tmp_path / "wide.toml"
    path.write_text(PROFILE)
    return load_profile(path)


def test_the_table_loads_round_trips_and_does_not_change_the_model_key(tmp_path):
    prof = wide(tmp_path)
    assert prof.uncertainty["kp_per_p"] == 0.1 and prof.uncertainty["delay_s"] == 0.004
    assert load_profile("sts3215").uncertainty["kp_per_p"] > 0  # extends: table by table
    again = tmp_path / "again.toml"
    again.write_text(profile_toml(prof))
    assert load_profile(again).uncertainty == prof.uncertainty
    # the table says how sure the values are, not what the model is
    plain = tmp_path / "plain.toml"
    plain.write_text(profile_toml(prof).split("[uncertainty]")[0])
    assert profile_key(again) == profile_key(plain)


@pytest.mark.parametrize(
    "table, match",
    [
        ("kp = 0.1", "expected some of kp_per_p"),
        ("delay_s = -0.01", "uncertainty.delay_s"),
        ("armature = 'big'", "uncertainty.armature"),
        ("torque_limit = 1e9", "uncertainty.torque_limit"),
    ],
)
def test_a_bad_table_says_what_is_wrong(tmp_path, table, match):
    path = tmp_path / "bad.toml"
    path.write_text(f'name = "bad"\nextends = "sts3215"\n\n[uncertainty]\n{table}\n')
    with pytest.raises(ProfileError, match=match):
        load_profile(path)


def test_draws_spread_as_the_table_says_at_the_supply_and_are_seeded(tmp_path):
    prof = wide(tmp_path)
    rng = np.random.default_rng(0)
    draws = [draw_servo_deltas(prof, rng, sigmas=2.0) for _ in range(400)]
    assert list(draws[0]) == list(JOINT_NAMES)
    assert set(draws[0]["shoulder_lift"]) == {"kp_per_p", "frictionloss", "delay_s"}
    scale = prof.supply_scale  # kp_per_p is given at measured_at_v, the draws at the supply
    for key, sd in (("kp_per_p", 0.1 * scale), ("delay_s", 0.004)):
        values = np.array([d[j][key] for d in draws for j in JOINT_NAMES])
        assert abs(values.mean()) < 0.15 * 2 * sd
        assert values.std() == pytest.approx(2 * sd, rel=0.1)
        assert np.abs(values).max() <= MAX_SIGMAS * 2 * sd + 1e-12
    # friction cannot go below zero whatever the draw
    fl = np.array([d[j]["frictionloss"] for d in draws for j in JOINT_NAMES])
    assert (fl >= -prof.servo.frictionloss - 1e-12).all()
    a = draw_servo_deltas(prof, np.random.default_rng(7))
    b = draw_servo_deltas(prof, np.random.default_rng(7))
    assert a == b


def test_no_table_or_no_sigmas_draws_nothing(tmp_path):
    rng = np.random.default_rng(1)
    before = rng.bit_generator.state
    assert draw_servo_deltas("official", rng) == {j: {} for j in JOINT_NAMES}
    assert draw_servo_deltas(wide(tmp_path), rng, sigmas=0.0) == {j: {} for j in JOINT_NAMES}
    assert rng.bit_generator.state == before
    with pytest.raises(ProfileError, match="actuator sigmas"):
        draw_servo_deltas(wide(tmp_path), rng, sigmas=10.0)


def test_profile_error_is_one_of_the_package_errors():
    from so101sim import errors

    assert ProfileError is errors.ProfileError and issubclass(ProfileError, errors.SettingError)
