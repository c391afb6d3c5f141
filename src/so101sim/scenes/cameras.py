"""Simulated cameras added to a scene at load time with ``mujoco.MjSpec``.

A :class:`CameraSpec` says where a simulated camera sits (metres, in the world or on the
gripper), where it looks and its field of view; :data:`PRESET_CAMERAS` has ``front`` (in front
of the arm, looking back at it and the space it works in, like the usual LeRobot table set-up)
and ``wrist`` (on the gripper, looking along the jaws at what they grasp, like the common SO-101
wrist-camera mount). :func:`so101sim.scenes.build_model` compiles a scene with them; the
``draft`` render preset finds the same scene with simplified meshes
(:func:`so101sim.scenes.scene_builder`).

Frames come from :class:`so101sim.recording.FrameRenderer` with ``camera=<name>``; the
robot's cameras (:class:`so101sim.robot.SO101SimFollower`) are built on it.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace

import mujoco
import numpy as np

from ..errors import CameraError, ModelError
from ..validation import check_count, check_input_file, check_range

MAX_CAMERA_PIXELS = 4096
MAX_CAMERAS = 16
"""The most cameras one scene or camera file may hold."""
MAX_CAMERA_FILE_BYTES = 64 * 1024
"""The largest camera file read (a few cameras take a few hundred bytes)."""
"""The largest camera width or height accepted, in pixels."""

CAMERA_BODIES = ("world", "gripper")
"""Where a camera can be mounted: fixed in the world, or on the gripper (moves with it)."""


@dataclass(frozen=True)
class CameraSpec:
    """A simulated camera: ``pos`` (metres) in the frame of ``body`` ("world" or "gripper"),
    looking at ``lookat`` (same frame), ``up`` the direction that is up in the picture,
    vertical field of view ``fovy`` (degrees), and the frames it delivers (``width`` ×
    ``height`` at ``fps``)."""

    name: str
    pos: tuple[float, float, float]
    lookat: tuple[float, float, float]
    body: str = "world"
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    fovy: float = 60.0
    width: int = 640
    height: int = 480
    fps: float = 30.0

    def validated(self) -> CameraSpec:
        """Return self if every field is valid, else raise CameraError saying what to use."""
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise CameraError(
                f"camera name {self.name!r} is not valid; expected a name of letters, digits "
                "and underscores, such as 'front'"
            )
        if self.body not in CAMERA_BODIES:
            raise CameraError(
                f"camera {self.name!r}: body = {self.body!r}; expected one of "
                f"{', '.join(CAMERA_BODIES)}"
            )
        for what in ("pos", "lookat", "up"):
            v = getattr(self, what)
            if len(v) != 3:
                raise CameraError(f"camera {self.name!r}: {what} = {v!r}; expected 3 numbers")
            for x in v:
                check_range(
                    x, f"camera {self.name!r} {what}", low=-100, high=100, error=CameraError
                )
        if np.linalg.norm(np.subtract(self.lookat, self.pos)) < 1e-6:
            raise CameraError(f"camera {self.name!r} looks at its own position; move lookat")
        check_range(self.fovy, f"camera {self.name!r} fovy", low=1, high=170, error=CameraError)
        for what in ("width", "height"):
            check_count(
                getattr(self, what),
                f"camera {self.name!r} {what}",
                minimum=16,
                maximum=MAX_CAMERA_PIXELS,
                unit=" pixels",
                error=CameraError,
            )
        check_range(self.fps, f"camera {self.name!r} fps", low=1, high=240, error=CameraError)
        return self

    def xyaxes(self) -> tuple[float, ...]:
        """The camera frame's x (right) and y (up) axes in its body's frame: MuJoCo cameras
        look along their -z axis."""
        forward = np.subtract(self.lookat, self.pos, dtype=float)
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        if np.linalg.norm(right) < 1e-9:  # looking straight along "up": pick another up
            right = np.cross(forward, (1.0, 0.0, 0.0))
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        return (*right.tolist(), *up.tolist())


WRIST_LENS_M = (0.0025, 0.0609, 0.0120)
"""Where the wrist camera's lens sits in the gripper's frame (metres): the centre of the lens
hole of the SO-ARM100 repository's 32x32 UVC wrist mount (docs/cameras.md)."""
WRIST_AXIS = (0.0087, -0.4616, -0.8870)
"""The wrist camera's viewing direction in the gripper's frame: the mount's plate normal."""

