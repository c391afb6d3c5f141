"""``so101sim fit``: a hidden "true" arm (perturbed servos, a 47 ms delay) writes recordings; the
fit recovers its parameters and predicts a held-out motion within 0.5°."""

from __future__ import annotations

import pytest

pytest.importorskip("scipy")
pytest.importorskip("pyarrow")

from fidelity_helpers import record, true_arm, write_csv, write_lerobot

from so101sim.cli import main
from so101sim.fidelity.compare import compare
from so101sim.fidelity.fit import fit
from so101sim.fidelity.logs import ArmLog
from so101sim.model.arm import load_profile
from so101sim.units import JOINT_NAMES


@pytest.fixture(scope="module")
def episodes():
    return record(true_arm(), [11, 12, 13], seconds=4.0)


def test_fit_recovers_the_hidden_arm_and_predicts_held_out_motion(episodes):
    log = ArmLog(30.0, episodes, "synthetic", "csv")
    res = fit(
        [log],
        arm="sts3215",
        names=("kp_per_p", "damping"),
        joints=("shoulder_lift", "elbow_flex", "wrist_flex"),
        max_evaluations=20,
    )
    true = true_arm()
    assert res.fit_episodes == [0, 1] and res.heldout_episodes == [2]
    for joint in ("shoulder_lift", "elbow_flex", "wrist_flex"):
        want = true.joint(joint, scaled=False)
        for name in ("kp_per_p", "damping"):
            got = res.values[joint][name]
            assert got == pytest.approx(getattr(want, name), rel=0.08), (joint, name)
            assert 0 < res.stderr[joint][name] < 0.1 * got
    assert res.values["*"]["delay_s"] == pytest.approx(0.047, abs=0.003)
    assert res.heldout_error is not None and res.start_heldout_error is not None
    for name in JOINT_NAMES:
        assert res.heldout_error[name] < 0.5  # degrees (gripper units)
    # the profile's [uncertainty] is the largest standard error of each fitted parameter
    for name in ("kp_per_p", "damping", "delay_s"):
        worst = max(se[name] for se in res.stderr.values() if name in se)
        assert res.profile.uncertainty[name] == pytest.approx(worst)
    # the start (sts3215, 32 ms) was worse on the body joints that changed
    assert res.start_heldout_error["shoulder_lift"] > 3 * res.heldout_error["shoulder_lift"]


def test_cli_fit_writes_a_profile_compare_accepts(tmp_path, episodes, capsys):
    root = write_lerobot(tmp_path / "ds", episodes)
    out = tmp_path / "arm.toml"
    code = main(["fit", str(root), "-o", str(out), "--units", "degrees", "--iterations", "4",
                 "--episodes", "0-2"])  # fmt: skip
    assert code == 0
    text = capsys.readouterr().out
    assert "held-out episodes 2" in text and "±" in text and "delay_s" in text
    prof = load_profile(out)
    assert prof.joint("shoulder_lift").kp > 0
    assert "[uncertainty]" in out.read_text() and prof.uncertainty["delay_s"] > 0
    assert "so101sim fit" in prof.description and "bench" not in prof.description
    res = compare(write_csv(tmp_path / "e2.csv", episodes[2]), arm=out)
    assert res.frames == len(episodes[2].times) - 1  # a CSV log: its first row starts it
    # nothing half-done: an existing output is refused before any work
    assert main(["fit", str(root), "-o", str(out), "--units", "degrees"]) == 2
    assert "exists" in capsys.readouterr().err
