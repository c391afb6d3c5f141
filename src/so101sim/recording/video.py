"""Writing a run to an H.264 MP4 (:class:`VideoRecorder`), one frame every 1/fps s of
*simulated* time: a 6 s motion at 30 frames/s is 181 frames (:func:`video_frames`) however fast
the machine renders."""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco

from ..errors import RecordingError
from ..simulation import Observer, Trace
from .frames import FrameRenderer
from .paths import PendingFile, check_output_path
from .settings import VideoSettings, check_camera

log = logging.getLogger(__name__)

VIDEO_SUFFIXES = (".mp4", ".mov", ".mkv")
_EPS = 1e-9


def video_frames(duration: float, fps: float) -> int:
    """Frames a recording of ``duration`` simulated seconds holds: one at the start, then one
    every 1/fps s (a 6 s motion at 30 fps: 181)."""
    return math.floor(duration * fps + 1e-6) + 1


class VideoRecorder(Observer):
    """An observer that renders a frame every 1/fps s of simulated time and writes an H.264 MP4
    (imageio-ffmpeg, whose wheel ships ffmpeg).

    The first frame is the state when the recorder is first called; then one frame each time
    simulated time reaches the next frame's time. ``progress`` (e.g. a tqdm bar's ``update``) is
    called with 1 per frame. :meth:`close` finishes the file (also after an interruption).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        model: mujoco.MjModel,
        settings: VideoSettings | None = None,
        *,
        force: bool = False,
        progress: Callable[[int], Any] | None = None,
        preset: str = "veryfast",
        crf: int = 23,
    ) -> None:
        self.settings = (settings or VideoSettings()).validated()
        self.path = check_output_path(path, force=force, what="video", suffixes=VIDEO_SUFFIXES)
        check_camera(model, self.settings.camera)
        self.progress = progress
        self.preset = preset
        self.crf = crf
        self.frames = 0
        self.phase = ""
        self._t0: float | None = None
        self._last_time = -math.inf
        self._frames_since_anchor = 0
        self._renderer: FrameRenderer | None = None
        self._writer: Any = None
        self._file: PendingFile | None = None
        self.closed = False
        self._model = model

    # -- timeline
    def next_time(self) -> float:
        if self.closed:
            return math.inf
        if self._t0 is None:
            return -math.inf
        return self._t0 + self._frames_since_anchor / self.settings.fps - _EPS

    def on_steps(self, trace: Trace, phase: str) -> None:
        self.phase = phase

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        t = float(d.time)
        if self._t0 is None or t < self._last_time - _EPS:  # first call, or the clock was reset
            self._t0, self._frames_since_anchor = t, 0
        self.write_frame(d)
        self._last_time = t
        self._frames_since_anchor += 1
        return True

    # -- frames
    def open(self) -> None:
        """Start the renderer and the encoder (done by the first frame if not called)."""
        if self._writer is not None:
            return
        if self.closed:
            raise RecordingError(f"the video {str(self.path)!r} is already closed")
        import imageio_ffmpeg  # imported here only to keep start-up fast

        s = self.settings
        self._renderer = FrameRenderer(self._model, s)
        self._file = PendingFile(self.path)
        writer = imageio_ffmpeg.write_frames(
            str(self._file.tmp),
            (s.width, s.height),
            fps=float(s.fps),
            codec="libx264",
            quality=None,
            macro_block_size=2,
            output_params=["-preset", self.preset, "-crf", str(self.crf)],
        )
        writer.send(None)
        self._writer = writer
        log.debug(
            "recording %s (%dx%d, %g fps, %s)", self.path, s.width, s.height, s.fps, s.quality
        )

    def caption(self, d: mujoco.MjData) -> str:
        return f"t = {d.time:6.2f} s   {self.phase}".rstrip()

    def write_frame(self, d: mujoco.MjData) -> None:
        """Render ``d``'s state and append it to the video."""
        self.open()
        assert self._renderer is not None
        frame = self._renderer.render(d, self.caption(d) if self.settings.caption else None)
        self._writer.send(frame)
        self.frames += 1
        if self.progress is not None:
            self.progress(1)

    def close(self) -> Path | None:
        """Finish the file and move it into place; return its path (None if no frame was
        written: then no file is made)."""
        if self.closed:
            return self.path if self.frames else None
        self.closed = True
        if self._renderer is not None:
            self._renderer.close()
        if self._writer is None or self._file is None:
            return None
        try:
            self._writer.close()  # ffmpeg writes the MP4 index and exits
        except BaseException:
            self._file.discard()
            raise
        written = self._file.finish(keep=self.frames > 0)
        if written is not None:
            log.debug("wrote %d frames to %s", self.frames, self.path)
        return written
