"""``SO101SimExpert``: a task's scripted expert as a teleoperator
(``--teleop.type=so101_sim_expert --teleop.task=pick_cube``), so ``lerobot-record`` records
real demonstrations on the simulated arm.

It drives the ``so101_sim`` robot with the task's scene (``--robot.scene=pick_cube``,
``--robot.mode=lockstep``): LeRobot gives a teleoperator no handle on the robot, so it finds
the robot's :class:`~so101sim.robot.SO101SimFollower` in so101sim's registry of connected
followers (:mod:`so101sim.robot.scene`): the one that connects after it (``lerobot-record``
connects the teleoperator first), or one already connected, at the latest on the first
``get_action()``. Each ``get_action()`` is the expert's next joint targets
(``"<joint>.pos"``: degrees, gripper 0..100), planned from the arm's commanded targets and the
objects' real poses in that robot's simulation (:func:`so101sim.envs.sim_task`,
:func:`so101sim.envs.expert_for`).

**Takes and episodes.** A take is one run of the expert from a new start: the arm at its start
pose, the objects at poses drawn from ``seed + k`` for take ``k``.

Under ``lerobot-record`` a take is tied to LeRobot's episode, not to a count of calls: the
teleoperator finds LeRobot's record loop on the call stack (:func:`lerobot_episode`: the
``record_loop`` frame's ``start_episode_t``, which LeRobot sets anew for each episode, and its
``dataset``, None during the reset period). The first observation of each recorded episode
ends the take before it and makes the next take's reset before the state is read, so every
episode starts at its take's start, and a take never goes on into the next episode nor snaps
back inside one, however slowly the loop runs. When the expert's script is over the arm holds
still until LeRobot ends the episode; during the reset period it holds still too. A take whose
task had not succeeded when its episode ended (a loop too slow for ``--dataset.episode_time_s``,
or an expert that failed) is marked failed (``TakeRecord.failed``, ``failed_episodes``) with a
warning that says which episode, why and what to change.

Outside LeRobot's record loop (a hand-written loop, ``lerobot-teleoperate``) a take lasts
``config.take_calls`` = ``(episode_time_s + reset_time_s) * fps`` calls; at its last call the
next take's reset is asked for (made before the robot's next observation). Without a reset
period, the robot's first observation ``episode_time_s`` or more (wall clock) after the take's
first one also ends the take there (a loop that fell behind).

``takes`` records each take (:class:`TakeRecord`: seed, start poses, calls, success, when);
each is logged when it ends.
"""

from __future__ import annotations

import logging
import sys
import time
from dataclasses import dataclass, field
from typing import Any

from so101sim.envs import ScriptedExpert, SimTask, expert_for, sim_task
from so101sim.errors import So101SimError
from so101sim.robot import MOTOR_KEYS, RobotScene, find_follower, robot_scene, when_connected

from .config_so101sim import EXPERT_TELEOP_TYPE, SO101SimExpertConfig
from .errors import DeviceAlreadyConnectedError, DeviceNotConnectedError, lerobot_errors
from .leader import SimLeader

log = logging.getLogger(__name__)

MODE = "lockstep"


@dataclass
class TakeRecord:
    """One take of the expert: its start and how it went."""

    index: int
    seed: int
    placements: dict[str, tuple[float, float, float]]
    """The objects' start poses: x, y (metres), yaw (degrees)."""
    calls: int = 0
    success: bool = False
    """The task succeeded at some call of the take."""
    success_call: int | None = None
    """The first call (from 0) whose state showed success."""
    attempts: int = 0
    """Grasps retried by the expert."""
    cut_short: bool = False
    """The take ended before its ``take_calls`` (the recording loop fell behind)."""
    details: dict[str, float] = field(default_factory=dict)
    """The task's figures at the take's last call (e.g. ``cube_rise_m``)."""
    episode: int | None = None
    """LeRobot's episode (from 0, as recorded) that holds this take; None outside LeRobot's
    record loop."""
    failed: bool = False
    """The take's episode ended before the task succeeded: the episode holds no whole
    demonstration (``message`` says why)."""
    message: str = ""


@dataclass(frozen=True)
class LeRobotEpisode:
    """Where LeRobot's record loop is: which episode (its ``start_episode_t``), whether frames
    are being recorded (False in the reset period), its length (s) and rate."""

    start: float
    recording: bool
    control_time_s: float
    fps: float


def lerobot_episode(depth: int = 16) -> LeRobotEpisode | None:
    """LeRobot's ``record_loop`` that called us, read from its frame's variables (LeRobot tells
    a teleoperator nothing of its episodes); None when not called from one."""
    frame = sys._getframe(1)
    for _ in range(depth):
        frame = frame.f_back  # type: ignore[assignment]
        if frame is None:
            return None
        if frame.f_code.co_name == "record_loop" and "start_episode_t" in frame.f_locals:
            local = frame.f_locals
            try:
                return LeRobotEpisode(
                    start=float(local["start_episode_t"]),
                    recording=local.get("dataset") is not None,
                    control_time_s=float(local.get("control_time_s") or 0.0),
                    fps=float(local.get("fps") or 0.0),
                )
            except (TypeError, ValueError):
                return None
    return None


