"""The pose finder: pose the arm in the viewer, get the pose in the arm's units.

``so101sim pose`` opens MuJoCo's own (managed) viewer on the pose scene: the arm simulated with
gravity and the actuators switched off (on a private copy of the model), so it stays where a
slider or a drag (double-click a part, then Ctrl + right-drag) puts it; contacts still keep it
out of the floor. MuJoCo's Joint sliders (right panel, "Joint") can be dragged while the
simulation is paused (Space, or Pause in the left panel): this viewer can pause, the passive
one cannot, which is why the pose finder does not use the passive viewer.
:func:`find_poses` runs it: the window in the calling thread, and a thread that reads the
arm's pose about 15 times a second; when it has moved by more than a small threshold since
the last pose reported and then stays still for a few reads, :class:`PoseWatcher` reports it
(``on_pose``), and the command prints it ready to paste as a Python dict and as a TOML pose,
with a warning line when the tip or a part of the arm is below the floor or in the table
(:mod:`.clearance`; contacts keep most of the arm out, not the tip).

For a viewer of your own (a passive viewer you pause yourself, a test's fake),
:func:`open_pose_viewer` and :func:`watch_poses` do the same as a generator. The library never
prints: :class:`PoseChange` objects go to the caller, and :func:`format_python` /
:func:`format_toml` return text. The web studio's pose finder (:mod:`so101sim.studio.pose`)
needs no display.
"""

from __future__ import annotations

import copy
import threading
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from .. import viewer as _viewer
from ..errors import ModelError, ViewerError
from ..kinematics import TipPose, for_model
from ..model.load import arm_index, arm_units, load_model
from ..sim.simulation import Pacer, measured_radians
from ..sim.stepping import advance_unobserved
from ..units import JOINT_NAMES, STARTING_POSE, ArmUnits, Pose
from .clearance import pose_warnings


@dataclass(frozen=True)
class PoseChange:
    """A pose the arm was left in: ``number`` counts from 1 (the pose at the start)."""

    number: int
    time: float  # simulated time of the read, s
    pose: dict[str, float]  # arm units, rounded to ``digits``
    tip: TipPose | None = None  # where the gripper's tip is (metres, base frame)
    warnings: tuple[str, ...] = ()  # the tip or a part below the floor or in the table


class PoseWatcher:
    """Turns a stream of joint-angle reads into the poses worth reporting.

    A read is reported when it differs from the last reported pose by more than ``threshold``
    (degrees; gripper units) on some joint, and the last ``settle`` reads agree with each other
    within ``stable_tolerance``: the arm was moved, then left still. The first read is always
    reported.
    """

    def __init__(
        self,
        units: ArmUnits,
        *,
        threshold: float = 0.5,
        stable_tolerance: float = 0.05,
        settle: int = 3,
        digits: int = 1,
    ) -> None:
        self.units = units
        self.threshold = threshold
        self.stable_tolerance = stable_tolerance
        self.settle = max(1, settle)
        self.digits = digits
        self._reported: np.ndarray | None = None
        self._last: np.ndarray | None = None
        self._still = 0
        self.count = 0

    def update(self, q: np.ndarray, time: float = 0.0) -> PoseChange | None:
        """Feed one read (radians, JOINT_NAMES order); return a pose to report, or None."""
        values = self.units.from_radians(np.asarray(q, dtype=float))
        if self._last is not None and np.abs(values - self._last).max() <= self.stable_tolerance:
            self._still += 1
        else:
            self._still = 0
        self._last = values
        if self._reported is None or (
            self._still >= self.settle - 1
            and np.abs(values - self._reported).max() > self.threshold
        ):
            self._reported = values
            self.count += 1
            rounded = (round(float(v), self.digits) + 0.0 for v in values)
            pose = dict(zip(JOINT_NAMES, rounded, strict=True))
            return PoseChange(self.count, float(time), pose)
        return None


def pose_scene(
    model: mujoco.MjModel | str | Path | None = None, start: Pose = STARTING_POSE
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """A private copy of the model with gravity and actuation off, and data at ``start``."""
    base = model if isinstance(model, mujoco.MjModel) else load_model(model)
    m = copy.copy(base)
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_GRAVITY) | int(
        mujoco.mjtDisableBit.mjDSBL_ACTUATION
    )
    d = mujoco.MjData(m)
    units = arm_units(m)
    d.qpos[arm_index(m).qpos] = units.to_radians(units.pose_to_array(start))
    mujoco.mj_forward(m, d)
    return m, d


NO_DISPLAY_MESSAGE = (
    "the pose finder shows a window to pose the arm in, and there is no display here "
    "(DISPLAY is not set): run `so101sim pose --web` to pose it in a web browser instead, or "
    "run it on a desktop, or on one reached remotely (ssh -X, VNC)"
)


def check_display() -> None:
    """Raise :class:`ViewerError` when there is no display for the pose finder's window."""
    if not _viewer.has_display():
        raise ViewerError(NO_DISPLAY_MESSAGE)


