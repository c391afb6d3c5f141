"""Tests of so101sim.recording: video, CSV log, plot, presets, interruptions, bad input.

Videos here are small (a few dozen pixels) and motions short wherever the point allows, so the
file runs in seconds on a 2-core CPU with Mesa's software renderer.
"""

from __future__ import annotations

import copy
import csv
import json
import logging
import math

import imageio.v2 as imageio
import mujoco
import numpy as np
import pytest

from so101sim import (
    LAB_MOTION,
    STARTING_POSE,
    ZERO_POSE,
    Hold,
    Move,
    Simulation,
    cli,
    gl,
    run_motion,
    scene_path,
)
from so101sim import recording as rec
from so101sim.errors import (
    CameraError,
    OutputPathError,
    RecordingError,
    RenderBackendError,
    So101SimError,
)
from so101sim.model import load_model, model_source
from so101sim.simulation import Observer
from so101sim.units import JOINT_NAMES

SMALL = rec.VideoSettings(width=64, height=48, fps=30, quality="draft")


def read_video(path) -> tuple[list[np.ndarray], float]:
    reader = imageio.get_reader(path)
    try:
        fps = reader.get_meta_data()["fps"]
        return [np.asarray(f) for f in reader], fps
    finally:
        reader.close()


def read_csv(path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def no_partial_files(folder) -> bool:
    return not [p for p in folder.iterdir() if ".partial" in p.name]


class StopAt(Observer):
    """Raises ``exc`` the first time simulated time reaches ``t``."""

    def __init__(self, t: float, exc: BaseException) -> None:
        self.t, self.exc = t, exc

    def next_time(self) -> float:
        return self.t

    def on_time(self, m, d) -> bool:
        raise self.exc


# ---------------------------------------------------------------------------- video
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


def test_frame_size_above_the_models_offscreen_buffer(tmp_path):
    sim = Simulation()
    w, h = 704, 528
    assert w > sim.model.vis.global_.offwidth and h > sim.model.vis.global_.offheight
    fr = rec.FrameRenderer(sim.model, rec.VideoSettings(width=w, height=h, quality="draft"))
    try:
        frame = fr.render(sim.data, "t = 0.00 s")
    finally:
        fr.close()
    assert frame.shape == (h, w, 3) and frame.std() > 5
    assert sim.model.vis.global_.offwidth == 640  # the shared physics model is untouched


@pytest.mark.parametrize("quality", ["draft", "full"])
def test_both_quality_presets_render(quality):
    sim = Simulation()
    fr = rec.FrameRenderer(
        sim.model, rec.VideoSettings(width=64, height=48, quality=quality, caption=False)
    )
    try:
        assert fr.quality == quality
        frame = fr.render(sim.data).copy()
    finally:
        fr.close()
    assert frame.shape == (48, 64, 3)
    assert frame.std() > 5
    # the yellow arm is in the picture: red and green high, blue low
    yellow = (frame[..., 0] > 150) & (frame[..., 1] > 120) & (frame[..., 2] < 90)
    assert yellow.sum() > 20


def test_draft_uses_fewer_visual_triangles_and_keeps_the_bodies():
    sim = Simulation()
    full = rec.render_model(sim.model, "full", 640, 480)
    draft = rec.render_model(sim.model, "draft", 640, 480)
    assert (draft.nq, draft.nbody, draft.njnt) == (full.nq, full.nbody, full.njnt)

    def drawn_faces(m: mujoco.MjModel) -> int:
        visual = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]
        visual = [g for g in visual if m.geom_group[g] == 2]
        return sum(int(m.mesh_facenum[m.geom_dataid[g]]) for g in visual)

    assert drawn_faces(draft) < drawn_faces(full) / 5
    assert draft.vis.quality.offsamples == 0
    assert full.vis.quality.offsamples == sim.model.vis.quality.offsamples


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


