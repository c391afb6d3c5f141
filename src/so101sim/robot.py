"""A simulated SO-101 follower with LeRobot's robot interface.

Code written for the real arm through LeRobot runs on the simulation unchanged but for the
line that makes the robot::

    from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig

    robot = SO101SimFollower(SO101SimFollowerConfig(id="my_arm"))  # instead of SO101Follower
    robot.connect()
    obs = robot.get_observation()          # {"shoulder_pan.pos": deg, ..., "gripper.pos": 0..100}
    robot.send_action({"shoulder_pan.pos": 20.0})
    time.sleep(1.0)                        # the arm moves meanwhile, as the real one does
    robot.disconnect()

**Time.** In ``"realtime"`` mode (the default) a background thread steps the physics at
real-time speed (``speed`` × real time), pacing to absolute wall-clock deadlines; a goal takes
effect at the simulated time it arrives (within one physics block, 4 ms). In ``"lockstep"``
mode nothing moves on its own: :meth:`SO101SimFollower.step` advances simulated time, and each
``send_action`` (``lockstep_action_seconds``, default 0.02 s: a 50 Hz loop) and each
``get_observation`` (``lockstep_observation_seconds``, default 0) advance it by a fixed amount,
so runs are deterministic (bit-identical observations). One lock guards the MuJoCo data.

**Safety, as on the real arm.** ``max_relative_target`` clamps each goal to the present
position ± the cap, with LeRobot's warning; goals beyond a joint's limits are clipped to the
limits with a warning (the servos' position limits do this on the real arm); the gripper's
effort is bounded to half the actuator's force range, as LeRobot's ``configure()`` bounds the
real gripper (``Max_Torque_Limit`` 500 of 1000, "50% of max torque to avoid burnout").

**Bad input** (unknown keys, values that are not finite numbers) raises a clear error before
anything changes: the arm keeps its last valid goal.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import math
import numbers
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from pprint import pformat
from typing import Any

import numpy as np

from .errors import (
    DeviceAlreadyConnectedError,
    DeviceNotConnectedError,
    DurationError,
    JointNameError,
    JointValueError,
    RobotConfigError,
    So101SimError,
)
from .hardware import MOTOR_KEYS
from .model import arm_index, load_model
from .simulation import Pacer, Simulation
from .units import (
    GRIPPER_INDEX,
    JOINT_NAMES,
    LEROBOT_SUFFIX,
    STARTING_POSE,
    check_number,
    normalize_joint_name,
    parse_pose,
)

log = logging.getLogger(__name__)

MODES: tuple[str, ...] = ("realtime", "lockstep")
GRIPPER_TORQUE_FRACTION = 0.5
"""Share of the actuator's force range the gripper may use: LeRobot's ``configure()`` writes
``Max_Torque_Limit = 500`` (of 1000) to the real gripper (with ``Protection_Current = 250`` and
``Overload_Torque = 25``), so the simulated gripper gets 50 % of the model's force range."""

_BLOCK_SECONDS = 0.004  # real-time mode steps the physics in blocks of this much simulated time
_VIEWER_PERIOD = 1.0 / 60.0  # wall seconds between viewer syncs
_CLIP_WARN_TOLERANCE = 1e-3  # goals this close to a limit are clipped without a warning


def _positive(name: str, value: object, *, allow_zero: bool = False) -> float:
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool)
    v = float(value) if ok else math.nan  # type: ignore[arg-type]
    if not (math.isfinite(v) and (v >= 0 if allow_zero else v > 0)):
        expected = ">= 0" if allow_zero else "> 0"
        raise RobotConfigError(
            f"{name} = {value!r} is invalid; expected a finite number {expected}"
        )
    return v


