"""The lab's hand-in: record a student's own script to a video, with no screen recorder.

Two ways, the same result:

* **From Python**, one call in the script: :func:`record` returns a :class:`RecordingViewer`
  that works wherever the script used ``mujoco.viewer.launch_passive(m, d)``: as the ``viewer``
  of the lab helpers (``move_to_pose(m, d, viewer, ...)``) and in a handout-style loop
  (``viewer.sync()``, ``viewer.is_running()``, ``viewer.lock()``, ``viewer.close()``).
* **From the command line**, the script unchanged: ``so101sim record my_lab.py -o lab.mp4``
  runs it with :func:`run_script`, which makes ``mujoco.viewer.launch_passive`` return the
  recorder and the script's clock follow simulated time (:mod:`so101sim.lab.simclock`), so the
  handout's wall-clock loops run exactly the simulated time they ask for.

Frames are taken at the video's rate in *simulated* time; a title (the student's name) goes
in the caption, the video's metadata and the plot's heading. The video is drawn when the
recording closes (:class:`DeferredVideo` keeps each frame's state meanwhile, a few hundred bytes
each), so that the camera is fitted to the whole motion the script made, as ``so101sim run
--record`` fits it to the motion file's path: the arm's sweep fills the frame in every view.

Long on purpose: the two ways to a hand-in (:func:`record` on a motion, :func:`run_script` on
a student's script) share the recording viewer and its output checks, and read best together.
"""

from __future__ import annotations

import contextlib
import copy
import os
import runpy
import sys
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..errors import So101SimError, ViewerError
from ..recording import Recorder, VideoSettings
from ..recording.inline import RecordedFiles
from ..sim.simulation import Observer, Simulation, Trace
from ..validation import check_input_file, check_output_path
from .simclock import SimClock, simulated_time

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
        self.sim = Simulation.attach(m, d)
        self.recorder = Recorder(m, video=video, plot=plot, log=log, settings=settings, force=force)
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


# ---------------------------------------------------------------------------- scripts
@dataclass
class ScriptRun:
    """What :func:`run_script` did: the script's exit status and the files written."""

    exit_status: int
    outputs: dict[str, Path] = field(default_factory=dict)
    simulated_seconds: float = 0.0
    message: str = ""  # what sys.exit("text") said, for the CLI to print


class NothingRecordedError(So101SimError, RuntimeError):
    """The script never opened a viewer, so there was nothing to record."""


class _Session:
    """The one recording of a script run: made when the script first opens a viewer."""

    def __init__(
        self, clock: SimClock, video: PathArg, options: dict[str, Any], live: Any = None
    ) -> None:
        self.clock = clock
        self.video = video
        self.options = options
        self.live = live
        self.viewer: RecordingViewer | None = None

    def launch_passive(self, m: mujoco.MjModel, d: mujoco.MjData, **_: Any) -> RecordingViewer:
        if self.viewer is None:
            self.viewer = record(m, d, self.video, **self.options)
            if self.live is not None:
                self.viewer.also.append(self.live(m, d))
        elif self.viewer.sim.data is not d:
            raise ViewerError(
                "the script opened a second viewer on other data; so101sim record follows "
                "one simulation: open the viewer once"
            )
        self.clock.follow(d)
        return _Handle(self.viewer)

    def close(self) -> dict[str, Path]:
        return self.viewer.close() if self.viewer is not None else {}


class _Handle(RecordingViewer):
    """The session's viewer as the script sees it: closing it (the end of its ``with``
    block) keeps the recording open until the script ends."""

    def __init__(self, viewer: RecordingViewer) -> None:
        self.__dict__ = viewer.__dict__

    def close(self) -> dict[str, Path]:
        return dict(self.outputs)


def _refuse_launch(*args: Any, **kwargs: Any) -> None:
    raise ViewerError(
        "mujoco.viewer.launch() opens an interactive window that blocks; so101sim record "
        "needs launch_passive(m, d) (as the lab handout uses)"
    )


@contextlib.contextmanager
def _patched_viewer(session: _Session) -> Iterator[None]:
    """While the script runs: ``mujoco.viewer.launch_passive`` and so101sim's own
    ``open_viewer`` return the recorder, and ``so101sim.viewer.has_display()`` is True (a
    script that opens a viewer only when there is a display records too)."""
    import mujoco.viewer  # imported here: only script runs need it

    from .. import viewer as sim_viewer
    from ..viewer import passive

    modules = (sim_viewer, passive)  # what scripts import, and the module that calls them

    @contextlib.contextmanager
    def open_recorder(m: mujoco.MjModel, d: mujoco.MjData, **_: Any) -> Iterator[Any]:
        yield session.launch_passive(m, d)

    saved = (mujoco.viewer.launch_passive, mujoco.viewer.launch)
    saved_sim = [(mod.open_viewer, mod.has_display) for mod in modules]
    mujoco.viewer.launch_passive = session.launch_passive  # type: ignore[assignment]
    mujoco.viewer.launch = _refuse_launch  # type: ignore[assignment]
    for mod in modules:
        mod.open_viewer = open_recorder  # type: ignore[assignment]
        mod.has_display = lambda: True  # type: ignore[assignment]
    try:
        yield
    finally:
        mujoco.viewer.launch_passive, mujoco.viewer.launch = saved
        for mod, (opener, display) in zip(modules, saved_sim, strict=True):
            mod.open_viewer, mod.has_display = opener, display


