"""Recording a run: an MP4 video, a plot of commanded vs measured angles, and a CSV log.

Everything here is an :class:`so101sim.simulation.Observer`, so any run of moves and holds can
write to it, and all of it is clocked by *simulated* time: a 6 s motion at 30 frames/s is
181 frames (t = 0, 1/30, …, 6 s) however fast the machine renders.

>>> sim = Simulation()
>>> with Recorder(sim, video="lab.mp4", plot="lab.png", log="lab.csv"):
...     sim.move_to(ZERO_POSE, 2.0, phase="to_zero")
...     sim.hold(2.0)

Every output path is checked (folder exists and is writable, file absent unless
``force=True``) before anything runs. Files are written under a temporary name in the same
folder and renamed when closed, also after Ctrl-C or an error, so a path holds either a
complete, playable file of what ran or nothing.

Rendering uses ``mujoco.Renderer`` on a private copy of the model (its offscreen buffer raised
to the frame size), fed the simulation's joint angles: the physics model is never touched.
The ``draft`` quality preset (the default) swaps the visual meshes for simplified ones shipped
in ``so101sim/data/draft_meshes`` and turns off shadows, reflections and multisampling, which
makes a CPU renderer (Mesa llvmpipe) about 20× faster; ``full`` keeps the model's look.
"""

from __future__ import annotations

import copy
import csv
import functools
import hashlib
import json
import logging
import math
import os
import threading
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

import mujoco
import numpy as np

from . import gl
from .errors import CameraError, OutputPathError, RecordingError, RenderBackendError
from .model import arm_units, load_model, loaded_models, model_dir, model_source
from .simulation import Observer, Trace
from .units import GRIPPER_INDEX, JOINT_NAMES
from .viewer import frame_arm

log = logging.getLogger(__name__)

QUALITIES = ("draft", "full")
QUALITY_CHOICES = ("auto", *QUALITIES)
FREE_CAMERA = "free"
VIDEO_SUFFIXES = (".mp4", ".mov", ".mkv")
PLOT_SUFFIXES = (".png", ".pdf", ".svg")
MAX_FPS = 240.0
_EPS = 1e-9


# ---------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class VideoSettings:
    """How a video is rendered: frame size in pixels, frames per simulated second, camera
    ("free" = the viewer's default view of the arm, or a camera named in the model), quality
    preset ("draft", "full", or "auto": draft when OpenGL renders on the CPU, full on a GPU) and
    whether a caption (time, phase) is drawn."""

    width: int = 640
    height: int = 480
    fps: float = 30.0
    camera: str = FREE_CAMERA
    quality: str = "auto"
    caption: bool = True

    def validated(self) -> VideoSettings:
        """Return self if every field is valid, else raise RecordingError saying what to use."""
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 16 or v % 2:
                raise RecordingError(
                    f"{name} = {v!r} pixels is invalid; expected an even whole number >= 16 "
                    "(H.264 needs even frame sizes)"
                )
        fps = self.fps
        if isinstance(fps, bool) or not isinstance(fps, int | float | np.number):
            raise RecordingError(f"fps = {fps!r} is not a number; expected 1 to {MAX_FPS:g}")
        if not (math.isfinite(fps) and 1.0 <= fps <= MAX_FPS):
            raise RecordingError(f"fps = {fps} is invalid; expected 1 to {MAX_FPS:g} frames/s")
        if self.quality not in QUALITY_CHOICES:
            raise RecordingError(
                f"unknown quality {self.quality!r}; valid presets are {', '.join(QUALITY_CHOICES)}"
            )
        return self


def resolve_quality(quality: str) -> str:
    """ "auto" -> "draft" when OpenGL renders on the CPU (Mesa llvmpipe), "full" on a GPU."""
    if quality == "auto":
        return "draft" if gl.software_rendering() else "full"
    return quality


def camera_names(model: mujoco.MjModel) -> list[str]:
    """The cameras a video can use: "free" (the viewer's default view) and the model's named
    cameras."""
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i) for i in range(model.ncam)]
    return [FREE_CAMERA, *(n for n in names if n)]


