"""Teleoperation: mirror a LeRobot SO-101 leader arm on the simulated follower.

The leader's six Feetech STS3215 servos (ids 1..6, torque off so the arm can be moved by hand)
are read with one sync-read of ``Present_Position`` per tick through the Feetech SDK
(``scservo_sdk``, pip package ``feetech-servo-sdk``, with pyserial: ``pip install
'so101sim[leader]'``). Raw positions (ticks, 0..4095 per turn) become the arm's units with a
calibration in LeRobot's JSON format (``{motor: {id, drive_mode, homing_offset, range_min,
range_max}}``), with LeRobot's formulas:

* body joints, degrees: ``(raw - (range_min + range_max) / 2) * 360 / 4095``;
* gripper, 0..100: linear over ``[range_min, range_max]``, clamped (``100 - x`` if
  ``drive_mode``).

``homing_offset`` is not applied in software: LeRobot writes it into each servo, which then
reports positions with the offset already applied. :func:`teleoperate` runs LeRobot's
teleoperation loop (observe, read the leader, send, wait to the next tick at ``fps``) on any
robot with LeRobot's interface, and any bus with :meth:`LeaderBus.read_positions`, so it is
tested with a fake bus. Nothing here has been tried on a real leader arm.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ..errors import LeaderError
from ..model.load import default_units
from ..units import (
    JOINT_NAMES,
    LEROBOT_SUFFIX,
    ArmUnits,
)
from ..validation import check_count, check_duration, check_path_text
from .calibration import (
    CALIBRATION_FIELDS,
    LEADER_NAME,
    MAX_CALIBRATION_BYTES,
    MAX_TICK,
    MOTOR_IDS,
    TICKS_PER_TURN,
    FoundCalibration,
    MotorCalibration,
    default_calibration,
    find_calibration,
    lerobot_calibration_path,
    load_calibration,
    parse_calibration,
    ticks_to_pose,
)
from .helpers import Clock, check_fps, clock_for, sleep_until

log = logging.getLogger(__name__)

PRESENT_POSITION = (56, 2)  # (address, bytes) in the STS3215 control table
TORQUE_ENABLE = (40, 1)
HOMING_OFFSET = (31, 2)
DEFAULT_BAUDRATE = 1_000_000
DEFAULT_FPS = 60.0  # LeRobot's teleoperate default


def decode_sign_magnitude(value: int, sign_bit: int) -> int:
    """Feetech's sign-magnitude encoding -> a signed integer (bit ``sign_bit`` is the sign)."""
    return -(value & ~(1 << sign_bit)) if value & (1 << sign_bit) else value


class LeaderBus(Protocol):
    """What :func:`teleoperate` needs of the leader: raw positions, and closing."""

    def read_positions(self) -> dict[str, int]:
        """``{joint name: Present_Position in ticks}`` for the six motors."""
        ...

    def close(self) -> None: ...


class FeetechLeaderBus:
    """The leader arm on a serial port, through the Feetech SDK (protocol 0, 1 Mbaud).

    Opening disables every motor's torque (as LeRobot's leader ``configure()`` does) so the
    arm can be moved by hand, and warns if a servo's stored homing offset differs from the
    calibration's. Not tried on hardware.

    Raises:
        LeaderError: the SDK is not installed, the port cannot be opened, or a motor does not
            answer.
    """

    def __init__(
        self,
        port: str,
        *,
        calibration: Mapping[str, MotorCalibration] | None = None,
        baudrate: int = DEFAULT_BAUDRATE,
        sdk: Any = None,
    ) -> None:
        check_path_text(port, "serial port", error=LeaderError)  # "" is no port
        self._sdk = sdk if sdk is not None else _import_sdk()
        scs = self._sdk
        self.port = port
        self.ids = {n: (calibration[n].id if calibration else MOTOR_IDS[n]) for n in JOINT_NAMES}
        self._port = scs.PortHandler(port)
        try:
            opened = self._port.openPort() and self._port.setBaudRate(baudrate)
        except Exception as exc:  # serial.SerialException and the like
            raise LeaderError(
                f"cannot open the leader arm's port {port!r}: {exc}; expected the serial port "
                "of the leader's controller board (e.g. /dev/ttyACM0; `lerobot-find-port` "
                "finds it)"
            ) from None
        if not opened:
            raise LeaderError(f"cannot open {port!r} at {baudrate} baud")
        self._packet = scs.PacketHandler(0)
        addr, size = PRESENT_POSITION
        self._reader = scs.GroupSyncRead(self._port, self._packet, addr, size)
        for motor_id in self.ids.values():
            self._reader.addParam(motor_id)
        self._success = scs.COMM_SUCCESS
        try:
            self._configure(calibration)
        except LeaderError:
            self.close()
            raise

    def _configure(self, calibration: Mapping[str, MotorCalibration] | None) -> None:
        for name, motor_id in self.ids.items():
            result, _error = self._packet.write1ByteTxRx(self._port, motor_id, TORQUE_ENABLE[0], 0)
            if result != self._success:
                raise LeaderError(
                    f"motor {name!r} (id {motor_id}) on {self.port!r} does not answer "
                    f"({self._packet.getTxRxResult(result)}); check power and wiring"
                )
            if calibration is None:
                continue
            raw, result, _error = self._packet.read2ByteTxRx(self._port, motor_id, HOMING_OFFSET[0])
            if result == self._success:
                offset = decode_sign_magnitude(raw, 11)
                if offset != calibration[name].homing_offset:
                    log.warning(
                        "leader motor %r stores homing offset %d but the calibration says %d: "
                        "positions may be off; recalibrate with lerobot-calibrate",
                        name,
                        offset,
                        calibration[name].homing_offset,
                    )

    def read_positions(self) -> dict[str, int]:
        addr, size = PRESENT_POSITION
        result = self._reader.txRxPacket()
        if result != self._success:
            raise LeaderError(
                f"sync read of Present_Position failed on {self.port!r}: "
                f"{self._packet.getTxRxResult(result)}"
            )
        return {
            name: decode_sign_magnitude(self._reader.getData(motor_id, addr, size), 15)
            for name, motor_id in self.ids.items()
        }

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._port.closePort()


