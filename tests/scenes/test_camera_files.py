"""Cameras of your own (issue 31): a TOML camera file gives a camera's pose and field of view;
``--cameras`` takes presets and such files; the environments and ``expert_frames`` render them
under their own names."""

from __future__ import annotations

import math

import numpy as np
import pytest

from so101sim.envs import expert_frames, make
from so101sim.errors import CameraError, SettingError
from so101sim.scenes import (
    PRESET_CAMERAS,
    CameraSpec,
    camera_name,
    cameras_from_toml,
    load_cameras,
    parse_cameras,
    resolve_cameras,
)

RIG = """
[front]                    # the front preset, moved and narrower
pos = [0.45, 0.0, 0.40]
fovy = 55

[top]                      # a camera of your own, straight above the workspace
pos = [0.20, 0.0, 0.80]
lookat = [0.20, 0.0, 0.0]
up = [1.0, 0.0, 0.0]
fovy = 60
"""


def test_a_camera_file_moves_a_preset_and_adds_a_camera(tmp_path) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(RIG)
    front, top = load_cameras(path)
    assert front.name == "front" and front.pos == (0.45, 0.0, 0.40) and front.fovy == 55
    assert front.lookat == PRESET_CAMERAS["front"].lookat  # fields not given: the preset's
    assert top == CameraSpec("top", pos=(0.2, 0.0, 0.8), lookat=(0.2, 0.0, 0.0),
                             up=(1.0, 0.0, 0.0), fovy=60.0)  # fmt: skip


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[top]\npos = [0, 0, 1]\n", "give its pos and lookat"),
        ("[front]\nfov = 50\n", "unknown field 'fov'"),
        ("[front]\npos = [1, 2]\n", "expected 3 numbers"),
        ("[front]\nfovy = 'wide'\n", "expected a number"),
        ("[front]\nfovy = 400\n", "fovy"),
        ("[front\n", "not valid TOML"),
        ("", "names no camera"),
        ("front = 3\n", "expected a table"),
        ("[top]\npos = [0, 0, 1]\nlookat = [0, 0, 1]\n", "looks at its own position"),
        ("[top]\npos = [0, 0, 1]\nlookat = [0, 0, 0]\nbody = 'elbow'\n", "expected one of"),
    ],
)
def test_a_bad_camera_file_is_refused_saying_what_was_expected(text, message) -> None:
    with pytest.raises(CameraError, match=message):
        cameras_from_toml(text)


def test_a_camera_file_that_is_not_a_file_or_too_large_is_refused(tmp_path) -> None:
    with pytest.raises(CameraError, match="camera file"):
        load_cameras(tmp_path)  # a folder
    big = tmp_path / "big.toml"
    big.write_text("# " + "x" * 70_000 + "\n" + RIG)
    with pytest.raises(CameraError, match="bytes"):
        load_cameras(big)


def test_cameras_option_takes_presets_and_files_in_order(tmp_path) -> None:
    path = tmp_path / "rig.toml"
    path.write_text(RIG.split("[top]")[1].join(["[top]", ""]))  # only the top camera
    cams = parse_cameras(f"wrist,{path}")
    assert [camera_name(c) for c in cams] == ["wrist", "top"]
    with pytest.raises(CameraError, match="not a preset"):
        parse_cameras("wrist,side")
    path.write_text(RIG)
    with pytest.raises(CameraError, match="given twice"):
        parse_cameras(f"front,{path}")  # the file's front and the preset


def test_resolve_sizes_every_camera_and_refuses_a_repeat() -> None:
    top = CameraSpec("top", pos=(0.2, 0.0, 0.8), lookat=(0.2, 0.0, 0.0), up=(1.0, 0.0, 0.0))
    specs = resolve_cameras(["front", top], (48, 64))
    assert [(c.name, c.height, c.width) for c in specs] == [("front", 48, 64), ("top", 48, 64)]
    with pytest.raises(CameraError, match="given twice"):
        resolve_cameras(["front", "front"])


def test_an_environment_renders_a_camera_of_your_own_where_it_was_put() -> None:
    """The top camera sits where it was put, looks straight down with its field of view, and
    its images (at the environment's image size) differ from the front camera's."""
    top = CameraSpec("top", pos=(0.2, 0.0, 0.8), lookat=(0.2, 0.0, 0.0), up=(1.0, 0.0, 0.0),
                     fovy=40.0)  # fmt: skip
    env = make("pick_cube", cameras=["front", top], image_size=(64, 64), object_state=True)
    try:
        obs, _ = env.reset(seed=0)
        assert set(obs["pixels"]) == {"front", "top"}
        assert obs["pixels"]["top"].shape == (64, 64, 3)
        assert not np.array_equal(obs["pixels"]["top"], obs["pixels"]["front"])
        model = env.unwrapped.model
        cam = model.camera("top")
        assert math.isclose(float(model.cam_fovy[cam.id]), 40.0)
        data = env.unwrapped.sim.data
        np.testing.assert_allclose(data.cam_xpos[cam.id], (0.2, 0.0, 0.8), atol=1e-9)
        forward = -data.cam_xmat[cam.id].reshape(3, 3)[:, 2]  # MuJoCo cameras look along -z
        np.testing.assert_allclose(forward, (0.0, 0.0, -1.0), atol=1e-9)
    finally:
        env.close()


def test_an_environment_refuses_an_unknown_camera_name_as_before() -> None:
    with pytest.raises(SettingError, match="unknown camera 'top'"):
        make("pick_cube", cameras=["top"])


def test_expert_frames_store_a_camera_of_your_own_under_its_name() -> None:
    top = CameraSpec("top", pos=(0.2, 0.0, 0.8), lookat=(0.2, 0.0, 0.0), up=(1.0, 0.0, 0.0))
    frames = expert_frames("pick_cube", 3, cameras=["wrist", top], image_size=(32, 48))
    assert set(frames.images) == {"wrist", "top"}
    assert frames.images["top"].shape[1:] == (32, 48, 3)
    assert len(frames.images["top"]) == len(frames.actions)
