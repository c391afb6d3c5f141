"""``SO101SimCamera``: a camera of the ``so101_sim`` robot's scene as a LeRobot ``Camera``.

It renders through the robot's :class:`so101sim.robot.cameras.SimCamera`, so it exists only as
part of that robot (``--robot.cameras='{front: {type: so101_sim}}'``) and connects and
disconnects with it. ``read()``, ``async_read()`` and ``read_latest()`` return (height, width,
3) uint8 RGB frames of the simulation's present state.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from lerobot.cameras import Camera

from so101sim.robot import SimCamera

from .config_so101sim import SO101SimCameraConfig
from .errors import DeviceNotConnectedError, SimCameraError, raises_lerobot_errors

_ALONE = (
    "a so101_sim camera renders the so101_sim robot's scene and cannot be used on its own: "
    "give it in --robot.cameras of --robot.type=so101_sim"
)
_WITH_ROBOT = "a so101_sim camera connects and disconnects with its robot: call the robot's {}()"


class SO101SimCamera(Camera):
    """A simulated camera (see the module's documentation)."""

    def __init__(self, config: SO101SimCameraConfig, source: SimCamera | None = None) -> None:
        super().__init__(config)
        self.config = config
        self._source = source
        if source is not None:  # the robot's camera decides: its size is the frames' size
            self.width, self.height, self.fps = source.width, source.height, config.fps

    def __str__(self) -> str:
        name = self._source.name if self._source is not None else "?"
        return f"SO101SimCamera({name})"

    @property
    def is_connected(self) -> bool:
        return self._source is not None and self._source.is_connected

    @staticmethod
    def find_cameras() -> list[dict[str, Any]]:
        """None to find: simulated cameras are declared in the robot's config."""
        return []

    def connect(self, warmup: bool = True) -> None:
        """Raises SimCameraError: the robot connects its cameras."""
        raise SimCameraError(_ALONE if self._source is None else _WITH_ROBOT.format("connect"))

    def _checked_source(self) -> SimCamera:
        if self._source is None:
            raise SimCameraError(_ALONE)
        if not self._source.is_connected:
            raise DeviceNotConnectedError(f"{self} is not connected: connect its robot first.")
        return self._source

    @raises_lerobot_errors
    def read(self, color_mode: Any = None) -> np.ndarray:
        """A frame of the present state, rendered now (RGB; ``color_mode`` "bgr" flips it)."""
        frame = self._checked_source().read()
        if color_mode is not None and str(getattr(color_mode, "value", color_mode)) == "bgr":
            return np.ascontiguousarray(frame[..., ::-1])
        return frame

    @raises_lerobot_errors
    def async_read(self, timeout_ms: float = 200.0) -> np.ndarray:
        return self._checked_source().async_read(timeout_ms)

    @raises_lerobot_errors
    def read_latest(self, max_age_ms: int = 500) -> np.ndarray:
        return self._checked_source().read_latest(max_age_ms)

    def disconnect(self) -> None:
        """Raises SimCameraError (or DeviceNotConnectedError when not connected): the robot
        disconnects its cameras."""
        if not self.is_connected:
            raise DeviceNotConnectedError(f"{self} is not connected.")
        raise SimCameraError(_WITH_ROBOT.format("disconnect"))


__all__ = ["SO101SimCamera"]
