"""The command line: every subcommand, run as a user runs it."""

from __future__ import annotations

import threading
from typing import ClassVar

import pytest

from so101sim import cli
from so101sim.cli import build_parser, main
from so101sim.cli import tools as cli_tools
from so101sim.model import model_dir
from so101sim.robot import teleop
from so101sim.units import JOINT_NAMES


def test_run_headless_prints_each_phase(capsys):
    assert main(["run", "--headless"]) == 0
    out = capsys.readouterr().out
    for phase in ("to_zero", "hold", "return"):
        assert f"{phase} [" in out
    assert out.count("largest tracking error") == 3
    assert "target : shoulder_pan=0.00°" in out
    assert "shoulder_lift=-98.00°" in out  # back at the rest pose


def test_run_without_a_display_says_it_is_headless(capsys):
    assert main(["run"]) == 0  # tests run with DISPLAY unset
    assert "running headless" in capsys.readouterr().out


def test_hold(capsys):
    assert main(["hold", "--headless", "--duration", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "holding the starting pose" in out and "250 steps" in out


def test_model_path(capsys):
    assert main(["model-path"]) == 0
    path = capsys.readouterr().out.strip()
    assert path == str(model_dir())
    assert (model_dir() / "scene.xml").is_file()


def test_errors_exit_2_with_a_message(capsys, tmp_path):
    assert main(["run", "--headless", "--model", str(tmp_path / "x.xml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["hold", "--headless", "--duration", "0"]) == 2
    assert "duration" in capsys.readouterr().err


def test_view_without_display_is_an_error(capsys):
    assert main(["view"]) == 2
    assert "no display" in capsys.readouterr().err


def test_parser_requires_a_command():
    with pytest.raises(SystemExit):
        build_parser().parse_args([])


# ---------------------------------------------------------------------------- teleop


class FakeLeaderBus:
    """A leader held with the shoulder panned by +90° (LeRobot's default calibration)."""

    instances: ClassVar[list[FakeLeaderBus]] = []

    def __init__(self, port, *, calibration=None):
        self.port = port
        self.closed = False
        self.reads = 0
        FakeLeaderBus.instances.append(self)

    def read_positions(self):
        self.reads += 1
        raw = dict.fromkeys(JOINT_NAMES, 2047)
        raw["shoulder_pan"] = 2047 + 1024  # about +90°
        return raw

    def close(self):
        self.closed = True


def test_teleop_mirrors_a_leader_in_real_time(monkeypatch, capsys):
    monkeypatch.setattr(teleop, "FeetechLeaderBus", FakeLeaderBus)
    FakeLeaderBus.instances.clear()
    rc = cli.main(["teleop", "--port", "/dev/ttyFAKE", "--headless", "--duration", "0.3"])
    out = capsys.readouterr().out
    assert rc == 0
    bus = FakeLeaderBus.instances[-1]
    assert bus.port == "/dev/ttyFAKE" and bus.closed
    assert bus.reads >= 2
    assert "no calibration file" in out
    assert "ticks in" in out
    assert not [t for t in threading.enumerate() if t.name.startswith("so101sim-physics")]


def test_teleop_reports_a_bad_calibration_file(tmp_path, capsys):
    bad = tmp_path / "leader.json"
    bad.write_text("{}")
    rc = cli.main(["teleop", "--port", "/dev/ttyFAKE", "--calibration", str(bad)])
    assert rc == 2
    assert "calibration motors do not match" in capsys.readouterr().err


def test_teleop_reports_a_missing_port(capsys):
    rc = cli.main(["teleop", "--port", "/dev/does-not-exist", "--headless", "--duration", "0.1"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "so101sim: error:" in err
    assert "/dev/does-not-exist" in err or "so101sim[leader]" in err


def test_teleop_needs_a_port(capsys):
    with pytest.raises(SystemExit):
        cli.main(["teleop"])
    assert "--port" in capsys.readouterr().err


def test_bad_settings_fail_before_anything_runs_or_is_written(capsys, tmp_path):
    video = tmp_path / "a.mp4"
    assert main(["hold", "--duration", "nan", "--record", str(video)]) == 2
    err = capsys.readouterr().err
    assert "duration = nan" in err and "Traceback" not in err
    assert not video.exists() and list(tmp_path.iterdir()) == []
    assert main(["run", "--speed", "0"]) == 2
    assert "speed = 0.0 is invalid" in capsys.readouterr().err


def test_recording_headless_still_says_it_is_headless(capsys, tmp_path):
    assert main(["hold", "--duration", "0.1", "--log", str(tmp_path / "h.csv")]) == 0
    assert "running headless" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [("--fps", "0", "fps = 0.0 is invalid"), ("--duration", "-1", "duration = -1.0 s")],
)
def test_teleop_checks_its_numbers_before_opening_anything(
    monkeypatch, capsys, option, value, message
):
    from so101sim import robot

    opened = []
    monkeypatch.setattr(teleop, "FeetechLeaderBus", lambda *a, **k: opened.append("bus"))
    monkeypatch.setattr(robot, "SO101SimFollower", lambda *a, **k: opened.append("robot"))
    rc = cli.main(["teleop", "--port", "/dev/ttyFAKE", "--headless", option, value])
    captured = capsys.readouterr()
    assert rc == 2
    assert message in captured.err
    assert opened == []  # neither the port nor the simulated follower was opened
    assert captured.out == ""  # nothing printed before the error (no calibration notice)


def test_recording_shows_a_progress_bar_on_a_terminal(monkeypatch, tmp_path, capsys):
    import io
    import sys

    import tqdm

    class Terminal(io.StringIO):
        def isatty(self):  # tqdm(disable=None) shows a bar only on a terminal
            return True

    bars = []

    class SpyBar(tqdm.tqdm):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.enabled = not self.disable  # before close() disables it
            self.stream = kwargs.get("file")
            self.was_closed = False
            bars.append(self)

        def close(self):
            self.was_closed = True
            super().close()

    monkeypatch.setattr(tqdm, "tqdm", SpyBar)
    terminal = Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    video = tmp_path / "hold.mp4"
    argv = ["hold", "--duration", "0.2", "--record", str(video), "--width", "32"]
    assert main([*argv, "--height", "24", "--quality", "draft"]) == 0
    out = capsys.readouterr().out
    [bar] = bars
    assert bar.enabled and bar.stream is terminal  # on the terminal's stderr
    assert bar.total == 7  # frames at t = 0, 1/30, ..., 0.2 s
    assert bar.n == bar.total  # one update per frame written
    assert f"({bar.total} frames)" in out
    assert bar.was_closed


def test_recording_shows_no_progress_bar_off_a_terminal(monkeypatch, tmp_path):
    import tqdm

    bars = []

    class SpyBar(tqdm.tqdm):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            bars.append(self)

    monkeypatch.setattr(tqdm, "tqdm", SpyBar)
    argv = ["hold", "--duration", "0.2", "--record", str(tmp_path / "h.mp4"), "--width", "32"]
    assert main([*argv, "--height", "24", "--quality", "draft"]) == 0
    [bar] = bars
    assert bar.disable and bar.n == 0  # captured stderr is not a terminal: nothing drawn


def test_the_parsers_quality_choices_are_the_recorders():
    from so101sim.recording import QUALITY_CHOICES

    assert cli_tools.QUALITY_CHOICES == QUALITY_CHOICES


def test_building_the_parser_imports_no_mujoco_nor_numpy():
    import subprocess
    import sys

    code = (
        "import sys; from so101sim import cli; cli.build_parser(); "
        "print('mujoco' in sys.modules, 'numpy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "False"]


# ---------------------------------------------------------------------------- camera options
def test_camera_options_reach_the_videos_settings():
    argv = ["run", "--record", "a.mp4", "--view", "side", "--azimuth=-45", "--elevation", "-30",
            "--distance", "1.5", "--lookat=0.2,0,0.1"]  # fmt: skip
    settings = cli.run._outputs(build_parser().parse_args(argv)).settings.validated()
    assert settings.view == "side" and settings.azimuth == -45.0
    assert settings.elevation == -30.0 and settings.distance == 1.5
    assert settings.lookat == (0.2, 0.0, 0.1)
    args = build_parser().parse_args(["hold", "--record", "a.mp4", "--view", "top"])
    settings = cli.run._outputs(args).settings
    assert settings.view == "top" and settings.azimuth is None and settings.lookat is None


def test_the_parsers_views_are_the_framings():
    from so101sim.cli.tools import VIEW_CHOICES
    from so101sim.recording.framing import NAMED_VIEWS

    assert set(VIEW_CHOICES) == set(NAMED_VIEWS)


@pytest.mark.parametrize(
    ("option", "said"),
    [
        (["--azimuth", "abc"], "--azimuth 'abc' is not a number; expected a number of degrees"),
        (["--lookat", "1,2"], "expected three numbers X,Y,Z"),
        (["--lookat", "0,x,0"], "--lookat 'x' is not a number; expected three numbers X,Y,Z"),
        (["--elevation", "95"], "elevation = 95.0 is invalid; expected"),
        (["--distance", "nan"], "distance = nan"),
    ],
)
def test_bad_camera_options_are_one_line_errors_before_anything_runs(
    option, said, tmp_path, capsys
):
    video = tmp_path / "a.mp4"
    for command in (["run"], ["hold", "--duration", "0.2"]):
        assert main([*command, "--record", str(video), *option]) == 2
        out, err = capsys.readouterr()
        assert said in err and len(err.strip().splitlines()) == 1, err
        assert "steps]" not in out  # nothing simulated
        assert list(tmp_path.iterdir()) == []


def test_check_with_no_file_checks_the_lab_motion(capsys):
    assert main(["check"]) == 0
    out = capsys.readouterr().out
    assert "to_zero" in out and "return" in out and out.strip().endswith("PASS")


@pytest.mark.parametrize("command", ["run", "check"])
def test_a_video_given_as_the_motion_file_says_to_use_record(command, tmp_path, capsys):
    video = tmp_path / "lab.mp4"
    video.write_bytes(b"\x00\x00\x00\x18ftypmp42\x9f\xff" * 10)
    flag = "--record" if command == "run" else "so101sim run --record"
    for path in (video, tmp_path / "new.mp4", tmp_path / "plot.png"):  # and one not there yet
        assert main([command, str(path)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err and "codec" not in err
        assert f"{path}: " in err and "expected a TOML motion file" in err
        if path.suffix == ".mp4":
            assert err.endswith(f"to write a video use {flag} {path}")
        else:
            assert err.endswith(f"to write a plot use {flag.replace('record', 'plot')} {path}")


@pytest.mark.parametrize("command", ["run", "check"])
def test_a_python_script_given_as_the_motion_file_says_which_commands_take_one(
    command, tmp_path, capsys
):
    script = tmp_path / "my_lab.py"
    script.write_text("import mujoco\nimport mujoco.viewer\n")
    assert main([command, str(script), *(["--headless"] if command == "run" else [])]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert f"{script}:1: not valid TOML" in err
    assert err.endswith("`so101sim grade LOG.csv` judges the run against the lab's spec")
    assert "`so101sim record SCRIPT --log LOG.csv` runs your own script" in err
    assert main([command, str(tmp_path / "missing.py")]) == 2  # not there: no such hint
    assert "so101sim record SCRIPT" not in capsys.readouterr().err


def test_a_binary_file_is_not_a_motion_file(tmp_path, capsys):
    blob = tmp_path / "motion.bin"
    blob.write_bytes(bytes(range(256)))
    assert main(["run", str(blob)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"so101sim: error: {blob}: not a motion file: it is not UTF-8 text")
    assert "--record" not in err and len(err.splitlines()) == 1


def test_a_video_in_a_folder_that_cannot_hold_files_is_a_one_line_error(capsys):
    assert main(["hold", "--duration", "0.1", "--record", "/proc/lab.mp4"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("so101sim: error: cannot write the video '/proc/lab.mp4'")
    assert len(err.splitlines()) == 1 and "Traceback" not in err


class _StandInViewer:
    def sync(self):
        pass

    def is_running(self):
        return True


def _run_with_a_viewer(monkeypatch, clock, sleep, *argv):
    """``so101sim run`` in-process with a stand-in viewer (no display needed), its pacing on
    ``clock`` and ``sleep``; returns its stdout."""
    import contextlib

    from so101sim.cli import runplan
    from so101sim.sim.simulation import Pacer
    from so101sim.viewer import ViewerChoice

    monkeypatch.setattr(runplan, "choose_viewer", lambda headless=False: ViewerChoice(use=True))
    stand_in = contextlib.nullcontext(_StandInViewer())
    monkeypatch.setattr(runplan, "open_viewer", lambda *a, **k: stand_in)
    monkeypatch.setattr(runplan, "Pacer", lambda speed: Pacer(speed, clock=clock, sleep=sleep))
    assert main(["run", *argv]) == 0


def test_a_run_the_viewer_could_not_show_at_real_time_says_so(monkeypatch, capsys):
    # the run's wall clock jumps 0.5 s at every frame it paces (a machine far too slow to draw
    # the run at real time)
    wall = iter(range(10**6))
    _run_with_a_viewer(monkeypatch, lambda: 0.5 * next(wall), lambda s: None)
    out = capsys.readouterr().out
    assert "return [move" in out  # the run's report, then the note
    note = out.strip().splitlines()[-1]
    assert note.startswith("note: the viewer fell behind real time ") and " s in all)" in note
    assert "the simulated time and every figure above are exact anyway" in note
    assert "headless" not in out


def test_a_run_the_browser_page_could_not_show_at_real_time_says_so(monkeypatch, capsys):
    # ``run --web``: the page paces the run with the run's pacer (a stand-in for the studio,
    # no browser or server needed); its wall clock jumps 0.5 s at every frame it paces
    import contextlib
    import math

    from so101sim.cli import runplan
    from so101sim.cli import studio as cli_studio
    from so101sim.model import load_model
    from so101sim.sim.observers import Observer
    from so101sim.sim.simulation import Pacer

    class _Page(Observer):  # what the studio's observer does with the pacer, minus the page
        def __init__(self, pacer):
            self.pacer, self._next = pacer, -math.inf

        def next_time(self):
            return self._next

        def on_time(self, m, d):
            self.pacer.wait(d.time)
            self._next = d.time + 1 / 30 - 1e-9
            return True

    class _WebRun:
        model = load_model()

        def observers(self, run):
            return [_Page(run.pacer)]

    wall = iter(range(10**6))
    clock = lambda: 0.5 * next(wall)  # noqa: E731
    monkeypatch.setattr(cli_studio, "web_run", lambda args: contextlib.nullcontext(_WebRun()))
    monkeypatch.setattr(runplan, "Pacer", lambda speed: Pacer(speed, clock=clock))
    assert main(["run", "--web"]) == 0
    out = capsys.readouterr().out
    assert "return [move" in out  # the run's report, then the note
    note = out.strip().splitlines()[-1]
    assert note.startswith("note: the browser page fell behind real time ") and " s in all)" in note


def test_a_run_that_keeps_real_time_says_nothing_of_it(monkeypatch, capsys):
    t = [0.0]  # a clock that sleeping moves exactly on: never behind
    sleep = lambda s: t.__setitem__(0, t[0] + s)  # noqa: E731
    _run_with_a_viewer(monkeypatch, lambda: t[0], sleep, "--speed", "8")
    out = capsys.readouterr().out
    assert "return [move" in out and "behind real time" not in out
