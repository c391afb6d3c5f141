"""``so101sim fit``: a hidden "true" arm (perturbed servos, a 47 ms delay) writes recordings; the
fit recovers its parameters and predicts a held-out motion within 0.5°."""

from __future__ import annotations

import numpy as np
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
            # within its uncertainty (a reading step's noise at least: this log is read exactly)
            assert abs(got - getattr(want, name)) <= 3 * res.stderr[joint][name], (joint, name)
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


def _cli_fit(tmp_path, episodes, iterations: int, *more: str):
    """``so101sim fit`` of ``episodes`` written as a LeRobot dataset: its folder, the profile's
    path and the exit code."""
    root = write_lerobot(tmp_path / "ds", episodes)
    out = tmp_path / "arm.toml"
    code = main(["fit", str(root), "-o", str(out), "--units", "degrees", "--iterations",
                 str(iterations), *more])  # fmt: skip
    return root, out, code


def test_cli_fit_writes_a_profile_compare_accepts(tmp_path, episodes, capsys):
    root, out, code = _cli_fit(tmp_path, episodes, 4, "--episodes", "0-2")
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


def test_standard_errors_count_an_error_that_lasts_many_frames_once():
    """White residuals give the plain least-squares standard error; the same residuals smoothed
    over ~20 frames (a replay's error lasts) give a wider one, as many independent samples as
    they hold."""
    from so101sim.fidelity.fitparams import standard_errors

    rng = np.random.default_rng(0)
    jac = rng.normal(size=(2000, 2)) * 0.01
    white = rng.normal(size=(1000, 2))
    kernel = np.ones(20) / np.sqrt(20)
    smooth = np.stack([np.convolve(c, kernel, mode="same") for c in white.T], axis=1)
    plain = np.sqrt(np.diag(np.linalg.pinv(jac.T @ jac))) * np.sqrt(np.mean(white**2)) * 0.5
    got_white = standard_errors(jac, white, [500, 500], 0.5)
    got_smooth = standard_errors(jac, smooth, [500, 500], 0.5)
    assert got_white == pytest.approx(plain, rel=0.1)
    ratio = got_smooth / (plain * np.sqrt(np.mean(smooth**2) / np.mean(white**2)))
    assert np.all(ratio > 3.0) and np.all(ratio < 10.0)  # sqrt((1+rho)/(1-rho)), rho 0.95: 6.2


def test_cli_fit_load_friction_writes_each_joints_value(tmp_path, episodes, capsys):
    root, out, code = _cli_fit(tmp_path, episodes, 2, "--load-friction", "--force")
    assert code == 0
    assert "load_friction" in capsys.readouterr().out  # the per-joint table
    prof = load_profile(out)
    values = [prof.joint(j).load_friction for j in JOINT_NAMES]
    assert all(0.0 <= v <= 0.3 for v in values) and "load_friction" in out.read_text()
    assert "load_friction" not in out.read_text().split("[uncertainty]")[1]  # not drawn from
    # a servo field and no servo field at once: refused before any work
    out2 = tmp_path / "two.toml"
    assert main(["fit", str(root), "-o", str(out2), "--load-friction", "--calibration-only"]) == 2
    assert "--load-friction" in capsys.readouterr().err and not out2.exists()
