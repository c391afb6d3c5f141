"""Shared helpers of the recording tests: a small video setting and readers of what was written."""

from __future__ import annotations

import csv

import imageio.v2 as imageio
import numpy as np

from so101sim import recording as rec

SMALL = rec.VideoSettings(width=64, height=48, fps=30, quality="draft")
"""A 64×48 draft video at 30 frames/s, with caption: quick to render on a CPU."""


def read_video(path) -> tuple[list[np.ndarray], float]:
    reader = imageio.get_reader(path)
    try:
        fps = reader.get_meta_data()["fps"]
        return [np.asarray(f) for f in reader], fps
    finally:
        reader.close()


def read_csv(path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def no_partial_files(folder) -> bool:
    return not [p for p in folder.iterdir() if ".partial" in p.name]
