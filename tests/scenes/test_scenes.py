import math

import mujoco
import numpy as np
import pytest

from so101sim.errors import CameraError, ModelError, SettingError
from so101sim.model import load_model
from so101sim.recording import FrameRenderer, VideoSettings
from so101sim.recording.draft import render_model
from so101sim.scenes import (
    PRESET_CAMERAS,
    SCENE_PRESETS,
    SEPARATION_GAP_M,
    SceneObject,
    Table,
    TableScene,
    VisualJitter,
    VisualRandomizer,
    build_model,
    build_scene,
    camera,
    camera_names,
    object_pose,
    place_objects,
    preset_scene,
    sample_placements,
    scene_from_dict,
    scene_of,
)
from so101sim.sim.simulation import Simulation
from so101sim.units import STARTING_POSE, ZERO_POSE


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


# ---------------------------------------------------------------------------- table-top scenes


def _geom_id(m, name):
    return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)


def test_preset_scenes_add_a_table_and_free_objects_without_touching_the_arm():
    lab = load_model()
    m = build_scene(preset_scene("cube_to_bowl"))
    assert m.nq == lab.nq + 14 and m.nu == lab.nu  # two free bodies, no new actuator
    assert _geom_id(m, "table_top") >= 0 and m.geom_pos[_geom_id(m, "floor")][2] == -0.75
    assert scene_of(m).name == "cube_to_bowl"
    # the table's top is z = 0, where the base stands; the cube stands on it
    top = _geom_id(m, "table_top")
    assert m.geom_pos[top][2] + m.geom_size[top][2] == 0.0
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert object_pose(m, d, "cube")[2] == 0.0125
    # the lab scene is the shipped file, untouched: same gains, same contact bits
    assert m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC and lab.opt.cone == 0
    np.testing.assert_array_equal(m.actuator_gainprm, lab.actuator_gainprm)
    np.testing.assert_array_equal(m.actuator_forcerange, lab.actuator_forcerange)
    np.testing.assert_array_equal(m.dof_damping[:6], lab.dof_damping)


def test_the_arm_moves_as_in_the_lab_scene_when_it_touches_nothing():
    m = build_scene(preset_scene("pick_cube"))
    lab, tabletop = Simulation(), Simulation(m)
    a, b = lab.move_to(ZERO_POSE, 1.0), tabletop.move_to(ZERO_POSE, 1.0)
    np.testing.assert_allclose(a.measured, b.measured, atol=1e-6)
    c = Simulation(build_model())  # no objects, no table: bit for bit the lab scene
    np.testing.assert_array_equal(a.measured, c.move_to(ZERO_POSE, 1.0).measured)


def test_objects_of_every_shape_stand_still_on_the_table():
    shapes = {
        "box": (0.03, 0.02, 0.04),
        "cylinder": (0.03, 0.05),
        "sphere": (0.03,),
        "bowl": (0.1, 0.04),
        "open_box": (0.1, 0.08, 0.04),
    }
    objs = tuple(
        SceneObject(f"o_{s}", shape=s, size=size, mass=0.05, pos=(0.35, -0.3 + 0.15 * i))
        for i, (s, size) in enumerate(shapes.items())
    )
    m = build_scene(TableScene(objects=objs))
    sim = Simulation(m)
    before = {o.name: object_pose(m, sim.data, o.name) for o in objs}
    sim.hold(1.0)
    for o in objs:
        p = object_pose(m, sim.data, o.name)
        assert np.linalg.norm(p[:3] - before[o.name][:3]) < 5e-4, o.name
        assert abs(p[2] - o.height / 2) < 5e-4, o.name  # resting on z = 0, not sunk
    total = sum(m.body_mass[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, o.name)] for o in objs)
    assert math.isclose(total, 0.25, rel_tol=1e-9)


def test_start_poses_are_drawn_from_a_seed_inside_their_ranges_and_apart():
    scene = preset_scene("cube_to_bowl")
    a = sample_placements(scene.objects, 7, scene.keep_out)
    assert a == sample_placements(scene.objects, np.random.default_rng(7), scene.keep_out)
    assert a != sample_placements(scene.objects, 8, scene.keep_out)
    for seed in range(50):
        poses = sample_placements(scene.objects, seed, scene.keep_out)
        for obj in scene.objects:
            x, y, _ = poses[obj.name]
            assert obj.x_range[0] <= x <= obj.x_range[1]
            assert obj.y_range[0] <= y <= obj.y_range[1]
        (cx, cy, _), (bx, by, _) = poses["cube"], poses["bowl"]
        gap = (
            math.hypot(cx - bx, cy - by) - scene.object("cube").radius - scene.object("bowl").radius
        )
        assert gap >= SEPARATION_GAP_M
    # a scene with a seed is compiled with its objects there; place_objects moves them
    m = build_scene(preset_scene("cube_to_bowl", seed=7))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    np.testing.assert_allclose(object_pose(m, d, "cube")[:2], a["cube"][:2])
    place_objects(m, d, {"cube": (0.2, 0.05, 90.0)})
    np.testing.assert_allclose(
        object_pose(m, d, "cube"),
        [0.2, 0.05, 0.0125, *[math.sqrt(0.5), 0, 0, math.sqrt(0.5)]],
        atol=1e-12,
    )
    with pytest.raises(SettingError, match="no start poses keep the objects"):
        crowded = tuple(
            SceneObject(f"c{i}", x_range=(0.2, 0.21), y_range=(0, 0.01)) for i in range(3)
        )
        sample_placements(crowded, 0)


