"""so101sim grade, the library: hand-ins made with so101sim itself judged per phase, damaged
logs refused with one line, videos checked, a folder of hand-ins graded."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from grade_helpers import make_log, make_video

from so101sim.errors import SettingError
from so101sim.lab import gradefolder, gradelog
from so101sim.lab.grade import LabSpec, Tolerances, find_moves, grade_log
from so101sim.lab.gradefolder import grade_folder
from so101sim.lab.gradelog import NUMBER_COLUMNS, NotASo101SimLogError, read_run_log
from so101sim.lab.gradereport import format_folder, format_grade, summary_columns, write_summary
from so101sim.lab.gradevideo import check_video
from so101sim.recording.csvlog import csv_columns
from so101sim.units import JOINT_NAMES, STARTING_POSE


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("logs")
    made = {k: make_log(folder, k) for k in ("lab", "slow", "short", "no_return", "drift")}
    made["minimum_jerk"] = make_log(folder, "lab", shape="minimum_jerk")
    made["limited"] = make_log(folder, "lab", shape="limited")
    made["official"] = make_log(folder, "lab", arm="official")
    return made


def _failed(result):
    return {(p.name, c.name) for p in result.phases for c in p.checks if not c.passed}


@pytest.mark.parametrize("kind", ["lab", "minimum_jerk", "limited", "official"])
def test_the_lab_motion_passes_with_each_profile_and_arm(logs, kind):
    result = grade_log(logs[kind])
    assert result.passed, format_grade(result)
    assert [p.name for p in result.phases] == ["to_zero", "hold", "return"]
    for p, start in zip(result.phases, (0.0, 2.0, 4.0), strict=True):
        assert p.start == pytest.approx(start, abs=0.02)  # found from the commands alone
        assert p.duration == pytest.approx(2.0, abs=0.02)
    assert result.duration == pytest.approx(6.0, abs=1e-6)
    assert result.rows == 3000


def test_the_ideal_actuators_reach_far_closer_than_the_fitted_servos(logs):
    fitted = grade_log(logs["lab"]).phase("to_zero").check("reached")
    ideal = grade_log(logs["official"]).phase("to_zero").check("reached")
    assert ideal.value < 1.0 < fitted.value < Tolerances().angle_deg
    assert fitted.joint == "elbow_flex"  # the servo lags most at the elbow


def test_a_motion_too_slow_fails_its_phase_on_time(logs):
    result = grade_log(logs["slow"])
    assert _failed(result) == {("to_zero", "duration")}
    assert result.phase("to_zero").duration == pytest.approx(4.0, abs=0.02)
    assert result.failures == ["to_zero: took 4.000 s; expected 2 ± 0.25 s"]


def test_a_motion_not_reaching_zero_fails_to_zero_at_the_joint(logs):
    result = grade_log(logs["short"])
    assert _failed(result) == {("to_zero", "reached")}
    reached = result.phase("to_zero").check("reached")
    assert reached.joint == "shoulder_lift" and reached.value > 40.0


def test_a_motion_that_never_returns_fails_the_return(logs):
    result = grade_log(logs["no_return"])
    assert not result.passed
    assert ("return", "found") in _failed(result) and ("return", "end") in _failed(result)
    assert result.phase("hold").duration == pytest.approx(4.0, abs=0.02)
    assert not result.phase("return").found
    assert "never moved back" in format_grade(result)


def test_a_hold_that_drifts_fails_the_hold(logs):
    result = grade_log(logs["drift"])
    assert _failed(result) == {("hold", "held")}
    held = result.phase("hold").check("held")
    assert held.joint == "shoulder_pan" and held.value > 10.0
    assert result.phase("hold").duration == pytest.approx(2.0, abs=0.02)


def test_tolerances_change_the_verdict(logs):
    assert not grade_log(logs["lab"], tolerances=Tolerances(angle_deg=5.0)).passed
    assert grade_log(logs["slow"], tolerances=Tolerances(time_s=2.5)).passed
    for bad in ({"angle_deg": 0.0}, {"angle_deg": float("nan")}, {"time_s": -1.0}):
        with pytest.raises(SettingError, match="tolerance"):
            Tolerances(**bad)


def test_moves_are_found_from_the_commands_not_from_a_jump_at_the_hold():
    """The handout's hold commands the pose the arm reached: a small jump, not a move."""
    t = np.arange(1, 3001) * 0.002
    p = np.clip(t / 2.0, 0, 1)  # 2 s to zero
    p[t > 2.0] = 0.93  # the hold: the reached pose, 7 % short
    back = t > 4.0
    p[back] = 0.93 * (1 - (t[back] - 4.0) / 2.0)
    spec = LabSpec()
    rows = find_moves(t, p, spec)
    assert [(round(t[a], 3), round(t[b], 3)) for a, b in rows] == [(0.002, 2.0), (4.0, 6.0)]


def _without_servo_column(text: str) -> str:
    """The log as written before it had a servo_model column."""
    rows = list(csv.reader(text.splitlines()))
    keep = [k for k, name in enumerate(rows[0]) if name != "servo_model"]
    return "".join(",".join(row[k] for k in keep) + "\n" for row in rows)


