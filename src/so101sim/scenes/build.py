"""Compiling a scene: the shipped SO-101 model plus cameras, a table and objects, added with
``mujoco.MjSpec`` (:func:`scene_spec`, :func:`build_model`).

:func:`build_model` remembers how it made each model, so the ``draft`` render preset can make
the same scene again with simplified meshes (:func:`scene_builder`).
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco

from ..errors import SettingError
from ..model.arm import ArmLike
from ..model.build import Addition, ModelRecipe, build, recipe, recipe_of
from ..validation import check_count, check_range
from .cameras import CameraSpec, add_camera, check_camera_names
from .objects import MAX_OBJECTS, MAX_REACH_M, ContactSettings, SceneObject, Table
from .parts import add_jaw_pads, add_object, add_table, set_options
from .placement import Rectangle, placed, sample_placements


@dataclass(frozen=True)
class TableScene:
    """A table-top scene: what the arm stands on (``table``), the ``objects`` on it, extra
    ``cameras``, and the ``contact`` settings objects use. ``name`` is for messages. With a
    ``seed``, the objects that have ranges are compiled at start poses drawn from it
    (:func:`~so101sim.scenes.sample_placements`), else at their nominal poses; drawn poses
    stay out of the ``keep_out`` rectangles (x_min, x_max, y_min, y_max metres), e.g. where
    the folded arm lies."""

    objects: tuple[SceneObject, ...] = ()
    table: Table = field(default_factory=Table)
    cameras: tuple[CameraSpec, ...] = ()
    contact: ContactSettings = field(default_factory=ContactSettings)
    name: str = "custom"
    seed: int | None = None
    keep_out: tuple[Rectangle, ...] = ()

    def validated(self) -> TableScene:
        """A copy with every part checked, or a SettingError/CameraError saying what to use."""
        objects = tuple(o.validated() for o in self.objects)
        if len(objects) > MAX_OBJECTS:
            raise SettingError(
                f"scene {self.name!r} has {len(objects)} objects; expected at most {MAX_OBJECTS}"
            )
        names = [o.name for o in objects]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise SettingError(f"object {dup[0]!r} is given twice; object names must differ")
        keep_out = tuple(_rectangle(r) for r in self.keep_out)
        if self.seed is not None:
            seed = check_count(self.seed, "scene seed", maximum=2**63 - 1)
            objects = placed(objects, sample_placements(objects, seed, keep_out))
        return TableScene(
            objects=objects,
            table=self.table.validated(),
            cameras=tuple(c.validated() for c in self.cameras),
            contact=self.contact.validated(),
            name=str(self.name),
            seed=self.seed,
            keep_out=keep_out,
        )

    def object(self, name: str) -> SceneObject:
        """The object called ``name``."""
        for o in self.objects:
            if o.name == name:
                return o
        raise SettingError(
            f"scene {self.name!r} has no object {name!r}; its objects are "
            f"{', '.join(o.name for o in self.objects) or 'none'}"
        )


def _rectangle(r: object) -> Rectangle:
    if not isinstance(r, list | tuple) or len(r) != 4:
        raise SettingError(
            f"keep_out rectangle {r!r} is invalid; expected (x_min, x_max, y_min, y_max) metres"
        )
    lim = MAX_REACH_M
    x0, x1, y0, y1 = (check_range(v, "keep_out", low=-lim, high=lim, unit=" m") for v in r)
    if x0 > x1 or y0 > y1:
        raise SettingError(
            f"keep_out rectangle {r!r} is empty; expected x_min <= x_max and y_min <= y_max"
        )
    return (x0, x1, y0, y1)


def _scene_recipe(
    cameras: Sequence[CameraSpec],
    model: str | Path | None,
    scene: TableScene | None,
    arm: ArmLike,
    extra: Callable[[mujoco.MjSpec], None] | None = None,
) -> ModelRecipe:
    """The model builder's recipe of a scene: the file and profile, then one addition (the
    cameras, the table and objects of ``scene``, then ``extra``); never cached (a scene's
    objects may be drawn at random poses)."""
    cams = tuple(cameras) + (scene.cameras if scene is not None else ())

    def add(spec: mujoco.MjSpec) -> None:
        check_camera_names(spec, cams)
        for cam in cams:
            add_camera(spec, cam.validated())
        if scene is not None:
            _add_scene(spec, scene)
        if extra is not None:
            extra(spec)  # e.g. randomize.add_distractors: in every rebuild (draft renders)

    file = Path(model) if model is not None else None
    return recipe(file, arm=arm, additions=(Addition(None, add),))


def scene_spec(
    cameras: Sequence[CameraSpec] = (),
    model: str | Path | None = None,
    scene: TableScene | None = None,
    *,
    arm: ArmLike = None,
) -> mujoco.MjSpec:
    """The MjSpec of ``model`` (the shipped ``scene.xml`` by default) with the arm profile
    ``arm`` applied (None: the default profile, see :func:`so101sim.model.load_model`),
    ``cameras`` added, and the table, objects and cameras of ``scene``."""
    return _scene_recipe(cameras, model, scene, arm).spec()


def _add_scene(spec: mujoco.MjSpec, scene: TableScene) -> None:
    taken = {b.name for b in spec.bodies} | {g.name for g in spec.geoms if g.name}
    for obj in scene.objects:
        if obj.name in taken or obj.name == "table":
            raise SettingError(f"object name {obj.name!r} is taken by the model; choose another")
    add_table(spec, scene.table, scene.contact)
    if scene.objects:
        set_options(spec, scene.contact)
        add_jaw_pads(spec, scene.contact)
    for obj in scene.objects:
        add_object(spec, obj, scene.contact)


_scenes: weakref.WeakKeyDictionary[mujoco.MjModel, TableScene] = weakref.WeakKeyDictionary()
_lock = threading.Lock()


def build_model(
    cameras: Sequence[CameraSpec] = (),
    model: str | Path | None = None,
    *,
    scene: TableScene | None = None,
    extra: Callable[[mujoco.MjSpec], None] | None = None,
    arm: ArmLike = None,
) -> mujoco.MjModel:
    """Compile the shipped scene (or ``model``) with the arm profile ``arm`` (None: the
    default), ``cameras`` added, and with ``scene``'s table, objects and cameras, and whatever
    ``extra`` adds to its MjSpec, through the model builder
    (:func:`so101sim.model.build.build`). The draft render preset finds the same scene with
    simplified meshes (:func:`scene_builder`).

    Raises:
        ModelError, CameraError, SettingError: the model cannot be read or compiled; a camera
            or a part of the scene is not valid.
    """
    cams = tuple(c.validated() for c in cameras)
    checked = scene.validated() if scene is not None else None
    compiled = build(_scene_recipe(cams, model, checked, arm, extra))
    if checked is not None:
        with _lock:
            _scenes[compiled] = checked
    return compiled


def build_scene(
    scene: TableScene,
    model: str | Path | None = None,
    *,
    extra: Callable[[mujoco.MjSpec], None] | None = None,
    arm: ArmLike = None,
) -> mujoco.MjModel:
    """Compile ``scene`` (see :func:`build_model`)."""
    return build_model((), model, scene=scene, extra=extra, arm=arm)


def scene_builder(model: mujoco.MjModel) -> Callable[[], mujoco.MjSpec] | None:
    """The function that makes ``model``'s MjSpec again, if :func:`build_model` compiled it."""
    r = recipe_of(model)
    if r is None or not r.additions or r.additions[0].key is not None:
        return None
    return r.spec


def scene_of(model: mujoco.MjModel) -> TableScene | None:
    """The (validated) :class:`TableScene` ``model`` was compiled from, if any."""
    with _lock:
        return _scenes.get(model)


__all__ = [
    "TableScene",
    "build_model",
    "build_scene",
    "scene_builder",
    "scene_of",
    "scene_spec",
]
