"""Recording a run to any of a video, a plot and a CSV log at once (:class:`Recorder`), with
every path and setting checked before anything runs and every file finished on exit."""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import mujoco
import numpy as np

from ..errors import RecordingError, So101SimError
from ..model.build import servo_model
from ..sim.simulation import Observer
from ..validation import check_count
from .csvlog import CsvLog
from .inline import RecordedFiles
from .paths import check_distinct, check_output_path
from .plot import MAX_PLOT_SIZE, MIN_PLOT_SIZE, PLOT_SUFFIXES, TraceCollector, plot_run
from .settings import VideoSettings
from .video import VideoRecorder

PathArg = str | os.PathLike[str] | None
log = logging.getLogger(__name__)


class Recorder:
    """Records a run to any of a video, a plot and a CSV log; a context manager.

    ``target`` is a :class:`so101sim.sim.simulation.Simulation` (its ``observers`` get the
    recorder's observers while the block runs) or an ``MjModel`` (then pass
    :attr:`observers` to :func:`so101sim.motion.run_motion` yourself). Every path and setting is
    checked here, before anything runs. On exit the files are finished, read back and moved
    into place, also after Ctrl-C or an error (a second Ctrl-C while they are finished waits
    until they are); the plot is drawn from the steps that ran.

    >>> with Recorder(sim, video="lab.mp4", log="lab.csv") as rec:
    ...     sim.move_to(ZERO_POSE, 2.0); sim.hold(2.0)
    >>> rec.outputs   # {"video": Path("lab.mp4"), "log": Path("lab.csv")}
    """

    def __init__(
        self,
        target: Any,
        *,
        video: PathArg = None,
        plot: PathArg = None,
        log: PathArg = None,
        settings: VideoSettings | None = None,
        force: bool = False,
        progress: Callable[[int], Any] | None = None,
        plot_size: tuple[int, int] = (1280, 960),
        sweep: Sequence[np.ndarray] | None = None,
    ) -> None:
        self.sim, self.model = _target(target)
        if settings is not None and not isinstance(settings, VideoSettings):
            raise RecordingError(
                f"settings = {settings!r:.80} is not a VideoSettings; expected "
                "so101sim.recording.VideoSettings(width=..., height=..., fps=...)"
            )
        self.settings = (settings or VideoSettings()).validated()
        check_distinct(video, plot, log)
        self.plot_path = _checked_plot_path(plot, force)
        self.plot_size = _checked_plot_size(plot_size)
        self.force = force
        self.video = _video_recorder(video, self.model, self.settings, force, progress, sweep)
        self.log = CsvLog(log, self.model, force=force) if log is not None else None
        self.collector = TraceCollector(self.model) if plot is not None else None
        # the collector first: it cannot fail, so the plot has every step that ran
        self.observers: list[Observer] = [
            o for o in (self.collector, self.video, self.log) if o is not None
        ]
        self.outputs: dict[str, Path] = RecordedFiles()  # shown inline in Jupyter
        self.errors: dict[str, So101SimError] = {}  # outputs that could not be written
        self._attached = False
        self._plot_tries = 0

    def __enter__(self) -> Recorder:
        if self.sim is not None:
            self.sim.observers.extend(self.observers)
            self._attached = True
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc is None:
            self.close()
            return
        try:  # what stopped the block goes on; an output that failed is logged
            self.close()
        except So101SimError as error:
            log.error("%s", error)

    def close(self) -> dict[str, Path]:
        """Finish every output; return {"video"/"log"/"plot": path} of the files written
        (also kept in :attr:`outputs`).

        Every output is finished even if another fails. A Ctrl-C (KeyboardInterrupt) during
        the finish does not cut it short: the files are finished first, then it is raised
        (after :data:`MAX_INTERRUPTS` of them, what is not finished is dropped). Any other
        exception during the finish (SystemExit) drops what is not finished.

        Raises:
            So101SimError: an output could not be written (a full disk); the others are
                finished, and the error of each one that failed is in :attr:`errors`.
        """
        first: KeyboardInterrupt | None = None
        count = 0
        while True:
            try:
                self._finish()
                break
            except KeyboardInterrupt as exc:  # no calls here: another may land at any call
                count += 1
                first = exc if first is None else first
                if count > MAX_INTERRUPTS:
                    self.abandon()
                    raise
            except BaseException:
                self.abandon()
                raise
        if first is not None:
            raise first
        if self.errors:
            raise next(iter(self.errors.values()))
        return RecordedFiles(self.outputs)

    def _repr_html_(self) -> str:
        """In Jupyter: the files written so far, the video and the plot shown inline."""
        return RecordedFiles(self.outputs)._repr_html_()

    def _finish(self) -> None:
        """Detach, then finish each output not finished yet, each even if another is
        interrupted (resumable: call again after a KeyboardInterrupt)."""
        self._detach()
        steps = (("video", self.video), ("log", self.log), ("plot", self.collector))
        interrupt: KeyboardInterrupt | None = None
        for key, out in steps:
            if out is None or key in self.outputs or key in self.errors:
                continue
            try:
                self._finish_one(key, self._draw_plot if key == "plot" else out.close)
            except KeyboardInterrupt as exc:
                interrupt = exc if interrupt is None else interrupt
        if interrupt is not None:
            raise interrupt

    def _finish_one(self, key: str, finish: Callable[[], Path | None]) -> None:
        try:
            written = finish()
        except So101SimError as exc:  # finish the other files, then report
            self.errors[key] = exc
            return
        if written is not None:
            self.outputs[key] = written

    def abandon(self) -> None:
        """Stop writing and remove every unfinished file (the finished ones stay)."""
        self._detach()
        if self.video is not None and "video" not in self.outputs:
            self.video.abandon()
        if self.log is not None and "log" not in self.outputs:
            self.log.abandon()

    def _detach(self) -> None:
        if not self._attached or self.sim is None:
            return
        for o in self.observers:
            if o in self.sim.observers:
                self.sim.observers.remove(o)
        self._attached = False

    def _draw_plot(self) -> Path | None:
        if self.collector is None or self.plot_path is None:
            return None
        run = self.collector.run_log()
        if not len(run.times):
            return None
        w, h = self.plot_size
        # a second try (after a Ctrl-C) may find the file the first one wrote
        force, self._plot_tries = self.force or self._plot_tries > 0, self._plot_tries + 1
        title = getattr(self.settings, "title", None)  # the run's title heads the plot too
        servo = servo_model(self.model)
        return plot_run(
            run, self.plot_path, width=w, height=h, force=force, title=title, servo=servo
        )