def test_the_report_names_the_log_the_phases_and_the_servo_model(logs, tmp_path):
    plain = tmp_path / "plain.csv"
    plain.write_text(_without_servo_column(logs["lab"].read_text()))
    assert "servo model: not named in the log" in format_grade(grade_log(plain))
    named = tmp_path / "named.csv"
    named.write_text("# so101sim log, arm: sts3215 (fitted STS3215 servos)\n" + plain.read_text())
    result = grade_log(named)
    assert result.servo_model == "sts3215 (fitted STS3215 servos)" and result.passed
    text = format_grade(result)
    assert str(named) in text and "servo model: sts3215" in text
    assert text.splitlines()[-1] == "PASS"


# ---------------------------------------------------------------------------- damaged logs
def _header() -> str:
    return ",".join(csv_columns())


def _row(t: float = 0.002, value: str = "0") -> str:
    fields = {c: value for c in csv_columns()} | {"time": f"{t:.4f}", "phase": "to_zero"}
    return ",".join(fields[c] if c != "servo_model" else "sts3215" for c in csv_columns())


@pytest.mark.parametrize(
    ("text", "said"),
    [
        ("", "is empty"),
        ("# only a comment\n", "is empty"),
        ("a,b,c\n1,2,3\n", "not the header of a so101sim log"),
        (_header() + "\n", "holds the header but no rows"),
        (_header() + "\n" + _row() + "\n0.004,hold,1,2\n", "line 3 has 4 fields; expected"),
        (_header().replace("elbow_flex_measured", "elbow"), "no elbow_flex_measured column"),
        (_header() + "\n" + _row(value="nan") + "\n", "is not finite"),
        (_header() + "\n" + _row(value="inf") + "\n", "is not finite"),
        (_header() + "\n" + _row(value="abc") + "\n", "is not a number"),
        (_header() + "\n" + _row(0.004) + "\n" + _row(0.002) + "\n", "times that increase"),
    ],
)
def test_a_damaged_log_is_one_clear_error(tmp_path, text, said):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(NotASo101SimLogError, match=said) as info:
        grade_log(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_columns_are_taken_by_name_and_the_servo_model_column_is_read(tmp_path, logs):
    assert set(NUMBER_COLUMNS) | {"phase"} <= set(csv_columns())  # what run --log writes
    lines = logs["lab"].read_text().splitlines()
    header = [c for c in lines[0].split(",") if c != "servo_model"]
    order = [*header[::-1], "servo_model", "note"]  # any order, another column
    old = lines[0].split(",")
    text = ",".join(order) + "\n"
    for line in lines[1:]:
        row = dict(zip(old, line.split(","), strict=True)) | {"servo_model": "sts3215"}
        text += ",".join(row.get(c, "x") for c in order) + "\n"
    path = tmp_path / "shuffled.csv"
    path.write_text(text)
    result = grade_log(path)
    assert result.passed and result.servo_model == "sts3215"
    assert result.phase("to_zero").check("reached").value == pytest.approx(
        grade_log(logs["lab"]).phase("to_zero").check("reached").value
    )


def test_binary_missing_and_oversized_logs_are_refused(tmp_path, logs, monkeypatch):
    binary = tmp_path / "video.csv"
    binary.write_bytes(b"\x00\x01\x02" * 10)
    with pytest.raises(NotASo101SimLogError, match="NUL bytes"):
        read_run_log(binary)
    latin = tmp_path / "latin.csv"
    latin.write_bytes(b"time,\xe9\n")
    with pytest.raises(NotASo101SimLogError, match="not UTF-8"):
        read_run_log(latin)
    with pytest.raises(SettingError, match="does not exist"):
        read_run_log(tmp_path / "missing.csv")
    monkeypatch.setattr(gradelog, "MAX_LOG_BYTES", 10_000)
    with pytest.raises(NotASo101SimLogError, match="too large"):
        read_run_log(logs["lab"])
    monkeypatch.setattr(gradelog, "MAX_LOG_ROWS", 100)
    monkeypatch.setattr(gradelog, "MAX_LOG_BYTES", 64 * 2**20)
    with pytest.raises(NotASo101SimLogError, match="more than 100 rows"):
        read_run_log(logs["lab"])


# ---------------------------------------------------------------------------- video
def test_the_video_is_checked_for_opening_and_length(tmp_path, logs):
    good = make_video(tmp_path / "good.mp4", 181)  # 6 s at 30 fps, as so101sim records
    result = grade_log(logs["lab"], video=good)
    assert result.passed and result.video.length_s == pytest.approx(6.0)
    assert "181 frames at 30 fps" in format_grade(result)
    short = grade_log(logs["lab"], video=make_video(tmp_path / "short.mp4", 91))
    assert not short.passed and short.failures[0].startswith("video: 91 frames")
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(good.read_bytes()[:300])
    assert "does not open as a video" in check_video(broken, 6.0, 0.25).text
    missing = check_video(tmp_path / "none.mp4", 6.0, 0.25)
    assert not missing.passed and "does not exist" in missing.text


def test_a_video_too_large_is_not_read(tmp_path, monkeypatch):
    from so101sim.lab import gradevideo

    video = make_video(tmp_path / "good.mp4", 181)
    monkeypatch.setattr(gradevideo, "MAX_VIDEO_BYTES", 100)
    result = check_video(video, 6.0, 0.25)
    assert not result.passed and "expected a video of at most" in result.text
    assert result.frames is None  # never opened


# ---------------------------------------------------------------------------- folders
@pytest.fixture
def handins(tmp_path, logs):
    """Three students: two by file name (one too slow), one by sub-folder with its video."""
    folder = tmp_path / "handins"
    folder.mkdir()
    (folder / "ada.csv").write_bytes(logs["lab"].read_bytes())
    (folder / "bob.csv").write_bytes(logs["slow"].read_bytes())
    (folder / "carol").mkdir()
    (folder / "carol" / "lab2.csv").write_bytes(logs["official"].read_bytes())
    make_video(folder / "carol" / "lab2.mp4", 181)
    (folder / "notes.txt").write_text("not a hand-in")
    return folder


def test_a_folder_gives_one_line_per_student_and_a_summary(handins, tmp_path):
    result = grade_folder(handins)
    assert [(h.student, h.source, h.passed) for h in result.handins] == [
        ("ada", "file", True),
        ("bob", "file", False),
        ("carol", "folder", True),
    ]
    assert result.handins[2].result.video is not None  # found beside the log
    text = format_folder(result)
    lines = text.splitlines()
    assert "2 by file name, 1 by sub-folder name" in lines[0]
    student_lines = [line for line in lines if line.split()[0] in ("ada", "bob", "carol")]
    assert len(student_lines) == 3
    assert "FAIL" in student_lines[1] and "to_zero: took 4.000 s" in student_lines[1]
    summary = write_summary(result, tmp_path / "summary.csv")
    with open(summary, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == summary_columns()
    assert [r["student"] for r in rows] == ["ada", "bob", "carol"]
    assert [r["to_zero_passed"] for r in rows] == ["true", "false", "true"]
    assert float(rows[1]["to_zero_duration_s"]) == pytest.approx(4.0, abs=0.02)
    assert rows[2]["named_by"] == "sub-folder" and rows[2]["video_passed"] == "true"


def test_a_bad_hand_in_is_its_students_error_and_the_folder_is_bounded(
    handins, monkeypatch, tmp_path
):
    (handins / "dave.csv").write_text("not,a,log\n")
    (handins / "erin").mkdir()
    result = grade_folder(handins)
    errors = {h.student: h.error for h in result.handins if h.result is None}
    assert "not the header" in errors["dave"] and "no CSV log in erin/" in errors["erin"]
    assert not result.passed and "2 could not be graded" in format_folder(result)
    monkeypatch.setattr(gradefolder, "MAX_HANDINS", 3)
    with pytest.raises(SettingError, match="at most 3"):
        grade_folder(handins)
    (tmp_path / "empty").mkdir()
    with pytest.raises(SettingError, match="holds no hand-in"):
        grade_folder(tmp_path / "empty")
    with pytest.raises(SettingError, match="not a folder"):
        grade_folder(handins / "ada.csv")


def _handout_style_log(path, m) -> None:
    """The lab as the handout writes it (raw MuJoCo: a ramp from the measured pose, a hold of
    the pose reached, a ramp back), logged through so101sim.record with no video."""
    import mujoco

    from so101sim import record
    from so101sim.model.load import arm_units

    units = arm_units(m)
    d = mujoco.MjData(m)
    rest = np.array([STARTING_POSE[n] for n in JOINT_NAMES])
    d.qpos[:6] = units.to_radians(rest)

    def go(viewer, goal, seconds):
        begin, t0 = units.from_radians(d.qpos[:6].copy()), d.time
        while d.time - t0 <= seconds:
            a = min((d.time - t0) / seconds, 1.0)
            d.ctrl[:6] = units.to_radians((1 - a) * begin + a * goal)
            mujoco.mj_step(m, d)
            viewer.sync()

    with record(m, d, None, log=path) as viewer:
        go(viewer, np.zeros(6), 2.0)
        here, t0 = d.qpos[:6].copy(), d.time  # the handout's hold: the pose reached
        while d.time - t0 <= 2.0:
            d.ctrl[:6] = here
            mujoco.mj_step(m, d)
            viewer.sync()
        go(viewer, rest, 2.0)


def test_a_handout_style_script_on_the_fitted_servos_passes(tmp_path):
    """The fitted servos stop short, so the handout's hold commands a pose ~8° off zero: that
    jump of the command is not a move, and the phases are where the script put them."""
    from so101sim.model.load import load_model

    path = tmp_path / "handout.csv"
    _handout_style_log(path, load_model(physics_only=True))  # the default arm: sts3215
    result = grade_log(path)
    assert result.passed, format_grade(result)
    starts = [p.start for p in result.phases]
    assert starts == pytest.approx([0.002, 2.002, 4.004], abs=0.01)
    assert result.phase("to_zero").check("reached").value > 5.0  # the servos' lag: the jump
