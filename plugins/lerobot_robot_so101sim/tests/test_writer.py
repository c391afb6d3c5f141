"""LeRobot's writer made to keep up with ``so101sim dataset`` (``lerobot_robot_so101sim.writer``):
the image statistics equal LeRobot's own, the embedding pass is skipped only where it has
nothing to do, both are undone after the block, and a dataset whose videos span several files
loads with each episode's frames where they belong."""

from __future__ import annotations

import json

import datasets
import numpy as np
import pytest
from lerobot.datasets import LeRobotDataset, compute_stats, dataset_writer
from lerobot_robot_so101sim import writer
from lerobot_robot_so101sim.dataset import DatasetSettings, generate_dataset
from lerobot_robot_so101sim.episodes import simulate_episode

REPO_ID = "local/so101sim"


def frames(seed: int, n: int, shape=(120, 160)) -> list[np.ndarray]:
    """Camera-like frames whose range widens and narrows, so LeRobot re-bins its histograms."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        lo, hi = max(0, 90 - 11 * k), min(256, 110 + 13 * k)
        out.append(rng.integers(lo, hi, size=(*shape, 3), dtype=np.uint8))
    out.append(np.full((*shape, 3), 7, dtype=np.uint8))  # one flat frame
    return out


def test_eight_bit_statistics_are_lerobots_own():
    """As LeRobot's streaming encoder feeds them (pixels as rows, channels as columns): the
    minimum, maximum, mean, count and every quantile equal LeRobot's exactly; the standard
    deviation is the exact one to float32 rounding, where LeRobot's, from float32 sums of
    squares, is further off."""
    ours, theirs = writer.Uint8QuantileStats(), compute_stats.RunningQuantileStats()
    for f in frames(0, 12):
        ours.update(f.reshape(-1, 3))
        theirs.update(f.reshape(-1, 3))
    a, b = ours.get_statistics(), theirs.get_statistics()
    exact = np.concatenate([f.reshape(-1, 3) for f in frames(0, 12)]).astype(np.float64).std(0)
    assert sorted(a) == sorted(b)
    for key in a:
        if key == "std":
            np.testing.assert_allclose(a[key], exact, rtol=1e-5)
            np.testing.assert_allclose(b[key], exact, rtol=1e-3)
        else:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
            assert a[key].dtype == b[key].dtype, key
    # anything but 8-bit values goes to LeRobot's own update
    ours, theirs = writer.Uint8QuantileStats(), compute_stats.RunningQuantileStats()
    x = np.random.default_rng(1).normal(size=(500, 6)).astype(np.float32)
    ours.update(x)
    theirs.update(x)
    for key, value in ours.get_statistics().items():
        np.testing.assert_array_equal(value, theirs.get_statistics()[key], err_msg=key)


def test_fast_writer_skips_only_an_embedding_with_nothing_to_embed_and_is_undone(tmp_path):
    stats, embed = compute_stats.RunningQuantileStats, dataset_writer.embed_images
    rows = {"action": np.zeros((4, 6), np.float32), "index": np.arange(4)}
    plain = datasets.Dataset.from_dict(
        rows,
        features=datasets.Features(
            {"action": datasets.Sequence(datasets.Value("float32"), length=6),
             "index": datasets.Value("int64")}
        ),
    )  # fmt: skip
    png = tmp_path / "a.png"
    from PIL import Image

    Image.fromarray(np.full((4, 4, 3), 9, np.uint8)).save(png)
    with_image = datasets.Dataset.from_dict(
        {"image": [str(png)]}, features=datasets.Features({"image": datasets.Image()})
    )
    with writer.fast_writer():
        assert compute_stats.RunningQuantileStats is writer.Uint8QuantileStats
        assert dataset_writer.embed_images(plain) is plain  # the same rows, untouched
        embedded = dataset_writer.embed_images(with_image)  # LeRobot's pass: the bytes put in
        assert embedded is not with_image
        assert embedded.with_format("arrow")[:]["image"][0]["bytes"].as_py() == png.read_bytes()
    assert compute_stats.RunningQuantileStats is stats and dataset_writer.embed_images is embed
    with pytest.raises(RuntimeError), writer.fast_writer():
        raise RuntimeError("undone on an error too")
    assert compute_stats.RunningQuantileStats is stats and dataset_writer.embed_images is embed


def test_video_files_are_sized_from_the_first_episode():
    assert writer.episodes_per_video_file(200, 2) == writer.MIN_EPISODES_PER_VIDEO_FILE == 10
    assert writer.episodes_per_video_file(4000, 2) == 100  # at most 80 files: 40 a camera
    assert writer.video_file_mb(0.22, 10) == 3  # 160x120: about 14 such episodes a file
    assert writer.video_file_mb(1e-6, 10) == 1  # at least 1 MB
    assert writer.video_file_mb(30.0, 10) == 200  # at most LeRobot's default


def test_a_dataset_over_several_video_files_loads_each_episode_from_its_own(tmp_path, monkeypatch):
    """Files sized to hold one episode (so each episode starts a new one): the dataset loads,
    says so in info.json, and each episode's first and last images are that episode's."""
    monkeypatch.setattr(writer, "video_file_mb", lambda mb, per_file: 1.5 * mb)
    root = tmp_path / "ds"
    settings = DatasetSettings(
        root=str(root), task="pick_cube", episodes=3, seed=5, cameras=("front",),
        image_size=(48, 64), workers=1,
    )  # fmt: skip
    report = generate_dataset(settings)
    files = sorted((root / "videos" / "observation.images.front").rglob("*.mp4"))
    assert len(files) == 3
    info = json.loads((root / "meta" / "info.json").read_text())
    first = files[0].stat().st_size / 1024**2
    assert info["video_files_size_in_mb"] == pytest.approx(1.5 * first, rel=1e-6)
    ds = LeRobotDataset(REPO_ID, root=root)
    assert ds.num_episodes == 3 and ds.num_frames == report.frames
    recorded = {s: simulate_episode(settings, s).images["front"] for s in report.seeds}
    start = 0
    for seed, images in recorded.items():
        for t in (0, len(images) - 1):
            got = ds[start + t]["observation.images.front"].numpy().transpose(1, 2, 0) * 255
            err = {s: np.abs(got - im[min(t, len(im) - 1)]).mean() for s, im in recorded.items()}
            assert err[seed] < 6, (seed, t, err)  # the video codec's loss (h264 by default)
            if t > 0:  # the episode's end: its cube lifted where that seed put it
                assert err[seed] == min(err.values()), (seed, err)
        start += len(images)
