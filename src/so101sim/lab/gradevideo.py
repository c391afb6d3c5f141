"""The video of a lab hand-in, checked for ``so101sim grade``: it exists, opens (imageio, its
first frame decoded) and is as long as the run's log. Bounded: a video over
:data:`MAX_VIDEO_BYTES` is not read."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

MAX_VIDEO_BYTES = 2 * 2**30
"""The largest video checked (2 GiB; the lab's 6 s at 640x480 is well under 1 MiB)."""


@dataclass(frozen=True)
class VideoResult:
    """The hand-in's video: readable, and as long as the log within the time tolerance."""

    path: Path
    passed: bool
    text: str
    frames: int | None = None
    fps: float | None = None
    length_s: float | None = None


def check_video(path: str | os.PathLike[str], duration: float, tolerance_s: float) -> VideoResult:
    """Whether the video at ``path`` opens (imageio, its first frame decoded) and covers
    ``duration`` simulated seconds within ``tolerance_s``: so101sim's videos hold one frame at
    the start and one every 1/fps s, so their length is (frames - 1) / fps."""
    p = Path(path)
    try:
        size = p.stat().st_size if p.is_file() else None
    except OSError as exc:  # a name too long, a folder that cannot be read
        return VideoResult(p, False, f"{p.name[:40]} cannot be read ({exc.strerror})")
    if size is None:
        return VideoResult(p, False, f"{p.name} does not exist (or is not a file)")
    if size > MAX_VIDEO_BYTES:
        return VideoResult(
            p, False, f"{p.name} is {size / 2**30:.1f} GiB; expected a video of at most "
            f"{MAX_VIDEO_BYTES // 2**30} GiB",
        )  # fmt: skip
    import imageio.v2 as imageio  # imported here: only a video needs it

    try:
        with imageio.get_reader(p, format="FFMPEG") as reader:  # type: ignore[arg-type]
            fps = float(reader.get_meta_data().get("fps") or 0.0)
            reader.get_data(0)
            frames = int(reader.count_frames())
    except Exception as exc:  # whatever the decoder raises: not a readable video
        said = " ".join(str(exc).split())[:120] or type(exc).__name__
        return VideoResult(p, False, f"{p.name} does not open as a video ({said})")
    if not (fps > 0 and frames > 0):
        return VideoResult(p, False, f"{p.name} holds no frames", frames, fps)
    length = (frames - 1) / fps
    ok = abs(length - duration) <= tolerance_s
    text = f"{frames} frames at {fps:g} fps: {length:.2f} s (log: {duration:.2f} s)"
    if not ok:
        text += f"; expected the log's length ± {tolerance_s:g} s"
    return VideoResult(p, ok, text, frames, fps, length)


__all__ = ["MAX_VIDEO_BYTES", "VideoResult", "check_video"]
