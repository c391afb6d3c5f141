"""so101sim grade on the command line: exit 0 / 1 / 2, one line per student, the summary; and
the logs of so101sim record without a video."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from grade_helpers import make_log, make_video

from so101sim.cli import main
from so101sim.model import scene_path

SCRIPT = Path(__file__).parents[1] / "data" / "wallclock_lab.py"


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cli-logs")
    return {k: make_log(folder, k) for k in ("lab", "short")}


def test_grade_passes_the_lab_and_fails_a_short_move(logs, capsys):
    assert main(["grade", str(logs["lab"])]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{logs['lab']}: 3000 rows") and out.strip().endswith("PASS")
    for phase in ("to_zero", "hold", "return"):
        assert any(line.startswith(f"{phase} ") and "PASS" in line for line in out.splitlines())
    assert main(["grade", str(logs["short"])]) == 1
    out = capsys.readouterr().out
    assert "FAIL (1 reason(s))" in out and "to_zero: reached all zeros" in out
    assert main(["grade", str(logs["short"]), "--tolerance-deg", "60"]) == 0


def test_grade_json_of_a_log_and_of_a_folder(logs, tmp_path, capsys):
    import json

    video = make_video(tmp_path / "lab.mp4", 181)
    assert main(["grade", str(logs["short"]), "--video", str(video), "--json"]) == 1
    data = json.loads(capsys.readouterr().out)
    assert data["passed"] is False and data["log"] == str(logs["short"])
    assert [p["name"] for p in data["phases"]] == ["to_zero", "hold", "return"]
    reached = next(c for c in data["phases"][0]["checks"] if c["name"] == "reached")
    assert reached["passed"] is False and reached["joint"] == "shoulder_lift"
    assert data["video"]["frames"] == 181 and data["video"]["path"] == str(video)
    folder = tmp_path / "handins"
    folder.mkdir()
    (folder / "ada.csv").write_bytes(logs["lab"].read_bytes())
    (folder / "bob.csv").write_text("not a log\n")
    summary = tmp_path / "s.csv"
    assert main(["grade", str(folder), "--json", "--summary", str(summary)]) == 1
    data = json.loads(capsys.readouterr().out)  # the JSON alone on stdout
    assert [(h["student"], h["error"] is None) for h in data["handins"]] == [
        ("ada", True),
        ("bob", False),
    ]
    assert data["handins"][0]["grade"]["passed"] is True and summary.is_file()


def test_grade_with_the_video(logs, tmp_path, capsys):
    video = make_video(tmp_path / "lab.mp4", 181)
    assert main(["grade", str(logs["lab"]), "--video", str(video)]) == 0
    assert "video    lab.mp4" in capsys.readouterr().out
    assert main(["grade", str(logs["lab"]), "--video", str(tmp_path / "none.mp4")]) == 1
    assert "video: none.mp4 does not exist" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("make", "said"),
    [
        (lambda p: p.write_text("hello\n"), "not the header of a so101sim log"),
        (lambda p: p.write_text(""), "is empty"),
        (lambda p: p.mkdir(), "holds no hand-in"),  # an empty folder
    ],
)
def test_grade_of_what_is_not_a_log_is_one_error_line(tmp_path, capsys, make, said):
    path = tmp_path / "x.csv"
    make(path)
    assert main(["grade", str(path)]) == 2
    captured = capsys.readouterr()
    assert said in captured.err and len(captured.err.strip().splitlines()) == 1
    assert captured.out == ""


def test_grade_options_are_checked(logs, tmp_path, capsys):
    for argv, said in [
        (["--tolerance-deg", "nan"], "--tolerance-deg"),
        (["--time-tolerance-s", "0"], "--time-tolerance-s"),
        (["--summary", str(tmp_path / "s.csv")], "--summary writes one row per student"),
    ]:
        assert main(["grade", str(logs["lab"]), *argv]) == 2
        assert said in capsys.readouterr().err
    assert main(["grade", str(tmp_path), "--video", "v.mp4"]) == 2
    assert "--video goes with one log" in capsys.readouterr().err


def test_grade_a_folder_of_three_hand_ins(logs, tmp_path, capsys):
    folder = tmp_path / "handins"
    folder.mkdir()
    (folder / "ada.csv").write_bytes(logs["lab"].read_bytes())
    (folder / "bob.csv").write_bytes(logs["short"].read_bytes())
    (folder / "carol").mkdir()
    (folder / "carol" / "lab.csv").write_bytes(logs["lab"].read_bytes())
    summary = tmp_path / "summary.csv"
    summary.write_text("an older summary")
    assert main(["grade", str(folder), "--summary", str(summary)]) == 2  # before grading
    assert "already exists" in capsys.readouterr().err
    assert main(["grade", str(folder), "--summary", str(summary), "--force"]) == 1
    out = capsys.readouterr().out.splitlines()
    students = {line.split()[0]: line for line in out if line.split()[0] in ("ada", "bob", "carol")}
    assert len(students) == 3
    assert "file" in students["ada"] and "PASS" in students["ada"]
    assert "FAIL" in students["bob"] and "to_zero" in students["bob"]
    assert "sub-folder" in students["carol"] and "PASS" in students["carol"]
    assert out[-1] == f"wrote the summary to {summary}"
    with open(summary, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["student"], r["result"]) for r in rows] == [
        ("ada", "PASS"),
        ("bob", "FAIL"),
        ("carol", "PASS"),
    ]
    assert {"to_zero_passed", "hold_moved_deg", "return_end_error_deg"} <= set(rows[0])
    (folder / "ada.csv").unlink()
    (folder / "bob.csv").unlink()
    assert main(["grade", str(folder)]) == 0  # carol alone passes


def test_record_writes_a_log_without_a_video_and_grade_passes_the_handout_script(tmp_path, capsys):
    """A handout-style script (raw MuJoCo, its own helpers, the wall clock) under record."""
    log = tmp_path / "lab.csv"
    argv = ["record", str(SCRIPT), "--log", str(log), "--", str(scene_path())]
    assert main(argv) == 0
    assert f"wrote the log to {log}" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == [log]  # no video
    assert main(["grade", str(log)]) == 0
    assert capsys.readouterr().out.strip().endswith("PASS")
    assert main(["record", str(SCRIPT)]) == 2  # nothing to write
    assert "expected -o VIDEO.mp4, --log LOG.csv" in capsys.readouterr().err


def test_check_names_the_motion_it_judged(tmp_path, capsys):
    import json

    assert main(["check"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("checked the lab motion (") and first.endswith("lab.toml)")
    motion = tmp_path / "mine.toml"
    motion.write_text('start = "rest"\n[[steps]]\nhold = 0.2\n')
    assert main(["check", str(motion)]) == 0
    assert capsys.readouterr().out.splitlines()[0] == f"checked {motion}"
    assert main(["check", str(motion), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["motion"] == str(motion)


def _doc_block(text: str, command: str) -> list[str]:
    """The lines docs/grading.md shows after ``$ <command>``, to the end of its block."""
    lines = text.splitlines()
    start = lines.index(f"$ {command}") + 1
    end = next(k for k in range(start, len(lines)) if lines[k].startswith("```"))
    return lines[start:end]


def test_the_reports_in_docs_grading_are_what_grade_prints(tmp_path, monkeypatch, capsys):
    doc = (Path(__file__).parents[2] / "docs" / "grading.md").read_text()
    monkeypatch.chdir(tmp_path)
    slow = doc.split("```toml\n", 1)[1].split("```", 1)[0]  # too_slow.toml
    assert main(["run", "--headless", "--log", "lab.csv"]) == 0
    capsys.readouterr()
    assert main(["grade", "lab.csv"]) == 0
    assert capsys.readouterr().out.splitlines() == _doc_block(doc, "so101sim grade lab.csv")
    motion = tmp_path / "too_slow.toml"
    motion.write_text(slow)
    assert main(["run", "--headless", str(motion), "--log", "too_slow.csv"]) == 0
    capsys.readouterr()
    assert main(["grade", "too_slow.csv"]) == 1
    assert capsys.readouterr().out.splitlines() == _doc_block(doc, "so101sim grade too_slow.csv")


def test_grade_json_of_what_is_not_a_log_is_json_too(tmp_path, capsys):
    """Found by a new user: an autograder reading --json got nothing on stdout for a file that
    is not a log; now one object with the error, beside the error line, exit 2."""
    import json

    path = tmp_path / "frank.csv"
    path.write_text("name,score\nfrank,10\n")
    assert main(["grade", str(path), "--json"]) == 2
    captured = capsys.readouterr()
    data = json.loads(captured.out)
    assert data["log"] == str(path) and data["passed"] is None
    assert "not the header of a so101sim log" in data["error"]
    assert len(captured.err.strip().splitlines()) == 1