def relative_caps(max_relative_target: object) -> np.ndarray | None:
    """``max_relative_target`` as six caps in :data:`JOINT_NAMES` order (``inf``: uncapped),
    or None when there is no cap.

    Accepts a positive number (int or float: LeRobot rejects an int, this does not) applying to
    every joint, or a dict from joint name (``"elbow_flex"`` or ``"elbow_flex.pos"``) to a
    positive number; joints a dict leaves out are not capped.

    Raises:
        RobotConfigError: a cap that is not a finite number > 0, or a dict key that is not one
            of the six joints (the message lists them).
    """
    if max_relative_target is None:
        return None
    caps = np.full(len(JOINT_NAMES), math.inf)
    if isinstance(max_relative_target, Mapping):
        for key, value in max_relative_target.items():
            try:
                name = normalize_joint_name(key)
            except JointNameError:
                raise RobotConfigError(
                    f"max_relative_target has an unknown joint {key!r}; valid keys are "
                    f"{', '.join(JOINT_NAMES)} (or the same with '.pos')"
                ) from None
            caps[JOINT_NAMES.index(name)] = _positive(f"max_relative_target[{key!r}]", value)
        return caps
    if isinstance(max_relative_target, numbers.Real) and not isinstance(max_relative_target, bool):
        caps[:] = _positive("max_relative_target", max_relative_target)
        return caps
    raise RobotConfigError(
        f"max_relative_target = {max_relative_target!r} is invalid; expected None, a number > 0 "
        f"(degrees; 0..100 units for the gripper), or a dict from joint name to such a number"
    )


@dataclass(kw_only=True)
class SO101SimFollowerConfig:
    """Configuration of :class:`SO101SimFollower`.

    The first fields are LeRobot's ``SO101FollowerConfig`` fields that mean something here
    (``port``, the PID coefficients and ``num_read_retries`` do not); the rest are the sim's.
    """

    id: str | None = None
    """Name of this arm, as in LeRobot (shown in logs and ``str(robot)``)."""
    max_relative_target: float | int | dict[str, float] | None = None
    """Largest step from the present position a goal may ask for: one number for every joint,
    or a dict per joint (degrees; gripper in 0..100 units). None: no cap."""
    disable_torque_on_disconnect: bool = True
    """Accepted for LeRobot compatibility. The sim's physics stops at ``disconnect()``, so the
    arm neither falls (torque off) nor holds (torque on); it freezes until the next connect."""
    use_degrees: bool = True
    """Body joints in degrees. Only True is supported (LeRobot's -100..100 mode is not)."""
    cameras: dict[str, Any] = field(default_factory=dict)
    """No cameras are simulated yet: must stay empty."""
    model: str | Path | None = None
    """MJCF file to load instead of the shipped ``scene.xml``."""
    viewer: bool = False
    """Open MuJoCo's passive viewer at ``connect()`` (needs a display)."""
    mode: str = "realtime"
    """``"realtime"``: physics runs in the background at ``speed`` × real time.
    ``"lockstep"``: simulated time advances only through ``step()`` and the fixed amounts
    below, deterministically."""
    initial_pose: dict[str, float] = field(default_factory=lambda: dict(STARTING_POSE))
    """Pose the arm starts in (joint names or LeRobot keys; joints left out take
    :data:`~so101sim.units.STARTING_POSE`'s value)."""
    speed: float = 1.0
    """Real-time mode: simulated seconds per wall-clock second."""
    lockstep_action_seconds: float = 0.02
    """Lockstep mode: simulated seconds each ``send_action`` advances (0.02: a 50 Hz loop)."""
    lockstep_observation_seconds: float = 0.0
    """Lockstep mode: simulated seconds each ``get_observation`` advances."""
    gripper_torque_fraction: float = GRIPPER_TORQUE_FRACTION
    """Share of the gripper actuator's force range the gripper may use (0 < f <= 1)."""

    def __post_init__(self) -> None:
        if self.use_degrees is not True:
            raise RobotConfigError(
                "use_degrees=False (LeRobot's -100..100 range for the body joints) is not "
                "supported by the simulated follower; it reports body joints in degrees only: "
                "set use_degrees=True"
            )
        if self.cameras:
            raise RobotConfigError(
                f"cameras {sorted(self.cameras)} cannot be simulated yet; expected cameras={{}}"
            )
        if self.mode not in MODES:
            raise RobotConfigError(
                f"mode = {self.mode!r} is invalid; expected one of {', '.join(MODES)}"
            )
        relative_caps(self.max_relative_target)
        try:
            parse_pose(self.initial_pose, partial=True)
        except So101SimError as exc:
            raise RobotConfigError(f"initial_pose is invalid: {exc}") from None
        self.speed = _positive("speed", self.speed)
        self.lockstep_action_seconds = _positive(
            "lockstep_action_seconds", self.lockstep_action_seconds, allow_zero=True
        )
        self.lockstep_observation_seconds = _positive(
            "lockstep_observation_seconds", self.lockstep_observation_seconds, allow_zero=True
        )
        fraction = _positive("gripper_torque_fraction", self.gripper_torque_fraction)
        if fraction > 1:
            raise RobotConfigError(
                f"gripper_torque_fraction = {fraction} is invalid; expected 0 < fraction <= 1"
            )
        self.gripper_torque_fraction = fraction