MAX_INTERRUPTS = 2
"""Ctrl-Cs that :meth:`Recorder.close` lets wait while it finishes the files; one more drops
what is not finished."""


def _target(target: Any) -> tuple[Any, mujoco.MjModel]:
    """(simulation or None, model) of what a Recorder records."""
    if isinstance(target, mujoco.MjModel):
        return None, target
    model, observers = getattr(target, "model", None), getattr(target, "observers", None)
    if isinstance(model, mujoco.MjModel) and isinstance(observers, list):
        return target, model
    raise RecordingError(
        f"cannot record {type(target).__name__} {target!r:.60}; expected a "
        "so101sim.Simulation, or a mujoco.MjModel (then pass recorder.observers to run_motion)"
    )


def _checked_plot_size(size: Any) -> tuple[int, int]:
    if not isinstance(size, tuple | list) or len(size) != 2:
        raise RecordingError(f"plot_size = {size!r:.60}; expected (width, height) in pixels")
    w, h = (
        check_count(v, name, minimum=MIN_PLOT_SIZE, maximum=MAX_PLOT_SIZE, unit=" pixels",
                    error=RecordingError)
        for v, name in zip(size, ("plot width", "plot height"), strict=True)
    )  # fmt: skip
    return w, h


def _checked_plot_path(plot: PathArg, force: bool) -> Path | None:
    if plot is None:
        return None
    return check_output_path(plot, force=force, what="plot", suffixes=PLOT_SUFFIXES)


def _video_recorder(
    video: PathArg,
    model: mujoco.MjModel,
    settings: VideoSettings,
    force: bool,
    progress: Callable[[int], Any] | None,
    sweep: Sequence[np.ndarray] | None,
) -> VideoRecorder | None:
    if video is None:
        return None
    return VideoRecorder(video, model, settings, force=force, progress=progress, sweep=sweep)
