"""Tests of so101sim.recording.video: MP4 files clocked by simulated time, cameras.

Videos here are small (a few dozen pixels) and motions short wherever the point allows, so the
file runs in seconds on a 2-core CPU with Mesa's software renderer.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from recording_helpers import no_partial_files, read_video

from so101sim import LAB_MOTION, ZERO_POSE, Hold, Move, Simulation, run_motion, scene_path
from so101sim import recording as rec
from so101sim.errors import CameraError, So101SimError


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

    # the arm moves during 0-2 s and 4-6 s and is still while it holds (2-4 s)
    assert diff(0, 60) > 1.0
    assert diff(60, 120) < diff(0, 60) / 3
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
