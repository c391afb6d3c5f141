"""so101sim: a MuJoCo digital twin of the SO-101 arm, in the arm's own units."""

from . import gl as _gl  # noqa: F401  (picks the OpenGL backend before mujoco is imported)
from .errors import (
    DurationError,
    JointLimitError,
    JointNameError,
    JointValueError,
    ModelError,
    SimulationDivergedError,
    So101SimError,
    ViewerError,
)
from .model import load_model, model_dir, scene_path
from .motion import LAB_MOTION, Hold, Move, RunResult, SegmentResult, run_motion
from .robot import SO101SimFollower, SO101SimFollowerConfig
from .simulation import Pacer, Simulation
from .units import JOINT_NAMES, STARTING_POSE, ZERO_POSE

__version__ = "0.1.0"

__all__ = [
    "JOINT_NAMES",
    "LAB_MOTION",
    "STARTING_POSE",
    "ZERO_POSE",
    "DurationError",
    "Hold",
    "JointLimitError",
    "JointNameError",
    "JointValueError",
    "ModelError",
    "Move",
    "Pacer",
    "RunResult",
    "SO101SimFollower",
    "SO101SimFollowerConfig",
    "SegmentResult",
    "Simulation",
    "SimulationDivergedError",
    "So101SimError",
    "ViewerError",
    "__version__",
    "load_model",
    "model_dir",
    "run_motion",
    "scene_path",
]
