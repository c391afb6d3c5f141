"""Tests of so101sim.recording.Recorder and the CLI's recording options: all outputs at once,
interruptions, bad input."""

from __future__ import annotations

import math

import imageio.v2 as imageio
import pytest
from recording_helpers import SMALL, no_partial_files, read_csv, read_video

from so101sim import LAB_MOTION, Simulation, cli, run_motion
from so101sim import recording as rec
from so101sim.errors import OutputPathError, RecordingError
from so101sim.sim.simulation import Observer


class StopAt(Observer):
    """Raises ``exc`` the first time simulated time reaches ``t``."""

    def __init__(self, t: float, exc: BaseException) -> None:
        self.t, self.exc = t, exc

    def next_time(self) -> float:
        return self.t

    def on_time(self, m, d) -> bool:
        raise self.exc


@pytest.mark.parametrize("exc", [KeyboardInterrupt(), RuntimeError("boom")])
def test_interrupted_run_leaves_a_playable_video_and_a_complete_csv(tmp_path, exc):
    sim = Simulation()
    video, log, plot = tmp_path / "cut.mp4", tmp_path / "cut.csv", tmp_path / "cut.png"
    stop_at = 0.5
    with (
        pytest.raises(type(exc)),
        rec.Recorder(sim, video=video, log=log, plot=plot, settings=SMALL) as r,
    ):
        run_motion(sim.model, sim.data, LAB_MOTION, observers=[*r.observers, StopAt(stop_at, exc)])
    frames, _ = read_video(video)
    assert abs(len(frames) - stop_at * 30) <= 1 and len(frames) == r.video.frames
    assert frames[-1].shape == (48, 64, 3)
    _, rows = read_csv(log)
    assert len(rows) == round(stop_at / sim.timestep)
    assert all(len(row) == len(rec.csv_columns()) for row in rows)
    assert float(rows[-1][0]) == pytest.approx(stop_at)
    assert imageio.imread(plot).shape[:2] == (960, 1280)
    assert no_partial_files(tmp_path)


def test_bad_paths_and_settings_say_what_is_expected(tmp_path):
    sim = Simulation()
    with pytest.raises(OutputPathError, match=r"\.mp4"):
        rec.Recorder(sim, video=tmp_path / "a.gif")
    with pytest.raises(OutputPathError, match="is a folder"):
        rec.check_output_path(tmp_path)
    with pytest.raises(OutputPathError, match="must differ"):
        rec.Recorder(sim, log=tmp_path / "a.csv", plot=tmp_path / "a.csv")
    for settings, match in [
        (rec.VideoSettings(width=63), "even"),
        (rec.VideoSettings(height=0), "even"),
        (rec.VideoSettings(fps=0), "fps"),
        (rec.VideoSettings(fps=math.nan), "fps"),
        (rec.VideoSettings(quality="best"), "auto, draft, full"),
    ]:
        with pytest.raises(RecordingError, match=match):
            rec.Recorder(sim, video=tmp_path / "a.mp4", settings=settings)
    assert list(tmp_path.iterdir()) == []


def test_cli_records_video_plot_and_log(tmp_path, capsys):
    out = tmp_path
    code = cli.main(
        [
            "hold",
            "--duration",
            "0.5",
            "--headless",
            "--record",
            str(out / "h.mp4"),
            "--plot",
            str(out / "h.png"),
            "--log",
            str(out / "h.csv"),
            "--width",
            "48",
            "--height",
            "32",
            "--fps",
            "20",
            "--quality",
            "draft",
            "--no-caption",
        ]
    )
    assert code == 0
    frames, _ = read_video(out / "h.mp4")
    assert len(frames) == rec.video_frames(0.5, 20) and frames[0].shape == (32, 48, 3)
    assert len(read_csv(out / "h.csv")[1]) == 250
    assert imageio.imread(out / "h.png").ndim == 3
    printed = capsys.readouterr().out
    assert "wrote the video to" in printed and "wrote the log to" in printed


def test_cli_bad_output_fails_before_running(tmp_path, capsys):
    existing = tmp_path / "x.mp4"
    existing.write_bytes(b"old")
    assert cli.main(["hold", "--duration", "0.1", "--record", str(existing)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert existing.read_bytes() == b"old"
    assert cli.main(["run", "--log", str(tmp_path / "missing" / "x.csv")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert cli.main(["run", "--record", str(tmp_path / "y.mp4"), "--camera", "top"]) == 2
    err = capsys.readouterr().err
    assert "unknown camera 'top'" in err and "free" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.mp4"]
