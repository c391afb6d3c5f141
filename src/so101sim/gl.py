"""Choosing MuJoCo's OpenGL backend, which must happen before ``mujoco`` is first imported.

With no display (a server, CI, ssh), offscreen rendering needs EGL (Mesa renders it on the
CPU when there is no GPU) or, failing that, OSMesa. If ``MUJOCO_GL`` is already set, it is left
alone. The choice only looks for the libraries (a ``dlopen``, no GL context is made), so
importing so101sim stays cheap; :func:`backend_help` says what to install when none is found.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
import sys
from collections.abc import Callable

log = logging.getLogger(__name__)

# Library names tried for each headless backend, most specific first.
_LIBRARIES: dict[str, tuple[str, ...]] = {
    "egl": ("libEGL.so.1", "libEGL.so"),
    "osmesa": ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so"),
}
_FIND_NAMES = {"egl": "EGL", "osmesa": "OSMesa"}

selection = "not made yet"
"""What :func:`select_backend` did, for error messages."""

INSTALL_HINT = (
    "install Mesa's EGL (Debian/Ubuntu: `apt-get install libegl1 libgl1-mesa-dri`) or OSMesa "
    "(`apt-get install libosmesa6`), or run with a display (`xvfb-run so101sim ...`)"
)


def headless() -> bool:
    """True on Linux when no X11/Wayland display is available."""
    return sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )


def _dlopen(name: str) -> bool:
    try:
        ctypes.CDLL(name)
    except OSError:
        return False
    return True


def library_loads(backend: str, loader: Callable[[str], bool] = _dlopen) -> bool:
    """Whether the shared library of ``backend`` ("egl" or "osmesa") can be loaded here."""
    names = list(_LIBRARIES[backend])
    found = ctypes.util.find_library(_FIND_NAMES[backend])
    if found and found not in names:
        names.append(found)
    return any(loader(n) for n in names)


def choose_headless_backend(loader: Callable[[str], bool] = _dlopen) -> str | None:
    """ "egl" if libEGL loads, else "osmesa" if libOSMesa loads, else None."""
    for backend in ("egl", "osmesa"):
        if library_loads(backend, loader):
            return backend
    return None


def _mujoco_imported() -> bool:
    return "mujoco" in sys.modules


def select_backend(loader: Callable[[str], bool] = _dlopen) -> str | None:
    """With no display and nothing chosen, set ``MUJOCO_GL`` to EGL, or OSMesa when EGL does not
    load; return the choice (None: none loads, rendering will fail with :func:`backend_help`)."""
    global selection
    if "MUJOCO_GL" in os.environ:
        selection = "MUJOCO_GL was set before so101sim was imported"
    elif not headless():
        selection = "a display is available: MuJoCo's default (GLFW)"
    elif _mujoco_imported():
        selection = (
            "mujoco was imported before so101sim, too late to choose a headless backend "
            "(import so101sim first, or set MUJOCO_GL=egl)"
        )
    else:
        backend = choose_headless_backend(loader)
        if backend is not None:
            os.environ["MUJOCO_GL"] = backend
            selection = f"no display: chose {backend} (its library loads)"
        else:
            selection = "no display, and neither libEGL nor libOSMesa loads"
    log.debug("OpenGL backend: %s", selection)
    return os.environ.get("MUJOCO_GL")


def ensure_offscreen_backend(loader: Callable[[str], bool] = _dlopen) -> str | None:
    """Make offscreen rendering possible when ``mujoco`` was imported before so101sim on a
    machine with no display (MuJoCo then picked GLFW, which needs one): switch the context class
    its ``Renderer`` uses to EGL, or OSMesa, whichever loads. Returns ``MUJOCO_GL``."""
    global selection
    if os.environ.get("MUJOCO_GL") or not headless():
        return os.environ.get("MUJOCO_GL")
    backend = choose_headless_backend(loader)
    if backend is None:
        return None
    try:
        from mujoco.rendering.classic import gl_context

        if backend == "egl":
            from mujoco.egl import GLContext
        else:
            from mujoco.osmesa import GLContext
    except ImportError as exc:  # another mujoco layout, or PyOpenGL bound to another platform
        log.debug("could not switch MuJoCo's GL context to %s: %s", backend, exc)
        return None
    gl_context.GLContext = GLContext
    os.environ["MUJOCO_GL"] = backend
    selection = f"mujoco was imported before so101sim with no display: switched to {backend}"
    log.debug("OpenGL backend: %s", selection)
    return backend


def backend_help(error: BaseException | str | None = None) -> str:
    """The message for a renderer that could not start: what failed and what to install."""
    chosen = os.environ.get("MUJOCO_GL", "(unset)")
    what = f": {error}" if error else ""
    return (
        f"offscreen rendering could not start (MUJOCO_GL={chosen}; {selection}){what}; "
        f"expected a working EGL, OSMesa or display: {INSTALL_HINT}. To force a backend set "
        "MUJOCO_GL=egl or MUJOCO_GL=osmesa before starting Python"
    )


select_backend()


_renderer_string: str | None = None


def renderer_string() -> str:
    """The OpenGL renderer's name (``GL_RENDERER``, e.g. "llvmpipe (LLVM 15.0.7, 256 bits)" for
    Mesa on a CPU), from a 16×16 offscreen context made once per process; "" if none starts."""
    global _renderer_string
    if _renderer_string is None:
        ensure_offscreen_backend()
        try:
            from mujoco.rendering.classic import gl_context
            from OpenGL import GL

            ctx = gl_context.GLContext(16, 16)
            try:
                ctx.make_current()
                raw = GL.glGetString(GL.GL_RENDERER)
                _renderer_string = raw.decode(errors="replace") if raw else ""
            finally:
                ctx.free()
        except Exception as exc:  # no backend: the renderer itself will report it
            log.debug("could not query GL_RENDERER: %s", exc)
            _renderer_string = ""
    return _renderer_string


SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "swiftshader", "software")


def software_rendering() -> bool:
    """True when OpenGL renders on the CPU (Mesa llvmpipe and the like) or cannot be queried."""
    name = renderer_string().lower()
    return not name or any(s in name for s in SOFTWARE_RENDERERS)
