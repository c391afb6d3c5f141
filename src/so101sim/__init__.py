"""so101sim: a MuJoCo digital twin of the SO-101 arm, in the arm's own units.

Body joints in degrees (0 = middle of the joint's range), the gripper on 0-100 (0 closed).
Start with :class:`Simulation`, the lab's helpers in :mod:`so101sim.lab`, or the LeRobot-style
:class:`SO101SimFollower`.
"""

from . import gl as _gl  # noqa: F401  (picks the OpenGL backend before mujoco is imported)
from .errors import (
    CalibrationError,
    CameraError,
    DeviceAlreadyConnectedError,
    DeviceNotConnectedError,
    DurationError,
    JointLimitError,
    JointNameError,
    JointValueError,
    LeaderError,
    ModelError,
    MotionFileError,
    OutputPathError,
    RateError,
    RecordingError,
    RenderBackendError,
    RobotConfigError,
    SettingError,
    SimulationDivergedError,
    So101SimError,
    TrajectoryLimitError,
    ViewerError,
)
from .model import load_model, model_dir, scene_path
from .motion import LAB_MOTION, Hold, Move, RunResult, SegmentResult, run_motion
from .motionfile import MotionFile, lab_motion_path, load_motion
from .preflight import PreflightReport, Thresholds, check_motion_file, preflight
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
    "CalibrationError",
    "CameraError",
    "DeviceAlreadyConnectedError",
    "DeviceNotConnectedError",
    "DurationError",
    "Hold",
    "JointLimitError",
    "JointNameError",
    "JointValueError",
    "LeaderError",
    "ModelError",
    "MotionFile",
    "MotionFileError",
    "Move",
    "OutputPathError",
    "Pacer",
    "PreflightReport",
    "RateError",
    "Recorder",
    "RecordingError",
    "RenderBackendError",
    "RobotConfigError",
    "RunResult",
    "SO101SimFollower",
    "SO101SimFollowerConfig",
    "SegmentResult",
    "SettingError",
    "Simulation",
    "SimulationDivergedError",
    "So101SimError",
    "Thresholds",
    "TrajectoryLimitError",
    "VideoSettings",
    "ViewerError",
    "__version__",
    "check_motion_file",
    "lab_motion_path",
    "load_model",
    "load_motion",
    "model_dir",
    "plot_run",
    "preflight",
    "run_motion",
    "scene_path",
]
