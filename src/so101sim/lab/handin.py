"""The lab's hand-in: record a student's own script to a video, with no screen recorder.

Two ways, the same result:

* **From Python**, one call in the script: :func:`record` returns a :class:`RecordingViewer`
  that works wherever the script used ``mujoco.viewer.launch_passive(m, d)``: as the ``viewer``
  of the lab helpers (``move_to_pose(m, d, viewer, ...)``) and in a handout-style loop
  (``viewer.sync()``, ``viewer.is_running()``, ``viewer.lock()``, ``viewer.close()``); see
  :mod:`.recviewer`.
* **From the command line**, the script unchanged: ``so101sim record my_lab.py -o lab.mp4``
  runs it with :func:`run_script`, which makes ``mujoco.viewer.launch_passive`` return the
  recorder and the script's clock follow simulated time (:mod:`so101sim.lab.simclock`), so the
  handout's wall-clock loops run exactly the simulated time they ask for. ``--arm`` gives the
  script's own model a servo model (:mod:`.arming`); a script whose arm starts with its
  targets at zero is commanded to hold its starting pose (:func:`hold_start`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import runpy
import sys
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..errors import ModelError, So101SimError, ViewerError
from ..model.build import servo_model
from ..model.load import arm_index, arm_units
from ..validation import check_input_file, check_output_path
from .arming import script_arm
from .recviewer import DeferredVideo, PathArg, RecordingViewer, record
from .simclock import SimClock, simulated_time

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------- scripts
@dataclass
class ScriptRun:
    """What :func:`run_script` did: the script's exit status and the files written."""

    exit_status: int
    outputs: dict[str, Path] = field(default_factory=dict)
    simulated_seconds: float = 0.0
    message: str = ""  # what sys.exit("text") said, for the CLI to print
    servo_model: str = ""  # the servo model the recorded run used, in words


class NothingRecordedError(So101SimError, RuntimeError):
    """The script never opened a viewer, so there was nothing to record."""


class _Session:
    """The one recording of a script run: made when the script first opens a viewer."""

    def __init__(
        self,
        clock: SimClock,
        video: PathArg,
        options: dict[str, Any],
        live: Any = None,
        say: Callable[[str], None] | None = None,
    ) -> None:
        self.clock = clock
        self.video = video
        self.options = options
        self.live = live
        self.say = say
        self.viewer: RecordingViewer | None = None

    def launch_passive(self, m: mujoco.MjModel, d: mujoco.MjData, **_: Any) -> RecordingViewer:
        if self.viewer is None:
            note = hold_start(m, d)
            if note:
                _say(self.say, note)
            self.viewer = record(m, d, self.video, **self.options)
            if self.live is not None:
                self.viewer.also.append(self.live(m, d))
        elif self.viewer.script_data is not d:
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


def _say(say: Callable[[str], None] | None, text: str) -> None:
    if say is not None:
        say(text)
    else:
        log.warning("%s", text)


def hold_start(m: mujoco.MjModel, d: mujoco.MjData) -> str:
    """The start lurch, prevented: when a script opens its viewer before its first step with
    every arm target in ``d.ctrl`` at 0 while the arm is posed elsewhere (the lab handout's
    ``set_initial_pose`` sets only ``d.qpos``), the servos would pull the arm toward all
    zeros on the first step. The lab's spirit is "start holding this pose", so the targets
    are set to the pose. Returns the line saying so ("" when nothing was done)."""
    try:
        idx = arm_index(m)
    except ModelError:  # not an SO-101: nothing to say about its servos
        return ""
    q = d.qpos[idx.qpos]
    if d.time != 0.0 or d.ctrl[idx.actuator].any() or np.abs(q).max() < 1e-6:
        return ""
    lo, hi = m.actuator_ctrlrange[idx.actuator].T
    limited = m.actuator_ctrllimited[idx.actuator].astype(bool)
    d.ctrl[idx.actuator] = np.where(limited, np.clip(q, lo, hi), q)
    units = arm_units(m)
    pose = ", ".join(f"{n}={v:.1f}" for n, v in units.array_to_pose(units.from_radians(q)).items())
    closed = units.from_radians(np.zeros(len(q)))[-1]  # the gripper's qpos 0, in 0-100 units
    return (
        "the script's arm targets (d.ctrl) were all 0 at the start while the arm stands at "
        f"{pose} (degrees; the gripper on so101sim's 0-100 scale, where qpos 0 is "
        f"{closed:.1f}): so101sim record commands that starting pose (the arm starts holding it, "
        "rather than lurching toward zero on the first step); set d.ctrl or use "
        "so101sim.lab.set_initial_pose to choose"
    )


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


