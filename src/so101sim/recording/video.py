"""Writing a run to an H.264 MP4 (:class:`VideoRecorder`), one frame every 1/fps s of
*simulated* time: a 6 s motion at 30 frames/s is 181 frames (:func:`video_frames`) however fast
the machine renders."""

from __future__ import annotations

import functools
import logging
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

import mujoco
import numpy as np

from ..errors import OutputPathError, RecordingError
from ..model.build import servo_model, servo_name
from ..sim.simulation import Observer, Trace
from .encoder import FfmpegEncoder, count_frames
from .frames import FrameRenderer
from .paths import PendingFile, check_output_path, write_error
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
    (with the ffmpeg of the imageio-ffmpeg wheel: :class:`~.encoder.FfmpegEncoder`).

    The first frame is the state when the recorder is first called; then one frame each time
    simulated time reaches the next frame's time. ``progress`` (e.g. a tqdm bar's ``update``) is
    called with 1 per frame. :meth:`close` finishes the file (also after an interruption) and
    reads it back before it is moved into place.
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
        sweep: Sequence[np.ndarray] | None = None,
    ) -> None:
        self.settings = (settings or VideoSettings()).validated()
        self.sweep = sweep  # the arm's joint positions over the run, when known (framing)
        self.path = check_output_path(path, force=force, what="video", suffixes=VIDEO_SUFFIXES)
        self.force = force  # the finished file replaces one there by then only with force
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
        self._encoder: FfmpegEncoder | None = None
        self._file: PendingFile | None = None
        self.closed = False
        self._finished = False
        self._written: Path | None = None
        self._verified: int | None = None  # frames the file holds, read back
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
        if self._encoder is not None:
            return
        if self.closed:
            raise RecordingError(f"the video {str(self.path)!r} is already closed")
        s = self.settings
        if self._renderer is None:
            self._renderer = FrameRenderer(self._model, s, sweep=self.sweep)
        self._file = PendingFile(self.path, force=self.force)
        try:
            self._encoder = FfmpegEncoder(
                self._file.tmp,
                s.width,
                s.height,
                s.fps,
                preset=self.preset,
                crf=self.crf,
                metadata={
                    **({"title": s.title} if s.title else {}),
                    "comment": f"so101sim; servo model: {servo_model(self._model)}",
                },
            )
        except OSError as exc:  # ffmpeg could not start
            self._file.discard()
            raise write_error("video", self.path, exc) from exc
        log.debug(
            "recording %s (%dx%d, %g fps, %s)", self.path, s.width, s.height, s.fps, s.quality
        )

    def caption(self, d: mujoco.MjData) -> str:
        servo = f"   servos: {self.servo}" if self.servo else ""
        return f"t = {d.time:6.2f} s   {self.phase}{servo}".rstrip()

    @functools.cached_property
    def servo(self) -> str:
        """The run's servo model, short (the caption names it)."""
        return servo_name(self._model)

    def write_frame(self, d: mujoco.MjData) -> None:
        """Render ``d``'s state and append it to the video.

        Raises:
            OutputPathError: ffmpeg stopped taking frames (a full disk): the run should stop.
        """
        self.open()
        assert self._renderer is not None and self._encoder is not None
        frame = self._renderer.render(d, self.caption(d) if self.settings.caption else None)
        try:
            self._encoder.send(frame)
        except OutputPathError as exc:
            self._fail(str(exc))
        self.frames += 1
        if self.progress is not None:
            self.progress(1)

    def close(self) -> Path | None:
        """Finish the file, read it back and move it into place; return its path (None if no
        frame was written: then no file is made). :attr:`frames` is then the number of frames
        the file holds, as read back.

        May be interrupted (Ctrl-C) and called again: it goes on where it stopped.

        Raises:
            OutputPathError: ffmpeg failed (a full disk) or the file does not open; nothing is
                left at the path.
        """
        if self._finished:
            return self._written
        self.closed = True
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._encoder is not None and self._file is not None:
            self._written = self._finish_file(self._encoder, self._file)
        self._finished = True
        return self._written

    def _finish_file(self, encoder: FfmpegEncoder, file: PendingFile) -> Path | None:
        if file.committed:  # done, then interrupted before it was noted
            return file.path
        status = encoder.finish()  # ffmpeg writes the MP4 index and exits
        if status != 0 or encoder.error is not None:
            self._fail(encoder.failure())
        if self._verified is None:
            try:
                self._verified = count_frames(file.tmp) if encoder.sent else 0
            except OutputPathError as exc:
                self._fail(str(exc))
        frames = self._verified
        if encoder.sent and not frames:
            self._fail(f"ffmpeg wrote no frame of the {encoder.sent} it was sent")
        if frames != encoder.sent:
            log.warning("%s holds %d frames; %d were sent", self.path, frames, encoder.sent)
        self.frames = frames
        try:
            written = file.finish(keep=frames > 0)
        except OSError as exc:
            self._fail(exc)
        encoder.close_messages()
        if written is not None:
            log.debug("wrote %d frames to %s", frames, self.path)
        return written

    def _fail(self, why: str | OSError) -> NoReturn:
        self.abandon()
        self._finished = True
        raise write_error("video", self.path, why)

    def abandon(self) -> None:
        """Stop ffmpeg and remove the unfinished file (nothing is left at the path)."""
        self.closed = True
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._encoder is not None and self._encoder.proc.poll() is None:
            self._encoder.kill()
        if self._file is not None:
            self._file.discard()