def check_camera(model: mujoco.MjModel, name: str) -> str:
    """Return ``name`` if the model can render from it, else raise CameraError listing the
    valid names."""
    valid = camera_names(model)
    if name not in valid:
        raise CameraError(
            f"unknown camera {name!r}; valid cameras for this model are {', '.join(valid)}"
            + (" (the model names no camera of its own)" if len(valid) == 1 else "")
        )
    return name


# ---------------------------------------------------------------------------- output paths
def check_output_path(
    path: str | os.PathLike[str],
    *,
    force: bool = False,
    what: str = "output",
    suffixes: Sequence[str] = (),
) -> Path:
    """Check that ``path`` can be written, before anything runs; return it as a Path.

    Raises:
        OutputPathError: the folder does not exist or is not writable, the path is a folder,
            the suffix is not one of ``suffixes``, or the file exists and ``force`` is False.
    """
    p = Path(path).expanduser()
    if suffixes and p.suffix.lower() not in suffixes:
        raise OutputPathError(
            f"{what} file {str(p)!r} has the wrong extension; expected one of {', '.join(suffixes)}"
        )
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise OutputPathError(
            f"cannot write the {what} {str(p)!r}: the folder {str(folder)!r} does not exist; "
            "expected an existing folder (create it first)"
        )
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(
            f"cannot write the {what} {str(p)!r}: the folder {str(folder)!r} is not writable; "
            "expected a folder you can write to"
        )
    if p.is_dir():
        raise OutputPathError(f"the {what} path {str(p)!r} is a folder; expected a file name")
    if p.exists() and not force:
        raise OutputPathError(
            f"the {what} file {str(p)!r} already exists; expected a new file name, or force "
            "overwriting (--force)"
        )
    return p