def _import_sdk() -> Any:
    try:
        # optional: the Feetech SDK only for a real leader arm
        import scservo_sdk
    except ImportError:
        raise LeaderError(
            "the Feetech SDK is not installed; install the leader extra: "
            "pip install 'so101sim[leader]' (feetech-servo-sdk and pyserial)"
        ) from None
    return scservo_sdk


def _leader_action(
    raw: Mapping[str, int],
    calibration: Mapping[str, MotorCalibration],
    limits: tuple[np.ndarray, np.ndarray],
) -> dict[str, float]:
    """The leader's raw positions as a follower action, clipped to ``limits`` (quietly: at
    debug level)."""
    pose = ticks_to_pose(raw, calibration)
    values = np.array([pose[n] for n in JOINT_NAMES])
    clipped = np.clip(values, *limits)
    if np.any(clipped != values):
        log.debug("leader beyond the follower's limits; clipped %s", values)
    return {f"{n}{LEROBOT_SUFFIX}": float(clipped[i]) for i, n in enumerate(JOINT_NAMES)}


def _finished(
    elapsed: float,
    ticks: int,
    duration: float | None,
    max_ticks: int | None,
    should_stop: Callable[[], bool] | None,
) -> bool:
    """Whether teleoperation stops after this tick (``should_stop`` is asked last, and only
    when the other limits have not stopped it)."""
    return (
        (duration is not None and elapsed >= duration - 1e-9)
        or (max_ticks is not None and ticks >= max_ticks)
        or (should_stop is not None and bool(should_stop()))
    )


@dataclass(frozen=True)
class TeleopResult:
    """How a teleoperation session went."""

    ticks: int
    late_ticks: int  # ticks whose work took longer than 1 / fps
    duration: float  # on the robot's clock
    last_action: dict[str, float]


def _follower_units(robot: Any) -> ArmUnits:
    """The units of the follower's own model when it is simulated, else the shipped model's."""
    units = getattr(getattr(robot, "simulation", None), "units", None)
    return units if isinstance(units, ArmUnits) else default_units()


def teleoperate(
    robot: Any,
    leader: LeaderBus,
    calibration: Mapping[str, MotorCalibration] | None = None,
    *,
    fps: float = DEFAULT_FPS,
    duration: float | None = None,
    max_ticks: int | None = None,
    clock: Clock | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> TeleopResult:
    """Mirror ``leader`` on ``robot`` at ``fps`` ticks per second, as LeRobot's teleoperation
    loop does: read the robot's observation, read the leader, send its pose, wait to the
    next tick (absolute deadlines on the robot's clock).

    Leader values beyond the follower's joint limits are clipped to them here (silently, at
    debug level), so the follower does not warn 60 times a second: the limits of the
    follower's own model (``robot.simulation.units``, as with ``so101sim teleop --model``),
    else of the shipped model. Stops after ``duration``
    seconds, ``max_ticks`` ticks, or when ``should_stop()`` is true; otherwise runs until
    interrupted (Ctrl-C).

    Raises (before anything is read or sent): RateError for a bad ``fps``, DurationError for
    a bad ``duration``, SettingError for a ``max_ticks`` that is not a whole number >= 0.
    """
    fps = check_fps(fps)
    if duration is not None:
        duration = check_duration(duration)
    if max_ticks is not None:
        max_ticks = check_count(max_ticks, "max_ticks")
    calibration = calibration if calibration is not None else default_calibration()
    clock = clock if clock is not None else clock_for(robot)
    limits = _follower_units(robot).limits
    period = 1.0 / fps
    t0 = clock.now()
    ticks = late = 0
    action: dict[str, float] = {}
    while True:
        tick_start = clock.now()
        robot.get_observation()
        action = _leader_action(leader.read_positions(), calibration, limits)
        robot.send_action(action)
        ticks += 1
        if clock.now() - tick_start > period:
            late += 1
        sleep_until(clock, t0 + ticks * period)
        if _finished(clock.now() - t0, ticks, duration, max_ticks, should_stop):
            break
    if late:
        log.warning(
            "teleoperation ran slower than %g Hz on %d of %d ticks; control may be unstable",
            fps,
            late,
            ticks,
        )
    return TeleopResult(ticks=ticks, late_ticks=late, duration=clock.now() - t0, last_action=action)


__all__ = [
    "CALIBRATION_FIELDS",
    "DEFAULT_FPS",
    "LEADER_NAME",
    "MAX_CALIBRATION_BYTES",
    "MAX_TICK",
    "MOTOR_IDS",
    "TICKS_PER_TURN",
    "FeetechLeaderBus",
    "FoundCalibration",
    "LeaderBus",
    "MotorCalibration",
    "TeleopResult",
    "decode_sign_magnitude",
    "default_calibration",
    "find_calibration",
    "lerobot_calibration_path",
    "load_calibration",
    "parse_calibration",
    "teleoperate",
    "ticks_to_pose",
]
