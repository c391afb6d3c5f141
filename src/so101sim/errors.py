"""The exceptions of so101sim: one base class, one subclass per kind of mistake.

Every message says what was wrong and what was expected, so that a student reading a
traceback knows what to change. Catch :class:`So101SimError` to handle them all.
"""

from __future__ import annotations


class So101SimError(Exception):
    """Base class of every error raised by so101sim."""


class JointNameError(So101SimError, ValueError):
    """A pose or action names an unknown joint, or lacks one that is required."""


class JointValueError(So101SimError, ValueError):
    """A joint value is not a finite number."""


class JointLimitError(JointValueError):
    """A joint target lies outside the joint's limits (in the arm's units).

    ``what`` is the fact ("elbow_flex = 120° is outside the joint's limits -96.8°..96.8°") and
    ``advice`` what the caller can do about it; the message is both. ``joint``, ``value``,
    ``lower`` and ``upper`` are kept as attributes.
    """

    def __init__(
        self,
        what: str,
        advice: str = "",
        *,
        joint: str = "",
        value: float = float("nan"),
        lower: float = float("nan"),
        upper: float = float("nan"),
    ) -> None:
        self.what, self.advice = what, advice
        self.joint, self.value, self.lower, self.upper = joint, value, lower, upper
        super().__init__(f"{what}; {advice}" if advice else what)


class SettingError(So101SimError, ValueError):
    """A setting that is not valid: a playback speed, a step count, a move's shape name, limits or
    thresholds. The message gives the valid values.

    The more specific kinds of setting derive from it: :class:`DurationError`,
    :class:`RateError`, :class:`RecordingError` and :class:`RobotConfigError`; catch
    ``SettingError`` for all of them.
    """


class ProfileError(SettingError):
    """An arm profile that cannot be found, read or used: an unknown name, a missing file,
    invalid TOML, an unknown field or a value out of its bounds."""


class DurationError(SettingError):
    """A duration is not a finite number of seconds greater than zero (and at most a day)."""


class UnreachableError(So101SimError, ValueError):
    """A tip position (and orientation) the arm cannot reach within the joint limits; the
    message gives the closest reachable distance."""


class ModelError(So101SimError):
    """A model file does not exist, does not compile, or lacks the SO-101 joints."""


class SimulationDivergedError(So101SimError, RuntimeError):
    """The physics became unstable (MuJoCo warned, or the state holds NaN/inf)."""


class ClosedError(So101SimError, RuntimeError):
    """An object was used after ``close()`` (a Gymnasium environment stepped after it closed)."""


class ViewerError(So101SimError, RuntimeError):
    """The interactive viewer cannot be opened here (no display, macOS without mjpython)."""


class MotionFileError(So101SimError, ValueError):
    """A motion file cannot be read, is not valid TOML, or says something invalid.

    ``path``, ``line`` (1-based; 0 when no line applies, e.g. a missing file) and ``reason`` are
    kept as attributes; the message reads ``path:line: reason``.
    """

    def __init__(self, path: str, line: int, reason: str) -> None:
        self.path = str(path)
        self.line = int(line)
        self.reason = reason
        where = f"{self.path}:{self.line}" if self.line > 0 else self.path
        super().__init__(f"{where}: {reason}")


class TrajectoryLimitError(So101SimError, ValueError):
    """A move is shorter than the joints' velocity, acceleration and jerk limits allow, and
    stretching it was not allowed (strict mode)."""


class OutputPathError(So101SimError, ValueError):
    """An output file (video, plot, log) cannot be written: its folder is missing or not
    writable, or the file exists and overwriting was not asked for."""


class CameraError(So101SimError, ValueError):
    """A camera name the model does not have; the message lists the valid ones."""


class RenderBackendError(So101SimError, RuntimeError):
    """No OpenGL backend could render offscreen (EGL, OSMesa); the message says what to install."""


class RecordingError(SettingError):
    """Invalid recording settings (frame size, frame rate, quality preset)."""


# ---------------------------------------------------------------------------- robot interface
class DeviceNotConnectedError(So101SimError, ConnectionError):
    """A robot (or leader arm) was used before ``connect()`` or after ``disconnect()``.

    Mirrors LeRobot's error of the same name (a ``ConnectionError``), so code that catches
    LeRobot's kind of error catches this one too.
    """

    def __init__(
        self, message: str = "This device is not connected. Try calling `connect()` first."
    ) -> None:
        self.message = message
        super().__init__(message)


class DeviceAlreadyConnectedError(So101SimError, ConnectionError):
    """``connect()`` was called on a robot that is already connected (as in LeRobot)."""

    def __init__(
        self,
        message: str = "This device is already connected. Try not calling `connect()` twice.",
    ) -> None:
        self.message = message
        super().__init__(message)


class RobotConfigError(SettingError):
    """A simulated robot's configuration holds a value it cannot use."""


class CalibrationError(So101SimError, ValueError):
    """A leader arm's calibration (LeRobot's JSON format) is missing, malformed or unusable."""


class LeaderError(So101SimError, RuntimeError):
    """The leader arm cannot be reached: SDK not installed, port missing, a motor not answering."""


class RateError(SettingError):
    """A rate (goals, frames or ticks per second) is not a finite number greater than zero."""


class MissingDependencyError(So101SimError, ImportError):
    """An optional package (an extra such as ``so101sim[fidelity]``, or a LeRobot plugin) that
    the asked-for feature needs is not installed; the message says what to install."""
