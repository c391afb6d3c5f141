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

**The viewer** (``viewer=True``) draws a copy of the arm (:class:`so101sim.viewer.MirroredViewer`,
with the shipped draft meshes when OpenGL renders on the CPU: ``viewer_quality``). About 60
times a wall-clock second the physics copies its state to it, holding the lock for
microseconds; the viewer's own thread draws it. So the physics never waits for the drawing,
and what is done in the window (perturbing, sliders) does not reach the physics.

**Threads end with the robot.** ``disconnect()`` stops the physics thread and closes the
viewer. A robot still connected when the interpreter exits is stopped first, by an ``atexit``
hook registered at ``connect()`` (a thread stepping MuJoCo while Python finalizes crashes the
process), and a robot dropped while connected is stopped when it is garbage-collected: the
threads hold what they use (the simulation, its lock, a stop event), never the robot.

**Safety, as on the real arm.** ``max_relative_target`` clamps each goal to the present
position ± the cap, with LeRobot's warning; goals beyond a joint's limits are clipped to the
limits with a warning (the servos' position limits do this on the real arm); the gripper's
effort is bounded to half the actuator's force range, as LeRobot's ``configure()`` bounds the
real gripper (``Max_Torque_Limit`` 500 of 1000, "50% of max torque to avoid burnout").

**Bad input** (unknown keys, values that are not finite numbers) raises a clear error before
anything changes: the arm keeps its last valid goal.

The configuration and its checks live in :mod:`so101sim.robot.config`, the action checks and
safety clamps in :mod:`so101sim.robot.actions`; the names users import are re-exported here.
The robot drives its :class:`~so101sim.sim.simulation.Simulation` through its methods only, but
for the viewer and the gripper's force range, which need the MuJoCo model and data.
"""

from __future__ import annotations

import logging
import threading
import time
import weakref
from collections.abc import Mapping
from pprint import pformat
from typing import Any

import numpy as np

from ..errors import DeviceAlreadyConnectedError, DeviceNotConnectedError, RobotConfigError
from ..exitgate import gated
from ..model.arm import gripper_full_range, load_profile
from ..sim import fastpath
from ..sim.simulation import Simulation
from ..units import GRIPPER_INDEX, STARTING_POSE, parse_pose
from ..validation import check_duration
from .actions import JOINT_INDEX, clamp_relative, clip_to_limits, parse_action
from .cameras import CameraRig, SimCamera, scene_model
from .config import (
    GRIPPER_TORQUE_FRACTION,
    MODES,
    VIEWER_QUALITIES,
    SO101SimFollowerConfig,
    relative_caps,
)
from .helpers import MOTOR_KEYS
from .scene import before_observation, register, unregister
from .threads import RobotThreads

log = logging.getLogger(__name__)

_CLAMP_MESSAGE = "Relative goal position magnitude had to be clamped to be safe.\n%s"  # LeRobot's
_CLIP_MESSAGE = "Goal position beyond the joint limits was clipped to the limits.\n%s"


class _FollowerClock:
    """The follower's own time as a :class:`so101sim.robot.helpers.Clock` (what
    ``robot.clock`` gives the helpers; not :class:`so101sim.lab.simclock.SimClock`, which
    stands in for the ``time`` module in a student's script).

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
        pose = dict(STARTING_POSE)
        pose.update(parse_pose(self.config.initial_pose, partial=True))
        # A private model (configure() changes the gripper's force range on it), with the
        # config's cameras and scene preset added; the rig renders them (robot.cameras).
        profile = load_profile(self.config.arm)  # the preset's distractors, textures built in
        model = scene_model(
            self.config.cameras, self.config.model, self.config.scene, self.config.randomize,
            arm=profile,
        )  # fmt: skip
        self._sim = Simulation(model, initial_pose=pose)
        self._limits = tuple(a.tolist() for a in self._sim.units.limits)  # floats, per action
        self._rig = CameraRig(self._sim, self.config.cameras)
        self._gripper = int(self._sim.index.actuator[GRIPPER_INDEX])
        # the gripper's full range (the profile's torque limit, before LeRobot's limit that
        # configure() applies: gripper_torque_fraction of it)
        self._gripper_forcerange = gripper_full_range(profile)
        self._lock = self._sim.lock
        self._connected = False
        self._runner = RobotThreads(self._sim, str(self), self.config.speed)  # until connect()
        self._finalizer: weakref.finalize | None = None
        self._clock = _FollowerClock(self)

    # ------------------------------------------------------------------ LeRobot's interface
    def __str__(self) -> str:
        return f"{self.id} {self.__class__.__name__}"

    def __enter__(self) -> SO101SimFollower:
        self.connect()
        return self

    def __exit__(self, exc_type: object, exc_value: object, traceback: object) -> None:
        self.disconnect()

    @property
    def _motors_ft(self) -> dict[str, type]:
        return dict.fromkeys(MOTOR_KEYS, float)

    @property
    def observation_features(self) -> dict[str, type | tuple[int, int, int]]:
        """``{"shoulder_pan.pos": float, ..., "gripper.pos": float}`` and, per camera,
        ``{name: (height, width, 3)}``."""
        return {**self._motors_ft, **self._rig.features}

    @property
    def cameras(self) -> dict[str, SimCamera]:
        """The simulated cameras by name (LeRobot's ``robot.cameras``): see
        :mod:`so101sim.robot.cameras`."""
        return self._rig.cameras

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
        runner = RobotThreads(self._sim, str(self), self.config.speed, rig=self._rig)
        self._rig.open()  # cameras: their renderers and their render thread
        try:
            if self.config.viewer:
                runner.open_viewer(self.config.viewer_quality)
            if self.config.mode == "realtime":
                runner.start_physics(f"so101sim-physics-{self.id}")
        except BaseException:
            runner.stop()  # nothing left running: cameras closed, threads joined
            raise
        self._finalizer = runner.tie_to(self)  # stopped at exit, or when the robot is collected
        self._runner = runner
        self._connected = True
        register(self)  # teleoperators that drive its scene find it there
        log.info("%s connected.", self)

    def calibrate(self) -> None:
        """Nothing to do: the simulated arm's joints are calibrated by construction."""
        log.info("%s needs no calibration (simulated arm)", self)

    def configure(self) -> None:
        """Bound the gripper's effort as LeRobot's ``configure()`` bounds the real gripper's
        torque (``Max_Torque_Limit`` 500 of 1000): the gripper actuator gets
        ``gripper_torque_fraction`` (50 %) of the arm profile's torque limit (the profile's
        own gripper ``torque_scale`` is replaced, not multiplied)."""
        with self._lock:  # the force range is in the model: no Simulation method sets it
            self._sim.model.actuator_forcerange[self._gripper] = (
                self._gripper_forcerange * self.config.gripper_torque_fraction
            )

    @gated  # no MuJoCo call left running at exit (exitgate); later ones refused
    def get_observation(self) -> dict[str, Any]:
        """The measured joint positions: ``{"shoulder_pan.pos": deg, ..., "gripper.pos": %}``,
        and a (height, width, 3) uint8 frame per camera, under the camera's name.

        The gripper's reading is clamped to 0..100, as LeRobot clamps it to the calibrated
        range; body joints are not clamped (LeRobot's degrees are not either).

        In lockstep mode, then advances ``lockstep_observation_seconds`` of simulated time.

        Raises:
            DeviceNotConnectedError: not connected.
            SimulationDivergedError: the physics became unstable.
            ClosedError: the interpreter is exiting.
        """
        self._check_connected()
        before_observation(self)  # a scene reset asked for between takes
        with self._lock:
            self._check_connected()  # again: disconnect() may have ended while we waited
            values = fastpath.pose_values(self._sim)
            # LeRobot clamps the gripper's reading to its calibrated range (0..100)
            values[GRIPPER_INDEX] = min(100.0, max(0.0, values[GRIPPER_INDEX]))
            shot = self._rig.snapshot() if self._rig.specs else None  # copied under the lock
            if self.config.mode == "lockstep" and self.config.lockstep_observation_seconds:
                self._runner.advance(self.config.lockstep_observation_seconds)
        obs: dict[str, Any] = dict(zip(MOTOR_KEYS, values, strict=True))
        if shot is not None:
            obs.update(self._rig.render(shot))  # cameras: rendered outside the physics lock
        return obs

    @gated  # no MuJoCo call left running at exit (exitgate); later ones refused
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
            ClosedError: the interpreter is exiting.
        """
        self._check_connected()
        goals = parse_action(action)  # plain floats from here on: microseconds per action
        names = list(goals)
        idx = [JOINT_INDEX[n] for n in names]
        with self._lock:
            self._check_connected()  # again: disconnect() may have ended while we waited
            wanted: Any = list(goals.values())
            if self._caps is not None:
                present = self._sim.pose_array()[idx]
                safe, clamped = clamp_relative(names, np.array(wanted), present, self._caps)
                wanted = safe.tolist()
                if clamped:
                    log.warning(_CLAMP_MESSAGE, pformat(clamped, indent=4))
            sent, clipped = clip_to_limits(names, wanted, self._limits)
            if clipped:
                log.warning(_CLIP_MESSAGE, pformat(clipped, indent=4))
            fastpath.command_joints(self._sim, idx, sent)
            if self.config.mode == "lockstep" and self.config.lockstep_action_seconds:
                self._runner.advance(self.config.lockstep_action_seconds)
        return dict(zip([MOTOR_KEYS[i] for i in idx], sent, strict=True))

    def disconnect(self) -> None:
        """Stop the physics thread (joined: none is left running) and close the viewer.

        Raises:
            DeviceNotConnectedError: not connected.
        """
        if not self._connected:
            raise self._not_connected()
        with self._lock:  # waits for an action or observation in flight (another thread's)
            self._connected = False
        if self._finalizer is not None:
            self._finalizer()  # stops the threads and removes the exit hook, once
            self._finalizer = None
        self._connected = False
        unregister(self)
        log.info("%s disconnected.", self)

    # ------------------------------------------------------------------ sim extras
    @property
    def time(self) -> float:
        """Simulated time in seconds."""
        with self._lock:
            return self._sim.time

    @property
    def clock(self) -> _FollowerClock:
        """This arm's clock (simulated time) for :mod:`so101sim.robot.helpers`."""
        return self._clock

    @property
    def simulation(self) -> Simulation:
        """The underlying :class:`~so101sim.sim.simulation.Simulation` (hold ``lock`` to touch it
        while connected in real-time mode)."""
        return self._sim

    @property
    def lock(self) -> threading.RLock:
        """The lock around the MuJoCo data."""
        return self._lock

    @property
    def viewer(self) -> Any:
        """The viewer opened by ``viewer=True`` (a :class:`so101sim.viewer.MirroredViewer`:
        its ``cam``, its ``frames`` drawn so far), or None when none is open."""
        return self._runner.viewer

    @property
    def viewer_open(self) -> bool:
        """Whether the viewer asked for by ``viewer=True`` is open (False once closed)."""
        viewer = self._runner.viewer
        return viewer is not None and bool(viewer.is_running())

    def goal(self) -> dict[str, float]:
        """The goals the arm is currently driven to (LeRobot keys)."""
        with self._lock:
            values = self._sim.commanded_array()
        return dict(zip(MOTOR_KEYS, values.tolist(), strict=True))

    @gated  # no MuJoCo call left running at exit (exitgate); later ones refused
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
        s = check_duration(seconds, "seconds", allow_zero=True)
        with self._lock:
            self._check_connected()  # again: disconnect() may have ended while we waited
            self._runner.advance(s)
            return self._sim.time

    # ------------------------------------------------------------------ internals
    def _not_connected(self) -> DeviceNotConnectedError:
        return DeviceNotConnectedError(
            f"{self.__class__.__name__} is not connected. Run `.connect()` first."
        )

    def _check_connected(self) -> None:
        if not self._connected:
            raise self._not_connected()
        if self._runner.error is not None:
            raise self._runner.error


__all__ = [
    "GRIPPER_TORQUE_FRACTION",
    "MODES",
    "VIEWER_QUALITIES",
    "SO101SimFollower",
    "SO101SimFollowerConfig",
    "parse_action",
    "relative_caps",
]
