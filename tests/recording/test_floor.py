"""Tests of so101sim.recording.floor: the draft preset draws an infinite floor as a few quads,
and the frames stay those of MuJoCo's 200 × 200 grid (within 2 grey levels)."""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest

from so101sim import Simulation, gl
from so101sim import recording as rec
from so101sim.recording import floor, frames

VIEWS = {
    # the arm on the checkered floor, the texture's phase visible at every tile edge
    "arm": {"width": 160, "height": 120},
    # low over the floor: the horizon, its haze and the far tiles
    "horizon": {"width": 320, "height": 240, "elevation": -3.0, "distance": 2.0},
    # 40 m away: MuJoCo moves an infinite plane under the camera, a finite one stays put
    "far away": {"width": 160, "height": 120, "lookat": (30.0, -25.0, 0.0), "distance": 3.0},
}


def _frames(
    monkeypatch, model: mujoco.MjModel, data: mujoco.MjData, view: dict, few_quads: bool
) -> tuple[np.ndarray, rec.FrameRenderer]:
    """Frames of two arm poses (or the model's state twice), with MuJoCo's grid or the quads."""
    with monkeypatch.context() as m:
        if not few_quads:
            m.setattr(frames, "finite_planes", lambda model: ())
        fr = rec.FrameRenderer(model, rec.VideoSettings(caption=False, quality="draft", **view))
    try:
        fr.render(data)  # MuJoCo re-centres its infinite plane under the previous frame's camera
        shots = []
        for q in (np.zeros(6), np.array([0.6, -0.8, 0.9, 0.4, -1.0, 0.3])):
            if model.nq == 6:  # the arm alone: two poses
                data.qpos[:6] = q
            mujoco.mj_forward(model, data)
            shots.append(fr.render(data).copy())
        return np.stack(shots), fr
    finally:
        fr.close()


def _assert_same(grid: np.ndarray, quads: np.ndarray, what: str, mean: float = 0.01) -> None:
    diff = np.abs(grid.astype(int) - quads.astype(int))
    assert diff.max() <= 2, f"{what}: {diff.max()} grey levels apart"
    assert diff.mean() < mean, f"{what}: {diff.mean()} grey levels apart on average"


@pytest.mark.parametrize("view", VIEWS, ids=list(VIEWS))
def test_the_floor_drawn_as_a_few_quads_gives_the_same_frames(monkeypatch, view):
    sim = Simulation()
    grid, plain = _frames(monkeypatch, sim.model, sim.data, VIEWS[view], few_quads=False)
    quads, fast = _frames(monkeypatch, sim.model, sim.data, VIEWS[view], few_quads=True)
    assert plain._planes == () and len(fast._planes) == 1
    fid = fast._planes[0]
    assert mujoco.mj_id2name(sim.model, mujoco.mjtObj.mjOBJ_GEOM, fid) == "floor"
    rm = fast.render_model
    zfar = rm.vis.map.zfar * rm.stat.extent
    assert (rm.geom_size[fid, :2] > zfar).all()  # finite, and past the far clipping plane
    assert (sim.model.geom_size[fid, :2] == 0).all()  # the physics model keeps its floor
    checker = quads[..., 2].astype(int) - quads[..., 0]  # the blue checker, lit and in view
    assert (checker > 10).mean() > 0.3
    _assert_same(grid, quads, view)


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
  <visual><headlight specular="0 0 0"/></visual>
  <asset>
    <texture name="t" type="2d" builtin="checker" width="8" height="8" rgb1="1 1 1" rgb2="0 0 0"/>
    <material name="m" texture="t" texrepeat="3 4" texuniform="{uniform}" specular="0"/>
  </asset>
  <worldbody>
    <light {light} dir="0 0 -1" pos="0 0 3"/>
    <geom name="floor" type="plane" size="{size}" material="m" pos="0.37 -0.21 0.05"
          euler="0 0 23"/>
    <body pos="0 0 .3"><freejoint/><geom type="box" size=".1 .1 .1" rgba=".8 .2 .2 1"/></body>
  </worldbody>
