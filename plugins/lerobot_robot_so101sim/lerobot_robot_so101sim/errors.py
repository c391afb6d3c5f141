"""Errors that both LeRobot and so101sim code catch.

LeRobot code catches ``lerobot.utils.errors.DeviceNotConnectedError`` (and
``DeviceAlreadyConnectedError``); so101sim code catches ``so101sim.errors``' classes of the same
names. The plugin raises classes that derive from both, so either ``except`` works, and
:func:`lerobot_errors` turns so101sim's into them at the plugin's edges.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

from lerobot.utils import errors as lerobot_errors_module

from so101sim import errors as sim_errors


class DeviceNotConnectedError(
    lerobot_errors_module.DeviceNotConnectedError, sim_errors.DeviceNotConnectedError
):
    """The simulated robot, camera or teleoperator was used before ``connect()`` or after
    ``disconnect()``: LeRobot's error and so101sim's at once."""


class DeviceAlreadyConnectedError(
    lerobot_errors_module.DeviceAlreadyConnectedError, sim_errors.DeviceAlreadyConnectedError
):
    """``connect()`` was called twice: LeRobot's error and so101sim's at once."""


class SimCameraError(sim_errors.CameraError):
    """A ``so101_sim`` camera used on its own: it renders the ``so101_sim`` robot's scene, and
    connects and disconnects with that robot."""


_TRANSLATED: tuple[tuple[type[Exception], type[Exception]], ...] = (
    (sim_errors.DeviceNotConnectedError, DeviceNotConnectedError),
    (sim_errors.DeviceAlreadyConnectedError, DeviceAlreadyConnectedError),
)


@contextmanager
def lerobot_errors() -> Iterator[None]:
    """Re-raise so101sim's connection errors as the classes above (same message)."""
    try:
        yield
    except (sim_errors.DeviceNotConnectedError, sim_errors.DeviceAlreadyConnectedError) as exc:
        for theirs, ours in _TRANSLATED:
            if isinstance(exc, theirs) and not isinstance(exc, ours):
                raise ours(str(exc)).with_traceback(exc.__traceback__) from None
        raise


F = TypeVar("F", bound=Callable[..., Any])


def raises_lerobot_errors(fn: F) -> F:
    """Decorate a method so that it raises the classes above instead of so101sim's."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with lerobot_errors():
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
