"""Recording a run to any of a video, a plot and a CSV log at once (:class:`Recorder`), with
every path and setting checked before anything runs and every file finished on exit."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import Any

import mujoco

from ..simulation import Observer
from .csvlog import CsvLog
from .paths import check_distinct, check_output_path
from .plot import PLOT_SUFFIXES, TraceCollector, plot_run
from .settings import VideoSettings
from .video import VideoRecorder

PathArg = str | os.PathLike[str] | None


class Recorder:
    """Records a run to any of a video, a plot and a CSV log; a context manager.

    ``target`` is a :class:`so101sim.simulation.Simulation` (its ``observers`` get the
    recorder's observers while the block runs) or an ``MjModel`` (then pass
    :attr:`observers` to :func:`so101sim.motion.run_motion` yourself). Every path and setting is
    checked here, before anything runs. On exit the files are finished and moved into place,
    also after Ctrl-C or an error; the plot is drawn from the steps that ran.

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
    ) -> None:
        self.sim = None if isinstance(target, mujoco.MjModel) else target
        self.model: mujoco.MjModel = target if self.sim is None else target.model
        self.settings = (settings or VideoSettings()).validated()
        check_distinct(video, plot, log)
        self.plot_path = _checked_plot_path(plot, force)
        self.plot_size = plot_size
        self.force = force
        self.video = _video_recorder(video, self.model, self.settings, force, progress)
        self.log = CsvLog(log, self.model, force=force) if log is not None else None
        self.collector = TraceCollector(self.model) if plot is not None else None
        self.observers: list[Observer] = [
            o for o in (self.video, self.log, self.collector) if o is not None
        ]
        self.outputs: dict[str, Path] = {}
        self._attached = False

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
        self.close()

    def close(self) -> dict[str, Path]:
        """Finish every output; return {"video"/"log"/"plot": path} of the files written."""
        self._detach()
        errors = self._close_files()
        self._draw_plot()
        if errors:
            raise errors[0]
        return dict(self.outputs)

    def _detach(self) -> None:
        if not self._attached or self.sim is None:
            return
        for o in self.observers:
            if o in self.sim.observers:
                self.sim.observers.remove(o)
        self._attached = False

    def _close_files(self) -> list[BaseException]:
        """Close the video and the log, each even if the other fails; return the errors."""
        errors: list[BaseException] = []
        for key, out in (("video", self.video), ("log", self.log)):
            if out is None:
                continue
            try:
                written = out.close()
            except Exception as exc:  # finish the other files, then report
                errors.append(exc)
                continue
            if written is not None:
                self.outputs[key] = written
        return errors

    def _draw_plot(self) -> None:
        if self.collector is None or self.plot_path is None or "plot" in self.outputs:
            return
        run = self.collector.run_log()
        if len(run.times):
            w, h = self.plot_size
            self.outputs["plot"] = plot_run(
                run, self.plot_path, width=w, height=h, force=self.force
            )


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
) -> VideoRecorder | None:
    if video is None:
        return None
    return VideoRecorder(video, model, settings, force=force, progress=progress)