PRESET_CAMERAS: dict[str, CameraSpec] = {
    # a USB webcam on the table in front of the arm, looking back at it (docs/cameras.md)
    "front": CameraSpec("front", pos=(0.5, 0.0, 0.42), lookat=(0.15, 0.0, 0.02), fovy=52.0),
    # the SO-ARM100 repository's 32x32 UVC wrist mount: the lens 61 mm beside the roll axis,
    # 12 mm behind the wrist-roll part, looking along the jaws, tilted 27.5 deg towards them
    "wrist": CameraSpec(
        "wrist",
        body="gripper",
        pos=WRIST_LENS_M,
        lookat=tuple(p + 0.1 * n for p, n in zip(WRIST_LENS_M, WRIST_AXIS, strict=True)),
        up=(0.0, 1.0, 0.0),
        fovy=75.0,
    ),
}
"""The cameras a config can name without saying where they are."""


def camera(name: str, **overrides: object) -> CameraSpec:
    """A preset camera (``front``, ``wrist``) with some fields changed, or a new camera when
    ``pos`` and ``lookat`` are given; validated."""
    if name in PRESET_CAMERAS:
        return replace(PRESET_CAMERAS[name], name=name, **overrides).validated()  # type: ignore[arg-type]
    if "pos" not in overrides or "lookat" not in overrides:
        raise CameraError(
            f"camera {name!r} is not a preset; give its pos and lookat (metres), or use one "
            f"of the presets {', '.join(PRESET_CAMERAS)}"
        )
    return CameraSpec(name=name, **overrides).validated()  # type: ignore[arg-type]


def add_camera(spec: mujoco.MjSpec, cam: CameraSpec) -> None:
    """Add ``cam`` to ``spec`` on its body (the world, or the gripper)."""
    if cam.body == "world":
        parent = spec.worldbody
    else:
        parent = spec.body(cam.body)
        if parent is None:
            raise ModelError(f"the model has no body {cam.body!r} to mount camera {cam.name!r}")
    c = parent.add_camera()
    c.name = cam.name
    c.pos = list(cam.pos)
    c.alt.type = mujoco.mjtOrientation.mjORIENTATION_XYAXES
    c.alt.xyaxes = list(cam.xyaxes())
    c.fovy = cam.fovy


def check_camera_names(spec: mujoco.MjSpec, cameras: tuple[CameraSpec, ...]) -> None:
    """Raise CameraError if two cameras share a name or one takes a name the model has."""
    names = [c.name for c in cameras]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise CameraError(f"camera {sorted(dup)[0]!r} is given twice; camera names must differ")
    for cam in cameras:
        if spec.camera(cam.name) is not None:
            raise CameraError(f"the model already has a camera {cam.name!r}; choose another name")


def camera_names(model: mujoco.MjModel) -> list[str]:
    """The named cameras of a model."""
    names = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i) for i in range(model.ncam))
    return [n for n in names if n]


def fovy_to_focal(fovy: float, height: int) -> float:
    """The focal length in pixels of a camera with vertical field of view ``fovy`` degrees."""
    return height / (2 * math.tan(math.radians(fovy) / 2))


CameraLike = str | CameraSpec
"""A camera as the environments and ``so101sim dataset`` take it: a preset's name, or a
:class:`CameraSpec` (e.g. from :func:`load_cameras`)."""


def camera_name(cam: CameraLike) -> str:
    """The name under which ``cam``'s images are stored (``observation.images.<name>``)."""
    return cam.name if isinstance(cam, CameraSpec) else cam


def resolve_cameras(
    cameras: Sequence[CameraLike], size: tuple[int, int] | None = None
) -> tuple[CameraSpec, ...]:
    """Each camera as a validated :class:`CameraSpec` (a name must be a preset's), rendered at
    ``size`` = (height, width) when given.

    Raises:
        CameraError: an unknown name, an invalid spec, a name given twice, or too many.
    """
    if isinstance(cameras, str | CameraSpec):
        raise CameraError(f"cameras = {cameras!r}; expected a list of cameras, such as ['front']")
    cams = list(cameras)
    if len(cams) > MAX_CAMERAS:
        raise CameraError(f"{len(cams)} cameras given; expected at most {MAX_CAMERAS}")
    specs = []
    for cam in cams:
        if isinstance(cam, CameraSpec):
            spec = cam.validated()
        elif isinstance(cam, str) and cam in PRESET_CAMERAS:
            spec = PRESET_CAMERAS[cam]
        else:
            raise CameraError(
                f"camera {cam!r} is not a preset; expected one of {', '.join(PRESET_CAMERAS)}, "
                "or a camera of your own (its pos, lookat and fovy) from a camera file "
                "(docs/cameras.md)"
            )
        if size is not None:
            spec = replace(spec, height=size[0], width=size[1]).validated()
        specs.append(spec)
    names = [c.name for c in specs]
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})[0]
        raise CameraError(f"camera {twice!r} is given twice; camera names must differ")
    return tuple(specs)


