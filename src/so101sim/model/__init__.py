"""The model layer: the shipped SO-101 model loaded once, its compiled cache, its physics-only copy.

Modules: :mod:`.load` (``load_model``, ``scene_path``, the arm's units and indices),
:mod:`.cache` (compiled models kept between runs), :mod:`.trim` (the physics-only model),
:mod:`.twin` (a loaded model with a contact sensor, for the stepping kernel's contact counts),
:mod:`.build` (the one model builder: ``ModelRecipe``, ``build``, ``servo_model``),
:mod:`.index` (the shipped files, where the joints live); the arm profiles (:mod:`.arm`, their
public names, over :mod:`.servo` (the data), :mod:`.profiles` (TOML in and out), :mod:`.apply`
(applied to an ``MjSpec`` at load), :mod:`.runtime` (writes into a compiled model) and
:mod:`.draw` (draws from their uncertainty)).

May import: ``so101sim.units`` and the base modules (and MuJoCo).
"""

from .arm import load_profile
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
    "load_profile",
    "loaded_models",
    "model_dir",
    "model_source",
    "scene_path",
    "servo_model",
]
