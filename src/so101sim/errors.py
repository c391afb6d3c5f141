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
    """A joint target lies outside the joint's limits (in the arm's units)."""


class DurationError(So101SimError, ValueError):
    """A duration is not a finite number greater than zero."""


class ModelError(So101SimError):
    """A model file does not exist, does not compile, or lacks the SO-101 joints."""


class SimulationDivergedError(So101SimError, RuntimeError):
    """The physics became unstable (MuJoCo warned, or the state holds NaN/inf)."""


class ViewerError(So101SimError, RuntimeError):
    """The interactive viewer cannot be opened here (no display, macOS without mjpython)."""


class OutputPathError(So101SimError, ValueError):
    """An output file (video, plot, log) cannot be written: its folder is missing or not
    writable, or the file exists and overwriting was not asked for."""


class CameraError(So101SimError, ValueError):
    """A camera name the model does not have; the message lists the valid ones."""


class RenderBackendError(So101SimError, RuntimeError):
    """No OpenGL backend could render offscreen (EGL, OSMesa); the message says what to install."""


class RecordingError(So101SimError, ValueError):
    """Invalid recording settings (frame size, frame rate, quality preset)."""
