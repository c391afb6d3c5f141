"""so101sim: a MuJoCo digital twin of the SO-101 arm, in the arm's own units.

Body joints in degrees (0 = middle of the joint's range), the gripper on 0-100 (0 closed).
Start with :class:`Simulation`, the lab's helpers in :mod:`so101sim.lab`, or the LeRobot-style
:class:`SO101SimFollower`.
"""

import importlib
from typing import TYPE_CHECKING, Any

from . import _compat
from .errors import (
    CalibrationError,
    CameraError,
    ClosedError,
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
    UnreachableError,
    ViewerError,
)

# Everything else is imported on first use (PEP 562), only to keep ``import so101sim`` fast:
# it imports no MuJoCo, no renderer and sets no environment variable. ``from so101sim import
# Simulation`` imports what Simulation needs, and no more.
_LAZY: dict[str, str] = {
    "load_model": "model",
    "model_dir": "model",
    "scene_path": "model",
    "LAB_MOTION": "motion",
    "Hold": "motion",
    "Move": "motion",
    "RunResult": "motion",
    "Segment": "motion",
    "run_motion": "motion",
    "Pacer": "sim",
    "SegmentResult": "sim",
    "Simulation": "sim",
    "MotionFile": "motion.file",
    "lab_motion_path": "motion.file",
    "load_motion": "motion.file",
    "PreflightReport": "preflight",
    "Thresholds": "preflight",
    "check_motion_file": "preflight",
    "preflight": "preflight",
    "Recorder": "recording",
    "VideoSettings": "recording",
    "plot_run": "recording",
    "record": "lab.handin",
    "RecordingViewer": "lab.handin",
    "SO101SimFollower": "robot",
    "SO101SimFollowerConfig": "robot",
    "JOINT_NAMES": "units",
    "STARTING_POSE": "units",
    "ZERO_POSE": "units",
}

if TYPE_CHECKING:
    from .lab.handin import RecordingViewer, record
    from .model import load_model, model_dir, scene_path
    from .motion import LAB_MOTION, Hold, Move, RunResult, Segment, run_motion
    from .motion.file import MotionFile, lab_motion_path, load_motion
    from .preflight import PreflightReport, Thresholds, check_motion_file, preflight
    from .recording import Recorder, VideoSettings, plot_run
    from .robot import SO101SimFollower, SO101SimFollowerConfig
    from .sim import Pacer, SegmentResult, Simulation
    from .units import JOINT_NAMES, STARTING_POSE, ZERO_POSE


_compat.install()  # old module paths (so101sim.simulation, ...) keep working for one release


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'so101sim' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


__version__ = "0.1.0"

__all__ = [
    "JOINT_NAMES",
    "LAB_MOTION",
    "STARTING_POSE",
    "ZERO_POSE",
    "CalibrationError",
    "CameraError",
    "ClosedError",
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
    "RecordingViewer",
    "RenderBackendError",
    "RobotConfigError",
    "RunResult",
    "SO101SimFollower",
    "SO101SimFollowerConfig",
    "Segment",
    "SegmentResult",
    "SettingError",
    "Simulation",
    "SimulationDivergedError",
    "So101SimError",
    "Thresholds",
    "TrajectoryLimitError",
    "UnreachableError",
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
    "record",
    "run_motion",
    "scene_path",
]
