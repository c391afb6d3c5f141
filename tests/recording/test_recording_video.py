"""Tests of so101sim.recording.video: MP4 files clocked by simulated time, cameras.

Videos here are small (a few dozen pixels) and motions short wherever the point allows, so the
file runs in seconds on a 2-core CPU with Mesa's software renderer.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest
from recording_helpers import SMALL, no_partial_files, read_video

from so101sim import LAB_MOTION, ZERO_POSE, Hold, Move, Simulation, cli, run_motion, scene_path
from so101sim import recording as rec
from so101sim.errors import CameraError, OutputPathError, RecordingError, So101SimError
from so101sim.recording.paths import PendingFile
from so101sim.sim.simulation import Observer


def test_video_has_duration_times_fps_frames_of_the_requested_size_and_shows_motion(tmp_path):
    sim = Simulation()
    path = tmp_path / "lab.mp4"
    settings = rec.VideoSettings(width=64, height=48, fps=30, quality="draft", caption=False)
    with rec.Recorder(sim, video=path, settings=settings) as r:
        result = run_motion(sim.model, sim.data, LAB_MOTION, observers=r.observers)
    assert result.completed and r.outputs == {"video": path}
    frames, fps = read_video(path)
    assert fps == pytest.approx(30.0)
    assert abs(len(frames) - 6.0 * 30) <= 1
    assert len(frames) == rec.video_frames(6.0, 30) == r.video.frames
    assert all(f.shape == (48, 64, 3) for f in frames)
    assert min(float(f.std()) for f in frames) > 5.0  # not blank

    def diff(i: int, j: int) -> float:
        return float(np.abs(frames[i].astype(int) - frames[j].astype(int)).mean())

    # the arm moves during 0-2 s and 4-6 s and is still while it holds (2-4 s), once it has
    # settled: the default servo (sts3215) ends a move lagging and settles in a few tenths of
    # a second
    assert diff(0, 60) > 1.0
    assert diff(75, 120) < diff(0, 60) / 3
    assert diff(120, 180) > 1.0
    assert no_partial_files(tmp_path)


def test_recorder_on_simulation_observers_follows_moves_and_holds(tmp_path):
    sim = Simulation()
    path = tmp_path / "api.mp4"
    settings = rec.VideoSettings(width=32, height=24, fps=20, quality="draft", caption=False)
    with rec.Recorder(sim, video=path, settings=settings):
        assert len(sim.observers) == 1
        sim.move_to(ZERO_POSE, 0.5)
        sim.hold(0.5)
    assert sim.observers == []
    frames, _ = read_video(path)
    assert len(frames) == rec.video_frames(1.0, 20)  # one continuous timeline across segments


def test_frames_follow_simulated_time_not_the_physics_step(tmp_path):
    # at 10 fps, 0.999 s of simulated time is frames at t = 0, 0.1, ..., 0.9
    sim = Simulation()
    settings = rec.VideoSettings(width=32, height=24, fps=10, quality="draft", caption=False)
    with rec.Recorder(sim, video=tmp_path / "a.mp4", settings=settings) as r:
        sim.hold(0.998)
    assert r.video.frames == 10


@pytest.mark.slow
def test_physics_is_identical_whatever_the_recording_preset(tmp_path):
    def run(quality: str | None):
        sim = Simulation()
        steps = (Move(ZERO_POSE, 0.3, phase="to_zero"), Hold(0.1))
        if quality is None:
            return run_motion(sim.model, sim.data, steps)
        settings = rec.VideoSettings(width=32, height=24, fps=10, quality=quality)
        with rec.Recorder(sim, video=tmp_path / f"{quality}.mp4", settings=settings) as r:
            return run_motion(sim.model, sim.data, steps, observers=r.observers)

    base = run(None)
    for quality in ("draft", "full"):
        other = run(quality)
        for a, b in zip(base.segments, other.segments, strict=True):
            np.testing.assert_array_equal(a.measured, b.measured)
            np.testing.assert_array_equal(a.times, b.times)


def test_unknown_camera_lists_the_valid_ones(tmp_path):
    sim = Simulation()
    assert rec.camera_names(sim.model) == ["free"]
    with pytest.raises(CameraError, match="valid cameras for this model are free") as info:
        rec.Recorder(sim, video=tmp_path / "a.mp4", settings=rec.VideoSettings(camera="top"))
    assert isinstance(info.value, So101SimError)


def test_a_camera_named_in_the_model_can_be_used(tmp_path):
    spec = mujoco.MjSpec.from_file(str(scene_path()))
    cam = spec.worldbody.add_camera()
    cam.name = "overhead"
    cam.pos = [0.1, 0.0, 1.0]
    sim = Simulation(spec.compile())
    assert rec.camera_names(sim.model) == ["free", "overhead"]
    settings = rec.VideoSettings(width=32, height=24, fps=10, camera="overhead", quality="draft")
    with rec.Recorder(sim, video=tmp_path / "o.mp4", settings=settings) as r:
        sim.hold(0.2)
    assert r.video.frames == 3
    with pytest.raises(CameraError, match="free, overhead"):
        rec.check_camera(sim.model, "side")


# ---------------------------------------------------------------------------- faults
@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_ffmpeg_failing_on_a_full_disk_is_an_error_not_a_written_video(tmp_path):
    sim = Simulation()
    path = tmp_path / "full.mp4"
    settings = rec.VideoSettings(width=320, height=240, fps=30, quality="draft")
    with (
        pytest.raises(OutputPathError, match="No space left on device"),
        rec.Recorder(sim, video=path, settings=settings) as r,
    ):
        PendingFile(path).tmp.symlink_to("/dev/full")  # ffmpeg's writes fail
        sim.hold(2.0)
    assert "video" not in r.outputs and list(tmp_path.iterdir()) == []


def test_a_video_that_does_not_read_back_is_not_kept(tmp_path, monkeypatch):
    from so101sim.recording import video

    def unreadable(path):
        raise OutputPathError(f"the video written to {str(path)!r} does not open (moov)")

    monkeypatch.setattr(video, "count_frames", unreadable)
    sim = Simulation()
    with (
        pytest.raises(OutputPathError, match="does not open"),
        rec.Recorder(sim, video=tmp_path / "v.mp4", settings=SMALL),
    ):
        sim.hold(0.1)
    assert list(tmp_path.iterdir()) == []


def test_frame_sizes_are_bounded_before_anything_is_allocated(tmp_path, capsys):
    for size in (9_999_999_998, 4098):
        with pytest.raises(RecordingError, match="from 16 to 4096"):
            rec.VideoSettings(width=size).validated()
    argv = ["hold", "--duration", "0.1", "--record", str(tmp_path / "a.mp4")]
    assert cli.main([*argv, "--width", "9999999998"]) == 2
    err = capsys.readouterr().err
    assert "width = 9999999998 pixels is out of range" in err and "4096" in err
    assert list(tmp_path.iterdir()) == []


def _ffmpeg_children() -> list[int]:
    """Process ids of this process's ffmpeg children (Linux /proc)."""
    pids = []
    for task in Path(f"/proc/{os.getpid()}/task").iterdir():
        children = (task / "children").read_text().split() if (task / "children").exists() else []
        for pid in map(int, children):
            with contextlib.suppress(OSError):
                if "ffmpeg" in Path(f"/proc/{pid}/comm").read_text():
                    pids.append(pid)
    return pids


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")
def test_ctrl_c_while_a_frame_is_piped_to_ffmpeg_leaves_a_playable_video(tmp_path):
    """The encoder is paused so that the pipe fills and the run waits on it; Ctrl-C lands
    then, as it did in 2 of 21 tries (a 48-byte MP4 with no index, reported as written)."""

    class PauseEncoder(Observer):
        def next_time(self) -> float:
            return 0.2 if not hasattr(self, "pids") else float("inf")

        def on_time(self, m, d) -> bool:
            self.pids = _ffmpeg_children()
            for pid in self.pids:
                os.kill(pid, signal.SIGSTOP)

            def interrupt_then_resume():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.5)
                for pid in self.pids:
                    os.kill(pid, signal.SIGCONT)

            threading.Timer(1.0, interrupt_then_resume).start()
            return True

    sim = Simulation()
    path = tmp_path / "cut.mp4"
    settings = rec.VideoSettings(width=640, height=480, fps=30, quality="draft", caption=False)
    pause = PauseEncoder()
    # Ctrl-C as a fresh Python takes it, whatever an earlier test in this worker process left
    # (the CLI's in-process runs install their own handlers for SIGINT)
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    mask = signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    try:
        recorder = rec.Recorder(sim, video=path, settings=settings)
        with pytest.raises(KeyboardInterrupt), recorder as r:
            run_motion(sim.model, sim.data, [Hold(30.0)], observers=[*r.observers, pause])
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        signal.signal(signal.SIGINT, handler)
    assert pause.pids  # the encoder was found and paused
    frames, _ = read_video(path)
    assert len(frames) == r.video.frames > 6  # every frame sent is in the file
    assert no_partial_files(tmp_path)


def test_a_close_interrupted_by_ctrl_c_goes_on_when_called_again(tmp_path, monkeypatch):
    from so101sim.recording.encoder import FfmpegEncoder

    finish = FfmpegEncoder.finish
    calls = []

    def interrupted_once(self):
        calls.append(1)
        if len(calls) == 1:
            self._frames.put(None)  # the end of input is queued, then Ctrl-C lands
            self._end_queued = True
            raise KeyboardInterrupt
        return finish(self)

    monkeypatch.setattr(FfmpegEncoder, "finish", interrupted_once)
    sim = Simulation()
    vr = rec.VideoRecorder(tmp_path / "v.mp4", sim.model, SMALL)
    sim.hold(0.2, observers=[vr])
    with pytest.raises(KeyboardInterrupt):
        vr.close()
    assert vr.close() == tmp_path / "v.mp4" == vr.close()
    assert len(read_video(tmp_path / "v.mp4")[0]) == vr.frames == 7
    assert no_partial_files(tmp_path)
