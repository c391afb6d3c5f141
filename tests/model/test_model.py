import copy

import mujoco
import numpy as np
import pytest

from so101sim.errors import ModelError
from so101sim.model import arm_index, default_units, load_model, model_dir, scene_path
from so101sim.units import JOINT_NAMES, STARTING_POSE


def test_the_official_model_ships_in_the_package():
    d = model_dir()
    for name in ("scene.xml", "so101_new_calib.xml", "LICENSE", "PROVENANCE.md", "README.md"):
        assert (d / name).is_file(), name
    assert len(list((d / "assets").glob("*.stl"))) == 13
    assert scene_path() == d / "scene.xml"


def test_load_model_compiles_once_per_process():
    assert load_model() is load_model()
    assert load_model(scene_path()) is load_model()


def test_model_facts():
    m = load_model()
    assert m.opt.timestep == 0.002
    assert m.nu == 6
    idx = arm_index(m)
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(j)) for j in range(m.njnt)]
    assert [names[i] for i in range(6)] == list(JOINT_NAMES)
    np.testing.assert_array_equal(idx.qpos, np.arange(6))
    np.testing.assert_array_equal(idx.actuator, np.arange(6))
    # the parsed (not compiled) limits used for unit conversion equal the compiled ones
    np.testing.assert_allclose(default_units().lower, idx.lower, rtol=0, atol=1e-12)
    np.testing.assert_allclose(default_units().upper, idx.upper, rtol=0, atol=1e-12)


def test_missing_file(tmp_path):
    with pytest.raises(ModelError, match="does not exist"):
        load_model(tmp_path / "nope.xml")


def test_file_that_does_not_compile(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><geom type='sphere'/></worldbody>")
    with pytest.raises(ModelError, match="does not compile"):
        load_model(bad)


def test_model_without_the_arm(tmp_path):
    other = tmp_path / "ball.xml"
    other.write_text(
        "<mujoco><worldbody><body><joint name='j'/><geom size='.1'/></body></worldbody></mujoco>"
    )
    with pytest.raises(ModelError, match="shoulder_pan"):
        load_model(other)


def test_starting_pose_is_not_in_collision():
    m = copy.copy(load_model())
    m.geom_margin[:] = 0.003  # nothing within 3 mm either
    d = mujoco.MjData(m)
    d.qpos[:6] = default_units().to_radians(default_units().pose_to_array(STARTING_POSE))
    mujoco.mj_forward(m, d)
    assert d.ncon == 0


def test_a_folder_or_device_as_model_says_so(tmp_path):
    from so101sim.model import load_model

    for bad in (tmp_path, "/dev/null"):
        with pytest.raises(ModelError, match="not a regular file"):
            load_model(bad)
