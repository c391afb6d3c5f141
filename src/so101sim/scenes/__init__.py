"""Scenes built at load time: the shipped SO-101 model plus cameras, a table and objects,
added with ``mujoco.MjSpec`` so the vendored files are never edited.

* cameras (:mod:`.cameras`): :class:`CameraSpec`, :data:`PRESET_CAMERAS` (``front``,
  ``wrist``), :func:`camera`;
* what a table-top scene holds (:mod:`.objects`): :class:`SceneObject`, :class:`Table`,
  :class:`ContactSettings`;
* compiling it (:mod:`.build`): :class:`TableScene`, :func:`build_model`,
  :func:`scene_spec`, :func:`scene_builder` (the ``draft`` render preset rebuilds a scene with
  simplified meshes through it);
* the objects' poses (:mod:`.placement`): :func:`object_pose`, :func:`place_object`, start
  poses drawn from a seed (:func:`sample_placements`);
* named scenes (:mod:`.presets`): :data:`SCENE_PRESETS` (``pick_cube``, ``cube_to_bowl``),
  :func:`preset_scene`, a motion file's ``[scene]`` (:func:`scene_from_dict`), colour, light
  and camera jitter (:class:`VisualJitter`).

Frames come from :class:`so101sim.recording.FrameRenderer` with ``camera=<name>``.

May import: ``so101sim.model``, ``so101sim.units`` and the base modules.
"""

from .build import TableScene, build_model, build_scene, scene_builder, scene_of, scene_spec
from .cameras import (
    CAMERA_BODIES,
    MAX_CAMERA_PIXELS,
    MAX_CAMERAS,
    PRESET_CAMERAS,
    CameraLike,
    CameraSpec,
    camera,
    camera_name,
    camera_names,
    cameras_from_toml,
    fovy_to_focal,
    load_cameras,
    parse_cameras,
    resolve_cameras,
)
from .objects import CONTAINERS, SHAPES, SURFACES, ContactSettings, SceneObject, Table
from .placement import (
    SEPARATION_GAP_M,
    Placement,
    object_pose,
    object_qpos,
    object_qvel,
    place_object,
    place_objects,
    placed,
    sample_placements,
)
from .presets import (
    BOWL,
    CUBE,
    FOLDED_ARM,
    SCENE_PRESETS,
    VisualJitter,
    VisualRandomizer,
    preset_scene,
    scene_from_dict,
)
from .randomize import (
    PRESETS as RANDOMIZE_PRESETS,
)
from .randomize import (
    Randomization,
    SceneRandomizer,
    add_distractors,
    add_textures,
    randomization,
    scene_additions,
)

__all__ = [
    "BOWL",
    "CAMERA_BODIES",
    "CONTAINERS",
    "CUBE",
    "FOLDED_ARM",
    "MAX_CAMERAS",
    "MAX_CAMERA_PIXELS",
    "PRESET_CAMERAS",
    "RANDOMIZE_PRESETS",
    "SCENE_PRESETS",
    "SEPARATION_GAP_M",
    "SHAPES",
    "SURFACES",
    "CameraLike",
    "CameraSpec",
    "ContactSettings",
    "Placement",
    "Randomization",
    "SceneObject",
    "SceneRandomizer",
    "Table",
    "TableScene",
    "VisualJitter",
    "VisualRandomizer",
    "add_distractors",
    "add_textures",
    "build_model",
    "build_scene",
    "camera",
    "camera_name",
    "camera_names",
    "cameras_from_toml",
    "fovy_to_focal",
    "load_cameras",
    "object_pose",
    "object_qpos",
    "object_qvel",
    "parse_cameras",
    "place_object",
    "place_objects",
    "placed",
    "preset_scene",
    "randomization",
    "resolve_cameras",
    "sample_placements",
    "scene_additions",
    "scene_builder",
    "scene_from_dict",
    "scene_of",
    "scene_spec",
]