class _PendingFile:
    """A file written under a hidden temporary name next to ``path`` and renamed over it by
    :meth:`commit`; :meth:`discard` removes it. A path never holds half a file."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.tmp = path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")

    def commit(self) -> None:
        os.replace(self.tmp, self.path)

    def discard(self) -> None:
        self.tmp.unlink(missing_ok=True)


# ---------------------------------------------------------------------------- render models
def draft_mesh_dir() -> Path:
    """The folder of the simplified visual meshes used by the ``draft`` preset."""
    return Path(__file__).parent / "data" / "draft_meshes"


@functools.cache
def _draft_manifest() -> dict[str, dict[str, Any]]:
    path = draft_mesh_dir() / "manifest.json"
    if not path.is_file():
        return {}
    return json.loads(path.read_text())["meshes"]


@functools.cache
def _sha256(path: str, mtime_ns: int) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _mesh_file(spec: mujoco.MjSpec, mesh: Any) -> Path:
    base = Path(spec.modelfiledir or ".")
    return base / (spec.meshdir or "") / mesh.file


_render_lock = threading.Lock()
_draft_cache: dict[tuple[str, int], mujoco.MjModel | None] = {}


def _compile_draft(source: Path) -> mujoco.MjModel | None:
    """Compile ``source`` for drawing only: visual mesh geoms use the shipped simplified meshes
    whose originals match (by SHA-256), collision geoms are left out. None if nothing matches."""
    manifest = _draft_manifest()
    spec = mujoco.MjSpec.from_file(str(source))
    swapped: dict[str, str] = {}
    for mesh in list(spec.meshes):
        entry = manifest.get(Path(mesh.file).name)
        original = _mesh_file(spec, mesh)
        if entry is None or not original.is_file():
            continue
        if _sha256(str(original), original.stat().st_mtime_ns) != entry["original_sha256"]:
            continue
        draft = spec.add_mesh()
        draft.name = f"{mesh.name}__draft"
        draft.file = str(draft_mesh_dir() / Path(mesh.file).name)
        draft.scale = mesh.scale
        swapped[mesh.name] = draft.name
    if not swapped:
        return None
    for geom in list(spec.geoms):
        if geom.type != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        if geom.contype or geom.conaffinity:
            spec.delete(geom)  # collision geometry: never drawn (group 3), not needed here
        elif geom.meshname in swapped:
            geom.meshname = swapped[geom.meshname]
    used = {g.meshname for g in spec.geoms}
    for mesh in list(spec.meshes):
        if mesh.name not in used:
            spec.delete(mesh)
    return spec.compile()


SHIPPED_MODEL_FILES = ("scene.xml", "so101_new_calib.xml", "so101_old_calib.xml")
"""The shipped MJCF files, in :func:`so101sim.model.model_dir`."""

# What drawing a model's state depends on: its tree, geoms, materials, meshes, cameras, lights.
_DRAWN_FIELDS = (
    "body_parentid", "body_pos", "body_quat", "body_ipos", "body_iquat",
    "jnt_type", "jnt_bodyid", "jnt_pos", "jnt_axis",
    "geom_type", "geom_bodyid", "geom_pos", "geom_quat", "geom_size", "geom_rgba",
    "geom_group", "geom_matid", "geom_dataid", "geom_contype", "geom_conaffinity",
    "mat_rgba", "mat_texid", "mesh_vertnum", "mesh_facenum", "mesh_vert", "mesh_face",
    "mesh_pos", "mesh_quat", "cam_pos", "cam_quat", "cam_fovy", "light_pos", "light_dir",
    "light_diffuse",
)  # fmt: skip
_fingerprints: weakref.WeakKeyDictionary[mujoco.MjModel, str] = weakref.WeakKeyDictionary()


def _drawing_fingerprint(model: mujoco.MjModel, *, cache: bool = False) -> str:
    """A content hash of everything that drawing ``model`` depends on (compiled mesh data
    included): two models with the same fingerprint draw the same pictures."""
    if cache and model in _fingerprints:
        return _fingerprints[model]
    h = hashlib.sha256(bytes(model.names))
    h.update(np.array([model.nq, model.nbody, model.ngeom, model.nmesh, model.nmat]).tobytes())
    for name in _DRAWN_FIELDS:
        h.update(np.ascontiguousarray(getattr(model, name)).tobytes())
    out = h.hexdigest()
    if cache:
        _fingerprints[model] = out
    return out


def _shipped_meshes(model: mujoco.MjModel) -> list[str]:
    """The model's meshes that are shipped SO-101 meshes with a draft version: same name
    and same number of faces as the original in the draft manifest."""
    manifest = _draft_manifest()
    out = []
    for i in range(model.nmesh):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MESH, i) or ""
        entry = manifest.get(f"{name}.stl")
        if entry is not None and int(model.mesh_facenum[i]) == entry["original_faces"]:
            out.append(name)
    return out


def draft_source(model: mujoco.MjModel) -> tuple[Path | None, str]:
    """The MJCF file whose draft version draws ``model``, and why not if there is none.

    A model compiled by :func:`so101sim.model.load_model` is its file. Any other model (one
    compiled by ``mujoco.MjModel.from_xml_path`` directly, or a ``copy.copy`` of a loaded
    model) is matched by content, compiled mesh data included, against the models
    ``load_model`` has compiled and the shipped files (:data:`SHIPPED_MODEL_FILES`).
    """
    source = model_source(model)
    if source is not None:
        return source, ""
    if not _shipped_meshes(model):
        return None, (
            "none of its meshes is a shipped SO-101 mesh with a draft version (compared by "
            f"mesh name and face count with {draft_mesh_dir() / 'manifest.json'})"
        )
    fingerprint = _drawing_fingerprint(model)
    seen: set[Path] = set()
    for path, loaded in loaded_models():
        seen.add(path)
        if _drawing_fingerprint(loaded, cache=True) == fingerprint:
            return path, ""
    for name in SHIPPED_MODEL_FILES:
        path = (model_dir() / name).resolve()
        if path in seen or not path.is_file():
            continue
        if _drawing_fingerprint(load_model(path), cache=True) == fingerprint:
            return path, ""
    return None, (
        "it uses the shipped SO-101 meshes but was not compiled by so101sim.load_model(), and "
        "its bodies, geoms, materials or meshes differ from every model load_model() has "
        f"compiled and from the shipped {', '.join(SHIPPED_MODEL_FILES)} (changed after "
        "loading?); load the file with so101sim.load_model(path) to get the draft meshes"
    )


def render_model(model: mujoco.MjModel, quality: str, width: int, height: int) -> mujoco.MjModel:
    """A private model to draw ``model``'s state with, at ``quality``, its offscreen buffer at
    least ``width`` × ``height``. Same bodies and joints as ``model``; the physics model itself
    is never changed.

    ``draft``: the simplified visual meshes (when ``model`` is, or draws the same as, a model
    compiled from a file whose meshes they were made from: see :func:`draft_source`), no
    multisampling, no reflections (shadows are turned off by the renderer); otherwise the
    model's own meshes, with a logged warning. ``full``: a copy of ``model`` as it is.
    """
    if quality not in QUALITIES:
        raise RecordingError(f"unknown quality {quality!r}; valid presets are {QUALITIES}")
    base = model
    if quality == "draft":
        source, why = draft_source(model)
        if source is not None:
            key = (str(source), source.stat().st_mtime_ns)
            with _render_lock:
                if key not in _draft_cache:
                    try:
                        _draft_cache[key] = _compile_draft(source)
                    except (ValueError, mujoco.FatalError) as exc:  # keep the model's meshes
                        log.warning("draft meshes not used for %s: %s", source, exc)
                        _draft_cache[key] = None
                draft = _draft_cache[key]
            if draft is not None and (draft.nq, draft.nbody) == (model.nq, model.nbody):
                base = draft
            else:
                why = f"no shipped simplified mesh matches the meshes of {source}"
        if base is model:
            log.warning(
                "draft preset: falling back to the model's own meshes (slower to draw on a "
                "CPU renderer; shadows and reflections are still off) because %s",
                why,
            )
    rm = copy.copy(base)
    rm.vis.global_.offwidth = max(int(rm.vis.global_.offwidth), width)
    rm.vis.global_.offheight = max(int(rm.vis.global_.offheight), height)
    if quality == "draft":
        rm.vis.quality.offsamples = 0
        rm.mat_reflectance[:] = 0.0
    return rm


# ---------------------------------------------------------------------------- caption
class _Caption:
    """Draws one line of text into the bottom-left of a frame: FreeType (through matplotlib's
    bundled font) rasterises the string into a small alpha mask, numpy blends it in."""

    def __init__(self, height: int) -> None:
        from matplotlib import font_manager
        from matplotlib.ft2font import FT2Font

        self.font = FT2Font(font_manager.findfont("DejaVu Sans Mono"))
        self.size = max(8.0, height / 30)
        self.margin = max(4, height // 60)
        self._last: tuple[str, np.ndarray] | None = None

    def _mask(self, text: str) -> np.ndarray:
        if self._last is not None and self._last[0] == text:
            return self._last[1]
        self.font.set_size(self.size, 72)
        self.font.set_text(text, 0.0)
        self.font.draw_glyphs_to_bitmap(antialiased=True)
        mask = np.asarray(self.font.get_image(), dtype=np.float32) / 255.0
        self._last = (text, mask)
        return mask

    def draw(self, frame: np.ndarray, text: str) -> None:
        mask = self._mask(text)
        h, w = frame.shape[:2]
        pad = self.margin
        mh, mw = min(mask.shape[0], h - 2 * pad), min(mask.shape[1], w - 2 * pad)
        if mh <= 0 or mw <= 0:
            return
        y0, x0 = h - pad - mh - pad // 2, pad
        box = frame[y0 - pad // 2 : y0 + mh + pad // 2, x0 - pad // 2 : x0 + mw + pad // 2]
        box[:] = (box * 0.45).astype(np.uint8)  # darken the text's background
        region = frame[y0 : y0 + mh, x0 : x0 + mw].astype(np.float32)
        a = mask[:mh, :mw, None]
        frame[y0 : y0 + mh, x0 : x0 + mw] = (region * (1 - a) + 255.0 * a).astype(np.uint8)


# ---------------------------------------------------------------------------- frames
class FrameRenderer:
    """Draws the state of ``(model, data)`` to RGB frames with ``mujoco.Renderer`` on a private
    render model (see :func:`render_model`).

    Raises:
        CameraError, RecordingError: bad settings.
        RenderBackendError: no OpenGL backend works here (the message says what to install).
    """

    def __init__(self, model: mujoco.MjModel, settings: VideoSettings | None = None) -> None:
        self.settings = s = (settings or VideoSettings()).validated()
        check_camera(model, s.camera)
        self.model = model
        self.quality = resolve_quality(s.quality)
        self.render_model = render_model(model, self.quality, s.width, s.height)
        self.render_data = mujoco.MjData(self.render_model)
        gl.ensure_offscreen_backend()
        try:
            self.renderer = mujoco.Renderer(self.render_model, height=s.height, width=s.width)
        except Exception as exc:  # EGL/OSMesa/GLFW failures come as many exception types
            raise RenderBackendError(gl.backend_help(exc)) from exc
        if self.quality == "draft":
            flags = self.renderer.scene.flags
            flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
            flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        if s.camera == FREE_CAMERA:
            self.camera: mujoco.MjvCamera | str = mujoco.MjvCamera()
            frame_arm(self.camera)
        else:
            self.camera = s.camera
        self.frame = np.empty((s.height, s.width, 3), dtype=np.uint8)
        self._caption = _Caption(s.height) if s.caption else None

    def render(self, d: mujoco.MjData, caption: str | None = None) -> np.ndarray:
        """The frame of ``d``'s current state (a reused (height, width, 3) uint8 array)."""
        rm, rd = self.render_model, self.render_data
        rd.time = d.time
        rd.qpos[:] = d.qpos
        if rm.nmocap:
            rd.mocap_pos[:] = d.mocap_pos
            rd.mocap_quat[:] = d.mocap_quat
        mujoco.mj_kinematics(rm, rd)
        mujoco.mj_comPos(rm, rd)
        mujoco.mj_camlight(rm, rd)
        self.renderer.update_scene(rd, camera=self.camera)
        self.renderer.render(out=self.frame)
        if self._caption is not None and caption:
            self._caption.draw(self.frame, caption)
        return self.frame

    def close(self) -> None:
        self.renderer.close()


