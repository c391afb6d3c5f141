"""What the command line prints, and the signal handling that finishes output files first.

While a command runs, SIGINT, SIGTERM and SIGHUP all raise :class:`Interrupted` (a
KeyboardInterrupt), so each one finishes the output files as Ctrl-C does; one that comes while
they are finished waits until they are (:class:`_Signals`). The exit status is then 128 + the
signal's number (130 for Ctrl-C). The library installs no signal handler: this belongs to the
command line.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from ..errors import So101SimError
from ..validation import escape_controls  # every printer escapes: see say()

if TYPE_CHECKING:
    from tqdm import tqdm

    from ..motion.segments import RunResult
    from ..recording import Recorder
    from ..sim.simulation import SegmentResult


# ---------------------------------------------------------------------------- printing
def say(
    *values: object, sep: str = " ", end: str = "\n", file: Any = None, flush: bool = False
) -> None:
    """print(), with control characters escaped (:func:`escape_controls`): every line the
    command line prints goes through here."""
    text = escape_controls(sep.join(str(v) for v in values))
    print(text, end=end, file=file if file is not None else sys.stdout, flush=flush)


class EscapingFormatter(logging.Formatter):
    """Log lines with control characters escaped, as everything else printed."""

    def format(self, record: logging.LogRecord) -> str:
        return escape_controls(super().format(record))


ARM_HELP = (
    "arm profile, the servos' model: sts3215 (default: fitted on a real STS3215, it sags and "
    "lags as the real arm does), official (the vendored ideal position actuators), "
    "sts3215-12v, sts3215-load (with gear friction that grows with the load), or a TOML file "
    "written by `so101sim fit`"
)


def add_arm_option(parser: Any) -> None:
    """``--arm NAME|FILE`` (every command that simulates the arm; default: the default
    profile). The value is resolved by :func:`so101sim.model.arm.load_profile`."""
    parser.add_argument("--arm", metavar="NAME|FILE", default=None, help=ARM_HELP)


def format_segment(seg: SegmentResult) -> str:
    """A phase's report: target, reached pose, largest tracking error."""
    # start-up: the units module (NumPy) only when a report is printed
    from ..units import format_pose, format_value

    joint, err = seg.worst_tracking_error
    status = "" if seg.completed else "  (stopped early)"
    return (
        f"{escape_controls(seg.phase, lines=False)} [{seg.kind}, "
        f"{seg.start_time:.3f}-{seg.end_time:.3f} s, "
        f"{seg.steps} steps]{status}\n"
        f"  target : {format_pose(seg.target)}\n"
        f"  reached: {format_pose(seg.reached)}\n"
        f"  largest tracking error: {format_value(joint, err, 3)} ({joint})"
    )


def print_run(result: RunResult) -> None:
    for seg in result.segments:
        say(format_segment(seg))
    if not result.completed:
        say(f"run ended early at t = {result.end_time:.3f} s (viewer closed)")


def _progress_bar(frames: int | None) -> tqdm | None:
    """A bar on stderr counting the video's frames (None without a video)."""
    if frames is None:
        return None
    # start-up: tqdm only when a video is recorded
    from tqdm import tqdm

    return tqdm(
        total=frames,
        unit="frame",
        desc="recording",
        file=sys.stderr,
        delay=1.0,  # shown only for renders that take more than a second
        disable=None,  # and only on a terminal
        leave=False,
    )