INSTRUCTIONS = (
    "Press Space (or Pause, left panel) to pause, open 'Joint' in the right panel and drag its "
    "sliders (radians there); or double-click a part and Ctrl+right-drag it. Each pose the arm "
    "is left in is printed below, in degrees; close the window to finish."
)


def find_poses(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    on_pose: Callable[[PoseChange], Any],
    *,
    watcher: PoseWatcher | None = None,
    period: float = 1.0 / 15.0,
) -> int:
    """Open MuJoCo's viewer on the pose scene ``(m, d)`` (:func:`pose_scene`) and call
    ``on_pose`` with each pose the arm is left in (the first at once), from a thread of its own,
    until the window is closed; returns the number of poses reported.

    Raises:
        ViewerError: there is no display.
        Exception: what ``on_pose`` raised (the watching stops; the window stays until closed).
    """
    check_display()
    watcher = watcher if watcher is not None else PoseWatcher(arm_units(m))
    stop = threading.Event()
    failed: list[BaseException] = []
    scratch = mujoco.MjData(m)  # the reported pose is judged here, not on the viewer's data

    def watch() -> None:
        while not stop.is_set():
            q = np.array(measured_radians(m, d), copy=True)  # the viewer steps meanwhile
            change = watcher.update(q, float(d.time))
            if change is not None:
                try:
                    on_pose(_judged(m, scratch, change))
                except BaseException as exc:  # handed to the caller after the window closes
                    failed.append(exc)
                    return
            stop.wait(period)

    thread = threading.Thread(target=watch, name="so101sim-pose-watcher", daemon=True)
    thread.start()
    try:
        _viewer.view(m, d)  # MuJoCo's managed viewer: blocks until the window is closed
    finally:
        stop.set()
        thread.join(timeout=5.0)
    if failed:
        raise failed[0]
    return watcher.count


def open_pose_viewer(m: mujoco.MjModel, d: mujoco.MjData) -> AbstractContextManager[Any]:
    """Open the viewer with its joint sliders on the pose scene (a context manager).

    Raises:
        ViewerError: there is no display (the window is the pose finder's whole point, so
            there is no headless way), or the viewer cannot be opened.
    """
    if not _viewer.has_display():
        raise ViewerError(NO_DISPLAY_MESSAGE)
    return _viewer.open_viewer(m, d, show_ui=True)


def watch_poses(
    viewer: Any,
    m: mujoco.MjModel,
    d: mujoco.MjData,
    *,
    watcher: PoseWatcher | None = None,
    period: float = 1.0 / 15.0,
    pacer: Pacer | None = None,
) -> Iterator[PoseChange]:
    """Run the pose scene in ``viewer`` (``is_running()``, ``sync()``, ``lock()``) in real time
    and yield each pose the arm is left in, until the viewer closes."""
    watcher = watcher if watcher is not None else PoseWatcher(arm_units(m))
    pacer = pacer if pacer is not None else Pacer()
    n = max(1, round(period / m.opt.timestep))
    scratch = mujoco.MjData(m)
    while viewer.is_running():
        viewer.sync()  # picks up slider moves and drags
        with viewer.lock():
            q = measured_radians(m, d)
            t = float(d.time)
        change = watcher.update(q, t)
        if change is not None:
            yield _judged(m, scratch, change)
        with viewer.lock():
            advance_unobserved(
                m, d, None, n
            )  # the stepping kernel: the targets as the sliders set them
        pacer.wait(float(d.time))


def _tip(m: mujoco.MjModel, pose: dict[str, float]) -> TipPose | None:
    """The tip for ``pose``, or None for a model without the SO-101's tip and base sites."""
    try:
        return for_model(m).tip_array(np.array([pose[n] for n in JOINT_NAMES]))
    except ModelError:
        return None


def _judged(m: mujoco.MjModel, scratch: mujoco.MjData, change: PoseChange) -> PoseChange:
    """``change`` with its tip and its warnings (the pose set on ``scratch``)."""
    units = arm_units(m)
    scratch.qpos[arm_index(m).qpos] = units.to_radians(units.pose_to_array(change.pose))
    mujoco.mj_kinematics(m, scratch)
    return replace(change, tip=_tip(m, change.pose), warnings=pose_warnings(m, scratch))


def format_python(pose: Pose) -> str:
    """``{"shoulder_pan": 0.0, ...}``: paste into a script."""
    return "{" + ", ".join(f"{k!r}: {float(v)!r}".replace("'", '"') for k, v in pose.items()) + "}"


def format_toml(name: str, pose: Pose) -> str:
    """``name = { shoulder_pan = 0.0, ... }``: paste under ``[poses]`` in a motion file."""
    return f"{name} = {{ " + ", ".join(f"{k} = {float(v)!r}" for k, v in pose.items()) + " }"


__all__ = [
    "PoseChange",
    "PoseWatcher",
    "check_display",
    "find_poses",
    "format_python",
    "format_toml",
    "pose_scene",
    "watch_poses",
]
