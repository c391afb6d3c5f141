"""The exception hierarchy: one base class, one subclass per kind, the right builtin bases."""

import inspect

import pytest

from so101sim import errors
from so101sim.errors import (
    DeviceAlreadyConnectedError,
    DeviceNotConnectedError,
    JointLimitError,
    JointValueError,
    MotionFileError,
    So101SimError,
)

ALL = [
    obj
    for _, obj in inspect.getmembers(errors, inspect.isclass)
    if issubclass(obj, Exception) and obj.__module__ == errors.__name__
]


def test_every_error_is_a_so101sim_error_and_documented():
    assert len(ALL) >= 15
    for cls in ALL:
        assert issubclass(cls, So101SimError), cls
        assert cls.__doc__ and len(cls.__doc__) > 20, cls


def test_every_error_is_exported_from_the_package():
    import so101sim

    for cls in ALL:
        assert getattr(so101sim, cls.__name__) is cls


@pytest.mark.parametrize(
    "name, builtin",
    [
        ("JointNameError", ValueError),
        ("JointValueError", ValueError),
        ("DurationError", ValueError),
        ("SettingError", ValueError),
        ("MotionFileError", ValueError),
        ("SimulationDivergedError", RuntimeError),
        ("ViewerError", RuntimeError),
        ("DeviceNotConnectedError", ConnectionError),
        ("DeviceAlreadyConnectedError", ConnectionError),
    ],
)
def test_errors_are_also_the_builtin_a_caller_would_catch(name, builtin):
    assert issubclass(getattr(errors, name), builtin)


def test_a_limit_error_is_a_value_error_of_the_joint():
    assert issubclass(JointLimitError, JointValueError)


def test_motion_file_error_says_where():
    e = MotionFileError("lab.toml", 12, "unknown key 'durration'")
    assert str(e) == "lab.toml:12: unknown key 'durration'"
    assert (e.path, e.line, e.reason) == ("lab.toml", 12, "unknown key 'durration'")
    assert str(MotionFileError("x.toml", 0, "file not found")) == "x.toml: file not found"


def test_connection_errors_use_lerobots_messages():
    # LeRobot's default texts; the robot passes its own name in ("... is not connected. Run
    # `.connect()` first."), tested in test_robot.py
    assert str(DeviceNotConnectedError()) == (
        "This device is not connected. Try calling `connect()` first."
    )
    assert "already connected" in str(DeviceAlreadyConnectedError())
