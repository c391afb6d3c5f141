"""Tests of so101sim.recording.frames (offscreen frames, caption) and the quality presets."""

from __future__ import annotations

import numpy as np
import pytest
from recording_helpers import SMALL

from so101sim import Simulation, gl
from so101sim import recording as rec
from so101sim.errors import RenderBackendError
from so101sim.recording import frames


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


def test_render_backend_failure_says_what_to_install(monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("eglInitialize failed")

    monkeypatch.setattr(frames.mujoco, "Renderer", broken)
    with pytest.raises(RenderBackendError, match="libegl1") as info:
        rec.FrameRenderer(Simulation().model, SMALL)
    assert "eglInitialize failed" in str(info.value) and "libosmesa6" in str(info.value)