class SO101SimExpert(SimLeader):
    """The scripted expert of a task as a teleoperator (see the module's documentation)."""

    config_class = SO101SimExpertConfig
    name = EXPERT_TELEOP_TYPE

    def __init__(self, config: SO101SimExpertConfig) -> None:
        super().__init__(config)
        self.config = config
        self.takes: list[TakeRecord] = []
        """Every take so far, the one under way last."""
        self._connected = False
        self._follower: Any = None
        self._scene: RobotScene | None = None
        self._task: SimTask | None = None
        self._expert: ScriptedExpert | None = None
        self._stop_listening: Any = None
        self._take = 0  # the take under way or next
        self._running = False  # a take is under way
        self._wall0 = 0.0
        self._obs_wall0: float | None = None  # the wall time of the next take's first observation
        self._episode_start: float | None = None  # LeRobot's start_episode_t of the take's episode
        self._episodes = 0  # LeRobot's recorded episodes seen
        self._last: dict[str, float] | None = None  # the last targets (held between takes)

    @property
    def failed_episodes(self) -> list[int]:
        """LeRobot's episodes (from 0) whose take failed (see :attr:`TakeRecord.failed`)."""
        return [t.episode for t in self.takes if t.failed and t.episode is not None]

    def connect(self, calibrate: bool = True) -> None:
        """Find the robot with the task's scene: connected already, or when it connects."""
        if self._connected:
            raise DeviceAlreadyConnectedError(f"{self} is already connected.")
        self.takes, self._take, self._running, self._obs_wall0 = [], 0, False, None
        self._episode_start, self._episodes, self._last = None, 0, None
        self._follower = self._scene = self._task = self._expert = None
        self._connected = True
        try:
            self._attach(find_follower(self.config.task, mode=MODE))
        except So101SimError:  # not connected yet (LeRobot connects the teleoperator first)
            self._stop_listening = when_connected(self._on_connect)

    def get_action(self) -> dict[str, float]:
        """The expert's next joint targets (degrees; gripper 0..100) for the robot's scene.

        Raises:
            DeviceNotConnectedError: not connected, or no connected ``so101_sim`` robot has
                the task's scene (so101sim's message says what to pass).
            RobotConfigError: that robot is not in lockstep mode.
        """
        if not self._connected:
            raise DeviceNotConnectedError(f"{self} is not connected. Run `.connect()` first.")
        if self._follower is None:
            with lerobot_errors():
                self._attach(find_follower(self.config.task, mode=MODE))
        episode = lerobot_episode()
        if episode is not None:
            return self._lerobot_action(episode)
        now = time.perf_counter()
        if self._running and self._fell_behind(now, late=0.5 / self.config.fps):
            self._end_take(cut_short=True)  # no observation told (a loop that does not observe)
        scene = self._scene
        assert scene is not None
        scene.apply_pending()  # the robot made it already if it observed since
        if not self._running:
            self._start_take(now)
        action = self._step()
        if self.takes[-1].calls >= self.config.take_calls:
            self._end_take(cut_short=False)
        return action

    def disconnect(self) -> None:
        if not self._connected:
            raise DeviceNotConnectedError(f"{self} is not connected.")
        if self._stop_listening is not None:
            self._stop_listening()
            self._stop_listening = None
        if self._running:
            if self.takes[-1].episode is not None:
                self._end_episode_take(None)
            else:
                self._end_take(cut_short=True, reset=False)
        if self._scene is not None and self._scene.observation_hook == self._before_observation:
            self._scene.observation_hook = None
        self._connected = False

    # ------------------------------------------------------------------ internals
    def _step(self) -> dict[str, float]:
        """The expert's next targets, the take's record updated."""
        task, expert = self._task, self._expert
        assert task is not None and expert is not None
        record = self.takes[-1]
        with self._follower.lock:
            target = expert.act()
            ev = task.evaluate()
        if ev.success and not record.success:
            record.success, record.success_call = True, record.calls
        record.calls += 1
        record.attempts, record.details = expert.attempts, dict(ev.details)
        self._last = dict(zip(MOTOR_KEYS, (float(v) for v in target), strict=True))
        return dict(self._last)

    def _hold(self) -> dict[str, float]:
        """Hold still: the last targets (the arm's commanded targets before any)."""
        if self._last is None:
            with self._follower.lock:
                now = self._follower.simulation.commanded_array()
            self._last = dict(zip(MOTOR_KEYS, (float(v) for v in now), strict=True))
        return dict(self._last)

    def _lerobot_action(self, episode: LeRobotEpisode) -> dict[str, float]:
        """``get_action`` inside LeRobot's record loop: the take is the episode's."""
        scene = self._scene
        assert scene is not None
        if not episode.recording:
            return self._hold()  # the reset period: nothing recorded, the arm holds
        if episode.start != self._episode_start:  # the loop did not observe first: do it here
            self._new_episode(episode)
        scene.apply_pending()
        if not self._running:
            self._start_take(time.perf_counter())
            self.takes[-1].episode = self._episodes - 1
        return self._step()

    def _new_episode(self, episode: LeRobotEpisode) -> None:
        """LeRobot began recording a new episode: end the take under way (judged), ask for
        the next take's reset (made before this observation reads the state)."""
        if self._running:
            self._end_episode_take(episode)
        elif self._scene is not None and self._scene.pending is None and self.takes:
            self._scene.request_reset(self._seed(self._take))
        self._episode_start = episode.start
        self._episodes += 1

    def _end_episode_take(self, episode: LeRobotEpisode | None) -> None:
        """The take of the episode that just ended: failed unless the task succeeded in it."""
        record = self.takes[-1]
        if not record.success:
            rate = ""
            if episode is not None and episode.control_time_s > 0 and episode.fps > 0:
                want = round(episode.control_time_s * episode.fps)
                rate = (
                    f" in {record.calls} frames ({want} at {episode.fps:g} fps in "
                    f"{episode.control_time_s:g} s: the loop ran at "
                    f"{record.calls / episode.control_time_s:.1f} Hz)"
                )
            record.failed = True
            record.message = (
                f"episode {record.episode} (take {record.index}, seed {record.seed}) holds no "
                f"whole demonstration: the task did not succeed before LeRobot ended the "
                f"episode{rate}; expected success within the episode: drop this episode from the "
                f"dataset, and give a longer --dataset.episode_time_s, fewer or smaller cameras, "
                f"or a quieter machine"
            )
            log.warning("%s: %s", self, record.message)
        self._end_take(cut_short=False)

    def _on_connect(self, follower: Any) -> None:
        """A follower connected: take it if it has the task's scene (and the teleoperator
        has none yet); the first take's reset is then made before its first observation."""
        config = follower.config
        if self._follower is None and config.scene == self.config.task and config.mode == MODE:
            self._attach(follower)

    def _attach(self, follower: Any) -> None:
        scene = robot_scene(follower)
        sim = follower.simulation
        self._task = sim_task(self.config.task, sim.model, sim, scene.scene, self.config.fps)
        self._expert = expert_for(self._task)
        self._follower, self._scene = follower, scene
        scene.observation_hook = self._before_observation
        scene.request_reset(self._seed(self._take))
        if self._stop_listening is not None:
            self._stop_listening()
            self._stop_listening = None
        log.info("%s drives %s (scene %s)", self, follower, scene.name)

    def _seed(self, take: int) -> int:
        return self.config.seed + take

    def _fell_behind(self, now: float, late: float = 0.0) -> bool:
        """LeRobot's loop has started a new episode although the take is not over: only
        knowable without a reset period (see the module's documentation)."""
        episode = self.config.episode_time_s + late  # type: ignore[operator]
        return self.config.reset_time_s == 0 and now - self._wall0 >= episode

    def _before_observation(self) -> None:
        """Called by the robot before each observation (before a pending reset is made): an
        observation ``episode_time_s`` or more after the take's first one is LeRobot's next
        episode's first (its loop ended the last one by the wall clock), so the take ends here
        and the next one's reset is made before this observation reads the state."""
        episode = lerobot_episode()
        if episode is not None:
            if episode.recording and episode.start != self._episode_start:
                self._new_episode(episode)
            return
        now = time.perf_counter()
        if self._running and self._fell_behind(now):
            self._end_take(cut_short=True)
        if not self._running and self._obs_wall0 is None:
            self._obs_wall0 = now  # the next take's first observation

    def _start_take(self, now: float) -> None:
        scene, task, expert = self._scene, self._task, self._expert
        assert scene is not None and task is not None and expert is not None
        task.remember_start()
        expert.reset()
        self.takes.append(TakeRecord(self._take, self._seed(self._take), dict(scene.placements)))
        first, self._obs_wall0 = self._obs_wall0, None
        self._running, self._wall0 = True, first if first is not None else now

    def _end_take(self, *, cut_short: bool, reset: bool = True) -> None:
        """The take under way is over: log it; ask for the next take's reset."""
        record = self.takes[-1]
        record.cut_short = cut_short
        self._running = False
        self._take += 1
        if reset and self._scene is not None:
            self._scene.request_reset(self._seed(self._take))
        if cut_short and reset:
            log.warning(
                "%s: take %d ended after %d of %d calls: the recording loop fell behind and "
                "LeRobot started a new episode (the next take starts with it)",
                self, record.index, record.calls, self.config.take_calls,
            )  # fmt: skip
        how = (
            f"success at call {record.success_call} ({record.success_call / self.config.fps:.2f} s)"
            if record.success and record.success_call is not None
            else "no success"
        )
        log.info(
            "%s: take %d (seed %d): %s, %d calls, %d grasp(s) retried",
            self, record.index, record.seed, how, record.calls, record.attempts,
        )  # fmt: skip


__all__ = ["LeRobotEpisode", "SO101SimExpert", "TakeRecord", "lerobot_episode"]