@contextlib.contextmanager
def _script_environment(path: Path, args: Sequence[str]) -> Iterator[None]:
    saved_argv, saved_path = sys.argv[:], sys.path[:]
    sys.argv = [str(path), *args]
    sys.path.insert(0, str(path.parent))
    try:
        yield
    finally:
        sys.argv, sys.path[:] = saved_argv, saved_path


@contextlib.contextmanager
def _arm_models(arm: object) -> Iterator[None]:
    """With an arm profile (``so101sim record --arm``): the script's models get it, both those
    it loads through so101sim (``load_model``, ``Simulation``: the profile is the default while
    it runs) and those it compiles with ``mujoco.MjModel.from_xml_path`` (as the lab handout
    does: a private copy of ``load_model(path, arm=...)``). None: the script's own models."""
    if arm is None:
        yield
        return
    from ..model.arm import default_profile, profile_key
    from ..model.load import load_model

    original = mujoco.MjModel.from_xml_path

    def from_xml_path(filename: str, assets: Any = None) -> mujoco.MjModel:
        if assets:
            return original(filename, assets)
        return copy.copy(load_model(filename, arm=profile))

    with default_profile(arm) as profile:  # type: ignore[arg-type]
        if not profile_key(profile):  # official: the files' own actuators, as they load
            yield
            return
        mujoco.MjModel.from_xml_path = staticmethod(from_xml_path)  # type: ignore[method-assign]
        try:
            yield
        finally:
            mujoco.MjModel.from_xml_path = original  # type: ignore[method-assign]


def _check_outputs(video: PathArg, options: dict[str, Any]) -> None:
    """The outputs of a script run, checked as :class:`Recorder` will check them."""
    from ..recording.paths import check_distinct
    from ..recording.plot import PLOT_SUFFIXES
    from ..recording.video import VIDEO_SUFFIXES

    force = bool(options.get("force", False))
    plot, log = options.get("plot"), options.get("log")
    if video is not None:  # None: the script is only shown (record --web)
        check_output_path(video, force=force, what="video", suffixes=VIDEO_SUFFIXES)
    if plot is not None:
        check_output_path(plot, force=force, what="plot", suffixes=PLOT_SUFFIXES)
    if log is not None:
        check_output_path(log, force=force, what="log")
    check_distinct(video, plot, log)


def run_script(
    script: str | os.PathLike[str],
    args: Sequence[str],
    video: PathArg,
    *,
    live: Any = None,
    **options: Any,
) -> ScriptRun:
    """Run a handout-style ``script`` (with ``args``) headless and record it to ``video``.

    While it runs, ``mujoco.viewer.launch_passive(m, d)`` returns the recorder (options as
    :func:`record` takes them: ``title``, ``width``, ``fps``, ``plot``, ``log``, …) and
    ``time.time``/``monotonic``/``perf_counter``/``sleep`` follow the simulated time of the
    data the viewer was opened on (see :mod:`so101sim.lab.simclock`). The script's output and
    exceptions pass through (an exception propagates after the files are finished); its
    exit status is returned.

    ``arm`` (an option): an arm profile for the models the script loads (see
    :func:`_arm_models`); None leaves them as the script makes them.
    ``live``: a function ``live(m, d)`` returning a viewer (``sync()``, and an
    :class:`~so101sim.sim.Observer`) shown alongside, e.g. the web studio's
    :class:`~so101sim.studio.live.StudioViewer`; the script then runs on the wall clock (the
    live viewer paces it to real time), and ``video`` may be None (nothing recorded).

    Raises:
        NothingRecordedError: the script ended without opening a viewer.
        SettingError: ``script`` is not a readable file (missing, a folder, a device, ...).
        OutputPathError: an output (``video``, ``plot``, ``log``) cannot be written.
    """
    # what the script is when not a file (a folder, /dev/zero), and every output, checked
    # before the script runs (the recording opens only when the script opens its viewer)
    path = check_input_file(script, "script", expected="a Python file (the script to run)")
    _check_outputs(video, options)
    arm = options.pop("arm", None)
    clock = SimClock()
    session = _Session(clock, video, options, live)
    status, message = 0, ""
    clocked = simulated_time(clock) if live is None else contextlib.nullcontext()
    try:
        with (
            _script_environment(path, args),
            _arm_models(arm),
            _patched_viewer(session),
            clocked,
        ):
            try:
                runpy.run_path(str(path), run_name="__main__")
            except SystemExit as exc:
                status, message = _exit_status(exc.code)
    finally:
        outputs = session.close()
    if session.viewer is None:
        raise NothingRecordedError(
            f"{path.name} never opened a viewer (mujoco.viewer.launch_passive(m, d), "
            "so101sim.viewer.open_viewer or so101sim.record): nothing to record; open the "
            "viewer as the lab handout does"
        )
    return ScriptRun(status, outputs, clock.elapsed(), message)


def _exit_status(code: object) -> tuple[int, str]:
    """Python's rule for ``sys.exit(code)``: None is 0, an int is itself, anything else is
    printed (by the caller) and is 1."""
    if code is None:
        return 0, ""
    if isinstance(code, int):
        return code, ""
    return 1, str(code)
