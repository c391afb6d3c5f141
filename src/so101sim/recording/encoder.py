"""Encoding frames to H.264 with the ffmpeg that ships in the ``imageio-ffmpeg`` wheel
(:class:`FfmpegEncoder`), and reading a written video back to count its frames
(:func:`count_frames`).

Why not ``imageio_ffmpeg.write_frames``: it ignores ffmpeg's exit status (a full disk gave
"Error writing trailer" and a file that does not open, reported as written), and a Ctrl-C that
lands while a frame is piped to ffmpeg kills ffmpeg, leaving an MP4 without its index. Here:

- ffmpeg runs in its own session, so a Ctrl-C or a hang-up sent to the terminal's process
  group does not reach it: it stops when its input ends, after writing the index;
- a thread pipes the frames, and Python raises KeyboardInterrupt only in the main thread, so a
  frame is never cut in half; the threads share only C-level queues (``queue.SimpleQueue``),
  which an interrupt cannot leave locked (a ``queue.Queue`` can: its lock is released by Python
  code, where a KeyboardInterrupt may land);
- :meth:`FfmpegEncoder.finish` may be interrupted and called again (it resumes); it returns
  ffmpeg's exit status, and ffmpeg's messages are kept for the error.
"""

from __future__ import annotations

import contextlib
import queue
import subprocess
import tempfile
import threading
import time
from fractions import Fraction
from pathlib import Path
from typing import IO, Any

import numpy as np

from ..errors import OutputPathError

_QUEUE_FRAMES = 4  # frames waiting for the pipe at most,
_QUEUE_BYTES = 32 * 2**20  # and at most this many bytes of them (but one frame)
_POLL_S = 0.002  # how often a full queue is looked at again
_NEVER_RELEASED = threading.Lock()
_NEVER_RELEASED.acquire()


def _pause(seconds: float) -> None:
    """Wait ``seconds`` of real time, in C (a lock that is never released). Not ``time.sleep``:
    under ``so101sim record`` a script's ``time.sleep`` moves its simulated clock at once
    (:mod:`so101sim.lab.simclock`), and waiting here for ffmpeg would move it on with each
    look at the queue (a busy machine's ffmpeg, behind, made a 6 s script's clock read 208 s)."""
    _NEVER_RELEASED.acquire(timeout=seconds)


_MESSAGES_KEPT = 4000  # characters of ffmpeg's messages kept for an error
_VERIFY_TIMEOUT_S = 600.0


def ffmpeg_exe() -> str:
    """The ffmpeg executable of ``imageio-ffmpeg`` (imported here only to keep start-up fast)."""
    # start-up: imageio-ffmpeg only when a video is encoded
    import imageio_ffmpeg

    return str(imageio_ffmpeg.get_ffmpeg_exe())


