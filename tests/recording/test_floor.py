"""Tests of so101sim.recording.floor: the draft preset draws the infinite floor as a few quads,
and the frames stay those of MuJoCo's 200 × 200 grid."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from so101sim import Simulation
from so101sim import recording as rec
from so101sim.recording import floor, frames

VIEWS = {
    # the arm on the checkered floor, the texture's phase visible at every tile edge
    "arm": {"width": 160, "height": 120},
    # low over the floor: the horizon, its haze and the far tiles
    "horizon": {"width": 320, "height": 240, "elevation": -3.0, "distance": 2.0},
}


def _frames(
    monkeypatch, sim: Simulation, view: dict, few_quads: bool
) -> tuple[np.ndarray, rec.FrameRenderer]:
    with monkeypatch.context() as m:
        if not few_quads:
            m.setattr(frames, "finite_planes", lambda model: ())
        fr = rec.FrameRenderer(sim.model, rec.VideoSettings(caption=False, quality="draft", **view))
    try:
        shots = []
        for q in (np.zeros(6), np.array([0.6, -0.8, 0.9, 0.4, -1.0, 0.3])):
            sim.data.qpos[:6] = q
            mujoco.mj_forward(sim.model, sim.data)
            shots.append(fr.render(sim.data).copy())
        return np.stack(shots), fr
    finally:
        fr.close()


@pytest.mark.parametrize("view", VIEWS, ids=list(VIEWS))
def test_the_floor_drawn_as_a_few_quads_gives_the_same_frames(monkeypatch, view):
    sim = Simulation()
    grid, plain = _frames(monkeypatch, sim, VIEWS[view], few_quads=False)
    quads, fast = _frames(monkeypatch, sim, VIEWS[view], few_quads=True)
    assert plain._planes == () and len(fast._planes) == 1
    fid = fast._planes[0]
    assert mujoco.mj_id2name(sim.model, mujoco.mjtObj.mjOBJ_GEOM, fid) == "floor"
    rm = fast.render_model
    zfar = rm.vis.map.zfar * rm.stat.extent
    assert (rm.geom_size[fid, :2] > zfar).all()  # finite, and past the far clipping plane
    assert (sim.model.geom_size[fid, :2] == 0).all()  # the physics model keeps its floor
    floor_px = (quads[..., 2] > quads[..., 0]).mean()  # the blue checker fills much of each frame
    assert floor_px > 0.3
    diff = np.abs(grid.astype(int) - quads.astype(int))
    assert diff.max() <= 2, f"{view}: {diff.max()} grey levels apart"
    assert diff.mean() < 0.01


def test_the_full_preset_keeps_the_models_floor():
    sim = Simulation()
    fr = rec.FrameRenderer(sim.model, rec.VideoSettings(width=64, height=48, quality="full"))
    try:
        assert fr._planes == ()
        fid = mujoco.mj_name2id(fr.render_model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
        assert (fr.render_model.geom_size[fid, :2] == 0).all()
    finally:
        fr.close()


PLANE_XML = """
<mujoco>
  <asset>
    <texture name="t" type="2d" builtin="checker" width="8" height="8" rgb1="1 1 1" rgb2="0 0 0"/>
    <material name="m" texture="t" texrepeat="3 4" texuniform="{uniform}"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="{size}" material="m"/>
    <body><freejoint/><geom type="box" size=".1 .1 .1"/></body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize(
    ("uniform", "size", "changed"),
    [("true", "0 0 .05", True), ("false", "0 0 .05", False), ("true", "0 2 .05", False)],
    ids=["texuniform", "not-texuniform", "infinite-one-way"],
)
def test_only_infinite_planes_whose_texture_phase_can_be_kept_are_changed(uniform, size, changed):
    model = mujoco.MjModel.from_xml_string(PLANE_XML.format(uniform=uniform, size=size))
    before = model.geom_size.copy()
    ids = floor.finite_planes(model)
    assert bool(ids) is changed
    if not changed:
        np.testing.assert_array_equal(model.geom_size, before)
        return
    zfar = model.vis.map.zfar * model.stat.extent
    # MuJoCo's grid: 200 steps of (2.1 zfar + 2 × one texture period) / 200 along each side
    np.testing.assert_allclose(model.geom_size[0, :2], [1.05 * zfar + 2 / 3, 1.05 * zfar + 2 / 4])
