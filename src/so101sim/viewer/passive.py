"""The interactive viewer: finding a display, opening MuJoCo's passive viewer, pacing it.

MuJoCo's passive viewer (``mujoco.viewer.launch_passive``) shows the simulation while our code
steps it; :class:`so101sim.sim.simulation.ViewerObserver` syncs it and paces it to the wall clock.
It needs a display; on macOS it also needs the script to run under ``mjpython``.
:func:`choose_viewer` decides, before anything opens, whether a run shows the viewer.

MuJoCo's ``sync()`` waits while the viewer draws a frame (about 25 ms with the full meshes on
Mesa's software OpenGL, llvmpipe, 1 to 3 ms with the draft meshes). ``open_viewer(...,
mirror=True)`` returns a :class:`MirroredViewer` instead: it draws a copy of the data, with the
draft meshes the recorder ships when OpenGL renders on the CPU (a VM, WSL, a remote desktop),
its ``sync()`` only copies the state, so the physics never waits for the drawing, and (on
Linux) the viewer's threads run at a lower priority (:data:`VIEWER_NICE`): MuJoCo's viewer
draws frames back-to-back, which on a CPU renderer keeps a core or more busy.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Literal, get_args

import mujoco
import numpy as np

from ..errors import ClosedError, SettingError, ViewerError
from ..exitgate import mujoco_call
from ..model.trim import is_physics_only
from ..validation import check_choice

log = logging.getLogger(__name__)

SCENE_AZIMUTH = 160.0
SCENE_ELEVATION = -20.0
ARM_LOOKAT = (0.14, 0.0, 0.15)
ARM_DISTANCE = 0.6


def has_display() -> bool:
    """Whether a window can be opened here (an X11/Wayland display on Linux; always elsewhere)."""
    if sys.platform.startswith("linux"):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def on_macos_without_mjpython() -> bool:
    """True on macOS when the interpreter is not ``mjpython`` (the passive viewer needs it)."""
    if sys.platform != "darwin":
        return False
    return "mjpython" not in os.path.basename(sys.executable).lower() and not os.environ.get(
        "MJPYTHON_BIN"
    )


NO_DISPLAY_NOTE = "no display found: running headless (use --headless to say so, xvfb-run to view)"


@dataclass(frozen=True)
class ViewerChoice:
    """Whether a run opens the viewer; ``note`` says why not when one was wanted (for the user),
    and is None otherwise."""

    use: bool
    note: str | None = None


def choose_viewer(headless: bool = False) -> ViewerChoice:
    """Viewer or headless: the viewer unless ``headless`` was asked for or there is no display;
    without a display the run goes on headless, and the choice's ``note`` says so."""
    if headless:
        return ViewerChoice(use=False)
    if has_display():
        return ViewerChoice(use=True)
    return ViewerChoice(use=False, note=NO_DISPLAY_NOTE)


MACOS_MESSAGE = (
    "on macOS MuJoCo's passive viewer only runs under mjpython, which ships with the mujoco "
    "package: run `mjpython -m so101sim run` instead of `so101sim run`, or add --headless"
)


def frame_arm(cam: Any) -> None:
    """Point a free camera (``MjvCamera`` or the viewer's ``cam``) at the arm as the scene's
    default view does: azimuth 160°, elevation −20°, the whole arm in the frame."""
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.azimuth = SCENE_AZIMUTH
    cam.elevation = SCENE_ELEVATION
    cam.distance = ARM_DISTANCE
    cam.lookat[:] = ARM_LOOKAT


ViewerQuality = Literal["auto", "draft", "full"]
"""How a viewer draws the arm (``"auto"``: the draft meshes on a CPU renderer)."""
VIEWER_QUALITIES: tuple[str, ...] = get_args(ViewerQuality)
"""What a mirrored viewer draws: ``"draft"`` (the simplified meshes the recorder ships, no
shadows or reflections), ``"full"`` (the model as it is), or ``"auto"`` (draft when OpenGL renders
on the CPU, e.g. Mesa llvmpipe in a VM, WSL or a remote desktop; full on a GPU)."""