_FILE_FIELDS = {f.name for f in fields(CameraSpec)} - {"name"}


def cameras_from_toml(text: str, where: str = "camera file") -> tuple[CameraSpec, ...]:
    """The cameras of a camera file's text: one table per camera, named as its images will
    be. A preset's name changes that preset's fields; any other name needs ``pos`` and
    ``lookat``::

        [front]                     # the front preset, moved
        pos = [0.45, 0.0, 0.40]     # metres, in the world (x forward, z up)
        fovy = 55                   # vertical field of view, degrees

        [top]                       # a camera of your own
        pos = [0.20, 0.0, 0.80]
        lookat = [0.20, 0.0, 0.0]
        fovy = 60

    Raises:
        CameraError: invalid TOML, an unknown field, a value of the wrong kind or out of range.
    """
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CameraError(
            f"{where} is not valid TOML ({exc}); expected one table per camera"
        ) from exc
    if not raw:
        raise CameraError(f"{where} names no camera; expected tables such as [front]")
    if len(raw) > MAX_CAMERAS:
        raise CameraError(f"{where} has {len(raw)} cameras; expected at most {MAX_CAMERAS}")
    cams = []
    for name, table in raw.items():
        if not isinstance(table, dict):
            raise CameraError(
                f"{where}: {name} = {table!r}; expected a table [{name}] of the camera's fields"
            )
        unknown = sorted(set(table) - _FILE_FIELDS)
        if unknown:
            raise CameraError(
                f"{where}: camera {name!r} has the unknown field {unknown[0]!r}; expected "
                f"{', '.join(sorted(_FILE_FIELDS))}"
            )
        values: dict[str, object] = {}
        for key, value in table.items():
            if key in ("pos", "lookat", "up"):
                ok = isinstance(value, list) and all(
                    isinstance(x, int | float) and not isinstance(x, bool) for x in value
                )
                if not ok or len(value) != 3:
                    raise CameraError(
                        f"{where}: camera {name!r} {key} = {value!r}; expected 3 numbers in metres"
                    )
                value = tuple(float(x) for x in value)
            elif key == "body" and not isinstance(value, str):
                raise CameraError(f"{where}: camera {name!r} body = {value!r}; expected a name")
            elif key != "body" and (not isinstance(value, int | float) or isinstance(value, bool)):
                raise CameraError(f"{where}: camera {name!r} {key} = {value!r}; expected a number")
            values[key] = value
        try:
            cams.append(camera(name, **values))
        except CameraError as exc:
            raise CameraError(f"{where}: {exc}") from None
    return tuple(cams)


def load_cameras(path: object) -> tuple[CameraSpec, ...]:
    """The cameras of a camera file (:func:`cameras_from_toml` says its format).

    Raises:
        CameraError: the file cannot be read, is too large, or holds an invalid camera.
    """
    p = check_input_file(path, "camera file", expected="a TOML file of cameras", error=CameraError)
    size = p.stat().st_size
    if size > MAX_CAMERA_FILE_BYTES:
        raise CameraError(
            f"camera file {str(p)!r} is {size} bytes; expected a few cameras "
            f"(at most {MAX_CAMERA_FILE_BYTES} bytes)"
        )
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CameraError(f"camera file {str(p)!r} cannot be read: {exc}") from exc
    return cameras_from_toml(text, f"camera file {str(p)!r}")


def parse_cameras(text: str) -> tuple[CameraLike, ...]:
    """A command line's ``--cameras``: comma-separated presets and camera files
    (``front,wrist``, ``my_rig.toml``, ``wrist,top.toml``), in that order.

    Raises:
        CameraError: an unknown preset, or a camera file :func:`load_cameras` refuses.
    """
    out: list[CameraLike] = []
    for item in (i.strip() for i in text.split(",")):
        if not item:
            continue
        if item.lower().endswith(".toml"):
            out.extend(load_cameras(item))
        elif item in PRESET_CAMERAS:
            out.append(item)
        else:
            raise CameraError(
                f"camera {item!r} is not a preset; expected {', '.join(PRESET_CAMERAS)} or a "
                "camera file ending in .toml (docs/cameras.md)"
            )
    resolve_cameras(out)  # names given twice, too many
    return tuple(out)