class FfmpegEncoder:
    """An ffmpeg process writing ``width`` × ``height`` RGB frames sent with :meth:`send` to an
    H.264 file at ``path`` (its container from the suffix), ``fps`` frames per second."""

    def __init__(
        self,
        path: Path,
        width: int,
        height: int,
        fps: float,
        *,
        preset: str = "veryfast",
        crf: int = 23,
        metadata: dict[str, str] | None = None,
    ) -> None:
        self.path = path
        tags = [a for k, v in (metadata or {}).items() for a in ("-metadata", f"{k}={v}")]
        self.size = (int(height), int(width), 3)
        rate = Fraction(float(fps)).limit_denominator(1001)
        cmd = [
            ffmpeg_exe(), "-y", "-nostdin", "-v", "error",
            "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-r", str(rate),
            "-i", "-", "-an", "-vcodec", "libx264", "-pix_fmt", "yuv420p",
            "-preset", preset, "-crf", str(crf), *tags, str(path),
        ]  # fmt: skip
        # ffmpeg's messages, kept for an error; open as long as the encoder is
        self._messages: IO[bytes] = tempfile.TemporaryFile()  # noqa: SIM115
        self.proc = subprocess.Popen(
            cmd,
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=self._messages,
            start_new_session=True,  # no SIGINT/SIGHUP from the terminal: we end it
        )
        self.sent = 0  # frames fully written to ffmpeg's input
        self.error: OSError | None = None  # the pipe broke (ffmpeg stopped early)
        # Only C-level queues between the threads: a KeyboardInterrupt can land at any Python
        # line of the main thread, and a queue.Queue or Thread.join interrupted half-way can
        # be left locked for good. :meth:`send` waits while ``_waiting`` frames are queued.
        frame_bytes = int(width) * int(height) * 3
        self._waiting = max(1, min(_QUEUE_FRAMES, _QUEUE_BYTES // frame_bytes))
        self._frames: queue.SimpleQueue[bytes | None] = queue.SimpleQueue()
        self._done: queue.SimpleQueue[bool] = queue.SimpleQueue()
        self._fed_all = False  # set by the thread before it says so on _done
        self._end_queued = False
        self._thread = threading.Thread(target=self._pipe, name="so101sim-ffmpeg", daemon=True)
        self._thread.start()

    def _pipe(self) -> None:
        stdin: Any = self.proc.stdin
        while (item := self._frames.get()) is not None:
            if self.error is None:
                try:
                    stdin.write(item)
                except (OSError, ValueError) as exc:
                    self.error = exc if isinstance(exc, OSError) else OSError(str(exc))
                else:
                    self.sent += 1
        try:
            stdin.close()  # end of input: ffmpeg writes the index and exits
        except OSError as exc:
            self.error = self.error or exc
        self._fed_all = True
        self._done.put(True)

    def send(self, frame: np.ndarray) -> None:
        """Queue one (height, width, 3) uint8 frame (copied) for ffmpeg; wait while the
        frames already queued fill the bound.

        Raises:
            OutputPathError: ffmpeg stopped taking frames (a full disk, a crash).
        """
        if self.error is not None or self.proc.poll() not in (None, 0):
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout=10.0)  # for its exit status and messages
            raise OutputPathError(self.failure())
        if frame.shape != self.size or frame.dtype != np.uint8:
            raise ValueError(f"frame of shape {frame.shape}, {frame.dtype}; expected {self.size}")
        data = frame.tobytes()
        while self._frames.qsize() >= self._waiting and self.error is None:
            _pause(_POLL_S)  # ffmpeg is behind: bounded memory
        self._frames.put(data)

    def _wait_fed(self, timeout: float | None = None) -> bool:
        """Wait until the thread has written (or dropped) every frame and closed the pipe."""
        end = None if timeout is None else time.monotonic() + timeout
        while not self._fed_all:
            if end is not None and time.monotonic() > end:
                return False
            with contextlib.suppress(queue.Empty):
                self._done.get(timeout=0.2)
        return True

    def finish(self) -> int:
        """End the input, wait for ffmpeg and return its exit status (0: the file is complete).
        May be interrupted and called again."""
        if not self._end_queued:
            self._frames.put(None)
            self._end_queued = True
        self._wait_fed()
        return self.proc.wait()

    def kill(self) -> None:
        """Stop ffmpeg now (the file is left incomplete: discard it)."""
        with contextlib.suppress(OSError):
            self.proc.kill()
        self.error = self.error or OSError("stopped")
        if not self._end_queued:
            self._frames.put(None)
            self._end_queued = True
        self._wait_fed(timeout=5.0)
        self.proc.wait()

    def messages(self) -> str:
        """The end of what ffmpeg printed (its errors)."""
        try:
            self._messages.seek(0)
            text = self._messages.read().decode("utf-8", "replace")
        except (OSError, ValueError):
            return ""
        return " ".join(text.split())[-_MESSAGES_KEPT:]

    def failure(self) -> str:
        """Why the video could not be written, for an error message."""
        status = self.proc.poll()
        said = self.messages()
        if self.error is not None and status is None:
            return f"ffmpeg stopped taking frames ({self.error.strerror or self.error})"
        what = f"ffmpeg exited with status {status}" if status else "ffmpeg failed"
        return f"{what}: {said}" if said else what

    def close_messages(self) -> None:
        with contextlib.suppress(OSError):
            self._messages.close()


def count_frames(path: Path) -> int:
    """The video frames in the file at ``path``, read back by ffmpeg without decoding them.

    Raises:
        OutputPathError: the file does not open as a video (no index, truncated, empty).
    """
    cmd = [
        ffmpeg_exe(), "-nostdin", "-v", "error", "-nostats", "-i", str(path),
        "-map", "0:v:0", "-c", "copy", "-f", "null", "-progress", "pipe:1", "-",
    ]  # fmt: skip
    try:
        out = subprocess.run(
            cmd,
            capture_output=True,
            text=True,
            timeout=_VERIFY_TIMEOUT_S,
            start_new_session=True,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise OutputPathError(f"the video {str(path)!r} could not be read back: {exc}") from None
    frames = [line[6:] for line in out.stdout.splitlines() if line.startswith("frame=")]
    if out.returncode != 0 or not frames or not frames[-1].strip().isdigit():
        said = " ".join(out.stderr.split())[-_MESSAGES_KEPT:] or f"status {out.returncode}"
        raise OutputPathError(
            f"the video written to {str(path)!r} does not open ({said}); expected a playable file"
        )
    return int(frames[-1])