class MirroredViewer:
    """A passive viewer that draws a copy of the physics, so the physics never waits for drawing.

    It shows ``model``/``data`` (its own model, possibly with the draft meshes, and its own
    data). :meth:`sync` only copies the source data's state (time, joint positions and
    velocities, mocap poses: microseconds) and returns; a thread of its own
    (``so101sim-viewer-sync``) then computes the copy's positions (``mj_forward``) and hands it
    to MuJoCo's viewer, which may take a frame's drawing time (about 25 ms with the full meshes
    on llvmpipe). States synced faster than the viewer draws are skipped: it always shows the
    latest. Call :meth:`sync` where the source data is not being stepped (holding the lock the
    stepping holds, or from the stepping thread).

    Whatever is done in the window (perturbing a body with Ctrl+drag, the joint sliders)
    changes the copy only and never reaches the physics. The pose finder, which reads the
    sliders, uses the viewer on the live data (``open_viewer(..., mirror=False)``).
    """

    def __init__(
        self, handle: Any, model: mujoco.MjModel, data: mujoco.MjData, source: mujoco.MjData
    ) -> None:
        self.handle = handle
        self.model = model
        self.data = data
        self.frames = 0  # states handed to MuJoCo's viewer so far (for frames/s)
        self._source = source
        self._fields = [f for f in _MIRRORED if getattr(data, f).shape == getattr(source, f).shape]
        self._staged = {f: np.array(getattr(source, f), copy=True) for f in self._fields}
        self._time = float(source.time)
        self._fresh = False
        self._closed = False
        self._cond = threading.Condition()
        self._thread = threading.Thread(
            target=self._sync_loop, name="so101sim-viewer-sync", daemon=True
        )
        self._thread.start()

    @property
    def cam(self) -> Any:
        return self.handle.cam

    @property
    def opt(self) -> Any:
        return self.handle.opt

    def is_running(self) -> bool:
        return bool(self.handle.is_running()) and not self._closed

    def lock(self) -> Any:
        """The viewer's own lock (around its copy of the data)."""
        return self.handle.lock()

    def sync(self, state_only: bool = False) -> None:
        """Copy the source data's state for the viewer to show; returns without drawing."""
        with self._cond:
            for f in self._fields:
                np.copyto(self._staged[f], getattr(self._source, f))
            self._time = float(self._source.time)
            self._fresh = True
            self._cond.notify()

    def close(self) -> None:
        """Stop the sync thread and close the window (waits for the thread)."""
        with self._cond:
            self._closed = True
            self._cond.notify()
        self.handle.close()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=10.0)

    def _take(self) -> tuple[float, dict[str, np.ndarray]] | None:
        """The latest staged state (waits for one), or None once closed."""
        with self._cond:
            while not self._fresh and not self._closed:
                self._cond.wait()
            if self._closed:
                return None
            self._fresh = False
            return self._time, {f: a.copy() for f, a in self._staged.items()}

    def _sync_loop(self) -> None:
        m, d = self.model, self.data
        while (state := self._take()) is not None:
            t, arrays = state
            try:
                with mujoco_call(), self.handle.lock():  # none once the interpreter exits
                    for f, a in arrays.items():
                        getattr(d, f)[:] = a
                    d.time = t
                    mujoco.mj_forward(m, d)
            except ClosedError:
                return
            self.handle.sync()
            self.frames += 1


_MIRRORED = ("qpos", "qvel", "mocap_pos", "mocap_quat")

VIEWER_NICE = 10
"""The niceness a mirrored viewer's threads get (Linux): MuJoCo's viewer draws frames
back-to-back, which on a CPU renderer takes a core or more; at this niceness the physics gets
the CPU first (about 9 to 1 against the drawing when both want it)."""


def _native_threads() -> set[int]:
    """The process's thread ids (Linux; empty elsewhere)."""
    try:
        return {int(t) for t in os.listdir("/proc/self/task")}
    except OSError:
        return set()


def lower_priority(thread_ids: set[int], nice: int = VIEWER_NICE) -> None:
    """Give the threads ``thread_ids`` (native ids) the niceness ``nice`` at least (Linux: per
    thread); best effort, errors are ignored."""
    for tid in thread_ids:
        with contextlib.suppress(OSError):
            os.setpriority(os.PRIO_PROCESS, tid, max(nice, os.getpriority(os.PRIO_PROCESS, tid)))


def copy_state(source: mujoco.MjData, dest: mujoco.MjData) -> None:
    """Copy what drawing needs (time, joint positions and velocities, mocap poses) from
    ``source`` to ``dest`` where their sizes match."""
    for f in _MIRRORED:
        a, b = getattr(source, f), getattr(dest, f)
        if a.shape == b.shape:
            b[:] = a
    dest.time = source.time


def mirror_model(m: mujoco.MjModel, quality: ViewerQuality = "auto") -> mujoco.MjModel:
    """The model a mirrored viewer draws ``m`` with: ``quality`` as :data:`VIEWER_QUALITIES`
    says (``"auto"``: draft when OpenGL renders on the CPU). Same bodies and joints as ``m``;
    ``m`` itself is never changed."""
    # imported here: the recorder's modules are only needed by a mirrored viewer (and
    # so101sim.recording imports this module's frame_arm)
    from ..recording.draft import render_model
    from ..recording.settings import resolve_quality

    resolved = resolve_quality(check_choice(quality, "viewer quality", VIEWER_QUALITIES))
    shown = render_model(m, resolved, 0, 0)
    if resolved == "draft":
        shown.light_castshadow[:] = 0  # no shadows: a shadow pass doubles the drawing
    return shown


