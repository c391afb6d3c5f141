"""The interactive viewer: MuJoCo's passive viewer on a run, and the pose finder.

Modules: :mod:`.passive`
(``open_viewer``, ``has_display``, ``choose_viewer``), :mod:`.posefinder` (``so101sim pose``).

May import: ``so101sim.recording`` (the draft meshes), ``so101sim.motion``, ``so101sim.sim``,
``so101sim.kinematics``, ``so101sim.model``, ``so101sim.units`` and the base modules.
"""

from ..sim.observers import close_at_exit  # a script's own viewer, at its end
from .passive import (
    ARM_DISTANCE,
    ARM_LOOKAT,
    MACOS_MESSAGE,
    NO_DISPLAY_NOTE,
    SCENE_AZIMUTH,
    SCENE_ELEVATION,
    VIEWER_NICE,
    VIEWER_QUALITIES,
    MirroredViewer,
    ViewerChoice,
    ViewerQuality,
    choose_viewer,
    copy_state,
    frame_arm,
    has_display,
    lower_priority,
    mirror_model,
    on_macos_without_mjpython,
    open_viewer,
    view,
)

__all__ = [
    "ARM_DISTANCE",
    "ARM_LOOKAT",
    "MACOS_MESSAGE",
    "NO_DISPLAY_NOTE",
    "SCENE_AZIMUTH",
    "SCENE_ELEVATION",
    "VIEWER_NICE",
    "VIEWER_QUALITIES",
    "MirroredViewer",
    "ViewerChoice",
    "ViewerQuality",
    "choose_viewer",
    "close_at_exit",
    "copy_state",
    "frame_arm",
    "has_display",
    "lower_priority",
    "mirror_model",
    "on_macos_without_mjpython",
    "open_viewer",
    "view",
]
