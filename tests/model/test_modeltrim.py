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
from so101sim.motion import LAB_MOTION, run_segments
from so101sim.sim.simulation import Simulation


@pytest.fixture(scope="module")
def full():
    return mujoco.MjModel.from_xml_path(str(scene_path()))


@pytest.fixture(scope="module")
def trimmed(full):
    data = modeltrim.physics_only(full)
    assert data is not None
    return mujoco.MjModel.from_binary_path("m.mjb", {"m.mjb": data})


def test_the_physics_only_model_drops_the_mesh_faces_and_trees_and_nothing_else(full, trimmed):
    assert full.nmeshface > 300_000 and full.nbvh > 600_000
    assert trimmed.nmeshface == 0
    assert trimmed.nbvh == max(
        a + n for a, n in zip(full.body_bvhadr, full.body_bvhnum, strict=True)
    )
    assert (trimmed.mesh_bvhnum == 0).all() and (trimmed.mesh_facenum == 0).all()
    # the bodies' trees (the collision mid-phase) are kept as they were
    np.testing.assert_array_equal(trimmed.bvh_aabb, full.bvh_aabb[: trimmed.nbvh])
    np.testing.assert_array_equal(trimmed.bvh_child, full.bvh_child[: trimmed.nbvh])
    np.testing.assert_array_equal(trimmed.bvh_nodeid, full.bvh_nodeid[: trimmed.nbvh])
    compared = 0
    for name in dir(full):
        value = getattr(full, name, None)
        if name.startswith("_") or name in modeltrim.TRIMMED or not isinstance(value, np.ndarray):
            continue
        np.testing.assert_array_equal(getattr(trimmed, name), value, err_msg=name)
        compared += 1
    assert compared > 300
    assert mujoco.mj_sizeModel(trimmed) < mujoco.mj_sizeModel(full) / 4


def _rollout(model, seed=3, steps=6000):
    """Random targets held 0.4 s each: the arm hits the floor and itself."""
    d = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    lo, hi = model.actuator_ctrlrange.T
    rows, contacts = [], 0
    for k in range(steps):
        if k % 200 == 0:
            d.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, d)
        contacts = max(contacts, d.ncon)
        rows.append(np.concatenate([[d.time, d.ncon], d.qpos, d.qvel, d.qacc, d.actuator_force]))
    return np.array(rows), contacts


def test_the_physics_is_bit_for_bit_the_same_with_contacts(full, trimmed):
    a, contacts = _rollout(full)
    b, _ = _rollout(trimmed)
    assert contacts >= 2  # the run touched something
    np.testing.assert_array_equal(a, b)
    traces = []
    for m in (full, trimmed):
        r = run_segments(Simulation(m), LAB_MOTION, trace=True)
        traces.append(np.vstack([s.measured for s in r.segments]))
    np.testing.assert_array_equal(traces[0], traces[1])


@pytest.mark.parametrize("damage", ["drop", "swap", "missing"])
def test_a_layout_it_cannot_read_keeps_the_full_model(full, monkeypatch, tmp_path, caplog, damage):
    header = modeltrim._header_path().read_text()
    depth = next(line for line in header.splitlines() if " bvh_depth," in line)
    child = next(line for line in header.splitlines() if " bvh_child," in line)
    broken = tmp_path / "mjxmacro.h"
    if damage == "drop":  # one array fewer than MuJoCo writes
        broken.write_text(header.replace(depth + "\n", ""))
    elif damage == "swap":  # two arrays in the wrong order
        broken.write_text(header.replace(depth, "@").replace(child, depth).replace("@", child))
    monkeypatch.setattr(modeltrim, "_header_path", lambda: broken)
    modeltrim._macros.cache_clear()
    try:
        with caplog.at_level("DEBUG", logger="so101sim.model.trim"):
            assert modeltrim.physics_only(full) is None
        assert "keeping the full model" in caplog.text
    finally:
        modeltrim._macros.cache_clear()


def test_a_model_with_a_flex_keeps_the_full_model():
    flex = mujoco.MjModel.from_xml_string(
        """<mujoco><worldbody><flexcomp name="f" type="grid" count="3 3 1" spacing=".1 .1 .1"
        dim="2"/></worldbody></mujoco>"""
    )
    assert flex.nflex == 1 and modeltrim.physics_only(flex) is None
    assert "flex" in modeltrim.why_not(flex)


def _scene_with(extra_body: str = "", extension: str = "", sensors: str = "") -> mujoco.MjModel:
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
    return mujoco.MjModel.from_xml_string(xml, assets)


def test_ray_casting_sensors_and_sdf_plugins_keep_the_full_model():
    ranged = _scene_with(
        extra_body='<site name="eye" pos="0 0 0.5" zaxis="0 0 -1"/>',
        sensors='<rangefinder site="eye"/>',
    )
    assert modeltrim.physics_only(ranged) is None  # rangefinders cast rays at the meshes
    assert "RANGEFINDER" in modeltrim.why_not(ranged)
    touching = _scene_with(
        extra_body='<site name="pad" pos="0 0 0.5" size="0.01"/>',
        sensors='<framepos objtype="site" objname="pad"/>',
    )
    assert modeltrim.why_not(touching) is None and modeltrim.physics_only(touching) is not None
    sdf = _scene_with(
        extension='<extension><plugin plugin="mujoco.sdf.torus"><instance name="torus">'
        '<config key="radius1" value="0.05"/><config key="radius2" value="0.01"/></instance>'
        '</plugin></extension><asset><mesh name="torus"><plugin instance="torus"/></mesh></asset>',
        extra_body='<body pos="0.3 0 0.3"><freejoint/><geom type="sdf" mesh="torus">'
        '<plugin instance="torus"/></geom></body>',
    )
    assert modeltrim.physics_only(sdf) is None and modeltrim.why_not(sdf) is not None


def test_an_unexpected_error_while_trimming_keeps_the_full_model(full, monkeypatch):
    def broken(model):
        raise KeyError("bvh_depth")  # e.g. a field another MuJoCo renamed

    monkeypatch.setattr(modeltrim, "_trimmed_mjb", broken)
    assert modeltrim.physics_only(full) is None


def test_load_model_physics_only_comes_from_its_own_cache_entry(tmp_path, monkeypatch):
    import so101sim.model.load as model_module

    monkeypatch.setenv("SO101SIM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(model_module, "_cache", {})
    m = load_model(physics_only=True)
    assert m.nmeshface == 0 and m.nbvh < 100
    assert len(list((tmp_path / "cache").glob("*-physics*.mjb"))) == 1
    monkeypatch.setattr(model_module, "_cache", {})
    assert load_model(physics_only=True).nmeshface == 0  # read back from the entry
    assert load_model().nmeshface > 0  # the full model is another entry
    monkeypatch.setattr(model_module, "_cache", {})
    monkeypatch.setenv("SO101SIM_NO_CACHE", "1")
    assert load_model(physics_only=True).nmeshface > 0  # no cache: the full model


def test_a_run_that_draws_nothing_uses_the_physics_only_model(tmp_path):
    quiet = prepare_run(LAB_MOTION, headless=True)
    assert quiet.sim.model.nmeshface == 0 and modeltrim.is_physics_only(quiet.sim.model)
    video = prepare_run(LAB_MOTION, headless=True, outputs=Outputs(video=tmp_path / "a.mp4"))
    assert video.sim.model.nmeshface > 0  # it is drawn: the full model
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
    assert drawn.nmeshface > 0 and (drawn.nq, drawn.nbody) == (physics.nq, physics.nbody)
    assert render_model(physics, "draft", 64, 48).nmeshface > 0
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
