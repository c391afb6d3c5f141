"""so101sim: a MuJoCo digital twin of the SO-101 arm, in the arm's own units.

Body joints in degrees (0 = middle of the joint's range), the gripper on 0-100 (0 closed).
Start with :class:`Simulation`, the lab's helpers in :mod:`so101sim.lab`, or the LeRobot-style
:class:`SO101SimFollower`.
"""

from typing import TYPE_CHECKING

from . import _compat
from ._lazy import lazy_names
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
    MissingDependencyError,
    ModelError,
    MotionFileError,
    OutputPathError,
    ProfileError,
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
# Simulation`` imports what Simulation needs, and no more. The names are those imported under
# TYPE_CHECKING below (read by so101sim._lazy), each written once.
if TYPE_CHECKING:
    from .lab.handin import RecordingViewer, record
    from .model import load_model, model_dir, scene_path
    from .motion import LAB_MOTION, Hold, Move, RunResult, Segment, run_motion
    from .motion.file import MotionFile, lab_motion_path, load_motion
    from .preflight import PreflightReport, Thresholds, check_motion_file
    from .recording import Recorder, VideoSettings, plot_run
    from .robot import SO101SimFollower, SO101SimFollowerConfig
    from .sim import Pacer, SegmentResult, Simulation
    from .units import JOINT_NAMES, STARTING_POSE, ZERO_POSE


# ``so101sim.preflight`` is the subpackage, whatever was imported first (it was also the
# function ``preflight.preflight``, depending on import order); calling it still works, with a
# DeprecationWarning, for one release.

__version__ = "0.1.0"

_compat.install()  # old module paths (so101sim.simulation, ...) keep working for one release
__getattr__, __dir__ = lazy_names(__name__)