class _SimClock:
    """Simulated time as a :class:`so101sim.hardware.Clock`.

    Lockstep: ``sleep`` advances the physics. Real time: ``sleep`` waits on the wall clock
    (scaled by ``speed``) while the background thread advances it.
    """

    def __init__(self, robot: SO101SimFollower) -> None:
        self._robot = robot

    def now(self) -> float:
        return self._robot.time

    def sleep(self, seconds: float) -> None:
        if seconds <= 0:
            return
        robot = self._robot
        if robot.config.mode == "lockstep":
            robot.step(seconds)
        else:
            time.sleep(seconds / robot.config.speed)


class SO101SimFollower:
    """A simulated SO-101 follower arm with LeRobot's ``Robot`` interface.

    See the module's documentation. Observations and actions use LeRobot's keys
    (``"shoulder_pan.pos"`` ...), body joints in degrees (0 = middle of the range) and the
    gripper on 0..100 (0 closed).
    """

    config_class = SO101SimFollowerConfig
    name = "so101_sim_follower"

    def __init__(self, config: SO101SimFollowerConfig | None = None) -> None:
        self.config = config if config is not None else SO101SimFollowerConfig()
        self.robot_type = self.name
        self.id = self.config.id
        self.calibration: dict[str, Any] = {}
        self._caps = relative_caps(self.config.max_relative_target)
        # A private copy: configure() changes the gripper's force range on it.
        model = copy.copy(load_model(self.config.model))
        self._index = arm_index(model)
        self._gripper_forcerange = model.actuator_forcerange[
            self._index.actuator[GRIPPER_INDEX]
        ].copy()
        pose = dict(STARTING_POSE)
        pose.update(parse_pose(self.config.initial_pose, partial=True))
        self._sim = Simulation(model, initial_pose=pose)
        self._lock = self._sim.lock
        self._connected = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self._viewer_stack: contextlib.ExitStack | None = None
        self._viewer: Any = None
        self._last_sync = -math.inf
        self._clock = _SimClock(self)

    # ------------------------------------------------------------------ LeRobot's interface
    def __str__(self) -> str:
        return f"{self.id} {self.__class__.__name__}"

    def __enter__(self) -> SO101SimFollower:
        self.connect()
        return self

    def __exit__(self, exc_type: object, exc_value: object, traceback: object) -> None:
        self.disconnect()

    def __del__(self) -> None:
        try:
            if self.is_connected:
                self.disconnect()
        except Exception:
            pass

    @property
    def _motors_ft(self) -> dict[str, type]:
        return dict.fromkeys(MOTOR_KEYS, float)

    @property
    def observation_features(self) -> dict[str, type]:
        """``{"shoulder_pan.pos": float, ..., "gripper.pos": float}`` (no cameras)."""
        return self._motors_ft

    @property
    def action_features(self) -> dict[str, type]:
        """The same six ``"<joint>.pos": float`` keys as :attr:`observation_features`."""
        return self._motors_ft

    @property
    def is_connected(self) -> bool:
        return self._connected

    @property
    def is_calibrated(self) -> bool:
        """Always True: the simulated arm needs no calibration."""
        return True

    def connect(self, calibrate: bool = True) -> None:
        """Start the arm: configure it, open the viewer if asked, and in real-time mode start
        the physics thread.

        Raises:
            DeviceAlreadyConnectedError: already connected.
            ViewerError: ``viewer=True`` and no viewer can be opened here (nothing started).
        """
        if self._connected:
            raise DeviceAlreadyConnectedError(f"{self.__class__.__name__} is already connected.")
        if not self.is_calibrated and calibrate:
            self.calibrate()
        self.configure()
        if self.config.viewer:
            self._open_viewer()
        self._error = None
        if self.config.mode == "realtime":
            self._stop.clear()
            self._thread = threading.Thread(
                target=self._run_physics, name=f"so101sim-physics-{self.id}", daemon=True
            )
            self._thread.start()
        self._connected = True
        log.info("%s connected.", self)

    def calibrate(self) -> None:
        """Nothing to do: the simulated arm's joints are calibrated by construction."""
        log.info("%s needs no calibration (simulated arm)", self)

    def configure(self) -> None:
        """Bound the gripper's effort as LeRobot's ``configure()`` bounds the real gripper's
        torque (``Max_Torque_Limit`` 500 of 1000): the gripper actuator gets
        ``gripper_torque_fraction`` (50 %) of the model's force range."""
        g = self._index.actuator[GRIPPER_INDEX]
        with self._lock:
            self._sim.model.actuator_forcerange[g] = (
                self._gripper_forcerange * self.config.gripper_torque_fraction
            )

    def get_observation(self) -> dict[str, float]:
        """The measured joint positions: ``{"shoulder_pan.pos": deg, ..., "gripper.pos": %}``.

        The gripper's reading is clamped to 0..100, as LeRobot clamps it to the calibrated
        range; body joints are not clamped (LeRobot's degrees are not either).

        In lockstep mode, then advances ``lockstep_observation_seconds`` of simulated time.

        Raises:
            DeviceNotConnectedError: not connected.
            SimulationDivergedError: the physics became unstable.
        """
        self._check_connected()
        with self._lock:
            values = self._sim.pose_array()
            # LeRobot clamps the gripper's reading to its calibrated range (0..100)
            values[GRIPPER_INDEX] = min(100.0, max(0.0, values[GRIPPER_INDEX]))
            if self.config.mode == "lockstep" and self.config.lockstep_observation_seconds:
                self._advance(self.config.lockstep_observation_seconds)
        return dict(zip(MOTOR_KEYS, values.tolist(), strict=True))

    def send_action(self, action: Mapping[str, Any]) -> dict[str, float]:
        """Set new goal positions and return the goals actually sent.

        ``action`` maps some or all of the six ``"<joint>.pos"`` keys to goals (degrees,
        gripper 0..100); joints left out keep their goal. Each goal is clamped to the present
        position ± ``max_relative_target`` (with a warning) and clipped to the joint's limits
        (with a warning). In lockstep mode, then advances ``lockstep_action_seconds``.

        Raises (the arm keeps its last valid goal):
            DeviceNotConnectedError: not connected.
            JointNameError: an unknown key (the message lists the valid ones).
            JointValueError: a goal that is not a finite number.
        """
        self._check_connected()
        goals = parse_action(action)
        with self._lock:
            present = self._sim.pose_array()
            full = self._sim.commanded_array()
            names = list(goals)
            idx = [JOINT_NAMES.index(n) for n in names]
            wanted = np.array([goals[n] for n in names])
            safe = self._clamp_relative(names, wanted, present[idx])
            sent = self._clip_to_limits(names, safe, idx)
            full[idx] = sent
            self._sim.command_array(full, check=False)
            if self.config.mode == "lockstep" and self.config.lockstep_action_seconds:
                self._advance(self.config.lockstep_action_seconds)
        return {f"{n}{LEROBOT_SUFFIX}": float(v) for n, v in zip(names, sent, strict=True)}

    def disconnect(self) -> None:
        """Stop the physics thread (joined: none is left running) and close the viewer.

        Raises:
            DeviceNotConnectedError: not connected.
        """
        if not self._connected:
            raise DeviceNotConnectedError(
                f"{self.__class__.__name__} is not connected. Run `.connect()` first."
            )
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self._viewer_stack is not None:
            self._viewer_stack.close()
            self._viewer_stack = None
            self._viewer = None
        self._connected = False
        log.info("%s disconnected.", self)

    # ------------------------------------------------------------------ sim extras
    @property
    def time(self) -> float:
        """Simulated time in seconds."""
        with self._lock:
            return float(self._sim.data.time)

    @property
    def clock(self) -> _SimClock:
        """This arm's clock (simulated time) for :mod:`so101sim.hardware`'s helpers."""
        return self._clock

    @property
    def simulation(self) -> Simulation:
        """The underlying :class:`~so101sim.simulation.Simulation` (hold ``lock`` to touch it
        while connected in real-time mode)."""
        return self._sim

    @property
    def lock(self) -> threading.RLock:
        """The lock around the MuJoCo data."""
        return self._lock

    @property
    def viewer_open(self) -> bool:
        """Whether the viewer asked for by ``viewer=True`` is open (False once closed)."""
        return self._viewer is not None and bool(self._viewer.is_running())

    def goal(self) -> dict[str, float]:
        """The goals the arm is currently driven to (LeRobot keys)."""
        with self._lock:
            values = self._sim.commanded_array()
        return dict(zip(MOTOR_KEYS, values.tolist(), strict=True))

    def step(self, seconds: float) -> float:
        """Lockstep mode: advance simulated time by ``seconds`` (rounded to whole physics steps)
        holding the current goals; return the new simulated time.

        Raises:
            DeviceNotConnectedError: not connected.
            RobotConfigError: called in real-time mode (there, the physics runs on its own).
            DurationError: ``seconds`` is not a finite number >= 0.
        """
        self._check_connected()
        if self.config.mode != "lockstep":
            raise RobotConfigError(
                "step() advances simulated time only in lockstep mode; in real-time mode the "
                "physics runs on its own: wait with time.sleep instead"
            )
        if isinstance(seconds, bool) or not isinstance(seconds, numbers.Real):
            raise DurationError(f"seconds = {seconds!r} is not a number; expected seconds >= 0")
        s = float(seconds)
        if not (math.isfinite(s) and s >= 0):
            raise DurationError(f"seconds = {s} is invalid; expected a finite number >= 0")
        with self._lock:
            self._advance(s)
            return float(self._sim.data.time)

    # ------------------------------------------------------------------ internals
    def _check_connected(self) -> None:
        if not self._connected:
            raise DeviceNotConnectedError(
                f"{self.__class__.__name__} is not connected. Run `.connect()` first."
            )
        if self._error is not None:
            raise self._error

    def _clamp_relative(
        self, names: list[str], goal: np.ndarray, present: np.ndarray
    ) -> np.ndarray:
        if self._caps is None:
            return goal
        cap = self._caps[[JOINT_NAMES.index(n) for n in names]]
        safe = present + np.clip(goal - present, -cap, cap)
        warnings = {
            n: {"original goal_pos": float(g), "safe goal_pos": float(s)}
            for n, g, s in zip(names, goal, safe, strict=True)
            if abs(s - g) > 1e-4
        }
        if warnings:
            log.warning(
                "Relative goal position magnitude had to be clamped to be safe.\n%s",
                pformat(warnings, indent=4),
            )
        return safe

    def _clip_to_limits(self, names: list[str], goal: np.ndarray, idx: list[int]) -> np.ndarray:
        lo, hi = self._sim.units.limits
        clipped = np.clip(goal, lo[idx], hi[idx])
        warnings = {
            n: {
                "original goal_pos": float(g),
                "clipped goal_pos": float(c),
                "limits": (float(lo[i]), float(hi[i])),
            }
            for n, g, c, i in zip(names, goal, clipped, idx, strict=True)
            if abs(c - g) > _CLIP_WARN_TOLERANCE
        }
        if warnings:
            log.warning(
                "Goal position beyond the joint limits was clipped to the limits.\n%s",
                pformat(warnings, indent=4),
            )
        return clipped

    def _advance(self, seconds: float) -> None:
        """Step ``seconds`` of simulated time holding the goals (lock held by the caller)."""
        n = round(seconds / self._sim.timestep)
        if n <= 0:
            return
        self._sim.step(n)
        self._sync_viewer()

    def _sync_viewer(self) -> None:
        if self._viewer is None:
            return
        now = time.perf_counter()
        if now - self._last_sync < _VIEWER_PERIOD:
            return
        self._last_sync = now
        if self._viewer.is_running():
            self._viewer.sync()

    def _open_viewer(self) -> None:
        from .viewer import open_viewer

        # open_viewer closes the window and waits for its render thread when the stack closes
        stack = contextlib.ExitStack()
        self._viewer = stack.enter_context(open_viewer(self._sim.model, self._sim.data))
        self._viewer_stack = stack
        self._last_sync = -math.inf

    def _run_physics(self) -> None:
        """The real-time physics thread: step a block, then sleep until the next block's end
        is due on the wall clock (absolute deadlines, no drift)."""
        m, d = self._sim.model, self._sim.data
        block = max(1, round(_BLOCK_SECONDS / m.opt.timestep)) * m.opt.timestep
        pacer = Pacer(self.config.speed, sleep=self._stop.wait)
        with self._lock:
            t = float(d.time)
        pacer.wait(t)
        try:
            while not self._stop.is_set():
                pacer.wait(t + block)
                if self._stop.is_set():
                    break
                with self._lock:
                    self._advance(block)
                    t = float(d.time)
        except Exception as exc:  # surfaced by the next call from the user's thread
            self._error = exc
            log.error("%s: the physics thread stopped: %s", self, exc)
        if pacer.lag_events:
            log.debug("%s: physics fell behind real time %d times", self, pacer.lag_events)