def test_caption_is_drawn_into_the_frame():
    sim = Simulation()
    settings = rec.VideoSettings(width=160, height=120, quality="draft")
    fr = rec.FrameRenderer(sim.model, settings)
    try:
        fr.render(sim.data)  # warm-up: llvmpipe's first frame can differ by a pixel
        plain = fr.render(sim.data).copy()
        captioned = fr.render(sim.data, "t = 1.23 s  to_zero").copy()
    finally:
        fr.close()
    changed = np.abs(plain.astype(int) - captioned.astype(int)).sum(axis=2) > 0
    ys, xs = np.nonzero(changed)
    assert len(ys) > 50
    assert ys.min() > 120 // 2 and xs.min() < 160 // 4  # bottom-left only


def test_auto_quality_is_draft_on_a_cpu_and_full_on_a_gpu(monkeypatch):
    monkeypatch.setattr(gl, "software_rendering", lambda: True)
    assert rec.resolve_quality("auto") == "draft"
    monkeypatch.setattr(gl, "software_rendering", lambda: False)
    assert rec.resolve_quality("auto") == "full"
    assert rec.resolve_quality("draft") == "draft"


# ---------------------------------------------------------------------------- CSV log
def test_csv_has_one_row_per_control_step_and_ends_at_the_final_target(tmp_path):
    sim = Simulation()
    path = tmp_path / "lab.csv"
    with rec.Recorder(sim, log=path) as r:
        result = run_motion(sim.model, sim.data, LAB_MOTION, observers=r.observers)
    header, rows = read_csv(path)
    assert header == rec.csv_columns()
    assert header[:2] == ["time", "phase"]
    assert header[2:8] == [f"{n}_commanded" for n in JOINT_NAMES]
    assert header[8:] == [f"{n}_measured" for n in JOINT_NAMES]
    steps = sum(s.steps for s in result.segments)
    assert len(rows) == steps == round(6.0 / sim.timestep)
    times = np.array([float(row[0]) for row in rows])
    np.testing.assert_allclose(np.diff(times), sim.timestep, atol=1e-4)
    assert [row[1] for row in rows[:: steps // 3]] == ["to_zero", "hold", "return"]
    last = rows[-1]
    commanded = dict(zip(JOINT_NAMES, map(float, last[2:8]), strict=True))
    for name in JOINT_NAMES:
        assert commanded[name] == pytest.approx(STARTING_POSE[name], abs=1e-5)
    measured = np.array([float(v) for v in last[8:]])
    np.testing.assert_allclose(measured, result.segments[-1].measured[-1], atol=1e-5)


def test_csv_quotes_phase_names_with_commas(tmp_path):
    sim = Simulation()
    path = tmp_path / "q.csv"
    with rec.Recorder(sim, log=path):
        sim.hold(0.01, phase='wait, then "go"')
    _, rows = read_csv(path)
    assert len(rows) == 5 and rows[0][1] == 'wait, then "go"'


# ---------------------------------------------------------------------------- plot
def test_plot_is_a_png_of_the_requested_size(tmp_path):
    sim = Simulation()
    result = run_motion(sim.model, sim.data, LAB_MOTION)
    path = rec.plot_run(result, tmp_path / "lab.png", width=800, height=600)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = imageio.imread(path)
    assert image.shape[:2] == (600, 800)
    assert image[..., :3].std() > 10


def test_recorder_plot_matches_the_run(tmp_path):
    sim = Simulation()
    with rec.Recorder(sim, plot=tmp_path / "p.png", plot_size=(640, 480)) as r:
        run_motion(sim.model, sim.data, LAB_MOTION, observers=r.observers)
    run = r.collector.run_log()
    assert [p[0] for p in run.phases] == ["to_zero", "hold", "return"]
    assert run.phases[0][1] == pytest.approx(0.0) and run.phases[-1][2] == pytest.approx(6.0)
    assert imageio.imread(r.outputs["plot"]).shape[:2] == (480, 640)


# ---------------------------------------------------------------------------- interruptions
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
    assert all(len(row) == 14 for row in rows)
    assert float(rows[-1][0]) == pytest.approx(stop_at)
    assert imageio.imread(plot).shape[:2] == (960, 1280)
    assert no_partial_files(tmp_path)


# ---------------------------------------------------------------------------- bad input
def test_missing_output_folder_fails_before_anything_runs(tmp_path):
    sim = Simulation()
    for kwargs in ({"video": tmp_path / "no" / "a.mp4"}, {"log": tmp_path / "no" / "a.csv"}):
        with pytest.raises(OutputPathError, match="does not exist"):
            rec.Recorder(sim, **kwargs)
    assert sim.time == 0.0
    assert list(tmp_path.iterdir()) == []


def test_unwritable_output_folder_fails(tmp_path, monkeypatch):
    monkeypatch.setattr(rec.os, "access", lambda path, mode: False)
    with pytest.raises(OutputPathError, match="not writable"):
        rec.check_output_path(tmp_path / "a.csv")


def test_existing_file_is_kept_unless_forced(tmp_path):
    sim = Simulation()
    path = tmp_path / "old.csv"
    path.write_text("keep me")
    with pytest.raises(OutputPathError, match="already exists"):
        rec.Recorder(sim, log=path)
    assert path.read_text() == "keep me"
    with rec.Recorder(sim, log=path, force=True):
        sim.hold(0.01)
    assert path.read_text().startswith("time,phase,")


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


def test_render_backend_failure_says_what_to_install(monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("eglInitialize failed")

    monkeypatch.setattr(rec.mujoco, "Renderer", broken)
    with pytest.raises(RenderBackendError, match="libegl1") as info:
        rec.FrameRenderer(Simulation().model, SMALL)
    assert "eglInitialize failed" in str(info.value) and "libosmesa6" in str(info.value)


def test_shipped_draft_meshes_match_their_manifest():
    folder = rec.draft_mesh_dir()
    manifest = json.loads((folder / "manifest.json").read_text())["meshes"]
    stls = sorted(p.name for p in folder.glob("*.stl"))
    assert stls == sorted(manifest)
    total = 0
    for name, entry in manifest.items():
        data = (folder / name).read_bytes()
        faces = int(np.frombuffer(data, np.uint32, 1, 80)[0])
        assert faces == entry["faces"] <= entry["original_faces"]
        total += len(data)
    assert total < 3_000_000


# ---------------------------------------------------------------------------- the CLI
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


def _draws_draft_meshes(m: mujoco.MjModel) -> bool:
    names = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_MESH, i) for i in range(m.nmesh)}
    return bool(names) and all(n.endswith("__draft") for n in names)


@pytest.mark.parametrize(
    "make",
    [
        pytest.param(lambda: mujoco.MjModel.from_xml_path(str(scene_path())), id="from_xml_path"),
        pytest.param(lambda: copy.copy(load_model()), id="copy"),
    ],
)
def test_draft_recognises_the_shipped_model_however_it_was_compiled(make, caplog):
    model = make()
    assert model_source(model) is None  # not the object load_model() returned
    with caplog.at_level(logging.WARNING, logger="so101sim.recording"):
        rm = rec.render_model(model, "draft", 64, 48)
    assert _draws_draft_meshes(rm)
    assert (rm.nq, rm.nbody) == (model.nq, model.nbody)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_draft_warns_when_it_falls_back_to_the_models_own_meshes(caplog):
    edited = copy.copy(load_model())
    edited.geom_rgba[:, :3] = (0.9, 0.1, 0.1)  # edited after loading: drawn in red now
    with caplog.at_level(logging.WARNING, logger="so101sim.recording"):
        rm = rec.render_model(edited, "draft", 64, 48)
    assert not _draws_draft_meshes(rm)
    np.testing.assert_array_equal(rm.mesh_facenum, edited.mesh_facenum)
    [warning] = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert "falling back to the model's own meshes" in warning.getMessage()
    assert "load_model" in warning.getMessage()

    box = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><geom type='box' size='.1 .1 .1'/></worldbody></mujoco>"
    )
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="so101sim.recording"):
        rec.render_model(box, "draft", 64, 48)
    [warning] = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert "none of its meshes is a shipped SO-101 mesh" in warning.getMessage()
