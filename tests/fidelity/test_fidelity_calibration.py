"""A hidden "true" arm read through a miscalibrated range-mode follower (no LeRobot
calibration JSON: each body joint reads scale × angle + offset) with its gripper blocked on an
object: ``fit`` fits the servos and each joint's calibration on some episodes and predicts a
held-out one within 0.5°, better than the default profile; the calibration goes in the
profile's ``[calibration]``, which ``compare`` uses on such recordings (issue 32, points 2-3)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("scipy")
pytest.importorskip("pyarrow")

from fidelity_helpers import TRUE_CALIBRATION, as_read, range_mode, record, true_arm, write_lerobot

from so101sim.fidelity.compare import compare
from so101sim.fidelity.fit import fit
from so101sim.fidelity.fitparams import body_mean
from so101sim.model.arm import load_profile, profile_toml
from so101sim.units import JOINT_NAMES

JOINTS = tuple(TRUE_CALIBRATION)


@pytest.mark.slow
def test_fit_finds_the_calibration_and_predicts_a_held_out_episode(tmp_path):
    eps = as_read(record(true_arm(), [11, 12, 13, 14], 4.0), TRUE_CALIBRATION, blocked=(1.0, 2.5))
    root = write_lerobot(tmp_path / "ds", eps, transform=range_mode())
    res = fit([root], arm="sts3215", names=("kp_per_p", "damping"), joints=JOINTS,
              holdout=[3], max_evaluations=30)  # fmt: skip
    assert res.fit_episodes == [0, 1, 2] and res.heldout_episodes == [3]
    assert res.gripper_blocked_frames > 60  # 1.5 s of each episode, its edges aside
    for joint in JOINTS:  # fitted (the range-mode guess), with standard errors, in the profile
        cal = res.profile.calibration[joint]
        assert {"scale", "offset", "scale_sd", "offset_sd"} <= set(cal)
        assert res.values[joint]["cal_offset"] == pytest.approx(cal["offset"])
    # each recovered within two of its standard errors, and those errors say something (a
    # fraction of the bounds' width): the scale to a few hundredths, the offset to a degree or two
    for joint in JOINTS:
        got, se, true = res.values[joint], res.stderr[joint], TRUE_CALIBRATION[joint]
        for name in ("scale", "offset"):
            assert abs(got[f"cal_{name}"] - true[name]) <= 2 * se[f"cal_{name}"], (joint, name)
        assert 0 < se["cal_scale"] < 0.1 and 0 < se["cal_offset"] < 2.0, (joint, se)
    assert "offset" not in res.values[JOINTS[0]]  # the servo offset: the calibration's now
    held = res.heldout_error
    assert held is not None and res.default_heldout_error is not None
    assert body_mean(held) < 0.5  # degrees, as read (0.04 when written)
    assert all(held[n] < 0.6 for n in JOINT_NAMES[:5])  # the unfitted pan: 0.51
    assert body_mean(held) < 0.5 * body_mean(res.default_heldout_error)
    assert not res.worse_than_default
    assert body_mean(res.command_heldout_error) > 5 * body_mean(held)
    # compare uses the profile's calibration on the same kind of recording
    path = tmp_path / "fitted.toml"
    path.write_text(profile_toml(res.profile))
    assert load_profile(path).calibration == res.profile.calibration
    with_cal = compare(root, arm=path, episodes=[3])
    assert any("[calibration]" in w for w in with_cal.warnings)
    # one warning about the mapping, naming the joints the profile's calibration corrects
    mapping = [w for w in with_cal.warnings if "typical" in w]
    assert len(mapping) == 1 and "[calibration] on " in mapping[0], with_cal.warnings
    assert all(j in mapping[0] for j in JOINTS), mapping
    if set(JOINTS) != set(JOINT_NAMES[:5]):  # the others: approximate, and said so
        assert "approximate" in mapping[0], mapping
    plain = compare(root, arm="sts3215", episodes=[3])
    sim = np.mean([with_cal.joints[n].mae for n in JOINT_NAMES[:5]])
    assert sim < 0.6 and sim < np.mean([plain.joints[n].mae for n in JOINT_NAMES[:5]])


def test_fit_ignores_a_start_profiles_calibration_on_exact_degrees_as_compare_does(tmp_path):
    """A recording in degrees is taken as given: a start profile's ``[calibration]`` (fitted on
    another, range-mode recording) is used by neither ``compare`` nor ``fit``, so the start's
    held-out error ``fit`` prints is the one ``compare`` gives with that profile."""
    from dataclasses import replace

    root = write_lerobot(tmp_path / "ds", record(true_arm(), [21, 22], 2.0))
    start = replace(load_profile("sts3215"),
                    calibration={"shoulder_lift": {"scale": 1.0, "offset": 6.0}})  # fmt: skip
    path = tmp_path / "start.toml"
    path.write_text(profile_toml(start))
    res = fit([root], arm=path, names=("damping",), joints=("elbow_flex",), holdout=[1],
              max_evaluations=1, fit_delay=False, units="degrees")  # fmt: skip
    cmp = compare(root, arm=path, episodes=[1], units="degrees")
    assert any("[calibration] is not used" in w for w in cmp.warnings)
    assert res.start_heldout_error is not None
    for name in JOINT_NAMES[:5]:  # the same replay: not 6° off on shoulder_lift
        assert res.start_heldout_error[name] == pytest.approx(cmp.joints[name].mae, abs=0.05)
    assert res.start_heldout_error["shoulder_lift"] < 3.0
