"""The simulated follower's background work: the real-time physics thread and the viewer.

:class:`RobotThreads` holds what they need (the :class:`~so101sim.sim.simulation.Simulation`, its
lock, a stop event, the speed, the viewer) and never the robot, so that a robot dropped while
connected is collected; :meth:`RobotThreads.tie_to` stops them when it is, and at interpreter
exit (a thread stepping MuJoCo while Python finalizes crashes the process).

The viewer is a :class:`so101sim.viewer.MirroredViewer`: about 60 times a wall second the
physics copies its state to it, holding the lock for microseconds, and the viewer's own
thread draws; the physics never waits for the drawing.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import math
import threading
import time
import weakref
from typing import Any

import numpy as np

from ..errors import ClosedError
from ..sim.simulation import Pacer, Simulation
from ..sim.stepping import advance_unobserved, state_size

log = logging.getLogger(__name__)

BLOCK_SECONDS = 0.004
"""Real-time mode steps the physics in blocks of this much simulated time."""
VIEWER_PERIOD = 1.0 / 60.0
"""Wall seconds between two states handed to the viewer."""


class RobotThreads:
    """A connected robot's background work: the real-time physics thread and the viewer.

    It holds what they need (the simulation, its lock, a stop event, the speed) and no
    reference to the robot, so that a robot dropped while connected is collected and its
    finalizer can call :meth:`stop`; the ``atexit`` hook calls it too.
    """

    def __init__(self, sim: Simulation, label: str, speed: float, rig: Any = None) -> None:
        self.sim = sim
        self.rig = rig  # the robot's cameras (a CameraRig): closed with the threads
        self.label = label  # for logs: the robot's str()
        self.speed = speed
        self.stop_event = threading.Event()
        self.thread: threading.Thread | None = None
        self.error: BaseException | None = None
        self.viewer: Any = None
        self._viewer_stack: contextlib.ExitStack | None = None
        self._last_sync = -math.inf
        self._dt = sim.timestep
        self._scratch = np.empty(state_size(sim.model))  # the lockstep path's saved state

    def tie_to(self, owner: object) -> weakref.finalize:
        """Stop these threads at interpreter exit (an ``atexit`` hook registered now, so it
        runs before the exit hooks MuJoCo's viewer registered when it opened: the last
        registered runs first) and when ``owner`` is collected. Returns the finalizer: calling
        it stops the threads and removes the exit hook, once."""
        atexit.register(self.stop)
        finalizer = weakref.finalize(owner, _release, self)
        finalizer.atexit = False  # the hook above does it, in the right order
        return finalizer

    def open_viewer(self, quality: str) -> None:
        from ..viewer import open_viewer  # imported here: only a robot with a viewer needs it

        # open_viewer closes the window and waits for its threads when the stack closes
        stack = contextlib.ExitStack()
        # the viewer mirrors the live MuJoCo data: no Simulation method stands for it
        self.viewer = stack.enter_context(
            open_viewer(self.sim.model, self.sim.data, mirror=True, quality=quality)
        )
        self._viewer_stack = stack

    def start_physics(self, thread_name: str) -> None:
        self.thread = threading.Thread(target=self.run_physics, name=thread_name, daemon=True)
        self.thread.start()

    def stop(self) -> None:
        """Stop the physics thread (joined, unless called from it) and close the viewer.
        Safe to call again, from any thread, at interpreter exit."""
        self.stop_event.set()
        thread, self.thread = self.thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join()
        stack, self._viewer_stack = self._viewer_stack, None
        self.viewer = None
        if stack is not None:
            stack.close()
        if self.rig is not None:
            self.rig.close()  # its renderers, and its render thread joined

    def advance(self, seconds: float) -> None:
        """Step ``seconds`` of simulated time holding the goals (lock held by the caller)."""
        sim = self.sim
        n = round(seconds / self._dt)
        if n <= 0:
            return
        if sim.was_commanded and not sim.observers:  # the lockstep path: nothing else to do
            advance_unobserved(sim.model, sim.data, None, n, self._dt, self._scratch)
        else:
            sim.step(n, trace=False)
        if self.viewer is not None:
            self.sync_viewer()

    def sync_viewer(self) -> None:
        """Hand the state to the viewer, at most 60 times a wall second (lock held by the
        caller): a copy of a few numbers; the viewer's thread draws it."""
        viewer = self.viewer
        if viewer is None:
            return
        now = time.perf_counter()
        if now - self._last_sync >= VIEWER_PERIOD:
            self._last_sync = now
            viewer.sync()

    def run_physics(self) -> None:
        """The real-time physics thread: step a block, then sleep until the next block's end
        is due on the wall clock (absolute deadlines, no drift)."""
        sim, lock, stop = self.sim, self.sim.lock, self.stop_event
        dt = sim.timestep
        block = max(1, round(BLOCK_SECONDS / dt)) * dt
        pacer = Pacer(self.speed, sleep=stop.wait)
        with lock:
            t = sim.time
        pacer.wait(t)
        try:
            warned = False
            while not stop.is_set():
                pacer.wait(t + block)
                if stop.is_set():
                    break
                if pacer.lag_events and not warned:
                    warned = True
                    log.warning(
                        "%s: the physics fell behind real time at %.2f s of simulated time "
                        "(%.2f s behind the wall clock): this machine, or code holding "
                        "robot.lock, did not step it at %g x real time, so the arm moves "
                        "slower than the wall clock says (a time.sleep(x) covers less than x s "
                        "of simulated time; mode='lockstep' has no such limit)",
                        self.label,
                        t,
                        pacer.lag_s,
                        pacer.speed,
                    )
                with lock:
                    self.advance(block)
                    t = sim.time
        except ClosedError:  # the interpreter is exiting: the exit hook joins this thread
            pass
        except Exception as exc:  # surfaced by the next call from the user's thread
            self.error = exc
            log.error("%s: the physics thread stopped: %s", self.label, exc)
        if pacer.lag_events:
            log.debug("%s: physics fell behind real time %d times", self.label, pacer.lag_events)


def _release(threads: RobotThreads) -> None:
    """Stop a robot's threads and forget its exit hook (at disconnect, or when collected)."""
    atexit.unregister(threads.stop)
    threads.stop()


__all__ = ["BLOCK_SECONDS", "VIEWER_PERIOD", "FollowerClock", "RobotThreads"]


class FollowerClock:
    """The follower's own time as a :class:`so101sim.robot.helpers.Clock` (what
    ``robot.clock`` gives the helpers; not :class:`so101sim.lab.simclock.SimClock`, which
    stands in for the ``time`` module in a student's script).

    Lockstep: ``sleep`` advances the physics. Real time: ``sleep`` waits on the wall clock
    (scaled by ``speed``) while the background thread advances it.
    """

    def __init__(self, robot: Any) -> None:  # the SO101SimFollower (it imports this module)
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
