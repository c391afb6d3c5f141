"""``so101sim pretrain-backbone``: an image ACT whose backbone learnt the cube's place from a
so101sim dataset's images, written as ``lerobot-train`` saves a checkpoint, that
``lerobot-train --policy.path`` trains on from; its inputs are the joints and the cameras."""

from __future__ import annotations

import json

import numpy as np
import pytest
from lerobot_robot_so101sim.pretrain import PretrainSettings, tip_frame_positions
from test_cli import run, tool

from so101sim.errors import OutputPathError, SettingError
from so101sim.units import STARTING_POSE

REPO_ID = "local/so101sim"


@pytest.fixture(scope="module")
def image_dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("pre") / "ds"
    run(
        [tool("so101sim"), "dataset", "pick_cube", "--episodes", "3", "-o", str(root),
         "--cameras", "front,wrist", "--image-size", "64x48", "--environment-state",
         "--workers", "2", "--no-progress"],
        root.parent / "dataset.log",
    )  # fmt: skip
    return root


def test_a_point_on_the_tip_is_at_the_origin_of_the_tip_frame():
    """The wrist labels: a point at the tip is (0, 0, 0) in its frame, one 5 cm along the
    approach axis is (0.05, 0, 0), whatever the pose."""
    from so101sim.kinematics.core import Kinematics
    from so101sim.scenes import SCENE_PRESETS
    from so101sim.scenes.build import build_scene

    kin = Kinematics(build_scene(SCENE_PRESETS["pick_cube"]))
    poses = np.array([list(STARTING_POSE.values()), [20.0, -40.0, 30.0, 50.0, 10.0, 0.0]])
    points, along = [], []
    for p in poses:
        kin.frame_at(np.radians(p[:5]))
        tip = kin.data.site_xpos[kin.tip_site].copy()
        approach = kin.data.site_xmat[kin.tip_site].reshape(3, 3)[:, 0]
        points.append(tip)
        along.append(tip + 0.05 * approach)
    np.testing.assert_allclose(tip_frame_positions(poses, np.array(points)), 0.0, atol=1e-6)
    np.testing.assert_allclose(
        tip_frame_positions(poses, np.array(along)), [[0.05, 0, 0]] * 2, atol=1e-6
    )


def test_pretrain_writes_a_joints_and_cameras_act_that_lerobot_train_goes_on_from(
    image_dataset, tmp_path
):
    out = tmp_path / "pre"
    log = run(
        [tool("so101sim"), "pretrain-backbone", str(image_dataset), "-o", str(out),
         "--steps", "3", "--batch-size", "4", "--dim-model", "32", "--dim-feedforward", "64",
         "--encoder-layers", "1", "--chunk-size", "10", "--no-progress"],
        tmp_path / "pretrain.log",
    )  # fmt: skip
    assert f"wrote {out} after 3 steps" in log
    config = json.loads((out / "config.json").read_text())
    assert sorted(config["input_features"]) == [
        "observation.images.front",
        "observation.images.wrist",
        "observation.state",
    ]  # fmt: skip  (no object state: nothing a real arm lacks)
    assert config["input_features"]["observation.images.wrist"]["shape"] == [3, 48, 64]
    info = json.loads((out / "pretrain.json").read_text())
    report = info["report"]
    assert report["steps"] == 3 and report["held_out_episodes"] == 1
    assert report["frames"] > 100  # 3 episodes of several seconds at 30 fps
    for key in ("front_error_mm", "wrist_error_mm", "front_baseline_mm", "wrist_baseline_mm"):
        assert np.isfinite(report[key]) and report[key] > 0
    assert 10 < report["front_baseline_mm"] < 300  # the cube's spread over the table
    train = tmp_path / "train"
    run(
        [tool("lerobot-train"), f"--dataset.repo_id={REPO_ID}", f"--dataset.root={image_dataset}",
         f"--policy.path={out}", "--policy.device=cpu", "--policy.push_to_hub=false",
         "--steps=2", "--batch_size=2", "--num_workers=0", "--save_freq=2", "--log_freq=1",
         f"--output_dir={train}", "--wandb.enable=false"],
        tmp_path / "train.log",
    )  # fmt: skip
    trained = train / "checkpoints" / "last" / "pretrained_model"
    from safetensors.numpy import load_file

    before, after = load_file(out / "model.safetensors"), load_file(trained / "model.safetensors")
    key = "model.backbone.conv1.weight"
    assert before[key].shape == after[key].shape
    # trained on from the pretrained backbone (2 steps move it a little), not from scratch
    assert np.abs(after[key] - before[key]).max() < 0.1 * np.abs(before[key]).max()
    assert not np.array_equal(after[key], before[key])


def test_pretrain_refuses_a_dataset_without_the_cubes_pose_and_a_used_folder(
    image_dataset, tmp_path
):
    root = tmp_path / "ds"
    run(
        [tool("so101sim"), "dataset", "pick_cube", "--episodes", "1", "-o", str(root),
         "--cameras", "front,wrist", "--image-size", "32x24", "--workers", "1",
         "--no-progress"],
        tmp_path / "dataset.log",
    )  # fmt: skip
    with pytest.raises(SettingError, match="--environment-state"):
        PretrainSettings(dataset=str(root), output=str(tmp_path / "p")).checked()
    with pytest.raises(SettingError, match=r"meta/info\.json"):
        PretrainSettings(dataset=str(tmp_path), output=str(tmp_path / "p")).checked()
    with pytest.raises(SettingError, match="steps"):
        PretrainSettings(dataset=str(root), output=str(tmp_path / "p"), steps=0).checked()
    with pytest.raises(OutputPathError, match="not an empty folder"):
        PretrainSettings(dataset=str(image_dataset), output=str(root)).checked()
