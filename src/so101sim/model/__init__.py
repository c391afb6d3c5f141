"""The model layer: the shipped SO-101 model loaded once, its compiled cache, its physics-only copy.

May import: ``so101sim.errors``, ``so101sim.validation``, ``so101sim.units`` (and MuJoCo).
Modules: :mod:`.load` (``load_model``, ``scene_path``, the arm's units and indices),
:mod:`.cache` (compiled models kept between runs), :mod:`.trim` (the physics-only model),
:mod:`.twin` (a loaded model with a contact sensor, for the stepping kernel's contact counts),
:mod:`.build` (the one model builder: ``ModelRecipe``, ``build``, ``servo_model``),
:mod:`.index` (the shipped files, where the joints live), :mod:`.arm` (arm profiles).
"""

from .build import servo_model
from .load import (
    ArmIndex,
    arm_index,
    arm_units,
    default_units,
    load_model,
    loaded_models,
    model_dir,
    model_source,
    scene_path,
)

__all__ = [
    "ArmIndex",
    "arm_index",
    "arm_units",
    "default_units",
    "load_model",
    "loaded_models",
    "model_dir",
    "model_source",
    "scene_path",
    "servo_model",
]
