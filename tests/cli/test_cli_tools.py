from pathlib import Path

import pytest

from so101sim import cli
from so101sim.model import scene_path

SCRIPT = Path(__file__).parents[1] / "data" / "wallclock_lab.py"


def test_record_runs_an_unchanged_script_and_passes_its_output(tmp_path, capsys):
    out = tmp_path / "lab.mp4"
    argv = ["record", str(SCRIPT), "-o", str(out), "--title", "Lab 2 - Ada Lovelace",
            "--width", "160", "--height", "120", "--", str(scene_path())]  # fmt: skip
    assert cli.main(argv) == 0
    text = capsys.readouterr().out
    assert "done at t = 6.0" in text  # the script's own print
    assert f"wrote the video to {out}" in text and "6.0" in text
    assert out.stat().st_size > 1000


def test_record_passes_the_scripts_exit_status_and_traceback(tmp_path, capsys):
    boom = tmp_path / "boom.py"
    boom.write_text("raise ValueError('my bug')\n")
    assert cli.main(["record", str(boom), "-o", str(tmp_path / "b.mp4")]) == 1
    err = capsys.readouterr().err
    assert "ValueError: my bug" in err and "Traceback" in err
    missing = ["record", str(tmp_path / "nope.py"), "-o", str(tmp_path / "n.mp4")]
    assert cli.main(missing) == 2
    assert "does not exist" in capsys.readouterr().err


def test_workspace_draws_the_reachable_region(tmp_path, capsys):
    out = tmp_path / "ws.png"
    assert cli.main(["workspace", "--plot", str(out), "--samples", "2000"]) == 0
    assert out.stat().st_size > 1000
    assert "the tip reaches" in capsys.readouterr().out
    assert cli.main(["workspace", "--plot", str(out), "--samples", "2000"]) == 2  # exists
    assert "exists" in capsys.readouterr().err


def test_cache_info_and_clear(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("SO101SIM_CACHE_DIR", str(tmp_path / "c"))
    from so101sim.model import load_model

    load_model.__wrapped__ if hasattr(load_model, "__wrapped__") else None
    from so101sim.model import cache as modelcache

    modelcache.load_or_compile(scene_path(), lambda: load_model())
    assert cli.main(["cache"]) == 0
    assert "1 compiled model(s)" in capsys.readouterr().out
    assert cli.main(["cache", "clear"]) == 0
    assert "deleted 1 compiled model(s)" in capsys.readouterr().out
    assert modelcache.info().entries == 0
    pytest.importorskip("mujoco")


def _spy_on_recorders(monkeypatch):
    from so101sim.lab import recviewer as handin  # the recording viewer makes the Recorder

    seen = []

    class Spy(handin.Recorder):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            seen.append(self.settings)

    monkeypatch.setattr(handin, "Recorder", Spy)
    return seen


def test_record_takes_the_camera_options(tmp_path, capsys, monkeypatch):
    seen = _spy_on_recorders(monkeypatch)
    script = tmp_path / "short.py"
    script.write_text(
        "import sys, mujoco, mujoco.viewer\n"
        "m = mujoco.MjModel.from_xml_path(sys.argv[1]); d = mujoco.MjData(m)\n"
        "with mujoco.viewer.launch_passive(m, d) as v:\n"
        "    for _ in range(20):\n"
        "        mujoco.mj_step(m, d); v.sync()\n"
    )
    argv = ["record", str(script), "-o", str(tmp_path / "s.mp4"), "--width", "64", "--height",
            "48", "--view", "top", "--azimuth", "30", "--elevation=-60", "--distance", "2",
            "--lookat=0.1,0,0.05", "--", str(scene_path())]  # fmt: skip
    assert cli.main(argv) == 0, capsys.readouterr().err
    [settings] = seen
    assert (settings.view, settings.azimuth, settings.elevation) == ("top", 30.0, -60.0)
    assert settings.distance == 2.0 and settings.lookat == (0.1, 0.0, 0.05)


def test_record_checks_the_camera_options_before_the_script_runs(tmp_path, capsys):
    script = tmp_path / "loud.py"
    script.write_text("print('the script ran')\n")
    argv = ["record", str(script), "-o", str(tmp_path / "l.mp4"), "--elevation", "-120"]
    assert cli.main(argv) == 2
    out, err = capsys.readouterr()
    assert "the script ran" not in out and "elevation = -120.0 is invalid" in err
    assert not (tmp_path / "l.mp4").exists()


def test_record_takes_record_as_o_and_refuses_two_videos_or_none(tmp_path, capsys):
    out = tmp_path / "lab.mp4"
    argv = ["record", str(SCRIPT), "--record", str(out), "--width", "160", "--height", "120",
            "--", str(scene_path())]  # fmt: skip
    assert cli.main(argv) == 0
    assert f"wrote the video to {out}" in capsys.readouterr().out and out.is_file()
    two = [
        "record",
        str(SCRIPT),
        "-o",
        str(tmp_path / "a.mp4"),
        "--record",
        str(tmp_path / "b.mp4"),
    ]
    assert cli.main(two) == 2
    err = capsys.readouterr().err.strip()
    assert "name two videos" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "a.mp4").exists() and not (tmp_path / "b.mp4").exists()
    assert cli.main(["record", str(SCRIPT)]) == 2
    assert "expected -o VIDEO.mp4" in capsys.readouterr().err


def test_record_puts_the_title_on_the_plot_too(tmp_path, capsys, monkeypatch):
    from so101sim.recording import recorder

    titles = []
    real = recorder.plot_run

    def plot_run(*args, **kwargs):
        titles.append(kwargs.get("title"))
        return real(*args, **kwargs)

    monkeypatch.setattr(recorder, "plot_run", plot_run)
    argv = ["record", str(SCRIPT), "-o", str(tmp_path / "lab.mp4"), "--plot",
            str(tmp_path / "lab.png"), "--title", "Lab 2 - Ada Lovelace", "--width", "160",
            "--height", "120", "--", str(scene_path())]  # fmt: skip
    assert cli.main(argv) == 0
    assert titles == ["Lab 2 - Ada Lovelace"]
    assert (tmp_path / "lab.png").is_file()
