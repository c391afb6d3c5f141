"""LeRobot 0.6.1's own command-line tools, unchanged, driving the simulated arm: teleoperate with
the motion teleoperator, record a 2-episode dataset with two cameras, reload it, replay an
episode, and roll out a small image policy trained on it.

Everything is offline (``HF_HUB_OFFLINE=1``, see conftest.py) and small (64×48 images, 3 s
episodes). Lockstep mode makes each run's simulated time follow its frames exactly, so the
checks are on simulated time and states, never on how fast this machine is.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.cli

HERE = Path(__file__).parent
BIN = Path(sys.executable).parent
FPS = 30
EPISODE_S = 3
CAMERAS = (
    "{front: {type: so101_sim, width: 64, height: 48}, "
    "wrist: {type: so101_sim, width: 64, height: 48}}"
)
ROBOT = ["--robot.type=so101_sim", "--robot.mode=lockstep", f"--robot.cameras={CAMERAS}"]
QUIET = ["--play_sounds=false"]
REPO_ID = "local/so101_sim_lab"


def run(args: list[str], log: Path, timeout: int = 600) -> str:
    """Run a command; fail with the end of its output if it fails. Returns the output."""
    done = subprocess.run(
        args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=timeout,
        env=os.environ.copy(),
    )  # fmt: skip
    log.write_text(done.stdout)
    assert done.returncode == 0, f"{args[0]} failed ({done.returncode}):\n{done.stdout[-4000:]}"
    return done.stdout


def tool(name: str) -> str:
    """The path of a LeRobot console script in this venv (the README's commands)."""
    path = BIN / name
    return str(path) if path.exists() else shutil.which(name) or name


def probe(log_json: Path, script: str, args: list[str], out: Path) -> dict:
    """Run LeRobot's ``script`` main() with the robot's observations and actions logged."""
    run([sys.executable, str(HERE / "cli_probe.py"), str(log_json), script, *args], out)
    return json.loads(log_json.read_text())


@pytest.fixture(scope="session")
def dataset(tmp_path_factory) -> Path:
    """``lerobot-record``: 2 episodes × 3 s, front and wrist cameras, the motion teleoperator."""
    root = tmp_path_factory.mktemp("datasets") / "lab"
    run(
        [
            tool("lerobot-record"), *ROBOT, "--teleop.type=so101_sim_motion",
            f"--dataset.repo_id={REPO_ID}", f"--dataset.root={root}",
            "--dataset.single_task=the lab motion", "--dataset.num_episodes=2",
            f"--dataset.episode_time_s={EPISODE_S}", "--dataset.reset_time_s=0",
            f"--dataset.fps={FPS}", "--dataset.push_to_hub=false", "--display_data=false", *QUIET,
        ],
        root.parent / "record.log",
    )  # fmt: skip
    return root


def test_teleoperate_plays_the_motion_on_the_sim_with_a_custom_camera(tmp_path):
    top = "{top: {type: so101_sim, width: 32, height: 32, pos: [0.3, 0, 0.6], lookat: [0.1, 0, 0]}}"
    out = run(
        [
            tool("lerobot-teleoperate"), "--robot.type=so101_sim", f"--robot.cameras={top}",
            "--teleop.type=so101_sim_motion", f"--fps={FPS}", "--teleop_time_s=3",
            "--display_data=false",
        ],
        tmp_path / "teleoperate.log",
    )  # fmt: skip
    assert "SO101SimFollower disconnected." in out


def test_record_writes_the_real_followers_features_and_robot_type(dataset):
    info = json.loads((dataset / "meta" / "info.json").read_text())
    assert info["robot_type"] == "so101_sim"
    assert info["total_episodes"] == 2 and info["fps"] == FPS
    assert info["total_frames"] >= 2 * 10  # frames follow the wall clock: a busy machine has fewer
    keys = [f"{j}.pos" for j in ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex")]
    keys += ["wrist_roll.pos", "gripper.pos"]
    features = info["features"]
    assert features["observation.state"]["names"] == keys == features["action"]["names"]
    for cam in ("front", "wrist"):
        assert features[f"observation.images.{cam}"]["shape"] == [48, 64, 3]
        assert list((dataset / "videos" / f"observation.images.{cam}").rglob("*.mp4"))


def test_the_dataset_reloads_with_its_features_and_image_shapes(dataset):
    from lerobot.datasets import LeRobotDataset

    ds = LeRobotDataset(REPO_ID, root=dataset)
    assert ds.meta.robot_type == "so101_sim" and ds.num_episodes == 2
    frame = ds[len(ds) - 1]
    assert tuple(frame["observation.state"].shape) == (6,) == tuple(frame["action"].shape)
    for cam in ("front", "wrist"):
        image = frame[f"observation.images.{cam}"]
        assert tuple(image.shape) == (3, 48, 64)  # LeRobot's channel-first float images
        assert float(image.std()) > 0.01  # a picture, not a blank frame
    states = ds.hf_dataset.with_format("numpy")["observation.state"]
    assert np.ptp(np.stack(states)[:, 1]) > 10  # the shoulder moved during the recording


def test_replay_of_episode_0_reaches_the_recorded_states_within_1_degree(dataset, tmp_path):
    from lerobot.datasets import LeRobotDataset

    log = probe(
        tmp_path / "replay.json",
        "lerobot_replay",
        [
            *ROBOT,
            f"--dataset.repo_id={REPO_ID}",
            f"--dataset.root={dataset}",
            "--dataset.episode=0",
            *QUIET,
        ],
        tmp_path / "replay.log",
    )
    ds = LeRobotDataset(REPO_ID, root=dataset, episodes=[0])
    recorded = np.stack(ds.hf_dataset.with_format("numpy")["observation.state"])
    names = ds.features["observation.state"]["names"]
    replayed = np.array([[o[n] for n in names] for o in log["observations"]])
    assert len(replayed) == len(recorded) == len(log["actions"])
    assert np.abs(replayed - recorded).max() < 1.0
    times = np.array([o["time"] for o in log["observations"]])
    # lockstep: frame k at k/fps of simulated time, to within half a 2 ms physics step
    np.testing.assert_allclose(times - times[0], np.arange(len(times)) / FPS, atol=0.0011)


def test_rollout_of_a_small_image_policy_trained_on_the_dataset(dataset, tmp_path):
    policy = tmp_path / "policy"
    train = [sys.executable, str(HERE / "train_tiny_act.py"), "--root", str(dataset)]
    out = run([*train, "--repo-id", REPO_ID, "--out", str(policy)], tmp_path / "train.log")
    assert "observation.images.front, observation.images.wrist" in out
    log = probe(
        tmp_path / "rollout.json",
        "lerobot_rollout",
        [
            *ROBOT,
            "--strategy.type=base",
            f"--policy.path={policy}",
            "--device=cpu",
            "--task=the lab motion",
            "--duration=3",
            f"--fps={FPS}",
            *QUIET,
        ],
        tmp_path / "rollout.log",
    )
    assert len(log["actions"]) >= 5
    first = log["observations"][0]
    for cam in ("front", "wrist"):
        assert first[cam]["shape"] == [48, 64, 3] and first[cam]["dtype"] == "uint8"
    assert all(np.isfinite(list(a.values())).all() for a in log["actions"])