# ---------------------------------------------------------------------------- video
class VideoRecorder(Observer):
    """An observer that renders a frame every 1/fps s of simulated time and writes an H.264 MP4
    (imageio-ffmpeg, whose wheel ships ffmpeg).

    The first frame is the state when the recorder is first called; then one frame each time
    simulated time reaches the next frame's time. ``progress`` (e.g. a tqdm bar's ``update``) is
    called with 1 per frame. :meth:`close` finishes the file (also after an interruption).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        model: mujoco.MjModel,
        settings: VideoSettings | None = None,
        *,
        force: bool = False,
        progress: Callable[[int], Any] | None = None,
        preset: str = "veryfast",
        crf: int = 23,
    ) -> None:
        self.settings = (settings or VideoSettings()).validated()
        self.path = check_output_path(path, force=force, what="video", suffixes=VIDEO_SUFFIXES)
        check_camera(model, self.settings.camera)
        self.progress = progress
        self.preset = preset
        self.crf = crf
        self.frames = 0
        self.phase = ""
        self._t0: float | None = None
        self._last_time = -math.inf
        self._frames_since_anchor = 0
        self._renderer: FrameRenderer | None = None
        self._writer: Any = None
        self._file: _PendingFile | None = None
        self.closed = False
        self._model = model

    # -- timeline
    def next_time(self) -> float:
        if self.closed:
            return math.inf
        if self._t0 is None:
            return -math.inf
        return self._t0 + self._frames_since_anchor / self.settings.fps - _EPS

    def on_steps(self, trace: Trace, phase: str) -> None:
        self.phase = phase

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        t = float(d.time)
        if self._t0 is None or t < self._last_time - _EPS:  # first call, or the clock was reset
            self._t0, self._frames_since_anchor = t, 0
        self.write_frame(d)
        self._last_time = t
        self._frames_since_anchor += 1
        return True

    # -- frames
    def open(self) -> None:
        """Start the renderer and the encoder (done by the first frame if not called)."""
        if self._writer is not None:
            return
        if self.closed:
            raise RecordingError(f"the video {str(self.path)!r} is already closed")
        import imageio_ffmpeg

        s = self.settings
        self._renderer = FrameRenderer(self._model, s)
        self._file = _PendingFile(self.path)
        writer = imageio_ffmpeg.write_frames(
            str(self._file.tmp),
            (s.width, s.height),
            fps=float(s.fps),
            codec="libx264",
            quality=None,
            macro_block_size=2,
            output_params=["-preset", self.preset, "-crf", str(self.crf)],
        )
        writer.send(None)
        self._writer = writer
        log.debug(
            "recording %s (%dx%d, %g fps, %s)", self.path, s.width, s.height, s.fps, s.quality
        )

    def caption(self, d: mujoco.MjData) -> str:
        return f"t = {d.time:6.2f} s   {self.phase}".rstrip()

    def write_frame(self, d: mujoco.MjData) -> None:
        """Render ``d``'s state and append it to the video."""
        self.open()
        assert self._renderer is not None
        frame = self._renderer.render(d, self.caption(d) if self.settings.caption else None)
        self._writer.send(frame)
        self.frames += 1
        if self.progress is not None:
            self.progress(1)

    def close(self) -> Path | None:
        """Finish the file and move it into place; return its path (None if no frame was
        written: then no file is made)."""
        if self.closed:
            return self.path if self.frames else None
        self.closed = True
        if self._renderer is not None:
            self._renderer.close()
        if self._writer is None or self._file is None:
            return None
        try:
            self._writer.close()  # ffmpeg writes the MP4 index and exits
        except BaseException:
            self._file.discard()
            raise
        if self.frames == 0:
            self._file.discard()
            return None
        self._file.commit()
        log.debug("wrote %d frames to %s", self.frames, self.path)
        return self.path