def parse_action(action: object) -> dict[str, float]:
    """Validate a LeRobot action: ``{"<joint>.pos": finite number}`` for some of the six joints.

    Returns ``{joint name: value}``. Raises before anything changes:

    Raises:
        JointNameError: not a dict, or a key that is not one of the six ``"<joint>.pos"`` keys
            (the message lists them).
        JointValueError: a value that is not a finite real number.
    """
    if not isinstance(action, Mapping):
        raise JointNameError(
            f"an action must be a dict keyed by {', '.join(MOTOR_KEYS)}, got "
            f"{type(action).__name__}"
        )
    out: dict[str, float] = {}
    for key, value in action.items():
        name = key[: -len(LEROBOT_SUFFIX)] if isinstance(key, str) else None
        if not (isinstance(key, str) and key.endswith(LEROBOT_SUFFIX) and name in JOINT_NAMES):
            raise JointNameError(
                f"unknown action key {key!r}; valid keys are {', '.join(MOTOR_KEYS)} "
                "(the robot's action_features)"
            )
        try:
            out[name] = check_number(name, value)
        except JointValueError as exc:
            raise JointValueError(f"action {key!r}: {exc}") from None
    return out


__all__ = [
    "GRIPPER_TORQUE_FRACTION",
    "MODES",
    "SO101SimFollower",
    "SO101SimFollowerConfig",
    "parse_action",
    "relative_caps",
]