def _check_can_open(quality: str, mirror: bool) -> None:
    check_choice(quality, "viewer quality", VIEWER_QUALITIES)
    if quality == "draft" and not mirror:
        raise SettingError(
            "the viewer shows the draft meshes only on a copy of the physics: pass "
            "mirror=True with quality='draft' (or use quality='auto' or 'full')"
        )
    if on_macos_without_mjpython():
        raise ViewerError(MACOS_MESSAGE)
    if not has_display():
        raise ViewerError(
            "no display to open the viewer on (DISPLAY is not set); run without the viewer "
            "(--headless on so101sim's commands, viewer=False in Python), or start a virtual "
            "display: `xvfb-run so101sim ...` or `xvfb-run python your_script.py`"
        )


def _launch_passive(
    m: mujoco.MjModel, d: mujoco.MjData, *, show_ui: bool, key_callback: Any
) -> Any:
    # mujoco.viewer (GLFW) only when a window opens: it needs a display
    import mujoco.viewer

    try:
        return mujoco.viewer.launch_passive(
            m, d, key_callback=key_callback, show_left_ui=show_ui, show_right_ui=show_ui
        )
    except RuntimeError as exc:  # macOS without mjpython, or GLFW failed to start
        if sys.platform == "darwin":
            raise ViewerError(MACOS_MESSAGE) from exc
        raise ViewerError(f"the viewer could not be opened: {exc}") from exc


@contextlib.contextmanager
def open_viewer(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    *,
    show_ui: bool = False,
    key_callback: Any = None,
    mirror: bool = False,
    quality: ViewerQuality = "auto",
) -> Iterator[Any]:
    """Open MuJoCo's passive viewer on ``(m, d)``, framed on the arm; closes it on exit.

    ``mirror=False`` (the default): the viewer draws ``(m, d)`` themselves with the model's
    meshes (``quality`` must be ``"auto"`` or ``"full"``); its ``sync()`` draws while the
    caller waits, and what is done in the window (sliders, perturbations) reaches ``d``, as the
    pose finder needs. ``mirror=True``: a :class:`MirroredViewer` drawing a copy, at
    ``quality`` (:data:`VIEWER_QUALITIES`; ``"auto"``: the draft meshes on a CPU renderer), whose
    ``sync()`` never waits for drawing, and whose threads run at niceness :data:`VIEWER_NICE`
    (Linux); changes made in its window do not reach ``d``.

    Raises:
        ViewerError: no display, or macOS without mjpython (the message says what to do).
        SettingError: ``quality`` is not one of :data:`VIEWER_QUALITIES`, or is ``"draft"``
            without ``mirror=True``, or ``m`` is a physics-only model without ``mirror=True``.
    """
    if not mirror and is_physics_only(m):
        raise SettingError(
            "this model was loaded with physics_only=True: it has no visual geoms to draw;"
            " open the viewer with mirror=True (it draws the full model of the same file) "
            "or load the model with so101sim.load_model(path)"
        )
    _check_can_open(quality, mirror)
    shown_m, shown_d = m, d
    if mirror:
        shown_m = mirror_model(m, quality)
        shown_d = mujoco.MjData(shown_m)
        copy_state(d, shown_d)  # the window opens on the present pose
    before, tasks = set(threading.enumerate()), _native_threads()
    handle = _launch_passive(shown_m, shown_d, show_ui=show_ui, key_callback=key_callback)
    ui_threads = [t for t in threading.enumerate() if t not in before]
    if mirror:  # drawing runs in the background: it yields the CPU to the physics
        lower_priority(_native_threads() - tasks, VIEWER_NICE)
    shown: Any = handle
    try:
        with handle.lock():
            frame_arm(handle.cam)
        if mirror:
            shown = MirroredViewer(handle, shown_m, shown_d, d)
        shown.sync()
        yield shown
    finally:
        shown.close()
        # The viewer's render thread is a daemon: if the interpreter exits (and GLFW is
        # terminated) while it is still tearing its window down, the process segfaults.
        # Wait for it to finish so that closing is clean.
        for t in ui_threads:
            t.join(timeout=10.0)
        log.debug("viewer closed")


def view(m: mujoco.MjModel, d: mujoco.MjData) -> None:
    """Open MuJoCo's full interactive viewer (it runs the physics itself) until it is closed."""
    if on_macos_without_mjpython():
        # launch() works on macOS without mjpython; only the passive viewer needs it.
        pass
    elif not has_display():
        raise ViewerError(
            "no display to open the viewer on (DISPLAY is not set); run `so101sim view --web` "
            "to see it in a web browser instead (no display needed), or on a server "
            "`xvfb-run so101sim view`, or record a video"
        )
    # mujoco.viewer (GLFW) only when a window opens: it needs a display
    import mujoco.viewer

    mujoco.viewer.launch(m, d)
