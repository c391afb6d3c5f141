"""Every path a user names is checked once, before any work, by one shared check
(so101sim.validation: check_output_path for what is written, check_input_file for what is
read): an empty path, a name or a path too long for the file system, a read-only folder, a
folder or a device where a file is expected are one error line, never a traceback (issue 23)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from so101sim.cli import main
from so101sim.errors import ModelError, OutputPathError, SettingError
from so101sim.validation import check_input_file, check_output_path, check_path_length

LONG_NAME = "a" * 300  # over NAME_MAX (255)
LONG_PATH = "/tmp/" + "/".join(["b" * 200] * 22)  # over PATH_MAX (4096)
UNWRITABLE = "/proc/so101sim-test"  # no file can be created there, not even by root


def _error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.startswith("so101sim: error:")]
    assert len(lines) == 1, err
    return lines[0]


# ---------------------------------------------------------------------------- the shared check
@pytest.mark.parametrize("path", ["", "   ", LONG_NAME + ".png", LONG_PATH + ".png"])
def test_an_output_path_that_cannot_be_a_file_is_refused(path: str) -> None:
    with pytest.raises(OutputPathError, match=r"empty|bytes long"):
        check_output_path(path, what="plot", suffixes=(".png",))


def test_a_folder_name_too_long_is_refused_before_any_stat(tmp_path: Path) -> None:
    p = tmp_path / LONG_NAME / "x.png"
    with pytest.raises(OutputPathError, match=r"a folder name in the plot path .* 300 bytes"):
        check_output_path(p, what="plot")
    with pytest.raises(SettingError, match="300 bytes long"):
        check_path_length(p, "plot")


@pytest.mark.parametrize(
    "path, says",
    [
        ("", "empty"),
        (LONG_NAME, "304 bytes long"),
        (LONG_PATH, "bytes long; expected fewer than"),
        ("/dev/zero", "character device, not a regular file"),
        ("/tmp", "is a folder, not a regular file"),
        ("/nonexistent/x.xml", "does not exist"),
    ],
)
def test_an_input_file_says_what_it_is(path: str, says: str) -> None:
    name = path + ".xml" if path in (LONG_NAME,) else path
    with pytest.raises(ModelError, match=says):
        check_input_file(name, "model file", expected="an MJCF file", error=ModelError)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_folder_is_refused(tmp_path: Path) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(OutputPathError, match="not writable"):
            check_output_path(ro / "w.png", what="plot")
    finally:
        ro.chmod(0o755)


# ---------------------------------------------------------------------------- the commands
def test_workspace_checks_its_plot_before_the_work(capsys, monkeypatch) -> None:
    from so101sim.kinematics import workspace

    def no_work(*args, **kwargs):  # pragma: no cover - the check must come first
        raise AssertionError("sampled the workspace before checking the plot path")

    monkeypatch.setattr(workspace, "sample_workspace", no_work)
    assert main(["workspace", "--plot", f"{UNWRITABLE}/w.png"]) == 2
    assert "cannot write the workspace plot" in _error_line(capsys)


@pytest.mark.parametrize(
    "argv, says",
    [
        (["check", "--model", LONG_NAME + ".xml"], "model file name"),
        (["check", "--model", LONG_PATH + ".xml"], "expected fewer than 4096 bytes"),
        (["check", "--model", ""], "model file path is empty"),
        (["hold", "--headless", "--duration", "0.1", "--log", LONG_PATH + ".csv"], "bytes long"),
        (["hold", "--headless", "--duration", "0.1", "--log", LONG_NAME + ".csv"], "bytes long"),
        (["examples", LONG_NAME], "examples folder name"),
        (["examples", ""], "examples folder path is empty"),
        (["record", "/dev/zero", "-o", "r.mp4"], "character device, not a regular file"),
        (["record", "/tmp", "-o", "r.mp4"], "is a folder, not a regular file"),
        (["record", "", "-o", "r.mp4"], "script path is empty"),
    ],
)
def test_a_bad_path_is_one_error_line(capsys, argv: list[str], says: str) -> None:
    assert main(argv) == 2
    assert says in _error_line(capsys)


def test_an_empty_log_is_refused_not_skipped(capsys, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["hold", "--headless", "--duration", "0.1", "--log", ""]) == 2
    assert "log path is empty" in _error_line(capsys)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["run", "check"])
def test_an_empty_motion_file_is_refused_not_the_lab_motion(capsys, command: str) -> None:
    assert main([command, "--headless", ""] if command == "run" else [command, ""]) == 2
    assert "motion file path is empty" in _error_line(capsys)
    assert "PASS" not in capsys.readouterr().out


def test_examples_into_an_empty_name_copies_nothing(capsys, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["examples", ""]) == 2
    assert list(tmp_path.iterdir()) == []


def test_record_checks_its_outputs_before_the_script_runs(capsys, tmp_path: Path) -> None:
    script = tmp_path / "s.py"
    marker = tmp_path / "ran"
    script.write_text(f"open({str(marker)!r}, 'w').close()\n")
    assert main(["record", str(script), "-o", f"{UNWRITABLE}/r.mp4"]) == 2
    assert "cannot write the video" in _error_line(capsys)
    assert main(["record", str(script), "-o", str(tmp_path / "r.mp4"), "--log", ""]) == 2
    assert "log path is empty" in _error_line(capsys)
    assert not marker.exists()


def test_check_variants_with_an_empty_plot_is_refused(capsys) -> None:
    assert main(["check", "--variants", "2", "--plot", ""]) == 2
    assert "plot path is empty" in _error_line(capsys)


def test_a_width_out_of_range_says_so_with_its_bounds(capsys) -> None:
    argv = ["hold", "--headless", "--duration", "0.1", "--record", "x.mp4", "--width"]
    assert main([*argv, "9" * 20]) == 2
    line = _error_line(capsys)
    assert "width = an integer of 20 digits is out of range" in line
    assert "from 16 to 4096" in line
    assert main([*argv, "17"]) == 2
    assert "width = 17 pixels is odd" in _error_line(capsys)


# ---------------------------------------------------------------------------- empty names
def test_teleop_refuses_an_empty_calibration_id_or_port(capsys) -> None:
    from so101sim.errors import CalibrationError, LeaderError
    from so101sim.robot.teleop import FeetechLeaderBus, find_calibration

    with pytest.raises(CalibrationError, match="calibration file path is empty"):
        find_calibration("")  # was: "" taken for no file, the default calibration used
    with pytest.raises(CalibrationError, match="leader id is empty"):
        find_calibration(None, " ")
    with pytest.raises(LeaderError, match="serial port path is empty"):
        FeetechLeaderBus("", sdk=object())
    assert main(["teleop", "--headless", "--port", "/x", "--calibration", ""]) == 2
    assert "calibration file path is empty" in _error_line(capsys)
