"""Choosing MuJoCo's OpenGL backend for offscreen rendering, when rendering is asked for.

With no display (a server, CI, ssh), offscreen rendering needs EGL (Mesa renders it on the
CPU when there is no GPU) or, failing that, OSMesa. If ``MUJOCO_GL`` is already set, it is left
alone. Importing this module changes nothing: :func:`prepare_for_rendering` makes the choice,
and is called by whatever is about to render (the recorder's frame renderer, the renderer
query); a command that will render can call it early, before ``mujoco`` is imported, so that
MuJoCo reads the choice from ``MUJOCO_GL``. Called later, it switches the context class
MuJoCo's ``Renderer`` uses instead. The choice only looks for the libraries (a ``dlopen``, no
GL context is made); :func:`backend_help` says what to install when none is found.
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
"""What :func:`prepare_for_rendering` did, for error messages."""

_chosen: str | None = None
"""The backend so101sim put in ``MUJOCO_GL`` (None: it set nothing)."""

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


def prepare_for_rendering(loader: Callable[[str], bool] = _dlopen) -> str | None:
    """Make offscreen rendering possible here, before the first renderer starts; return
    ``MUJOCO_GL`` (None: MuJoCo's default, or no backend loads).

    Before ``mujoco`` is imported: :func:`select_backend` (sets ``MUJOCO_GL``, which MuJoCo
    reads when it is imported). After, with no display and ``MUJOCO_GL`` unset:
    :func:`ensure_offscreen_backend` (switches MuJoCo's context class). Cheap to call again.
    """
    if "MUJOCO_GL" in os.environ or not headless() or not _mujoco_imported():
        return select_backend(loader)
    return ensure_offscreen_backend(loader)


def one_rasterizer_thread() -> None:
    """A worker process's start where several workers share the cores: Mesa's CPU rasteriser
    draws in the thread that renders, with no thread of its own (``LP_NUM_THREADS=0``, unless
    already set; Mesa reads it when the first GL context is made). The workers already keep
    the cores busy: a rasteriser thread only hands each frame over and back (two context
    switches a camera frame), and with one a dataset worker spent 7.9-8.5 ms of CPU a frame of
    two 160x120 cameras against 6.0-6.5 ms without, for the same pixels. Defined here, in a
    module that imports nothing heavy, so that a process pool started with it as its
    initializer imports nothing else to run it."""
    os.environ.setdefault("LP_NUM_THREADS", "0")


def skip_opengl() -> bool:
    """For a command that draws nothing (``so101sim run --headless`` without ``--record``):
    tell MuJoCo not to load an OpenGL backend at all (``MUJOCO_GL=disable``; its default would
    load the GLFW library, a noticeable part of a short run's start-up). Only before ``mujoco``
    is imported and when ``MUJOCO_GL`` is unset; returns whether it was set."""
    if "MUJOCO_GL" in os.environ or _mujoco_imported():
        return False
    _set_backend("disable", "so101sim set MUJOCO_GL=disable: the command draws nothing")
    return True


def _set_backend(backend: str, why: str) -> None:
    global selection, _chosen
    os.environ["MUJOCO_GL"] = _chosen = backend
    selection = why
    log.debug("OpenGL backend: %s", selection)


def select_backend(loader: Callable[[str], bool] = _dlopen) -> str | None:
    """With no display and nothing chosen, set ``MUJOCO_GL`` to EGL, or OSMesa when EGL does not
    load; return the choice (None: none loads, rendering will fail with :func:`backend_help`).

    Only useful before ``mujoco`` is imported (see :func:`prepare_for_rendering`)."""
    global selection
    chosen = os.environ.get("MUJOCO_GL")
    if chosen is not None:
        if chosen != _chosen:
            selection = "MUJOCO_GL was set outside so101sim"
        return chosen
    if not headless():
        selection = "a display is available: MuJoCo's default (GLFW)"
    elif _mujoco_imported():
        selection = (
            "mujoco was imported before a backend was chosen, too late to set MUJOCO_GL "
            "(call so101sim.gl.prepare_for_rendering() first, or set MUJOCO_GL=egl)"
        )
    else:
        backend = choose_headless_backend(loader)
        if backend is not None:
            _set_backend(backend, f"no display: chose {backend} (its library loads)")
            return backend
        selection = "no display, and neither libEGL nor libOSMesa loads"
    log.debug("OpenGL backend: %s", selection)
    return None


def ensure_offscreen_backend(loader: Callable[[str], bool] = _dlopen) -> str | None:
    """Make offscreen rendering possible when ``mujoco`` was imported before a backend was
    chosen, on a machine with no display (MuJoCo then picked GLFW, which needs one): switch the
    context class its ``Renderer`` uses to EGL, or OSMesa, whichever loads. Returns
    ``MUJOCO_GL``."""
    global selection
    if os.environ.get("MUJOCO_GL") or not headless():
        return os.environ.get("MUJOCO_GL")
    backend = choose_headless_backend(loader)
    if backend is None:
        selection = "no display, and neither libEGL nor libOSMesa loads"
        return None
    try:
        # MuJoCo's OpenGL modules only once a backend is chosen (importing them binds one)
        from mujoco.rendering.classic import gl_context

        if backend == "egl":
            from mujoco.egl import GLContext
        else:
            from mujoco.osmesa import GLContext
    except ImportError as exc:  # another mujoco layout, or PyOpenGL bound to another platform
        selection = f"could not switch MuJoCo's GL context to {backend}: {exc}"
        log.debug("OpenGL backend: %s", selection)
        return None
    gl_context.GLContext = GLContext
    _set_backend(backend, f"mujoco was imported first, with no display: switched to {backend}")
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


_renderer_string: str | None = None


def renderer_string() -> str:
    """The OpenGL renderer's name (``GL_RENDERER``, e.g. "llvmpipe (LLVM 15.0.7, 256 bits)" for
    Mesa on a CPU), from a 16×16 offscreen context made once per process; "" if none starts."""
    global _renderer_string
    if _renderer_string is None:
        prepare_for_rendering()
        try:
            # MuJoCo's OpenGL modules only once a backend is chosen (importing them binds one)
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
