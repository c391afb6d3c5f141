"""Where the sim is wrong, at a glance (issue 32, point 4): static holds and moves apart, the
worst windows with their times (marked in --plot), a blocked gripper left out of its error;
LeRobot's calibration found by --robot-id; explicit held-out episodes."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest

pytest.importorskip("pyarrow")

from fidelity_helpers import as_read, commands, record, write_lerobot

from so101sim.cli import main
from so101sim.errors import CalibrationError
from so101sim.fidelity.calibration import lerobot_calibration_path
from so101sim.fidelity.compare import compare
from so101sim.fidelity.logs import ArmLog, Episode
from so101sim.fidelity.plot import plot_heading
from so101sim.fidelity.windows import blocked_gripper, still_frames, worst_windows
from so101sim.model.arm import load_profile
from so101sim.units import JOINT_NAMES


def _hold_then_move() -> Episode:
    """2 s holding still, then 2 s of sines, at 30 fps (real = command: only the shape)."""
    t, cmd = commands(5, seconds=4.0)
    cmd[t < 2.0] = cmd[np.searchsorted(t, 2.0)]
    return Episode(0, t, cmd, cmd.copy())


def test_still_frames_are_where_the_command_holds():
    ep = _hold_then_move()
    still = still_frames(ep.command, ep.times)
    assert still[ep.times < 1.8].all()
    assert not still[ep.times > 2.3].any()


def test_a_blocked_gripper_is_found_and_a_closing_one_is_not():
    ep = as_read([_hold_then_move()], {}, blocked=(1.0, 2.0))[0]
    blocked = blocked_gripper(ep.command, ep.measured, ep.times)
    inside = (ep.times >= 1.0) & (ep.times < 2.0)
    assert blocked[inside].mean() > 0.75 and not blocked[~inside].any()  # edges: it moved
    # a gripper that lags its command while it moves is not blocked
    lag = ep.command.copy()
    lag[3:, 5] = ep.command[:-3, 5]
    assert not blocked_gripper(ep.command, lag, ep.times).any()


def test_the_worst_window_is_where_the_error_is():
    t = np.arange(0, 6, 1 / 30)
    err = np.full((len(t), 6), 0.2)
    err[(t > 3.0) & (t < 3.8), 2] = 9.0
    (w, *_) = worst_windows([(4, t, err)], JOINT_NAMES)
    assert w.episode == 4 and w.joint == "elbow_flex" and 2.7 < w.t0 < 3.1 and w.t1 > 3.6


def test_compare_splits_holds_from_moves_and_leaves_a_blocked_gripper_out(tmp_path, capsys):
    arm = load_profile("sts3215")
    (ep,) = record(arm, [5], seconds=4.0)
    ep = Episode(0, ep.times, ep.command, ep.measured)
    # the real arm: the sim's own motion, an elbow 6 deg off for 0.5 s, a gripper blocked
    bumped = ep.measured.copy()
    bumped[(ep.times > 2.5) & (ep.times < 3.0), 2] += 6.0
    (real,) = as_read([Episode(0, ep.times, ep.command, bumped)], {}, blocked=(0.5, 1.5))
    res = compare(ArmLog(30.0, [real], "synthetic", "csv"), arm=arm, keep_traces=True)
    assert res.gripper_blocked_frames > 20
    # blocked frames left out and the sim stalled where the real one did (2.4 without either:
    # the sim shuts on nothing and reopens late; what is left is the edges of the jump)
    assert res.joints["gripper"].mae < 1.0
    assert any("blocked" in w for w in res.warnings)
    worst = res.worst[0]
    assert worst.joint == "elbow_flex" and worst.t0 < 3.0 and worst.t1 > 2.5
    assert set(res.holds) == set(res.moves) == set(JOINT_NAMES)
    obj = res.to_json()
    assert obj["worst_windows"][0]["joint"] == "elbow_flex"
    json.dumps(obj)  # NaN-free (null where a joint never held or never moved)
    root = write_lerobot(tmp_path / "ds", [real])
    png = tmp_path / "o.png"
    assert main(["compare", str(root), "--units", "degrees", "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "holds" in out and "moves" in out and "worst window: episode 0" in out
    body = re.search(r"body joints: sim mae ([0-9.]+) deg, command mae ([0-9.]+) deg", out)
    assert body is not None, out
    rows = {ln.split()[0]: ln.split() for ln in out.splitlines() if ln.split()[:1] != []}
    names = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
    assert float(body[1]) == pytest.approx(sum(float(rows[n][1]) for n in names) / 5, abs=0.01)
    assert png.stat().st_size > 1000
    # the plot says which episode it draws and what its shading means
    assert plot_heading(res, True) == (
        "episode 0\nshaded red: the worst windows of error; blue: the real gripper blocked"
    )
    two = dataclasses.replace(res, episodes=[2, 3], worst=[])
    assert plot_heading(two, False).startswith("episodes 2, 3, one after another (dashed: where")


def test_robot_id_reads_lerobots_calibration_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("HF_LEROBOT_CALIBRATION", str(tmp_path / "cal"))
    folder = tmp_path / "cal" / "robots" / "so_follower"
    folder.mkdir(parents=True)
    cal = {n: {"id": i + 1, "drive_mode": 0, "homing_offset": 0, "range_min": 1000,
               "range_max": 3000} for i, n in enumerate(JOINT_NAMES)}  # fmt: skip
    (folder / "my_arm.json").write_text(json.dumps(cal))
    assert lerobot_calibration_path("my_arm") == folder / "my_arm.json"
    with pytest.raises(CalibrationError, match="no LeRobot calibration for robot id 'other'"):
        lerobot_calibration_path("other")
    with pytest.raises(CalibrationError, match="not a robot id"):
        lerobot_calibration_path("../etc/passwd")
    # a range-mode dataset read with it: exact degrees, no guess
    ep = _hold_then_move()
    tf = lambda v: np.r_[np.asarray(v[:5]) / ((3000 - 1000) / 200 * 360 / 4095), v[5]]  # noqa: E731
    root = write_lerobot(tmp_path / "ds", [ep], transform=tf)
    res = compare(root, robot_id="my_arm")
    assert not any("guess" in w or "approximate" in w for w in res.warnings)
    assert res.command_baseline["elbow_flex"] < 0.01


def test_fit_holds_out_the_episodes_it_is_told(tmp_path, capsys):
    eps = record(load_profile("sts3215"), [1, 2, 3], seconds=1.5)
    root = write_lerobot(tmp_path / "ds", eps)
    out = tmp_path / "a.toml"
    argv = ["fit", str(root), "-o", str(out), "--units", "degrees", "--iterations", "1"]
    code = main([*argv, "--holdout", "0"])
    text = capsys.readouterr().out
    assert "fitted on episodes 1,2" in text and "held-out episodes 0" in text
    assert "default" in text and "commands" in text
    assert code in (0, 1)  # 1: refused as worse than the default (then nothing written)
    assert out.exists() == (code == 0)
    # --episodes the fitted ones, --holdout the held-out ones, even when --episodes leaves it out
    code = main([*argv, "--force", "--episodes", "1-2", "--holdout", "0"])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "fitted on episodes 1,2" in text and "held-out episodes 0" in text
    # an episode the log does not have is still refused
    assert main([*argv, "--force", "--episodes", "1-2", "--holdout", "5"]) == 2
    assert "has no episode 5" in capsys.readouterr().err


def test_fit_refuses_a_profile_worse_than_the_default_on_held_out_episodes(tmp_path, capsys):
    eps = record(load_profile("sts3215"), [1, 2], seconds=1.5)  # the default is the truth
    root = write_lerobot(tmp_path / "ds", eps)
    out = tmp_path / "a.toml"
    argv = ["fit", str(root), "-o", str(out), "--units", "degrees", "--arm", "official",
            "--iterations", "1", "--holdout", "1"]  # fmt: skip
    assert main(argv) == 1  # one step from the vendored actuator: far from the real servo
    _, err = capsys.readouterr()
    assert "REFUSED" in err and "WORSE than the default" in err and not out.exists()
    assert "more --iterations (1 now" in err  # what may help, with what this fit used
    assert main([*argv, "--force"]) == 0
    assert out.exists() and "worse than the default" in capsys.readouterr().err


def test_a_refused_load_friction_fit_suggests_a_start_with_load_friction():
    from argparse import Namespace

    from so101sim.cli.fidelity import _refusal_hint

    hint = _refusal_hint(Namespace(iterations=30, load_friction=True, arm=None))
    assert "--arm sts3215-load" in hint and "--iterations" not in hint
    assert "sts3215-load" not in _refusal_hint(
        Namespace(iterations=30, load_friction=True, arm="sts3215-load")
    )
    assert "sts3215-load" not in _refusal_hint(
        Namespace(iterations=30, load_friction=False, arm=None)
    )


def test_fit_calibration_only_keeps_the_servos_and_needs_a_guessed_calibration(tmp_path, capsys):
    from fidelity_helpers import TRUE_CALIBRATION, range_mode

    eps = as_read(record(load_profile("sts3215"), [1, 2], seconds=1.5), TRUE_CALIBRATION)
    degrees = write_lerobot(tmp_path / "deg", eps)
    out = tmp_path / "a.toml"
    argv = ["fit", "-o", str(out), "--iterations", "2", "--calibration-only", "--force"]
    assert main([*argv, str(degrees), "--units", "degrees"]) == 2  # its calibration is given
    assert "nothing to fit" in capsys.readouterr().err and not out.exists()
    ranged = write_lerobot(tmp_path / "rng", eps, transform=range_mode())
    assert main([*argv, str(ranged)]) == 0
    prof = load_profile(out)
    assert set(prof.calibration) == set(JOINT_NAMES[:5])
    start = load_profile("sts3215")
    assert prof.servo == start.servo and prof.joints == start.joints  # servos untouched
