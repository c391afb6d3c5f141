import copy
import os
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from so101sim.cli.runplan import Outputs, prepare_run
from so101sim.model import load_model, scene_path
from so101sim.model import trim as modeltrim
from so101sim.model.build import compile_spec
from so101sim.motion import LAB_MOTION, run_segments
from so101sim.sim.simulation import Simulation


@pytest.fixture(scope="module")
def full():
    return mujoco.MjModel.from_xml_path(str(scene_path()))


@pytest.fixture(scope="module")
def trimmed(full):
    model = modeltrim.physics_only(
        mujoco.MjSpec.from_file(str(scene_path())), full, compile_spec=compile_spec
    )
    assert model is not None
    return model


def test_the_physics_only_model_drops_the_visual_geoms_and_keeps_hulls(full, trimmed):
    assert full.nmeshface > 300_000 and full.nbvh > 600_000
    assert modeltrim.is_physics_only(trimmed) and not modeltrim.is_physics_only(full)
    colliding = (full.geom_contype | full.geom_conaffinity) != 0
    assert trimmed.ngeom == colliding.sum() < full.ngeom  # only the visual geoms dropped
    assert ((trimmed.geom_contype | trimmed.geom_conaffinity) != 0).all()
    assert trimmed.nmeshface < full.nmeshface / 5 and trimmed.nbvh < full.nbvh / 5
    assert mujoco.mj_sizeModel(trimmed) < mujoco.mj_sizeModel(full) / 3
    # what the dynamics read is the same array for array
    for name in ("body_mass", "body_inertia", "body_ipos", "jnt_range", "actuator_gainprm"):
        np.testing.assert_array_equal(getattr(trimmed, name), getattr(full, name), err_msg=name)
    assert str(trimmed.opt) == str(full.opt)
    # each collision mesh is its hull, in the same place: the hull's box in the world, and its
    # vertex count (qhull may merge a few all but coplanar ones the second time)
    summaries = [_hull_summaries(full), _hull_summaries(trimmed)]
    for (n_full, box_full), (n_trim, box_trim) in zip(*summaries, strict=True):
        assert abs(n_full - n_trim) <= 0.01 * n_full
        np.testing.assert_allclose(box_full, box_trim, atol=1e-9)