def _check_outputs(video: PathArg, options: dict[str, Any]) -> None:
    """The outputs of a script run, checked as :class:`Recorder` will check them."""
    # start-up: the recording package (video, plot) only when a run writes outputs
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
    exceptions pass through (an exception propagates after the files are finished:
    :func:`written_before` names them); its
    exit status is returned.

    ``arm`` (an option): an arm profile for the models the script runs (see
    :mod:`so101sim.lab.arming`); None leaves them as the script makes them (a model compiled
    from ``scene.xml`` by the script: the file's own actuators, ``official``). ``say`` (an
    option): how to tell the user what changed (the profile, the starting targets), once each;
    None: logged as warnings.
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
    say = options.pop("say", None)
    clock = SimClock()
    session = _Session(clock, video, options, live, say)
    status, message = 0, ""
    clocked = simulated_time(clock) if live is None else contextlib.nullcontext()
    outputs: dict[str, Path] = {}
    try:
        with (
            _script_environment(path, args),
            script_arm(arm, say),
            _patched_viewer(session),
            clocked,
        ):
            try:
                runpy.run_path(str(path), run_name="__main__")
            except SystemExit as exc:
                status, message = _exit_status(exc.code)
    except BaseException as exc:  # the script's own error: it goes up with what was written
        outputs = session.close()
        setattr(exc, _WRITTEN, dict(outputs))
        raise
    else:
        outputs = session.close()
    if session.viewer is None:
        raise NothingRecordedError(
            f"{path.name} never opened a viewer (mujoco.viewer.launch_passive(m, d), "
            "so101sim.viewer.open_viewer or so101sim.record): nothing to record; open the "
            "viewer as the lab handout does"
        )
    servo = servo_model(session.viewer.sim.model)
    return ScriptRun(status, outputs, clock.elapsed(), message, servo)


_WRITTEN = "so101sim_outputs"


def written_before(exc: BaseException) -> dict[str, Path]:
    """The files :func:`run_script` finished before ``exc`` (the script's own error, or an
    interrupt) went up: ``{"video": path, ...}`` (empty when the script never opened its
    viewer or nothing was asked for)."""
    return dict(getattr(exc, _WRITTEN, {}))


def script_line(exc: BaseException, script: str | os.PathLike[str]) -> str:
    """Where in ``script`` ``exc`` came from, as ``file:line`` (the innermost frame of the
    script's own code in its traceback; a syntax error's own line), or "" when it did not
    pass through the script."""
    try:
        target = Path(script).resolve()
    except OSError:
        return ""
    if isinstance(exc, SyntaxError) and exc.filename and exc.lineno:
        with contextlib.suppress(OSError):
            if Path(exc.filename).resolve() == target:
                return f"{script}:{exc.lineno}"
    line, tb = 0, exc.__traceback__
    while tb is not None:
        with contextlib.suppress(OSError):
            if Path(tb.tb_frame.f_code.co_filename).resolve() == target:
                line = tb.tb_lineno
        tb = tb.tb_next
    return f"{script}:{line}" if line else ""


def script_traceback(exc: BaseException, script: str | os.PathLike[str]) -> str:
    """``exc``'s traceback as ``python script`` would show it: from the script's own first
    frame on, without the frames of so101sim and runpy that ran it; a syntax error in the
    script itself as Python shows one (no traceback); the whole traceback when the script's
    code is not in it."""
    try:
        target = Path(script).resolve()
    except OSError:
        target = None

    def ours(filename: str | None) -> bool:
        with contextlib.suppress(OSError, TypeError):
            return target is not None and Path(filename).resolve() == target  # type: ignore[arg-type]
        return False

    last = "".join(traceback.format_exception_only(type(exc), exc))
    if isinstance(exc, SyntaxError) and ours(exc.filename):
        return last
    tb = exc.__traceback__
    while tb is not None and not ours(tb.tb_frame.f_code.co_filename):
        tb = tb.tb_next
    if tb is None:
        return "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    return "Traceback (most recent call last):\n" + "".join(traceback.format_tb(tb)) + last


def _exit_status(code: object) -> tuple[int, str]:
    """Python's rule for ``sys.exit(code)``: None is 0, an int is itself, anything else is
    printed (by the caller) and is 1."""
    if code is None:
        return 0, ""
    if isinstance(code, int):
        return code, ""
    return 1, str(code)


__all__ = [
    "DeferredVideo",
    "NothingRecordedError",
    "RecordingViewer",
    "ScriptRun",
    "hold_start",
    "record",
    "run_script",
    "script_line",
    "script_traceback",
    "written_before",
]