# ---------------------------------------------------------------------------- CSV log
def csv_columns() -> list[str]:
    """The CSV log's columns: ``time`` (s), ``phase``, then ``<joint>_commanded`` and
    ``<joint>_measured`` for each joint (degrees; the gripper 0–100)."""
    return [
        "time",
        "phase",
        *(f"{n}_commanded" for n in JOINT_NAMES),
        *(f"{n}_measured" for n in JOINT_NAMES),
    ]


class CsvLog(Observer):
    """An observer that writes one CSV row per control step (= per physics step): simulated
    time, phase, commanded and measured value of each joint in the arm's units.

    Rows are flushed after each block of steps; :meth:`close` moves the file into place, so an
    interrupted run leaves a complete CSV of the steps taken so far.
    """

    def __init__(
        self, path: str | os.PathLike[str], model: mujoco.MjModel, *, force: bool = False
    ) -> None:
        self.path = check_output_path(path, force=force, what="log")
        self.units = arm_units(model)
        self.rows = 0
        self.closed = False
        self._file = _PendingFile(self.path)
        self._fh: Any = None

    def _open(self) -> None:
        self._fh = open(self._file.tmp, "w", newline="", encoding="utf-8")  # noqa: SIM115
        csv.writer(self._fh).writerow(csv_columns())

    def on_steps(self, trace: Trace, phase: str) -> None:
        if self.closed:
            return
        if self._fh is None:
            self._open()
        n = len(trace)
        if not n:
            return
        values = np.column_stack(
            [self.units.from_radians(trace.ctrl), self.units.from_radians(trace.qpos)]
        )
        quoted = (
            phase if not any(c in phase for c in ',"\n\r') else '"' + phase.replace('"', '""') + '"'
        )
        fmt = "%.4f," + quoted.replace("%", "%%") + "," + ",".join(["%.6f"] * values.shape[1])
        np.savetxt(self._fh, np.column_stack([trace.time, values]), fmt=fmt)
        self._fh.flush()
        self.rows += n

    def close(self) -> Path | None:
        """Close and move the file into place (None if no step was logged: no file is made)."""
        if self.closed:
            return self.path if self.rows else None
        self.closed = True
        if self._fh is None:
            return None
        self._fh.close()
        if not self.rows:
            self._file.discard()
            return None
        self._file.commit()
        return self.path