</mujoco>
"""


def _plane_frames(model: mujoco.MjModel, view: mujoco.MjvCamera, few_quads: bool) -> np.ndarray:
    """Frames of a model that is not an arm, drawn as FrameRenderer draws (without its arm)."""
    rm = copy.copy(model)
    planes = floor.finite_planes(rm) if few_quads else ()
    data = mujoco.MjData(rm)
    mujoco.mj_forward(rm, data)
    renderer = mujoco.Renderer(rm, height=120, width=160)
    try:
        shots = []
        for _ in range(3):
            renderer.update_scene(data, camera=view)
            floor.as_infinite(renderer.scene, rm, planes)
            shots.append(renderer.render().copy())
        return np.stack(shots[1:]), planes
    finally:
        renderer.close()


@pytest.mark.parametrize(
    ("elevation", "distance", "lookat"),
    [(-35.0, 3.0, (0.0, 0.0, 0.0)), (-4.0, 2.0, (-12.0, 7.0, 0.0))],
    ids=["near", "low and far"],
)
def test_a_turned_and_moved_plane_with_its_own_texture_repeat_keeps_its_frames(
    elevation, distance, lookat
):
    """Another floor than the shipped one: turned 23° about z, off the origin, a texture repeat
    that differs along its two sides (the phase is matched per side), white and black."""
    gl.prepare_for_rendering()
    xml = PLANE_XML.format(uniform="true", size="0 0 .05", light='directional="true"')
    model = mujoco.MjModel.from_xml_string(xml)
    view = mujoco.MjvCamera()
    view.lookat[:], view.distance, view.elevation, view.azimuth = lookat, distance, elevation, 60
    grid, _ = _plane_frames(model, view, few_quads=False)
    quads, planes = _plane_frames(model, view, few_quads=True)
    assert planes == (0,)
    assert (np.abs(quads.astype(int)[..., 1] - 128) > 60).mean() > 0.3  # the checker in view
    # black against white: the texture's sampling rounds a grey level either way on more pixels
    _assert_same(grid, quads, f"elevation {elevation}", mean=0.25)


@pytest.mark.parametrize(
    ("uniform", "size", "light", "changed"),
    [
        ("true", "0 0 .05", 'directional="true"', True),
        ("false", "0 0 .05", 'directional="true"', False),
        ("true", "0 2 .05", 'directional="true"', False),
        ("true", "0 0 .05", 'directional="false"', False),
    ],
    ids=["texuniform", "not-texuniform", "infinite-one-way", "point-light"],
)
def test_only_planes_whose_look_the_quads_keep_are_changed(uniform, size, light, changed):
    model = mujoco.MjModel.from_xml_string(
        PLANE_XML.format(uniform=uniform, size=size, light=light)
    )
    before = model.geom_size.copy()
    ids = floor.finite_planes(model)
    assert bool(ids) is changed
    if not changed:
        np.testing.assert_array_equal(model.geom_size, before)
        return
    zfar = model.vis.map.zfar * model.stat.extent
    # MuJoCo's grid: 200 steps of (2.1 zfar + 2 × one texture period) / 200 along each side
    np.testing.assert_allclose(model.geom_size[0, :2], [1.05 * zfar + 2 / 3, 1.05 * zfar + 2 / 4])


def test_a_frame_depends_only_on_the_state_and_the_camera_not_on_what_was_drawn_before():
    """The same state drawn again, after other states and far-away views, is the same frame to
    the bit (MuJoCo's own re-centring lags one frame: the quads follow this frame's camera)."""
    sim = Simulation()
    settings = rec.VideoSettings(width=96, height=72, caption=False, quality="draft")
    fr = rec.FrameRenderer(sim.model, settings)
    try:
        assert fr._planes
        mujoco.mj_forward(sim.model, sim.data)
        start = sim.data.qpos.copy()
        first = fr.render(sim.data).copy()
        home = fr.camera
        for lookat in ((20.0, 0.0, 0.0), (0.0, -35.0, 0.0)):
            fr.camera = mujoco.MjvCamera()
            fr.camera.lookat[:], fr.camera.distance = lookat, 2.0
            fr.render(sim.data)
        fr.camera = home
        sim.data.qpos[:6] = [0.6, -0.8, 0.9, 0.4, -1.0, 0.3]
        mujoco.mj_forward(sim.model, sim.data)
        fr.render(sim.data)
        sim.data.qpos[:] = start
        mujoco.mj_forward(sim.model, sim.data)
        np.testing.assert_array_equal(fr.render(sim.data), first)
    finally:
        fr.close()


@pytest.mark.parametrize(
    "material",
    ['material="m"', 'material="m5"', 'rgba=".5 .5 .5 1"'],
    ids=["repeat 3 4", "repeat 5 5", "no material"],
)
def test_the_floor_is_moved_under_the_camera_exactly_as_the_grid_arithmetic_puts_it(material):
    """Where the plane goes, bit for bit, against the grid's arithmetic written out in NumPy
    (float64, the step as the float32 texture repeat gives it), for cameras near and far from
    the plane's origin, where a float32 re-centring would round otherwise."""
    xml = PLANE_XML.format(uniform="true", size="0 0 .05", light='directional="true"')
    xml = xml.replace('material="m" pos', f"{material} pos").replace(
        "</asset>", '<material name="m5" texture="t" texrepeat="5 5" texuniform="true"/></asset>'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    planes = floor.finite_planes(model)
    assert planes == (0,)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    scene = mujoco.MjvScene(model, maxgeom=100)
    mat = int(model.geom_matid[0])
    rep = model.mat_texrepeat[mat] if mat >= 0 else np.zeros(2)
    scale = np.where(rep > 0, rep, 1.0)
    zfar = float(model.vis.map.zfar * model.stat.extent)
    step = np.where(rep > 0, 2.0 / scale, 2.1 * zfar / (floor.GRID - 2))
    half = model.geom_size[0, :2]
    phase = np.array([(half[0] + 1.0 / scale[0]), (-half[1] - 1.0 / scale[1])]) % (2.0 / scale)
    for lookat in [(2.0, 2.8, 0.0), (2.31, -3.7, 0.0), (40.1, 12.9, 0.0), (-7.77, 25.03, 0.0)]:
        view = mujoco.MjvCamera()
        view.lookat[:], view.distance, view.elevation, view.azimuth = lookat, 3.0, -30.0, 60.0
        mujoco.mjv_updateScene(
            model, data, mujoco.MjvOption(), None, view, mujoco.mjtCatBit.mjCAT_ALL, scene
        )
        (g,) = [scene.geoms[i] for i in range(scene.ngeom) if scene.geoms[i].objid == 0]
        pos, rot = np.array(g.pos, float), np.array(g.mat, float).reshape(3, 3)
        along = rot[:, :2].T @ (floor.head(scene) - pos)
        centre = 2.0 * step * np.floor(0.5 * along / step + 0.5)
        floor.as_infinite(scene, model, planes)
        expected = (pos + rot[:, :2] @ (centre + phase)).astype(np.float32)  # as a geom keeps it
        assert np.array_equal(np.array(g.pos), expected), lookat
