"""The recording viewer of the lab's hand-in: :func:`record` returns a
:class:`RecordingViewer`, a stand-in for ``mujoco.viewer.launch_passive(m, d)`` that records the
run (video, plot, CSV log) instead of showing it; ``so101sim record`` (:mod:`.handin`) gives it
to a student's unchanged script.

Frames are taken at the video's rate in *simulated* time; a title (the student's name) goes
in the caption, the video's metadata and the plot's heading. The video is drawn when the
recording closes (:class:`DeferredVideo` keeps each frame's state meanwhile, a few hundred bytes
each), so that the camera is fitted to the whole motion the script made, as ``so101sim run
--record`` fits it to the motion file's path: the arm's sweep fills the frame in every view.
Under ``record --arm`` the viewer follows the script's shadow (:mod:`.arming`).
"""

from __future__ import annotations

import os
import threading
from dataclasses import replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..recording import Recorder, VideoSettings
from ..recording.inline import RecordedFiles
from ..sim.simulation import Observer, Simulation, Trace
from .arming import shadow_of

PathArg = str | os.PathLike[str] | None


class DeferredVideo(Observer):
    """Stands in for a :class:`~so101sim.recording.VideoRecorder` while a script runs: it keeps
    the state of each frame due (time, joint positions, mocap poses, phase) and draws nothing;
    :meth:`replay` then gives the video its sweep (the arm's positions over the run, for the
    camera's framing) and draws every frame kept, at the same simulated times."""

    def __init__(self, video: Any, fps: float) -> None:
        self.video = video
        self.period = 1.0 / fps
        self.states: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, str]] = []
        self.phase = ""
        self._t0: float | None = None
        self._count = 0
        self._last = -np.inf

    def next_time(self) -> float:
        if self._t0 is None:
            return -np.inf
        return self._t0 + self._count * self.period - 1e-9

    def on_steps(self, trace: Trace, phase: str) -> None:
        self.phase = phase

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        t = float(d.time)
        if self._t0 is None or t < self._last - 1e-9:  # first frame, or a reset
            self._t0, self._count = t, 0
        self.states.append((t, d.qpos.copy(), d.mocap_pos.copy(), d.mocap_quat.copy(), self.phase))
        self._last = t
        self._count += 1
        return True

    def replay(self, m: mujoco.MjModel) -> None:
        """Fit the camera to the frames kept and draw them into the video (once)."""
        states, self.states = self.states, []
        if not states:
            return
        every = max(1, len(states) // 400)  # the sweep: at most ~400 poses to frame
        self.video.sweep = [q for _, q, *_ in states[::every]] + [states[-1][1]]
        d = mujoco.MjData(m)
        for t, qpos, mocap_pos, mocap_quat, phase in states:
            d.qpos[:], d.mocap_pos[:], d.mocap_quat[:] = qpos, mocap_pos, mocap_quat
            d.time = t
            mujoco.mj_forward(m, d)
            self.video.phase = phase
            self.video.on_time(m, d)


class RecordingViewer(Observer):
    """A stand-in for ``mujoco.viewer.launch_passive(m, d)`` that records the run.

    The lab helpers see it as an :class:`~so101sim.sim.simulation.Observer` and hand it every
    step; a raw loop calls :meth:`sync` after its steps. Either way a frame is taken each time
    simulated time passes the next frame time (``fps`` per simulated second). ``opt``, ``cam``
    and ``perturb`` exist as on MuJoCo's viewer, so scripts that set them still run. Closing it
    (or leaving its ``with`` block) writes the files; ``outputs`` says which.
    """

    def __init__(
        self,
        m: mujoco.MjModel,
        d: mujoco.MjData,
        video: PathArg,
        *,
        plot: PathArg = None,
        log: PathArg = None,
        settings: VideoSettings | None = None,
        force: bool = False,
        phase: str = "",
    ) -> None:
        self.script_data = d  # the script's own data (the shadow's under record --arm)
        self.shadow = shadow_of(m, d)
        self.sim = self.shadow.sim if self.shadow is not None else Simulation.attach(m, d)
        self.recorder = Recorder(
            self.sim.model, video=video, plot=plot, log=log, settings=settings, force=force
        )
        self.deferred: DeferredVideo | None = None
        if self.recorder.video is not None:  # drawn at close, framed on the whole motion
            self.deferred = DeferredVideo(self.recorder.video, self.recorder.settings.fps)
            observers = self.recorder.observers
            observers[observers.index(self.recorder.video)] = self.deferred
        self.phase = phase
        self.opt = mujoco.MjvOption()
        self.cam = mujoco.MjvCamera()
        self.perturb = mujoco.MjvPerturb()
        self.outputs: dict[str, Path] = {}
        self._lock = threading.RLock()
        self._closed = False
        self._started = False
        self._last_time = float(d.time)
        self.also: list[Any] = []  # viewers shown alongside (the web studio): sync(), Observer

    # -- the Observer side (the lab helpers, Simulation.move_to(viewer=...))
    def on_start(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        self._started = True
        for o in [*self.recorder.observers, *self.also]:
            o.on_start(m, d)

    def next_time(self) -> float:
        if self._closed:
            return float("inf")
        observers = [*self.recorder.observers, *self.also]
        return min((o.next_time() for o in observers), default=float("inf"))

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        for o in [*self.recorder.observers, *self.also]:
            if o.next_time() <= d.time + 1e-12:
                o.on_time(m, d)
        return not self._closed

    def on_steps(self, trace: Trace, phase: str) -> None:
        if len(trace.time):
            self._last_time = float(trace.time[-1])
        for o in [*self.recorder.observers, *self.also]:
            o.on_steps(trace, phase or self.phase)

    # -- the viewer side (handout-style loops)
    def sync(self) -> None:
        """Take what happened since the last call: a log row and, when a frame is due, a
        frame of the current state."""
        if self._closed:
            return
        if self.shadow is not None:  # a raw loop stepped the script's model: follow it
            self.shadow.follow()
        m, d = self.sim.model, self.sim.data
        if not self._started:
            self.on_start(m, d)
        if d.time > self._last_time:
            idx = self.sim.index
            row = Trace(
                np.array([d.time]),
                d.ctrl[idx.actuator][None].copy(),
                d.qpos[idx.qpos][None].copy(),
            )
            self.on_steps(row, self.phase)
        self.on_time(m, d)

    def is_running(self) -> bool:
        """True until :meth:`close`."""
        return not self._closed

    def lock(self) -> threading.RLock:
        """A lock, as MuJoCo's viewer has (nothing draws concurrently here)."""
        return self._lock

    def close(self) -> dict[str, Path]:
        """Finish the files (once); return {"video"/"plot"/"log": path} of those written."""
        if not self._closed:
            self._closed = True
            try:  # interrupted while drawing: the frames drawn so far are the video
                if self.deferred is not None:
                    self.deferred.replay(self.sim.model)
            finally:
                self.outputs = self.recorder.close()
        return RecordedFiles(self.outputs)

    def _repr_html_(self) -> str:
        """In Jupyter: the files written, the video and the plot shown inline."""
        return RecordedFiles(self.outputs)._repr_html_()

    def __enter__(self) -> RecordingViewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def record(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    video: PathArg,
    *,
    title: str | None = None,
    width: int = 640,
    height: int = 480,
    fps: float = 30.0,
    quality: str = "auto",
    camera: str = "free",
    caption: bool = True,
    plot: PathArg = None,
    log: PathArg = None,
    force: bool = False,
    view: str = "default",
    azimuth: float | None = None,
    elevation: float | None = None,
    distance: float | None = None,
    lookat: tuple[float, float, float] | None = None,
) -> RecordingViewer:
    """Record the run of ``(m, d)`` to ``video`` (MP4), optionally a ``plot`` and a ``log``:
    use the result where the script used ``mujoco.viewer.launch_passive(m, d)``::

        with so101sim.record(m, d, "lab.mp4", title="Lab 2 - Ada Lovelace") as viewer:
            move_to_pose(m, d, viewer, desired, 2.0)

    The free camera is fitted to the motion, seen from ``view`` ("default", "front", "side",
    "top") or ``azimuth``/``elevation`` (degrees); ``distance`` (m) and ``lookat`` (x, y, z in m)
    override the fitted ones. Every setting and path is checked before anything runs (the
    errors say what to use).
    """
    settings = VideoSettings(
        width=width, height=height, fps=fps, camera=camera, quality=quality, caption=caption,
        view=view, azimuth=azimuth, elevation=elevation, distance=distance, lookat=lookat,
    )  # fmt: skip
    if title is not None:
        settings = _with_title(settings, title)
    return RecordingViewer(m, d, video, plot=plot, log=log, settings=settings, force=force)


def _with_title(settings: VideoSettings, title: str) -> VideoSettings:
    if not hasattr(settings, "title"):  # a recorder without titles: keep the settings
        return settings
    return replace(settings, title=title)


__all__ = ["DeferredVideo", "PathArg", "RecordingViewer", "record"]
