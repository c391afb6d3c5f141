"""What a video is rendered with: :class:`VideoSettings` (frame size, frame rate, camera,
quality preset, caption), the quality presets and the cameras a model offers."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

import mujoco

from .. import gl
from ..errors import CameraError, RecordingError
from ..validation import check_choice, check_count, check_range
from .framing import NAMED_VIEWS, ViewName

Quality = Literal["draft", "full"]
QualityChoice = Literal["auto", "draft", "full"]
QUALITIES: tuple[str, ...] = get_args(Quality)
QUALITY_CHOICES: tuple[str, ...] = get_args(QualityChoice)
FREE_CAMERA = "free"
MAX_FPS = 240.0
MIN_FRAME_SIZE = 16
MAX_FRAME_SIZE = 4096
"""The largest frame width or height, in pixels (4K; a 4096×4096 frame is 48 MiB of RGB)."""


@dataclass(frozen=True)
class VideoSettings:
    """How a video is rendered: frame size in pixels, frames per simulated second, camera
    ("free" = the viewer's default view of the arm, or a camera named in the model), quality
    preset ("draft", "full", or "auto": draft when OpenGL renders on the CPU, full on a GPU) and
    whether a caption (time, phase) is drawn.

    With the free camera, the view is fitted to the space the arm sweeps during the run
    (:mod:`so101sim.recording.framing`), seen from the named ``view`` ("default", "front", "side",
    "top") or from ``azimuth``/``elevation`` (degrees); ``distance`` (m) and ``lookat``
    (x, y, z in m) override the fitted ones. ``title`` (e.g. the student's name) is drawn in
    the caption and written into the video's metadata."""

    width: int = 640
    height: int = 480
    fps: float = 30.0
    camera: str = FREE_CAMERA
    quality: QualityChoice = "auto"
    caption: bool = True
    title: str | None = None
    view: ViewName = "default"
    azimuth: float | None = None
    elevation: float | None = None
    distance: float | None = None
    lookat: tuple[float, float, float] | None = None

    def validated(self) -> VideoSettings:
        """Return self if every field is valid, else raise RecordingError saying what to use."""
        for name in ("width", "height"):
            check_count(
                getattr(self, name),
                name,
                minimum=MIN_FRAME_SIZE,
                maximum=MAX_FRAME_SIZE,
                even=True,
                unit=" pixels",
                expected=(
                    f"an even whole number of pixels from {MIN_FRAME_SIZE} to {MAX_FRAME_SIZE} "
                    "(H.264 needs even frame sizes)"
                ),
                error=RecordingError,
            )
        check_range(
            self.fps,
            "fps",
            low=1.0,
            high=MAX_FPS,
            expected=f"1 to {MAX_FPS:g} frames/s",
            error=RecordingError,
        )
        check_quality(self.quality, QUALITY_CHOICES)
        check_choice(self.view, "view", NAMED_VIEWS, error=RecordingError)
        for name, low, high in (
            ("azimuth", -360, 360),
            ("elevation", -90, 90),
            ("distance", 0.01, 100),
        ):
            if getattr(self, name) is not None:
                check_range(getattr(self, name), name, low=low, high=high, error=RecordingError)
        if self.lookat is not None:
            if len(self.lookat) != 3:
                raise RecordingError(f"lookat = {self.lookat!r}; expected three numbers X,Y,Z (m)")
            for v in self.lookat:
                check_range(v, "lookat", low=-100, high=100, error=RecordingError)
        if self.title is not None and (not isinstance(self.title, str) or len(self.title) > 200):
            raise RecordingError("title must be text of at most 200 characters")
        return self


def check_quality(quality: object, valid: tuple[str, ...] = QUALITIES) -> str:
    """``quality`` if it is one of ``valid``, else raise RecordingError listing them."""
    return check_choice(quality, "quality preset", valid, error=RecordingError)


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
