"""Named table-top scenes (:data:`SCENE_PRESETS`: ``pick_cube``, ``cube_to_bowl``, the lifts,
``push``, ``stack``), scenes read from a motion file's ``[scene]`` table
(:func:`scene_from_dict`), and the colour, light and camera jitter drawn from a seed for
images (:class:`VisualJitter`).

The presets' objects stand where a top-down grasp reaches them: the tool pointing straight
down reaches from about 9.5 to 22 cm from the shoulder's pan axis (3.9 cm in front of the base)
at the height it carries things; the ranges keep each object's grasp inside that ring.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace

import mujoco
import numpy as np

from ..errors import SettingError
from ..validation import check_choice, check_count, check_range
from .build import TableScene
from .cameras import PRESET_CAMERAS, CameraSpec, camera
from .objects import SceneObject, Table

CUBE = SceneObject(
    "cube",
    shape="box",
    size=(0.025, 0.025, 0.025),
    mass=0.03,
    rgba=(0.85, 0.15, 0.1, 1.0),
    pos=(0.19, 0.08),
    x_range=(0.14, 0.23),
    y_range=(-0.11, 0.11),
    yaw_range=(-45.0, 45.0),
)
"""A 2.5 cm, 30 g red cube, anywhere in a 9 × 22 cm patch in front of the arm (clear of the
folded arm)."""
BOWL = SceneObject(
    "bowl",
    shape="bowl",
    size=(0.09, 0.035),
    mass=0.15,
    rgba=(0.2, 0.45, 0.85, 1.0),
    pos=(0.19, -0.08),
    x_range=(0.14, 0.23),
    y_range=(-0.11, 0.11),
    wall=0.004,
)
"""A 9 cm wide, 3.5 cm tall blue bowl (its wall 16 flat segments), 150 g."""

CYLINDER = SceneObject(
    "object",
    shape="cylinder",
    size=(0.025, 0.035),
    mass=0.03,
    rgba=(0.95, 0.6, 0.1, 1.0),
    pos=(0.19, 0.08),
    x_range=(0.14, 0.23),
    y_range=(-0.11, 0.11),
)
"""A 2.5 cm wide, 3.5 cm tall, 30 g orange cylinder standing on the table (the lift task)."""
SPHERE = SceneObject(
    "object",
    shape="sphere",
    size=(0.028,),
    mass=0.025,
    rgba=(0.2, 0.7, 0.3, 1.0),
    pos=(0.19, 0.08),
    x_range=(0.14, 0.23),
    y_range=(-0.11, 0.11),
)
"""A 2.8 cm, 25 g green ball (the lift task)."""

MESH_OBJECT = SceneObject(
    "object",
    shape="mesh",
    size=(0.025, 0.03),
    mass=0.03,
    rgba=(0.6, 0.3, 0.8, 1.0),
    pos=(0.19, 0.08),
    x_range=(0.14, 0.23),
    y_range=(-0.11, 0.11),
    yaw_range=(-45.0, 45.0),
)
"""A 2.5 cm wide (across its flats), 3 cm tall, 30 g purple octagonal nut-like mesh made at
load time (the lift task)."""
PUSH_CUBE = replace(CUBE, x_range=(0.15, 0.21), y_range=(-0.09, 0.09))
"""The cube to push: a little inside the pick patch, so the fixed jaw behind it is in reach."""
MARK = SceneObject(
    "mark",
    shape="mark",
    size=(0.04, 0.001),
    mass=0.001,
    rgba=(0.1, 0.75, 0.25, 1.0),
    pos=(0.19, -0.08),
    x_range=(0.14, 0.23),
    y_range=(-0.11, 0.11),
)
"""A 4 cm green disc on the table where the cube is to be pushed (it touches nothing)."""
BLOCK = SceneObject(
    "block",
    shape="box",
    size=(0.03, 0.03, 0.03),
    mass=0.08,
    rgba=(0.2, 0.45, 0.85, 1.0),
    pos=(0.19, -0.08),
    x_range=(0.14, 0.23),
    y_range=(-0.11, 0.11),
    yaw_range=(-45.0, 45.0),
)
"""A 3 cm, 80 g blue cube to stack the red one on."""

FOLDED_ARM = (-0.1, 0.21, -0.035, 0.035)
"""Where the arm in its folded rest pose (:data:`so101sim.units.STARTING_POSE`) lies on the
table: its gripper rests 16 mm above the table up to 19 cm in front of the base. Drawn start
poses stay clear of it (x_min, x_max, y_min, y_max metres)."""

SCENE_PRESETS: dict[str, TableScene] = {
    "pick_cube": TableScene(objects=(CUBE,), name="pick_cube", keep_out=(FOLDED_ARM,)),
    "cube_to_bowl": TableScene(
        objects=(CUBE, BOWL),
        name="cube_to_bowl",
        keep_out=(FOLDED_ARM,),
    ),
    "lift_cylinder": TableScene(objects=(CYLINDER,), name="lift_cylinder", keep_out=(FOLDED_ARM,)),
    "lift_sphere": TableScene(objects=(SPHERE,), name="lift_sphere", keep_out=(FOLDED_ARM,)),
    "lift_mesh": TableScene(objects=(MESH_OBJECT,), name="lift_mesh", keep_out=(FOLDED_ARM,)),
    "push": TableScene(objects=(PUSH_CUBE, MARK), name="push", keep_out=(FOLDED_ARM,)),
    "stack": TableScene(objects=(CUBE, BLOCK), name="stack", keep_out=(FOLDED_ARM,)),
}
"""Table-top scenes by name: a cube to pick up; a cube to put in a bowl; a cylinder, a ball or
a mesh to lift (the lift tasks); a cube to push onto a mark; a cube to stack on a block."""


def preset_scene(
    name: str, *, cameras: Sequence[str | CameraSpec] = (), seed: int | None = None
) -> TableScene:
    """The preset scene ``name`` with ``cameras`` (preset names such as ``"front"``, or
    :class:`CameraSpec`), its objects at poses drawn from ``seed`` (None: nominal poses)."""
    check_choice(name, "scene preset", SCENE_PRESETS)
    cams = tuple(camera(c) if isinstance(c, str) else c for c in cameras)
    return replace(SCENE_PRESETS[name], cameras=cams, seed=seed).validated()


_OBJECT_KEYS = {f.name for f in fields(SceneObject)} | {"color"}
_TABLE_KEYS = {f.name for f in fields(Table)} | {"color"}
_SCENE_KEYS = {"preset", "table", "objects", "cameras", "seed"}


def _keys(d: object, what: str, valid: set[str]) -> Mapping[str, object]:
    if not isinstance(d, Mapping):
        raise SettingError(f"{what} = {d!r}; expected a table of {', '.join(sorted(valid))}")
    unknown = sorted(set(d) - valid)
    if unknown:
        raise SettingError(
            f"unknown key {unknown[0]!r} in {what}; valid keys are {', '.join(sorted(valid))}"
        )
    return d


def _renamed(d: Mapping[str, object]) -> dict[str, object]:
    out = dict(d)
    if "color" in out:
        out["rgba"] = out.pop("color")
    return out


def scene_from_dict(d: Mapping[str, object]) -> TableScene:
    """A scene from a motion file's ``[scene]`` table (parsed TOML), validated::

        [scene]
        preset = "pick_cube"          # optional: start from a preset
        table = "table"               # or "floor", or a table of Table's fields
        seed = 3                      # draw the objects' start poses from this seed
        cameras = ["front"]           # preset camera names
        [[scene.objects]]             # replaces the preset's objects when given
        name = "cube"
        shape = "box"                 # box, cylinder, sphere, bowl, open_box, mesh, mark
        size = 0.025                  # metres (see SceneObject)
        mass = 0.03                   # kg
        color = [0.9, 0.1, 0.1]
        pos = [0.2, 0.0]
        x_range = [0.15, 0.23]

    Raises:
        SettingError, CameraError: an unknown key or a value out of its bounds.
    """
    d = _keys(d, "[scene]", _SCENE_KEYS)
    base = TableScene(name="scene")
    if "preset" in d:
        base = SCENE_PRESETS[check_choice(d["preset"], "scene preset", SCENE_PRESETS)]
    table = base.table
    if "table" in d:
        t = d["table"]
        if isinstance(t, str):
            table = Table(surface=t)
        else:
            table = Table(**_renamed(_keys(t, "[scene.table]", _TABLE_KEYS)))  # type: ignore[arg-type]
    objects = base.objects
    if "objects" in d:
        items = d["objects"]
        if not isinstance(items, list):
            raise SettingError("[scene] objects must be a list of tables ([[scene.objects]])")
        objects = tuple(
            SceneObject(**_renamed(_keys(o, "[[scene.objects]]", _OBJECT_KEYS)))  # type: ignore[arg-type]
            for o in items
        )
    cams = d.get("cameras", [])
    if not isinstance(cams, list) or not all(isinstance(c, str) for c in cams):
        raise SettingError(
            f"[scene] cameras = {cams!r}; expected a list of camera names such as "
            f"{list(PRESET_CAMERAS)}"
        )
    seed = d.get("seed")
    if seed is not None:
        seed = check_count(seed, "[scene] seed", maximum=2**63 - 1)
    scene = replace(
        base, table=table, objects=objects, cameras=tuple(camera(c) for c in cams), seed=seed
    )
    return scene.validated()


@dataclass(frozen=True)
class VisualJitter:
    """How much the look of a scene changes from episode to episode (for image policies):
    ``color`` shifts each object's red, green and blue by up to this much (0..1), ``light``
    scales the lights' brightness by up to ±this share and moves them by up to this many
    metres, ``camera_m`` moves each named camera by up to this many metres. All zero: none."""

    color: float = 0.0
    light: float = 0.0
    camera_m: float = 0.0

    def validated(self) -> VisualJitter:
        return VisualJitter(
            color=check_range(self.color, "color jitter", low=0.0, high=1.0),
            light=check_range(self.light, "light jitter", low=0.0, high=0.9),
            camera_m=check_range(self.camera_m, "camera jitter", low=0.0, high=0.1, unit=" m"),
        )

    @property
    def active(self) -> bool:
        return bool(self.color or self.light or self.camera_m)


class VisualRandomizer:
    """Applies one :class:`VisualJitter` draw to several models of the same scene at once (the
    physics model, for a viewer, and the render models images are drawn with), always from
    their original look, so draws never pile up."""

    def __init__(
        self, models: Sequence[mujoco.MjModel], scene: TableScene, jitter: VisualJitter
    ) -> None:
        self.jitter = jitter.validated()
        self.models = list(models)
        self._geoms = [_object_geoms(m, scene) for m in self.models]
        self._base = [
            (m.geom_rgba.copy(), m.light_diffuse.copy(), m.light_pos.copy(), m.cam_pos.copy())
            for m in self.models
        ]
        self._objects = [o.name for o in scene.objects]

    def apply(self, rng: np.random.Generator) -> None:
        """Draw a new look from ``rng`` and give it to every model."""
        j = self.jitter
        shift = {n: rng.uniform(-j.color, j.color, 3) for n in self._objects}
        nlights = max((m.nlight for m in self.models), default=0)
        scale = rng.uniform(1 - j.light, 1 + j.light, nlights)
        move = rng.uniform(-j.light, j.light, (nlights, 3))
        ncam = max((m.ncam for m in self.models), default=0)
        cam = rng.uniform(-j.camera_m, j.camera_m, (ncam, 3))
        for m, geoms, (rgba, diffuse, lpos, cpos) in zip(
            self.models, self._geoms, self._base, strict=True
        ):
            for name, ids in geoms.items():
                m.geom_rgba[ids, :3] = np.clip(rgba[ids, :3] + shift[name], 0.0, 1.0)
            m.light_diffuse[:] = np.clip(diffuse * scale[: m.nlight, None], 0.0, 1.0)
            m.light_pos[:] = lpos + move[: m.nlight]
            m.cam_pos[:] = cpos + cam[: m.ncam]


def _object_geoms(model: mujoco.MjModel, scene: TableScene) -> dict[str, np.ndarray]:
    out = {}
    for obj in scene.objects:
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, obj.name)
        out[obj.name] = np.flatnonzero(model.geom_bodyid == bid)
    return out