# ---------------------------------------------------------------------------- plot
@dataclass
class RunLog:
    """Per-step arrays of a run in the arm's units, for plotting: ``times`` (n,), ``commanded``
    and ``measured`` (n, 6), ``phases`` [(name, start_time, end_time)]."""

    times: np.ndarray
    commanded: np.ndarray
    measured: np.ndarray
    phases: list[tuple[str, float, float]] = field(default_factory=list)

    @classmethod
    def from_result(cls, result: Any) -> RunLog:
        """From a :class:`so101sim.motion.RunResult` (or a single SegmentResult)."""
        segments = getattr(result, "segments", [result])
        if not segments:
            return cls(np.empty(0), np.empty((0, 6)), np.empty((0, 6)), [])
        return cls(
            np.concatenate([s.times for s in segments]),
            np.concatenate([s.commanded for s in segments]),
            np.concatenate([s.measured for s in segments]),
            [(s.phase, s.start_time, s.end_time) for s in segments],
        )


class TraceCollector(Observer):
    """Keeps every step of a run, for a plot made after it (see :meth:`run_log`)."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.units = arm_units(model)
        self.timestep = float(model.opt.timestep)
        self._blocks: list[tuple[Trace, str]] = []

    def on_steps(self, trace: Trace, phase: str) -> None:
        if len(trace):
            block = Trace(trace.time.copy(), trace.ctrl.copy(), trace.qpos.copy())
            self._blocks.append((block, phase))

    def run_log(self) -> RunLog:
        """The steps so far; consecutive blocks of the same phase make one shaded phase."""
        if not self._blocks:
            return RunLog(np.empty(0), np.empty((0, 6)), np.empty((0, 6)), [])
        times = np.concatenate([b.time for b, _ in self._blocks])
        cmd = self.units.from_radians(np.concatenate([b.ctrl for b, _ in self._blocks]))
        meas = self.units.from_radians(np.concatenate([b.qpos for b, _ in self._blocks]))
        phases: list[tuple[str, float, float]] = []
        for block, phase in self._blocks:
            start, end = float(block.time[0]) - self.timestep, float(block.time[-1])
            if phases and phases[-1][0] == phase:
                phases[-1] = (phase, phases[-1][1], end)
            else:
                phases.append((phase, start, end))
        return RunLog(times, cmd, meas, phases)


_PHASE_COLOURS = ("#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860")


def plot_run(
    result: Any,
    path: str | os.PathLike[str],
    *,
    width: int = 1280,
    height: int = 960,
    dpi: int = 100,
    force: bool = False,
    title: str | None = None,
) -> Path:
    """Plot a run: per joint the commanded and measured angle over time (the gripper on its
    0–100 scale), the phases shaded, and the tracking error |commanded − measured| of every
    joint; written with matplotlib's Agg backend to ``path`` (PNG of ``width`` × ``height``
    pixels, or PDF/SVG).

    ``result``: a :class:`so101sim.motion.RunResult`, a SegmentResult, or a :class:`RunLog`.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    p = check_output_path(path, force=force, what="plot", suffixes=PLOT_SUFFIXES)
    run = result if isinstance(result, RunLog) else RunLog.from_result(result)
    if len(run.times) == 0:
        raise RecordingError("nothing to plot: the run took no steps; expected a run of > 0 s")
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(4, 2)
    axes = [fig.add_subplot(grid[i // 2, i % 2]) for i in range(len(JOINT_NAMES))]
    err_ax = fig.add_subplot(grid[3, :])
    t = run.times
    for i, (ax, name) in enumerate(zip(axes, JOINT_NAMES, strict=True)):
        ax.plot(t, run.commanded[:, i], color="0.25", lw=1.2, ls="--", label="commanded")
        ax.plot(t, run.measured[:, i], color="#c44e52", lw=1.2, label="measured")
        ax.set_title(name, fontsize="medium")
        ax.set_ylabel("0–100" if i == GRIPPER_INDEX else "degrees")
        if i == GRIPPER_INDEX:
            ax.set_ylim(-5, 105)
        else:  # at least 2° of range, so a joint that does not move draws a flat line
            lo = min(run.commanded[:, i].min(), run.measured[:, i].min())
            hi = max(run.commanded[:, i].max(), run.measured[:, i].max())
            mid, half = (lo + hi) / 2, max((hi - lo) / 2 * 1.08, 1.0)
            ax.set_ylim(mid - half, mid + half)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize="small")
    err = np.abs(run.commanded - run.measured)
    for i, name in enumerate(JOINT_NAMES):
        unit = "" if i == GRIPPER_INDEX else "°"
        err_ax.plot(t, err[:, i], lw=1.0, label=f"{name} (max {err[:, i].max():.2f}{unit})")
    err_ax.set_title("tracking error |commanded − measured| (degrees; gripper 0–100)")
    err_ax.set_xlabel("simulated time (s)")
    err_ax.grid(alpha=0.3)
    fig.legend(
        *err_ax.get_legend_handles_labels(),
        loc="outside lower center",
        fontsize="small" if width >= 1000 else "x-small",
        ncol=6 if width >= 1200 else 3,
    )
    for k, (phase, t0, t1) in enumerate(run.phases):
        colour = _PHASE_COLOURS[k % len(_PHASE_COLOURS)]
        for ax in (*axes, err_ax):
            ax.axvspan(t0, t1, color=colour, alpha=0.08, lw=0)
        err_ax.text(
            (t0 + t1) / 2,
            0.97,
            phase,
            transform=err_ax.get_xaxis_transform(),
            ha="center",
            va="top",
            fontsize="small",
            color=colour,
        )
    for ax in (*axes, err_ax):
        ax.set_xlim(min(ph[1] for ph in run.phases) if run.phases else t[0], t[-1])
    fig.suptitle(title or "so101sim run: commanded vs measured joint angles")
    pending = _PendingFile(p)
    try:
        fig.savefig(pending.tmp, dpi=dpi, format=p.suffix.lstrip(".").lower())
        pending.commit()
    except BaseException:
        pending.discard()
        raise
    return p


# ---------------------------------------------------------------------------- recorder
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
        video: str | os.PathLike[str] | None = None,
        plot: str | os.PathLike[str] | None = None,
        log: str | os.PathLike[str] | None = None,
        settings: VideoSettings | None = None,
        force: bool = False,
        progress: Callable[[int], Any] | None = None,
        plot_size: tuple[int, int] = (1280, 960),
    ) -> None:
        self.sim = None if isinstance(target, mujoco.MjModel) else target
        self.model: mujoco.MjModel = target if self.sim is None else target.model
        self.settings = (settings or VideoSettings()).validated()
        paths = [Path(p).expanduser().resolve() for p in (video, plot, log) if p is not None]
        if len(set(paths)) != len(paths):
            raise OutputPathError("the video, plot and log paths must differ; got the same twice")
        self.plot_path = (
            check_output_path(plot, force=force, what="plot", suffixes=PLOT_SUFFIXES)
            if plot is not None
            else None
        )
        self.plot_size = plot_size
        self.force = force
        self.video = (
            VideoRecorder(video, self.model, self.settings, force=force, progress=progress)
            if video is not None
            else None
        )
        self.log = CsvLog(log, self.model, force=force) if log is not None else None
        self.collector = TraceCollector(self.model) if plot is not None else None
        self.observers: list[Observer] = [
            o for o in (self.video, self.log, self.collector) if o is not None
        ]
        self.outputs: dict[str, Path] = {}
        self._attached = False

    def open(self) -> Recorder:
        """Start the video's renderer and encoder now (else at the first frame)."""
        if self.video is not None:
            self.video.open()
        return self

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
        if self._attached and self.sim is not None:
            for o in self.observers:
                if o in self.sim.observers:
                    self.sim.observers.remove(o)
            self._attached = False
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
        if self.collector is not None and self.plot_path is not None and "plot" not in self.outputs:
            run = self.collector.run_log()
            if len(run.times):
                w, h = self.plot_size
                self.outputs["plot"] = plot_run(
                    run, self.plot_path, width=w, height=h, force=self.force
                )
        if errors:
            raise errors[0]
        return dict(self.outputs)


def video_frames(duration: float, fps: float) -> int:
    """Frames a recording of ``duration`` simulated seconds holds: one at the start, then one
    every 1/fps s (a 6 s motion at 30 fps: 181)."""
    return math.floor(duration * fps + 1e-6) + 1


__all__ = [
    "FREE_CAMERA",
    "QUALITIES",
    "QUALITY_CHOICES",
    "CsvLog",
    "FrameRenderer",
    "Recorder",
    "RunLog",
    "TraceCollector",
    "VideoRecorder",
    "VideoSettings",
    "camera_names",
    "check_camera",
    "check_output_path",
    "csv_columns",
    "draft_mesh_dir",
    "plot_run",
    "render_model",
    "resolve_quality",
    "video_frames",
]