# ---------------------------------------------------------------------------- signals
class Interrupted(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP, raised as a Ctrl-C is, so that each one finishes the files."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


class _Signals:
    """While a command runs, SIGINT, SIGTERM and SIGHUP raise :class:`Interrupted`. A signal
    that comes while the output files are finished (:attr:`finishing`), or within a second of
    the last one raised (it is on its way there), waits in :attr:`waiting` instead: the files
    are finished first. A third that waits gives them up (SystemExit)."""

    NAMES = ("SIGINT", "SIGTERM", "SIGHUP")

    def __init__(self) -> None:
        self.finishing = False
        self.waiting: list[int] = []
        self.raised: int | None = None  # the signal last raised as Interrupted
        self._raised_at = -math.inf
        self._previous: dict[int, Any] = {}  # the handlers found by the command now running
        self._originals: dict[int, Any] = {}  # those found before any command (not ours)
        self._ended_at = -math.inf

    def __enter__(self) -> _Signals:
        self.finishing, self.waiting, self._raised_at = False, [], -math.inf
        self.raised = None
        if threading.current_thread() is threading.main_thread():
            for name in self.NAMES:
                if (signum := getattr(signal, name, None)) is not None:
                    previous = self._previous[signum] = signal.signal(signum, self._handle)
                    if previous != self._swallow:
                        self._originals[signum] = previous
        return self

    def __exit__(self, *exc: object) -> None:
        # Interrupted: the command ends with 128 + the signal. One more signal on the way out
        # (a second Ctrl-C within milliseconds, while Python shuts down) must not end the
        # process by the signal instead: from now on they are swallowed (the next command
        # restores the handlers it found first).
        interrupted = self.raised is not None or bool(self.waiting)
        self._ended_at = time.monotonic()
        for signum, previous in self._previous.items():
            signal.signal(signum, self._swallow if interrupted else previous)
        self._previous.clear()

    def _swallow(self, signum: int, frame: object) -> None:
        """After an interrupted command: a signal within a second is swallowed (the process
        is on its way out with 128 + the first); a later one (a program that goes on after
        main()) does what the handler found before the command does."""
        if time.monotonic() - self._ended_at < 1.0:
            self.waiting.append(signum)
            return
        original = self._originals.get(signum, signal.SIG_DFL)
        signal.signal(signum, original)
        if callable(original):
            original(signum, frame)
        elif original == signal.SIG_DFL:
            os.kill(os.getpid(), signum)

    def _handle(self, signum: int, frame: object) -> None:
        now = time.monotonic()
        if not self.finishing and now - self._raised_at > 1.0:
            self._raised_at = now
            self.raised = signum
            raise Interrupted(signum)
        self.waiting.append(signum)
        if len(self.waiting) >= 3:
            _notice("so101sim: output files left unfinished\n")
            raise SystemExit(128 + signum)
        more = "twice more" if len(self.waiting) == 1 else "once more"
        _notice(
            f"so101sim: finishing with the output files first (signal {more} to stop at once, "
            "leaving them as they are)\n"
        )


def _notice(text: str) -> None:
    """Write to stderr from a signal handler (print() may be in the middle of a line)."""
    with contextlib.suppress(OSError):
        os.write(2, text.encode())


def _say(text: str, *, err: bool = False) -> None:
    """:func:`say`, except that a closed terminal (after SIGHUP) is not an error."""
    with contextlib.suppress(OSError):
        say(text, file=sys.stderr if err else sys.stdout, flush=True)


def _signal_name(signum: int) -> str:
    with contextlib.suppress(ValueError):
        return signal.Signals(signum).name
    return f"signal {signum}"


SIGNALS = _Signals()
"""The handlers :func:`main` installs while a command runs."""


@contextlib.contextmanager
def signals_end_the_window() -> Iterator[None]:
    """While MuJoCo's managed viewer runs: its window loop holds the main thread in C until the
    window closes, so no Python handler runs (SIGTERM, SIGHUP, even Ctrl-C would wait for the
    window). A thread woken by the signal itself (:func:`signal.set_wakeup_fd`) ends the
    process as the handlers would, ``so101sim: interrupted (SIGTERM)`` and 128 + the signal:
    the viewer holds nothing to finish. (Off the main thread, where no handler runs: nothing.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    read, write = os.pipe()
    os.set_blocking(write, False)
    previous = signal.set_wakeup_fd(write, warn_on_full_buffer=False)
    done = threading.Event()
    ending = {int(s) for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", 0)) if s}

    def watch() -> None:
        while not done.is_set():
            got = os.read(read, 1)
            if done.is_set() or not got:
                return
            if got[0] in ending:
                with contextlib.suppress(Exception):
                    sys.stdout.flush()
                _notice(f"so101sim: interrupted ({_signal_name(got[0])})\n")
                os._exit(128 + got[0])

    watcher = threading.Thread(target=watch, name="so101sim-window-signals", daemon=True)
    watcher.start()
    try:
        yield
    finally:
        done.set()
        signal.set_wakeup_fd(previous)
        with contextlib.suppress(OSError):
            os.write(write, b"\0")  # wakes the thread, which sees it is done
        watcher.join(timeout=10.0)
        os.close(read)
        os.close(write)


@atexit.register
def _ignore_signals_at_exit() -> None:
    """After an interrupted command, a signal during the interpreter's shutdown (which puts
    back the default handlers) would end the process by the signal instead of 128 + the
    first: ignore them from here on (the process is ending)."""
    if SIGNALS.raised is None and not SIGNALS.waiting:
        return
    for signum in SIGNALS._originals:
        with contextlib.suppress(OSError, ValueError):
            signal.signal(signum, signal.SIG_IGN)


@contextlib.contextmanager
def _reporting(recorder: Recorder, bar: tqdm | None) -> Iterator[None]:
    """Finish the recorder's files on the way out (also on Ctrl-C, SIGTERM, SIGHUP or an
    error) and say what was written; signals that come meanwhile wait until it is done."""
    try:
        yield
    except BaseException as exc:
        SIGNALS.finishing = True  # first, and no call before it: a call may be interrupted
        _finish_outputs(recorder, bar, exc)
        raise
    SIGNALS.finishing = True
    _finish_outputs(recorder, bar, None)


def _say_written(recorder: Recorder, so_far: str) -> None:
    for key, path in recorder.outputs.items():
        extra = f" ({recorder.video.frames} frames)" if key == "video" and recorder.video else ""
        _say(f"wrote the {key} {so_far}to {path}{extra}")


def _finish_outputs(recorder: Recorder, bar: tqdm | None, pending: BaseException | None) -> None:
    """Close the recorder and print what it wrote; raise what failed (a full disk), unless
    ``pending`` (what stopped the run) is on its way out: then print it."""
    if bar is not None:
        with contextlib.suppress(OSError):  # a terminal that hung up
            bar.close()
    # errors are in recorder.errors; an interrupt is already on its way (SIGNALS.waiting)
    with contextlib.suppress(So101SimError, KeyboardInterrupt):
        recorder.close()
    _say_written(recorder, "so far " if pending is not None else "")
    errors = [e for e in recorder.errors.values() if e is not pending]
    first = errors.pop(0) if errors and pending is None else None
    for error in errors:
        _say(f"so101sim: error: {error}", err=True)
    if first is not None:
        raise first
