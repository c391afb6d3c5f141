"""``SimLeader``: what the plugin's teleoperators without hardware share (the motion player and
the scripted expert): six ``"<joint>.pos"`` actions, no feedback, nothing to calibrate or
configure, connected until ``disconnect()``."""

from __future__ import annotations

from typing import Any

from lerobot.teleoperators import Teleoperator

from so101sim.robot import MOTOR_KEYS

from .errors import DeviceNotConnectedError


class SimLeader(Teleoperator):
    """A leader arm made of software; subclasses set ``_connected`` in ``connect()`` and
    write ``get_action()``."""

    _connected = False

    @property
    def action_features(self) -> dict[str, type]:
        return dict.fromkeys(MOTOR_KEYS, float)

    @property
    def feedback_features(self) -> dict[str, type]:
        return {}

    @property
    def is_connected(self) -> bool:
        return self._connected

    @property
    def is_calibrated(self) -> bool:
        return True

    def calibrate(self) -> None:
        """Nothing to calibrate."""

    def configure(self) -> None:
        """Nothing to configure."""

    def send_feedback(self, feedback: dict[str, Any]) -> None:
        """Ignored: a software leader takes no feedback."""

    def disconnect(self) -> None:
        if not self._connected:
            raise DeviceNotConnectedError(f"{self} is not connected.")
        self._connected = False


__all__ = ["SimLeader"]