def test_a_motion_file_scene_section_and_its_errors():
    scene = scene_from_dict(
        {
            "preset": "pick_cube",
            "table": "floor",
            "seed": 3,
            "cameras": ["front"],
            "objects": [
                {
                    "name": "can",
                    "shape": "cylinder",
                    "size": [0.04, 0.06],
                    "mass": 0.02,
                    "color": [0.1, 0.8, 0.1],
                    "pos": [0.2, 0.1],
                    "x_range": [0.15, 0.2],
                },
            ],
        }
    )
    assert scene.table.surface == "floor" and [o.name for o in scene.objects] == ["can"]
    assert scene.objects[0].rgba == (0.1, 0.8, 0.1, 1.0) and 0.15 <= scene.objects[0].pos[0] <= 0.2
    m = build_scene(scene)
    assert _geom_id(m, "table_top") < 0 and "front" in camera_names(m)
    assert (
        scene_from_dict({"preset": "cube_to_bowl"}).objects == SCENE_PRESETS["cube_to_bowl"].objects
    )
    bad = [
        ({"shelf": 1}, "unknown key 'shelf' in \\[scene\\]"),
        ({"preset": "juggle"}, "unknown scene preset 'juggle'"),
        ({"objects": [{"name": "c", "mass": 0}]}, "object 'c' mass = 0.0 kg is invalid"),
        ({"objects": [{"name": "c", "size": 2.0}]}, "object 'c' size = 2.0 m is invalid"),
        ({"objects": [{"name": "c", "shape": "cone"}]}, "unknown object 'c' shape 'cone'"),
        ({"objects": [{"name": "c", "colour": [1, 0, 0]}]}, "unknown key 'colour'"),
        ({"objects": [{"name": "c"}, {"name": "c"}]}, "object 'c' is given twice"),
        ({"objects": [{"name": "floor"}]}, "taken by the model"),
        (
            {"objects": [{"name": "b", "shape": "bowl", "size": [0.02, 0.02], "wall": 0.01}]},
            "leaves no room inside",
        ),
        ({"table": {"height": 9}}, "table height = 9.0 m is invalid"),
        ({"objects": [{"name": "c", "x_range": [0.3, 0.2]}]}, "low <= high"),
        ({"seed": -1}, "seed = -1"),
    ]
    for d, match in bad:
        with pytest.raises(SettingError, match=match):
            build_scene(scene_from_dict(d))


def test_visual_jitter_changes_colours_lights_and_cameras_from_the_original_look():
    m = build_scene(preset_scene("pick_cube", cameras=["front"]))
    cube = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "cube")
    rgba, cam, light = m.geom_rgba[cube].copy(), m.cam_pos.copy(), m.light_diffuse.copy()
    jit = VisualRandomizer([m], scene_of(m), VisualJitter(color=0.2, light=0.3, camera_m=0.02))
    rng = np.random.default_rng(0)
    for _ in range(20):  # draws never pile up: always within the bounds of the original
        jit.apply(rng)
        assert np.abs(m.geom_rgba[cube, :3] - rgba[:3]).max() <= 0.2 + 1e-12
        assert np.abs(m.cam_pos - cam).max() <= 0.02 + 1e-12
    assert not np.allclose(m.light_diffuse, light) and m.geom_rgba[cube, 3] == rgba[3]
    with pytest.raises(SettingError, match="camera jitter"):
        VisualJitter(camera_m=5.0).validated()


def test_an_object_scene_is_drawn_with_draft_meshes_and_shows_the_cube():
    m = build_scene(preset_scene("pick_cube", cameras=["front"]))
    draft = render_model(m, "draft", 64, 64)
    assert draft.nq == m.nq and draft.mesh_face.shape[0] < m.mesh_face.shape[0] / 2
    sim = Simulation(m, initial_pose=STARTING_POSE)
    place_objects(m, sim.data, {"cube": (0.25, 0.0, 0.0)})
    r = FrameRenderer(m, VideoSettings(width=96, height=64, camera="front", caption=False))
    frame = r.render(sim.data).astype(int)
    r.close()
    red = (frame[..., 0] > 150) & (frame[..., 1] < 80) & (frame[..., 2] < 80)
    assert red.sum() >= 4  # the red cube is in the picture


def test_table_and_contact_settings_are_checked():
    with pytest.raises(SettingError, match="table surface"):
        Table(surface="sofa").validated()
    from so101sim.scenes import ContactSettings

    with pytest.raises(SettingError, match="condim = 2"):
        ContactSettings(condim=2).validated()
    with pytest.raises(SettingError, match="solref time constant"):
        ContactSettings(solref=(0.0001, 1.0)).validated()
    with pytest.raises(SettingError, match="contact cone"):
        ContactSettings(cone="round").validated()


def test_drawn_start_poses_keep_clear_of_the_folded_arm():
    # The folded rest pose's gripper lies on the table in front of the base: a bowl drawn
    # there used to start inside it and be thrown off at the first step.
    for name in SCENE_PRESETS:
        scene = preset_scene(name)
        m = build_scene(scene)
        sim = Simulation(m)  # the arm in its folded rest pose
        base = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "base")
        arm = {b for b in range(m.nbody) if m.body_rootid[b] == base}
        objects = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, o.name) for o in scene.objects}
        for seed in range(40):
            place_objects(m, sim.data, sample_placements(scene.objects, seed, scene.keep_out))
            for c in sim.data.contact[: sim.data.ncon]:
                pair = {int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])}
                assert not (pair & arm and pair & objects), (name, seed)
    with pytest.raises(SettingError, match="keep_out rectangle"):
        TableScene(keep_out=((0.1, 0.0, 0.0, 0.1),)).validated()
