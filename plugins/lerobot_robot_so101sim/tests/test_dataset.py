"""``so101sim dataset``: a LeRobotDataset of the scripted expert written through LeRobot's own
writer, loaded by ``LeRobotDataset``, trained on by ``lerobot-train`` unchanged and the policy
evaluated (``so101sim eval``); the same seeds give the same episodes whatever the worker count.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from lerobot.datasets import LeRobotDataset
from lerobot_robot_so101sim.dataset import DatasetSettings, generate_dataset
from test_cli import run, tool

from so101sim.errors import OutputPathError, SettingError
from so101sim.units import STARTING_POSE

START = np.array(list(STARTING_POSE.values()))
KEYS = [f"{j}.pos" for j in STARTING_POSE]
REPO_ID = "local/so101sim"


def columns(root) -> dict[str, np.ndarray]:
    ds = LeRobotDataset(REPO_ID, root=root)
    data = ds.hf_dataset
    out = {k: np.stack(data[k]) for k in ("observation.state", "action")}
    out["observation.environment_state"] = np.stack(data["observation.environment_state"])
    out["episode_index"] = np.asarray(data["episode_index"])
    return out


def test_the_same_seeds_give_the_same_episodes_whatever_the_worker_count(tmp_path):
    settings = dict(
        task="pick_cube", episodes=3, seed=11, environment_state=True, randomize="light"
    )
    one = generate_dataset(DatasetSettings(root=str(tmp_path / "one"), workers=1, **settings))
    two = generate_dataset(DatasetSettings(root=str(tmp_path / "two"), workers=2, **settings))
    assert one.seeds == two.seeds == (11, 12, 13) and one.frames == two.frames
    a, b = columns(tmp_path / "one"), columns(tmp_path / "two")
    metas = [
        json.loads((tmp_path / d / "meta" / "so101sim.json").read_text()) for d in ("one", "two")
    ]
    assert metas[0]["randomization"] == metas[1]["randomization"]  # recorded, the same draws
    assert sorted(metas[0]["randomization"]) == ["11", "12", "13"]
    assert metas[0]["randomize"] == "light"
    assert metas[0]["servo_model"].startswith("sts3215 (")  # the servo model is named
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    # each episode from its own start: the folded pose, the cube where reset(seed) puts it
    firsts = [np.flatnonzero(a["episode_index"] == e)[0] for e in range(3)]
    for i in firsts:
        np.testing.assert_allclose(a["observation.state"][i], START, atol=0.5)
    assert len({tuple(a["observation.environment_state"][i][:2]) for i in firsts}) == 3
    with pytest.raises(OutputPathError, match="exists"):
        generate_dataset(DatasetSettings(root=str(tmp_path / "one"), **settings))
    with pytest.raises(SettingError, match="episodes"):
        DatasetSettings(root=str(tmp_path / "x"), task="pick_cube", episodes=0).checked()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["one", "two"]  # nothing half-done


def test_a_dataset_stopped_part_way_leaves_nothing_behind(tmp_path):
    """Ctrl-C after an episode was written (LeRobot's writer then holds open files and a
    streaming video encoder): no dataset, and no hidden temporary folder, even after the
    writer is garbage-collected (it finalizes itself then)."""
    import gc

    seen: list[int] = []

    def interrupt_at_the_second(ep) -> None:
        seen.append(ep.seed)
        if len(seen) == 2:
            raise KeyboardInterrupt

    settings = DatasetSettings(root=str(tmp_path / "ds"), task="pick_cube", episodes=3,
                               cameras=("wrist",), image_size=(48, 64), workers=1)  # fmt: skip
    with pytest.raises(KeyboardInterrupt) as stopped:
        generate_dataset(settings, progress=interrupt_at_the_second)
    del stopped  # its traceback holds the writer
    gc.collect()
    assert seen == [0, 1] and list(tmp_path.iterdir()) == []


@pytest.mark.cli
def test_so101sim_dataset_trains_with_lerobot_train_and_evaluates(tmp_path):
    """The CI path: 3 episodes with `so101sim dataset` in the LeRobot venv, read by
    LeRobotDataset, 5 steps of a tiny ACT with `lerobot-train` (CPU), 2 episodes of
    `so101sim eval`."""
    root = tmp_path / "ds"
    out = run(
        [tool("so101sim"), "dataset", "pick_cube", "--episodes", "3", "-o", str(root),
         "--environment-state", "--workers", "2", "--no-progress"],
        tmp_path / "dataset.log",
    )  # fmt: skip
    assert "wrote 3 episodes" in out
    ds = LeRobotDataset(REPO_ID, root=root)
    assert ds.num_episodes == 3 and ds.meta.robot_type == "so101_sim"
    assert ds.features["observation.state"]["names"] == KEYS
    assert ds.features["action"]["names"] == KEYS
    assert ds.features["observation.environment_state"]["shape"] == (7,)
    meta = json.loads((root / "meta" / "so101sim.json").read_text())
    assert meta["episode_seeds"] == [0, 1, 2] and meta["failed_seeds"] == []
    assert meta["settings"]["vcodec"] is None  # no camera: no video, no codec
    frame = ds[0]
    np.testing.assert_allclose(frame["observation.state"].numpy(), START, atol=0.5)
    train = tmp_path / "train"
    run(
        [tool("lerobot-train"), f"--dataset.repo_id={REPO_ID}", f"--dataset.root={root}",
         "--policy.type=act", "--policy.dim_model=32", "--policy.n_heads=2",
         "--policy.dim_feedforward=64", "--policy.n_encoder_layers=1",
         "--policy.n_decoder_layers=1", "--policy.use_vae=false", "--policy.chunk_size=10",
         "--policy.n_action_steps=10", "--policy.pretrained_backbone_weights=null",
         "--policy.device=cpu", "--policy.push_to_hub=false", "--steps=5", "--batch_size=4",
         "--num_workers=0", "--save_freq=5", "--log_freq=1", f"--output_dir={train}",
         "--wandb.enable=false"],
        tmp_path / "train.log",
    )  # fmt: skip
    policy = train / "checkpoints" / "last" / "pretrained_model"
    assert (policy / "model.safetensors").is_file()
    evaluation = tmp_path / "eval"
    out = run(
        [tool("so101sim"), "eval", str(policy), "--task", "pick_cube", "--episodes", "2",
         "--workers", "2", "--episode-length", "20", "-o", str(evaluation)],
        tmp_path / "eval.log",
    )  # fmt: skip
    report = json.loads((evaluation / "eval.json").read_text())
    assert report["episodes"] == 2 and 0 <= report["successes"] <= 2
    low, high = report["success_interval_95"]
    assert 0.0 <= low <= report["success_rate"] <= high <= 1.0
    assert "success" in out and "Running rollout" not in out  # one bar, not one per episode
    import imageio.v3 as iio

    for ep in report["per_episode"]:
        assert ep["randomization"] is None  # no --randomize: nothing drawn
        if not ep["success"] and ep.get("video"):  # a failure's video: its episode, no more
            assert iio.improps(ep["video"], plugin="pyav").shape[0] == ep["steps"]


def test_a_dataset_over_a_local_ray_with_two_workers_equals_the_local_one(tmp_path):
    """``so101sim dataset --ray``: the episodes as Ray tasks give the dataset the worker
    processes give, seed for seed."""
    pytest.importorskip("ray")
    settings = dict(task="pick_cube", episodes=2, seed=21, environment_state=True)
    local = generate_dataset(DatasetSettings(root=str(tmp_path / "local"), **settings))
    remote = generate_dataset(
        DatasetSettings(root=str(tmp_path / "ray"), use_ray=True, workers=2, **settings)
    )
    assert local.seeds == remote.seeds == (21, 22) and local.frames == remote.frames
    a, b = columns(tmp_path / "local"), columns(tmp_path / "ray")
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    with pytest.raises(SettingError, match="ray_address"):
        DatasetSettings(
            root=str(tmp_path / "x"), task="pick_cube", episodes=1, ray_address=""
        ).checked()


@pytest.mark.cli
def test_an_image_dataset_trains_an_image_policy_that_eval_and_policy_check_take(tmp_path, capsys):
    """The image path: 3 episodes with a camera of the user's own rig (``top``, from a camera
    file) and the wrist preset (the real follower's image keys and state names), 3 steps of a
    tiny image ACT with `lerobot-train`, 1 episode of `so101sim eval` given the same camera
    file (the failure video: the front view beside the policy's two cameras), and
    `so101sim policy-check` on the trained policy against a real follower's configs."""
    root = tmp_path / "ds"
    rig = tmp_path / "rig.toml"
    rig.write_text(  # the real camera's size and frame rate: the dataset records its own
        "[top]\npos = [0.2, 0.0, 0.8]\nlookat = [0.2, 0.0, 0.0]\nfovy = 60\n"
        "width = 320\nheight = 240\nfps = 15\n"
    )
    out = run(
        [tool("so101sim"), "dataset", "pick_cube", "--episodes", "3", "-o", str(root),
         "--cameras", f"{rig},wrist", "--image-size", "64x48", "--workers", "2",
         "--no-progress"],
        tmp_path / "dataset.log",
    )  # fmt: skip
    assert "wrote 3 episodes" in out
    assert "libx264" not in out and "moov atom" not in out  # no encoder or muxer chatter
    meta = json.loads((root / "meta" / "so101sim.json").read_text())
    assert meta["settings"]["cameras"][0]["pos"] == [0.2, 0.0, 0.8]  # the rig, kept with it
    assert meta["settings"]["vcodec"] == "h264"  # the default codec, recorded
    assert [(c["name"], c["width"], c["height"], c["fps"]) for c in meta["cameras"]] == [
        ("top", 64, 48, 30),
        ("wrist", 64, 48, 30),
    ]  # fmt: skip  (as rendered)
    assert "camera 'top': its file gives 320x240; the dataset records it at 64x48" in out
    assert "camera 'top': its file gives 15 fps; the dataset records every camera at 30" in out
    ds = LeRobotDataset(REPO_ID, root=root)
    assert ds.features["observation.state"]["names"] == KEYS
    assert ds.features["action"]["names"] == KEYS
    for cam in ("top", "wrist"):
        assert ds.features[f"observation.images.{cam}"]["shape"] == (48, 64, 3)
    assert "observation.environment_state" not in ds.features
    frame = ds[0]
    assert tuple(frame["observation.images.wrist"].shape) == (3, 48, 64)
    train = tmp_path / "train"
    run(
        [tool("lerobot-train"), f"--dataset.repo_id={REPO_ID}", f"--dataset.root={root}",
         "--policy.type=act", "--policy.dim_model=32", "--policy.n_heads=2",
         "--policy.dim_feedforward=64", "--policy.n_encoder_layers=1",
         "--policy.n_decoder_layers=1", "--policy.use_vae=false", "--policy.chunk_size=10",
         "--policy.n_action_steps=10", "--policy.pretrained_backbone_weights=null",
         "--policy.device=cpu", "--policy.push_to_hub=false", "--steps=3", "--batch_size=2",
         "--num_workers=0", "--save_freq=3", "--log_freq=1", f"--output_dir={train}",
         "--wandb.enable=false"],
        tmp_path / "train.log",
    )  # fmt: skip
    policy = train / "checkpoints" / "last" / "pretrained_model"
    config = json.loads((policy / "config.json").read_text())
    assert sorted(config["input_features"]) == [
        "observation.images.top", "observation.images.wrist", "observation.state"
    ]  # fmt: skip
    from so101sim.cli.main import main

    capsys.readouterr()
    assert main(["eval", str(policy), "--episodes", "1", "-o", str(tmp_path / "no")]) == 2
    assert "camera file" in capsys.readouterr().err  # where is top? a camera file says
    wrong_rate = ["--fps", "15", "--cameras", str(rig), "-o", str(tmp_path / "no")]
    assert main(["eval", str(policy), "--episodes", "1", *wrong_rate]) == 2
    assert "trained on 30 fps data" in capsys.readouterr().err  # its dataset's meta says
    evaluation = tmp_path / "eval"
    run(
        [tool("so101sim"), "eval", str(policy), "--episodes", "1", "--workers", "1",
         "--episode-length", "8", "--cameras", str(rig), "-o", str(evaluation)],
        tmp_path / "eval.log",
    )  # fmt: skip
    report = json.loads((evaluation / "eval.json").read_text())
    assert report["episodes"] == 1
    assert report["policy"] == str(policy.resolve()) and report["seed"] == 1000
    assert report["fps"] == 30 and report["episode_length"] == 8  # what was run
    assert report["camera_file"] == str(rig)
    import imageio.v3 as iio

    for ep in report["per_episode"]:
        if not ep["success"]:  # the front view (640x480) and each camera scaled to 480 rows
            assert ep["video"], "a failed episode has its video"
            props = iio.improps(ep["video"], plugin="pyav")
            assert props.shape[0] == ep["steps"] and props.shape[1:3] == (480, 640 * 3)

    def robot(name: str, cameras: dict) -> str:
        path = tmp_path / name
        arm = {"type": "so101_follower", "port": "/dev/ttyACM0", "use_degrees": True}
        path.write_text(json.dumps({"robot": {**arm, "cameras": cameras}}))
        return str(path)

    cam = {"type": "opencv", "index_or_path": 0, "width": 64, "height": 48, "fps": 30}
    good = robot("good.json", {"top": cam, "wrist": {**cam, "index_or_path": 1}})
    assert main(["policy-check", str(policy), "--robot-config", good]) == 0
    bad = robot("bad.json", {"top": {**cam, "width": 640, "height": 480}})
    assert main(["policy-check", str(policy), "--robot-config", bad]) == 1


def test_a_slow_video_encoder_loses_no_frame(tmp_path, monkeypatch, caplog):
    """The episodes arrive faster than real time, so on a busy machine LeRobot's video encoder
    falls behind; its queue holds a whole episode, so no frame is dropped (LeRobot drops one
    when the queue stays full for 0.1 s): each video has as many frames as its episode."""
    import threading
    import time

    import av
    from lerobot.datasets import video_utils
    from lerobot_robot_so101sim.writer import Uint8QuantileStats

    update = Uint8QuantileStats.update  # the statistics the encoder threads keep (.writer)

    stalls = []

    def stalled(self, batch):  # each video's encoder thread stalls 0.5 s on its first frame
        encoder = isinstance(threading.current_thread(), video_utils._CameraEncoderThread)
        if encoder and self._count == 0:
            stalls.append(threading.current_thread().name)
            time.sleep(0.5)
        return update(self, batch)

    monkeypatch.setattr(Uint8QuantileStats, "update", stalled)
    root = tmp_path / "ds"
    report = generate_dataset(
        DatasetSettings(
            root=str(root), task="pick_cube", episodes=1, seed=3, cameras=("front", "wrist"),
            image_size=(48, 64),
        )
    )  # fmt: skip
    assert report.frames > 31  # more than LeRobot's default queue (30 frames) holds
    assert len(stalls) == 2  # each camera's encoder did stall
    assert "dropped" not in caplog.text
    for cam in ("front", "wrist"):
        (video,) = (root / "videos" / f"observation.images.{cam}").rglob("*.mp4")
        with av.open(str(video)) as container:
            assert sum(1 for _ in container.decode(video=0)) == report.frames, cam


def test_a_dataset_worker_imports_neither_lerobot_nor_torch():
    """The pool `so101sim dataset` simulates on: its workers run so101sim's core only (this
    plugin's package imports LeRobot and torch, seconds of CPU per worker)."""
    from lerobot_robot_so101sim.episodes import worker_pool
    from worker_probe import loaded

    heavy = ["lerobot", "lerobot_robot_so101sim", "torch"]
    with worker_pool(1) as pool:
        seen = pool.submit(loaded, heavy).result(timeout=600)
    one_thread = os.environ.get("LP_NUM_THREADS", "0")  # the worker keeps one set here
    assert seen == {"imported": [], "LP_NUM_THREADS": one_thread}


@pytest.mark.parametrize(
    ("root", "message"),
    [
        (" ", "path is empty"),
        ("x" * 300, "300 bytes long; expected at most"),
        ("/proc/no-such-folder/ds", "expected a folder you can write to"),
    ],
)
def test_a_dataset_folder_that_cannot_be_written_is_refused_before_anything_runs(
    tmp_path, root, message
):
    path = root if root.startswith(("/", " ")) else str(tmp_path / root)
    with pytest.raises(OutputPathError, match=message):
        generate_dataset(DatasetSettings(root=path, task="pick_cube", episodes=1))
    assert list(tmp_path.iterdir()) == []  # nothing half-done


def test_a_long_legal_dataset_name_leaves_its_temporary_folder_within_the_name_limit(tmp_path):
    name = "d" * 250  # legal (NAME_MAX 255); ".<name>.<random>" would not be
    report = generate_dataset(
        DatasetSettings(root=str(tmp_path / name), task="pick_cube", episodes=1, workers=1)
    )
    assert report.frames > 0
    assert [p.name for p in tmp_path.iterdir()] == [name]


@pytest.mark.parametrize(("vcodec", "stream"), [("h264", "h264"), ("libsvtav1", "av1")])
def test_the_videos_codec_is_the_one_asked_for_and_keeps_the_rendered_frames(
    tmp_path, vcodec, stream
):
    """h264 (the default, fast to write) or AV1 (what lerobot-record writes): LeRobot records
    the codec in info.json, loads the dataset, and its decoded frames stay close to the images
    the episode rendered (compared with the episode simulated again from its seed)."""
    from lerobot_robot_so101sim.episodes import simulate_episode

    root = tmp_path / "ds"
    settings = DatasetSettings(
        root=str(root), task="pick_cube", episodes=1, seed=5, cameras=("front",),
        image_size=(120, 160), vcodec=vcodec,
    )  # fmt: skip
    report = generate_dataset(settings)
    info = json.loads((root / "meta" / "info.json").read_text())
    video = info["features"]["observation.images.front"]["info"]
    assert video["video.codec"] == stream
    if vcodec == "h264":  # the settings chosen for it, as LeRobot records them
        assert (video["video.preset"], video["video.crf"]) == ("ultrafast", 20)
    ds = LeRobotDataset(REPO_ID, root=root)
    raw = simulate_episode(settings, report.seeds[0]).images["front"]
    assert len(ds) == len(raw) == report.frames
    for t in (0, len(raw) // 2, len(raw) - 1):
        decoded = ds[t]["observation.images.front"].numpy().transpose(1, 2, 0) * 255
        mse = np.mean((decoded - raw[t].astype(np.float64)) ** 2)
        psnr = 10 * np.log10(255**2 / mse)
        assert psnr > 27, (t, psnr)  # measured: 30-31 dB for both codecs at 160x120


def test_without_videos_the_frames_are_stored_exactly_and_no_codec_is_recorded(tmp_path):
    """``--no-video``: the images as PNG frames in the data files, decoded to the very pixels
    the episode rendered; the codec given (or the default) is not used, so none is recorded."""
    from lerobot_robot_so101sim.episodes import simulate_episode

    root = tmp_path / "ds"
    settings = DatasetSettings(
        root=str(root), task="pick_cube", episodes=1, seed=5, cameras=("front",),
        image_size=(48, 64), video=False, vcodec="libsvtav1",
    )  # fmt: skip
    report = generate_dataset(settings)
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["features"]["observation.images.front"]["dtype"] == "image"
    assert not (root / "videos").exists()
    meta = json.loads((root / "meta" / "so101sim.json").read_text())
    assert meta["settings"]["video"] is False and meta["settings"]["vcodec"] is None
    ds = LeRobotDataset(REPO_ID, root=root)
    raw = simulate_episode(settings, report.seeds[0]).images["front"]
    assert len(ds) == len(raw) == report.frames
    for t in (0, len(raw) - 1):
        decoded = np.rint(ds[t]["observation.images.front"].numpy().transpose(1, 2, 0) * 255)
        np.testing.assert_array_equal(decoded.astype(np.uint8), raw[t])


def test_an_unknown_video_codec_is_refused():
    with pytest.raises(SettingError, match=r"vcodec.*h264"):
        DatasetSettings(root="x", task="pick_cube", episodes=1, vcodec="vp9").checked()