def _hull_summaries(model):
    """For each colliding mesh geom: its hull's vertex count, and the world box of those
    vertices at the rest pose."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    out = []
    for g in np.flatnonzero((model.geom_contype | model.geom_conaffinity) != 0):
        if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        mesh = model.geom_dataid[g]
        polys = range(model.mesh_polyadr[mesh], model.mesh_polyadr[mesh] + model.mesh_polynum[mesh])
        hull = set()
        for p in polys:
            start = model.mesh_polyvertadr[p]
            hull.update(model.mesh_polyvert[start : start + model.mesh_polyvertnum[p]].tolist())
        local = model.mesh_vert[model.mesh_vertadr[mesh] + np.array(sorted(hull))]
        world = local @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        out.append((len(hull), np.concatenate([world.min(0), world.max(0)])))
    return out


def _rollout(model, seed=3, steps=6000):
    """Random targets held 0.4 s each: the arm hits the floor and itself."""
    d = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    lo, hi = model.actuator_ctrlrange.T
    rows, contacts = [], []
    for k in range(steps):
        if k % 200 == 0:
            d.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, d)
        contacts.append(d.ncon)
        rows.append(np.concatenate([[d.time], d.qpos, d.qvel]))
    return np.array(rows), np.array(contacts)


def test_the_physics_is_the_same_before_and_after_contacts(full, trimmed):
    a, contacts = _rollout(full)
    b, contacts_trimmed = _rollout(trimmed)
    assert contacts.max() >= 2  # the run touched something
    first = int(np.argmax(contacts > 0))
    assert first > 100
    np.testing.assert_array_equal(a[:first], b[:first])  # step for step until a touch
    np.testing.assert_array_equal(contacts[: first + 1], contacts_trimmed[: first + 1])
    # with contacts, only rounding differs (a hull's frame sits at its own centre), which 12 s
    # of slamming into the floor and itself grows to a few milliradians (5.6 mrad measured)
    np.testing.assert_allclose(a[:, 1:7], b[:, 1:7], atol=0.02, rtol=0)  # qpos, radians
    assert ((contacts > 0) == (contacts_trimmed > 0)).mean() > 0.98  # touching at the same steps
    traces = []
    for m in (full, trimmed):
        r = run_segments(Simulation(m), LAB_MOTION, trace=True)
        traces.append(np.vstack([s.measured for s in r.segments]))
    np.testing.assert_array_equal(traces[0], traces[1])


def test_the_shipped_spec_is_left_as_it_was(full):
    spec = mujoco.MjSpec.from_file(str(scene_path()))
    before = spec.to_xml()
    assert modeltrim.physics_only(spec, full, compile_spec=compile_spec) is not None
    assert spec.to_xml() == before


def test_a_model_with_a_flex_keeps_the_full_model():
    flex = mujoco.MjModel.from_xml_string(
        """<mujoco><worldbody><flexcomp name="f" type="grid" count="3 3 1" spacing=".1 .1 .1"
        dim="2"/></worldbody></mujoco>"""
    )
    spec = mujoco.MjSpec.from_string(
        """<mujoco><worldbody><flexcomp name="f" type="grid" count="3 3 1" spacing=".1 .1 .1"
        dim="2"/></worldbody></mujoco>"""
    )
    assert flex.nflex == 1 and modeltrim.physics_only(spec, compile_spec=compile_spec) is None
    assert "flex" in modeltrim.why_not(flex)


def _scene_with(extra_body: str = "", extension: str = "", sensors: str = "") -> mujoco.MjSpec:
    spec = mujoco.MjSpec.from_file(str(scene_path()))
    xml = spec.to_xml()
    xml = xml.replace("<worldbody>", f"{extension}<worldbody>{extra_body}", 1)
    xml = xml.replace(
        "</mujoco>", f"<sensor>{sensors}</sensor></mujoco>" if sensors else "</mujoco>"
    )
    assets = {}
    for mesh in spec.meshes:
        path = scene_path().parent / "assets" / mesh.file
        assets[mesh.file] = path.read_bytes()
    return mujoco.MjSpec.from_string(xml, assets=assets)


def test_ray_casting_sensors_and_sdf_plugins_keep_the_full_model():
    ranged = _scene_with(
        extra_body='<site name="eye" pos="0 0 0.5" zaxis="0 0 -1"/>',
        sensors='<rangefinder site="eye"/>',
    )
    assert (
        modeltrim.physics_only(ranged, compile_spec=compile_spec) is None
    )  # rangefinders cast rays at the meshes
    assert "RANGEFINDER" in modeltrim.why_not(ranged.compile())
    touching = _scene_with(
        extra_body='<site name="pad" pos="0 0 0.5" size="0.01"/>',
        sensors='<framepos objtype="site" objname="pad"/>',
    )
    assert modeltrim.why_not(touching.copy().compile()) is None
    assert modeltrim.is_physics_only(modeltrim.physics_only(touching, compile_spec=compile_spec))
    sdf = _scene_with(
        extension='<extension><plugin plugin="mujoco.sdf.torus"><instance name="torus">'
        '<config key="radius1" value="0.05"/><config key="radius2" value="0.01"/></instance>'
        '</plugin></extension><asset><mesh name="torus"><plugin instance="torus"/></mesh></asset>',
        extra_body='<body pos="0.3 0 0.3"><freejoint/><geom type="sdf" mesh="torus">'
        '<plugin instance="torus"/></geom></body>',
    )
    assert (
        modeltrim.physics_only(sdf, compile_spec=compile_spec) is None
        and modeltrim.why_not(sdf.compile()) is not None
    )


def test_an_unexpected_error_while_trimming_keeps_the_full_model(full, monkeypatch, caplog):
    def broken(model, mesh_id):
        raise KeyError("mesh_polyvert")  # e.g. a field another MuJoCo renamed

    monkeypatch.setattr(modeltrim, "_hull_vertices", broken)
    with caplog.at_level("DEBUG", logger="so101sim.model.trim"):
        assert (
            modeltrim.physics_only(
                mujoco.MjSpec.from_file(str(scene_path())), full, compile_spec=compile_spec
            )
            is None
        )
    assert "keeping the full model" in caplog.text


def test_load_model_physics_only_comes_from_its_own_cache_entry(tmp_path, monkeypatch):
    import so101sim.model.build as model_module

    monkeypatch.setenv("SO101SIM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(model_module, "_built", {})
    m = load_model(physics_only=True)
    assert modeltrim.is_physics_only(m) and m.nmeshface < 100_000
    assert len(list((tmp_path / "cache").glob("*-physics*.mjb"))) == 1
    monkeypatch.setattr(model_module, "_built", {})
    assert modeltrim.is_physics_only(load_model(physics_only=True))  # read back from the entry
    assert not modeltrim.is_physics_only(load_model())  # the full model is another entry
    monkeypatch.setattr(model_module, "_built", {})
    monkeypatch.setenv("SO101SIM_NO_CACHE", "1")
    assert not modeltrim.is_physics_only(load_model(physics_only=True))  # no cache: full


def test_a_run_that_draws_nothing_uses_the_physics_only_model(tmp_path):
    quiet = prepare_run(LAB_MOTION, headless=True)
    assert modeltrim.is_physics_only(quiet.sim.model)
    video = prepare_run(LAB_MOTION, headless=True, outputs=Outputs(video=tmp_path / "a.mp4"))
    assert not modeltrim.is_physics_only(video.sim.model)  # it is drawn: the full model
    mine = load_model()
    assert prepare_run(LAB_MOTION, headless=True, model=mine).sim.model is mine


@pytest.mark.slow
def test_a_headless_command_loads_no_opengl_backend():
    code = (
        "import os; from so101sim import gl; print(gl.skip_opengl());"
        "import mujoco; print(os.environ['MUJOCO_GL'], gl.skip_opengl())"
    )
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "disable", "False"]
    env["MUJOCO_GL"] = "egl"  # a user's choice is kept
    out = subprocess.run(
        [sys.executable, "-c", code.replace("os.environ['MUJOCO_GL']", "'-'")],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.stdout.split() == ["False", "-", "False"], out.stderr


def test_drawing_a_physics_only_model_draws_the_full_one_or_says_why(tmp_path):
    from so101sim.errors import SettingError
    from so101sim.recording import render_model
    from so101sim.viewer import open_viewer

    physics = load_model(physics_only=True)
    physics_data = mujoco.MjData(physics)
    assert modeltrim.is_physics_only(physics)
    drawn = render_model(physics, "full", 64, 48)
    assert not modeltrim.is_physics_only(drawn) and drawn.ngeom > physics.ngeom
    assert (drawn.nq, drawn.nbody) == (physics.nq, physics.nbody)
    assert not modeltrim.is_physics_only(render_model(physics, "draft", 64, 48))
    stray = copy.copy(physics)  # not from load_model: no file to draw instead
    with pytest.raises(SettingError, match="physics_only=True"):
        render_model(stray, "full", 64, 48)
    with pytest.raises(SettingError, match="mirror=True"), open_viewer(physics, physics_data):
        pass


def test_the_recording_package_still_shows_its_modules():
    code = (
        "import so101sim.recording as r; import sys;"
        "print(r.recorder.__name__, r.video.__name__, 'so101sim.recording.plot' in sys.modules);"
        "print(r.plot_run.__module__)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [
        "so101sim.recording.recorder",
        "so101sim.recording.video",
        "True",  # the recorder imports the plot
        "so101sim.recording.plot",
    ]
