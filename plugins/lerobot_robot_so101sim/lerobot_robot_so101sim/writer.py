"""LeRobot's dataset writer (0.6.1) made to keep up with ``so101sim dataset``.

``lerobot-record`` hands the writer 30 frames a second; ``so101sim dataset`` hands it several
times that, and three of the writer's costs, harmless at 30 fps, then take most of the two
cores (per frame of two 160x120 cameras: ``bench/bench_dataset_writer.py``):

- **the image statistics**: its streaming encoder updates LeRobot's ``RunningQuantileStats``
  with every frame of every camera, and that sorts the frame's pixels into a 5 000-bin
  histogram per channel (about 3.5 ms a camera frame, twice the AV1 encoding of it). Within
  :func:`fast_writer`, an 8-bit image is counted once per grey level instead
  (:class:`Uint8QuantileStats`): the same histogram, bin for bin, and so the same quantiles,
  minimum and maximum; the sums are exact, where LeRobot's float32 sums round: the mean is
  LeRobot's while its sum stays within 2**24 (a frame of at most 65 793 pixels, as 160x120), and
  on two episodes' frames the standard deviation was within 4e-6 of the exact one (float64
  over every pixel), LeRobot's within 4e-4. (With ``--no-video`` LeRobot's statistics of the
  PNG frames, over a sample of whole episodes, go through it too: exact there as well);
- **a pass that embeds image files**: before writing an episode's rows LeRobot runs them, one
  at a time, through ``datasets``' ``embed_table_storage`` (about 13 ms an episode), which has
  nothing to do when the images are videos (they are not in the parquet); such an episode is
  now written as it is (the same rows and schema), and one with PNG images still goes through
  it;
- **the video files**: LeRobot appends each episode's video to the camera's current file by
  copying that whole file (its packets remuxed one by one in Python) until the file reaches
  ``video_files_size_in_mb``, 200 MB by default: a 200-episode dataset at 160x120 is one 33 MB
  file a camera, copied 200 times (6.6 GB written). :func:`size_video_files` sizes the files
  to hold about :func:`episodes_per_video_file` episodes instead (10, or more for a dataset
  that would otherwise have more than 80 video files), from the first episode's videos.

The dataset is the one LeRobot's writer makes (the same format, features, rows, videos and
statistics), and loads as any other; only the number of video files differs. The changes live
in this process only while :func:`fast_writer`'s block runs and are undone after it.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from lerobot.datasets import compute_stats, dataset_writer
from lerobot.datasets.utils import DEFAULT_VIDEO_FILE_SIZE_IN_MB

MIN_EPISODES_PER_VIDEO_FILE = 10
"""About how many episodes a video file holds at least (:func:`episodes_per_video_file`):
LeRobot copies the file so far for each episode it appends, so a file of ``k`` episodes costs
about ``k / 2`` copies of each of its packets."""
MAX_VIDEO_FILES = 80
"""At most about this many video files in a dataset, all cameras together: the training data
loader keeps 100 video decoders open (LeRobot's ``LEROBOT_VIDEO_DECODER_CACHE_SIZE``), and
one reopened for each sample would cost more than the copies save."""


class Uint8QuantileStats(compute_stats.RunningQuantileStats):
    """LeRobot's running statistics, with 8-bit pixels counted per grey level.

    A batch of ``uint8`` values (each row a pixel, each column a channel) is reduced to its
    256 counts per channel; the minimum, maximum and histogram are then what LeRobot's
    ``update`` gives (its histogram puts each grey level in the bin ``np.histogram`` does), and
    the sums of the values and of their squares are exact (LeRobot's float32 sums round past
    2**24: the same mean below that). Any other batch goes to LeRobot's own ``update``."""

    _LEVELS = np.arange(256, dtype=np.int64)
    _VALUES = _LEVELS.astype(np.float32)  # the grey levels as LeRobot's float32 batch holds them

    def update(self, batch: np.ndarray) -> None:
        if batch.dtype != np.uint8:
            super().update(batch)
            return
        batch = batch.reshape(-1, batch.shape[-1])
        num_elements, channels = batch.shape
        counts = np.stack([np.bincount(batch[:, c], minlength=256) for c in range(channels)])
        present = [np.flatnonzero(row) for row in counts]
        new_min = np.array([p[0] for p in present], dtype=np.float32)
        new_max = np.array([p[-1] for p in present], dtype=np.float32)
        n = np.float32(num_elements)
        # LeRobot's batch mean is a float32 sum over the batch divided by its length; a sum of
        # 8-bit values stays exact in float32 up to 2**24, where this one is exact throughout
        batch_mean = (counts @ self._LEVELS).astype(np.float32) / n
        batch_mean_of_squares = (counts @ (self._LEVELS * self._LEVELS)).astype(np.float32) / n
        if self._count == 0:
            self._mean = batch_mean
            self._mean_of_squares = batch_mean_of_squares
            self._min = new_min
            self._max = new_max
            self._histograms = [np.zeros(self._num_quantile_bins) for _ in range(channels)]
            self._bin_edges = [
                np.linspace(self._min[i] - 1e-10, self._max[i] + 1e-10, self._num_quantile_bins + 1)
                for i in range(channels)
            ]
        else:
            if channels != self._mean.size:
                raise ValueError(
                    "The length of new vectors does not match the initialized vector length."
                )
            max_changed = np.any(new_max > self._max)
            min_changed = np.any(new_min < self._min)
            self._max = np.maximum(self._max, new_max)
            self._min = np.minimum(self._min, new_min)
            if max_changed or min_changed:
                self._adjust_histograms()
        self._count += num_elements
        self._mean += (batch_mean - self._mean) * (num_elements / self._count)
        self._mean_of_squares += (batch_mean_of_squares - self._mean_of_squares) * (
            num_elements / self._count
        )
        for c in range(channels):
            bins = self._level_bins(c)[present[c]]
            inside = bins >= 0  # each level in its bin, as np.histogram puts it
            np.add.at(self._histograms[c], bins[inside], counts[c, present[c][inside]])

    def _level_bins(self, channel: int) -> np.ndarray:
        """The histogram bin of each grey level under the channel's current edges (-1: outside
        them), as ``np.histogram`` puts a value: ``edges[i] <= v < edges[i + 1]``, and the last
        bin takes its right edge too. Kept until the edges change."""
        cache = self.__dict__.setdefault("_level_bins_cache", {})
        edges = self._bin_edges[channel]
        kept = cache.get(channel)
        if kept is not None and kept[0] is edges:
            return kept[1]
        v = self._VALUES
        index = np.searchsorted(edges, v, side="right") - 1
        index[v == edges[-1]] = len(edges) - 2
        index[(v < edges[0]) | (v > edges[-1])] = -1
        cache[channel] = (edges, index)
        return index


def episodes_per_video_file(episodes: int, cameras: int) -> int:
    """How many episodes a video file holds: :data:`MIN_EPISODES_PER_VIDEO_FILE`, or more where
    a dataset of ``episodes`` with ``cameras`` cameras would otherwise have more than
    :data:`MAX_VIDEO_FILES` video files."""
    wanted = math.ceil(max(episodes, 1) * max(cameras, 1) / MAX_VIDEO_FILES)
    return max(MIN_EPISODES_PER_VIDEO_FILE, wanted)


def video_file_mb(first_episode_mb: float, per_file: int) -> int:
    """The ``video_files_size_in_mb`` (whole MB, as LeRobot's info.json holds it) of a file
    that holds about ``per_file`` episodes of ``first_episode_mb`` each: at least 1 MB, at most
    LeRobot's default."""
    wanted = math.ceil(first_episode_mb * per_file)
    return int(min(max(wanted, 1), DEFAULT_VIDEO_FILE_SIZE_IN_MB))


def size_video_files(dataset: Any, episodes: int) -> None:
    """After a new dataset's first episode, of the ``episodes`` it will have: its video files
    sized to hold :func:`episodes_per_video_file` episodes like the first (the largest of its
    videos, which are the cameras' first files), with LeRobot's ``update_chunk_settings``."""
    meta = dataset.meta
    if not meta.video_keys:
        return
    sizes = []
    for key in meta.video_keys:
        path = Path(meta.root) / meta.video_path.format(video_key=key, chunk_index=0, file_index=0)
        sizes.append(path.stat().st_size / 1024**2)
    per_file = episodes_per_video_file(episodes, len(meta.video_keys))
    meta.update_chunk_settings(video_files_size_in_mb=video_file_mb(max(sizes), per_file))


@contextmanager
def fast_writer() -> Iterator[None]:
    """Within this block, LeRobot's writer in this process counts 8-bit image statistics per
    grey level and skips the embedding pass where there is nothing to embed (see the
    module's text); both are put back after it."""
    original_stats = compute_stats.RunningQuantileStats
    original_embed = dataset_writer.embed_images

    def embed_images(dataset: Any) -> Any:
        from datasets.features.features import require_storage_embed

        if any(require_storage_embed(f) for f in dataset.features.values()):
            return original_embed(dataset)
        return dataset

    compute_stats.RunningQuantileStats = Uint8QuantileStats
    dataset_writer.embed_images = embed_images
    try:
        yield
    finally:
        compute_stats.RunningQuantileStats = original_stats
        dataset_writer.embed_images = original_embed


__all__ = [
    "MAX_VIDEO_FILES",
    "MIN_EPISODES_PER_VIDEO_FILE",
    "Uint8QuantileStats",
    "episodes_per_video_file",
    "fast_writer",
    "size_video_files",
    "video_file_mb",
]
