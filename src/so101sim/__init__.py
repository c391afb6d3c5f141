"""so101sim: a MuJoCo digital twin of the SO-101 arm, in the arm's own units."""

from . import gl as _gl  # noqa: F401  (picks the OpenGL backend before mujoco is imported)
from .errors import (
    CameraError,
    DurationError,
    JointLimitError,
    JointNameError,
    JointValueError,
    ModelError,
    OutputPathError,
    RecordingError,
    RenderBackendError,
    SimulationDivergedError,
    So101SimError,
    ViewerError,
)
from .model import load_model, model_dir, scene_path
from .motion import LAB_MOTION, Hold, Move, RunResult, SegmentResult, run_motion
from .recording import Recorder, VideoSettings, plot_run
from .robot import SO101SimFollower, SO101SimFollowerConfig
from .simulation import Pacer, Simulation
from .units import JOINT_NAMES, STARTING_POSE, ZERO_POSE

__version__ = "0.1.0"

__all__ = [
    "JOINT_NAMES",
    "LAB_MOTION",
    "STARTING_POSE",
    "ZERO_POSE",
    "CameraError",
    "DurationError",
    "Hold",
    "JointLimitError",
    "JointNameError",
    "JointValueError",
    "ModelError",
    "Move",
    "OutputPathError",
    "Pacer",
    "Recorder",
    "RecordingError",
    "RenderBackendError",
    "RunResult",
    "SO101SimFollower",
    "SO101SimFollowerConfig",
    "SegmentResult",
    "Simulation",
    "SimulationDivergedError",
    "So101SimError",
    "VideoSettings",
    "ViewerError",
    "__version__",
    "load_model",
    "model_dir",
    "plot_run",
    "run_motion",
    "scene_path",
]

# Motions as data, profiles, preflight (issue 6).
from .errors import MotionFileError, TrajectoryLimitError
from .motionfile import MotionFile, lab_motion_path, load_motion

__all__ += [
    "MotionFile",
    "MotionFileError",
    "TrajectoryLimitError",
    "lab_motion_path",
    "load_motion",
]
