"""Preflight: simulate a motion headless and judge it; the ``check`` command."""

from __future__ import annotations

import json

import pytest
from preflight_helpers import floor_motion

from so101sim import cli
from so101sim.errors import SettingError
from so101sim.model import default_units
from so101sim.motion import Hold, Move
from so101sim.motion.file import lab_motion_path
from so101sim.preflight import (
    Thresholds,
    check_motion_file,
    describe,
    format_report,
    preflight,
)
from so101sim.preflight.judge import EffortFinding, TrackingFinding, judge
from so101sim.preflight.measure import JointCheck, Measurements, StepCheck
from so101sim.units import JOINT_NAMES, STARTING_POSE


@pytest.fixture(scope="module")
def lab_report():
    return check_motion_file(lab_motion_path())


def test_the_lab_motion_passes(lab_report):
    assert lab_report.passed, lab_report.failures
    assert [s.phase for s in lab_report.steps] == ["to_zero", "hold", "return"]
    assert [s.line for s in lab_report.steps] == [16, 21, 25]
    assert all(set(s.joints) == set(JOINT_NAMES) for s in lab_report.steps)
    assert all(not s.contacts for s in lab_report.steps)


def test_the_report_measures_the_closest_approach_to_a_limit(lab_report):
    lo, hi = default_units().limits_dict()["shoulder_lift"]
    first = lab_report.steps[0].joints["shoulder_lift"]
    # the rest pose holds shoulder_lift 2° above its lower limit, and the arm sags a little
    assert first.limit_side == "lower"
    expected = STARTING_POSE["shoulder_lift"] - lo
    assert first.limit_margin == pytest.approx(expected, abs=1e-3)  # sts3215: 0.0002° sag
    # at the zero pose (the hold) it is mid-range: far from both limits
    assert lab_report.steps[1].joints["shoulder_lift"].limit_margin > 0.9 * (hi - lo) / 2


def test_the_linear_profile_spikes_but_smooth_profiles_do_not(lab_report):
    th = lab_report.thresholds
    # the vendored ideal actuators (kp 998) meet the lab's straight lines' velocity steps by
    # saturating for a few ms; the fitted servo's firmware slews its goal, and its effort (a
    # fraction of the profile's 3.92 N·m) stays under half
    ideal = check_motion_file(lab_motion_path(), arm="official")
    peaks = [j.peak_effort for s in ideal.steps for j in s.joints.values()]
    assert max(peaks) > th.max_effort  # the lab's straight lines saturate for a few ms
    assert any("smooth shape" in n for n in ideal.notes)
    peaks = [j.peak_effort for s in lab_report.steps for j in s.joints.values()]
    assert 0.2 < max(peaks) < 0.5 and not lab_report.notes
    smooth = preflight(
        [
            Move({**STARTING_POSE, **dict.fromkeys(JOINT_NAMES[:5], 0.0)}, 2.0, "minimum_jerk"),
            Hold(1.0),
        ],
        arm="official",
    )
    assert smooth.passed
    assert max(j.peak_effort for s in smooth.steps for j in s.joints.values()) < th.max_effort


def test_driving_into_the_floor_fails_with_the_contact(tmp_path):
    path = floor_motion(tmp_path)
    report = check_motion_file(path)
    assert not report.passed
    contacts = {(c.body1, c.body2) for s in report.steps for c in s.contacts}
    assert any("floor" in pair for pair in contacts)
    assert any("floor" in f and "touches" in f for f in report.failures)


def test_a_target_within_the_margin_of_a_limit_fails(tmp_path):
    hi = default_units().limits_dict()["shoulder_pan"][1]
    path = tmp_path / "limit.toml"
    path.write_text(
        f'[[steps]]\nmove = {{ shoulder_pan = {hi - 0.5!r} }}\nduration = 2.0\nshape = "limited"\n'
    )
    report = check_motion_file(path)
    assert not report.passed
    assert any("shoulder_pan comes within" in f and "upper limit" in f for f in report.failures)
    j = report.steps[0].joints["shoulder_pan"]
    assert j.limit_side == "upper" and j.limit_margin <= 0.5 + 1e-9
    # a wider margin than the distance passes that check
    assert check_motion_file(path, thresholds=Thresholds(limit_margin=0.25)).passed


def test_a_move_too_fast_for_the_actuators_fails():
    target = {**STARTING_POSE, "shoulder_lift": 0.0, "elbow_flex": 0.0}
    report = preflight([Move(target, 0.1), Hold(0.5)])
    assert not report.passed
    assert any("effort stays above" in f for f in report.failures)
    assert any("lags its target" in f for f in report.failures)


def test_findings_are_the_failures_and_notes_as_data():
    target = {**STARTING_POSE, "shoulder_lift": 0.0, "elbow_flex": 0.0}
    report = preflight([Move(target, 0.1), Hold(0.5)], arm="official")  # the ideal actuators
    failed = [f for f in report.findings if f.failed]
    assert [describe(f, report.thresholds) for f in failed] == list(report.failures)
    notes = [describe(f, report.thresholds) for f in report.findings if not f.failed]
    assert notes == list(report.notes)
    assert {(f.step, f.joint, type(f)) for f in failed} >= {
        (1, "shoulder_lift", EffortFinding),
        (1, "shoulder_lift", TrackingFinding),
    }
    # the table marks exactly the failed figures: two columns of two joints in two steps
    table = format_report(report)
    assert sum(line.count("!") for line in table.splitlines() if "ms" in line) == 8


