import numpy as np
import pytest

from so101sim.errors import CameraError, ModelError
from so101sim.recording import FrameRenderer, VideoSettings
from so101sim.recording.draft import render_model
from so101sim.scenes import PRESET_CAMERAS, build_model, camera, camera_names
from so101sim.simulation import Simulation
from so101sim.units import ZERO_POSE


def test_preset_cameras_are_added_at_load_time_and_physics_is_unchanged():
    m = build_model([camera("front"), camera("wrist")])
    assert set(camera_names(m)) == {"front", "wrist"}
    plain, cams = Simulation(), Simulation(m)
    a, b = plain.move_to(ZERO_POSE, 1.0), cams.move_to(ZERO_POSE, 1.0)
    np.testing.assert_array_equal(a.measured, b.measured)  # cameras change no physics


def test_the_wrist_camera_moves_with_the_gripper_and_the_front_one_does_not():
    m = build_model([camera("front", width=64, height=48), camera("wrist", width=64, height=48)])
    sim = Simulation(m)
    shots = {}
    for name in ("front", "wrist"):
        r = FrameRenderer(m, VideoSettings(width=64, height=48, camera=name, caption=False))
        before = r.render(sim.data).copy()
        sim.set_pose({**ZERO_POSE, "shoulder_pan": 40.0})
        after = r.render(sim.data).copy()
        sim.reset()
        r.close()
        shots[name] = (before, after)
        assert before.shape == (48, 64, 3) and before.dtype == np.uint8
        assert before.std() > 5  # not a blank frame
    assert np.abs(shots["wrist"][0].astype(int) - shots["wrist"][1]).mean() > 5  # it moved


def test_draft_render_model_of_a_built_scene_uses_the_simplified_meshes():
    m = build_model([camera("front")])
    draft = render_model(m, "draft", 64, 64)
    assert draft.nmesh > 0 and draft.mesh_face.shape[0] < m.mesh_face.shape[0] / 2
    assert "front" in camera_names(draft)


def test_custom_cameras_and_their_errors():
    cam = camera("side", pos=(0.0, -0.5, 0.2), lookat=(0.1, 0.0, 0.1), fovy=50)
    assert "side" in camera_names(build_model([cam]))
    with pytest.raises(CameraError, match="give its pos and lookat"):
        camera("top")
    with pytest.raises(CameraError, match="given twice"):
        build_model([camera("front"), camera("front")])
    with pytest.raises(CameraError, match="width"):
        camera("front", width=10**9)
    with pytest.raises(CameraError, match="body"):
        camera("front", body="elbow")
    with pytest.raises(CameraError, match="looks at its own position"):
        camera("x", pos=(0, 0, 0), lookat=(0, 0, 0))
    with pytest.raises(ModelError):
        build_model([], model="/nonexistent/scene.xml")
    assert set(PRESET_CAMERAS) == {"front", "wrist"}
