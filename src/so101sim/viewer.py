"""The interactive viewer: finding a display, opening MuJoCo's passive viewer, pacing it.

MuJoCo's passive viewer (``mujoco.viewer.launch_passive``) shows the simulation while our code
steps it; :class:`so101sim.simulation.ViewerObserver` syncs it and paces it to the wall clock.
It needs a display; on macOS it also needs the script to run under ``mjpython``.
:func:`choose_viewer` decides, before anything opens, whether a run shows the viewer.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import mujoco

from .errors import ViewerError

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


@contextlib.contextmanager
def open_viewer(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    *,
    show_ui: bool = False,
    key_callback: Any = None,
) -> Iterator[Any]:
    """Open MuJoCo's passive viewer on ``(m, d)``, framed on the arm; closes it on exit.

    Raises:
        ViewerError: no display, or macOS without mjpython (the message says what to do).
    """
    if on_macos_without_mjpython():
        raise ViewerError(MACOS_MESSAGE)
    if not has_display():
        raise ViewerError(
            "no display to open the viewer on (DISPLAY is not set); run headless "
            "(--headless), or start a virtual display with `xvfb-run so101sim ...`"
        )
    import mujoco.viewer

    before = set(threading.enumerate())
    try:
        handle = mujoco.viewer.launch_passive(
            m, d, key_callback=key_callback, show_left_ui=show_ui, show_right_ui=show_ui
        )
    except RuntimeError as exc:  # macOS without mjpython, or GLFW failed to start
        if sys.platform == "darwin":
            raise ViewerError(MACOS_MESSAGE) from exc
        raise ViewerError(f"the viewer could not be opened: {exc}") from exc
    ui_threads = [t for t in threading.enumerate() if t not in before]
    try:
        with handle.lock():
            frame_arm(handle.cam)
        handle.sync()
        yield handle
    finally:
        handle.close()
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
            "no display to open the viewer on (DISPLAY is not set); on a server use "
            "`xvfb-run so101sim view`, or record a video instead"
        )
    import mujoco.viewer

    mujoco.viewer.launch(m, d)