def test_judging_compares_each_figure_once():
    joint = JointCheck(
        limit_margin=0.5,
        limit_side="upper",
        peak_effort=0.95,
        saturated=0.01,
        peak_tracking_error=16.0,
    )
    step = StepCheck(1, "p", "move", 0, 0.0, 1.0, {"wrist_flex": joint, "gripper": joint}, ())
    measured = Measurements((step,), {"wrist_flex": (-90.0, 90.0), "gripper": (0.0, 100.0)}, ())
    kinds = [(f.joint, type(f).__name__, f.failed) for f in judge(measured, Thresholds())]
    assert kinds == [
        ("wrist_flex", "LimitFinding", True),
        ("wrist_flex", "EffortFinding", False),  # above max_effort, but briefly: a note
        ("wrist_flex", "TrackingFinding", True),
        ("gripper", "EffortFinding", False),  # the gripper is exempt from the limit margin
        ("gripper", "TrackingFinding", True),
    ]


def test_thresholds_are_applied(lab_report):
    tight = check_motion_file(lab_motion_path(), thresholds=Thresholds(limit_margin=3.0))
    assert not tight.passed
    assert all("shoulder_lift comes within" in f for f in tight.failures)
    with pytest.raises(SettingError, match="limit_margin"):
        Thresholds(limit_margin=-1)
    with pytest.raises(SettingError, match="max_saturation"):
        Thresholds(max_saturation=float("nan"))


def test_stretched_limited_moves_are_noted_or_refused():
    steps = [Move({**STARTING_POSE, "shoulder_pan": 30.0}, 0.05, shape="limited")]
    report = preflight(steps)
    assert any("stretched" in n for n in report.notes)
    from so101sim.errors import TrajectoryLimitError

    with pytest.raises(TrajectoryLimitError):
        preflight(steps, strict=True)


def test_the_table_then_pass_or_fail(lab_report, tmp_path):
    text = format_report(lab_report)
    assert text.splitlines()[-1] == "PASS"
    assert all(name in text for name in JOINT_NAMES)
    path = floor_motion(tmp_path)
    failed = format_report(check_motion_file(path))
    assert "FAIL" in failed and "contact:" in failed


def test_cli_check_exit_codes_and_json(tmp_path, capsys):
    assert cli.main(["check", str(lab_motion_path())]) == 0
    assert "PASS" in capsys.readouterr().out

    path = floor_motion(tmp_path)
    assert cli.main(["check", str(path), "--json"]) == 1
    data = json.loads(capsys.readouterr().out)
    assert data["passed"] is False and data["failures"]
    assert data["thresholds"]["limit_margin"] == 1.0
    step = data["steps"][0]
    assert set(step["joints"]) == set(JOINT_NAMES)
    assert {"limit_margin", "peak_effort", "saturated", "peak_tracking_error"} <= set(
        step["joints"]["elbow_flex"]
    )
    assert any(c["body1"] == "floor" or c["body2"] == "floor" for c in step["contacts"])


def test_cli_check_thresholds_and_errors(tmp_path, capsys):
    assert cli.main(["check", str(lab_motion_path()), "--limit-margin", "3"]) == 1
    assert "FAIL" in capsys.readouterr().out
    assert cli.main(["check", str(lab_motion_path()), "--max-effort", "-1"]) == 2
    assert "max_effort" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text("[[steps]]\nmove = 'nowhere'\nduration = 1\n")
    assert cli.main(["check", str(bad)]) == 2
    assert f"{bad}:2: unknown pose 'nowhere'" in capsys.readouterr().err


def test_the_example_motion_passes():
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "examples" / "wave.toml"
    report = check_motion_file(path)
    assert report.passed, report.failures
    assert len(report.steps) == 12


def test_check_reports_how_far_the_tip_strayed_from_a_straight_line():
    from so101sim.motion import Move
    from so101sim.preflight import format_report, preflight

    steps = [Move.to_tip((0.22, 0.05, 0.08), 2.0, pitch=-60, shape="minimum_jerk")]
    report = preflight(steps, start=STARTING_POSE)
    commanded, measured = report.steps[0].line_deviation_mm
    assert commanded <= 2.0 and 0 <= measured < 20.0
    assert "tip off the straight line" in format_report(report)
    assert list(report.to_dict()["steps"][0]["line_deviation_mm"]) == [commanded, measured]


def test_a_motion_files_tip_moves_are_planned_on_the_checked_model(monkeypatch):
    import so101sim.motion.file as motionfile
    from so101sim.model import load_model
    from so101sim.preflight import check_motion_file

    seen = []
    planner = motionfile.TipPlanner

    def recording_planner(model=None):
        seen.append(model)
        return planner(model)

    monkeypatch.setattr(motionfile, "TipPlanner", recording_planner)
    m = load_model()
    report = check_motion_file(
        lab_motion_path().parent.parent / "examples" / "tip_square.toml", model=m
    )
    assert seen and all(model is m for model in seen)
    assert report.steps  # the square was checked step by step
