"""Observers and pacing: what watches a run of the stepping kernel (:mod:`.stepping`).

Anything that wants to see a run (a viewer, a video recorder, a CSV log) is an
:class:`Observer`: it names the next simulated time it wants to be called at, and/or receives
every step's commanded and measured joint angles in blocks (:class:`Trace`). Wall-clock
pacing exists only to show a run to a person: :class:`Pacer` sleeps to absolute deadlines, so
it does not drift however long the run; :class:`ViewerObserver` syncs a viewer through one.
These names are also importable from :mod:`so101sim.sim.stepping`, as before.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import math
import sys
import threading
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from ..validation import check_range

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------- pacing
MAX_PLAYBACK_SPEED = 1000.0
"""The fastest playback a :class:`Pacer` accepts, in multiples of real time."""
MIN_PLAYBACK_SPEED = 1e-3
"""The slowest playback a :class:`Pacer` accepts (1/1000 of real time)."""


class Pacer:
    """Keeps simulated time in step with the wall clock, for showing a run to a person.

    Each :meth:`wait` sleeps until the absolute wall-clock deadline of the given simulated time
    (``wall0 + (sim_time - sim0) / speed``), so errors never accumulate. If the run falls more
    than ``max_lag`` seconds behind (a slow machine, a dragged window), it re-anchors instead of
    racing to catch up. ``clock`` and ``sleep`` are injectable for tests.
    """

    def __init__(
        self,
        speed: float = 1.0,
        *,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], Any] = time.sleep,
        max_lag: float = 0.25,
    ) -> None:
        self.speed = check_range(
            speed,
            "speed",
            low=MIN_PLAYBACK_SPEED,
            high=MAX_PLAYBACK_SPEED,
            expected=(
                f"a multiple of real time from {MIN_PLAYBACK_SPEED:g} to {MAX_PLAYBACK_SPEED:g} "
                "(1 = real time, 0.5 = half speed)"
            ),
        )
        self.clock = clock
        self.sleep = sleep
        self.max_lag = max_lag
        self._anchor: tuple[float, float] | None = None
        self.lag_events = 0
        self.lag_s = 0.0  # wall seconds the run fell behind in all, at the re-anchorings

    def reset(self) -> None:
        """Forget the anchor: the next :meth:`wait` starts a new timeline."""
        self._anchor = None

    def wait(self, sim_time: float) -> float:
        """Sleep until ``sim_time`` is due on the wall clock; return the seconds slept."""
        now = self.clock()
        if self._anchor is None:
            self._anchor = (now, sim_time)
            return 0.0
        wall0, sim0 = self._anchor
        delay = wall0 + (sim_time - sim0) / self.speed - now
        if delay > 0:
            self.sleep(delay)
            return delay
        if -delay > self.max_lag:
            self.lag_events += 1
            self.lag_s += -delay
            log.debug("pacing %.3f s behind the wall clock; re-anchoring", -delay)
            self._anchor = (now, sim_time)
        return 0.0


# ---------------------------------------------------------------------------- observers
@dataclass
class Trace:
    """Per-step record of stepping: the time after each step, the target applied during it and
    the joint angles after it (radians, arm joint order)."""

    time: np.ndarray  # (n,)
    ctrl: np.ndarray  # (n, 6)
    qpos: np.ndarray  # (n, 6)
    completed: bool = True
    steps: int = -1  # steps taken; -1: len(time) (a trace may keep no per-step arrays)
    # the blocks observers see: every step's whole state (FULLPHYSICS rows: time, qpos, qvel,
    # ...), as the kernel recorded it; None in the trace a run returns
    states: np.ndarray | None = None
    # how many contacts each step found (MuJoCo's ``ncon`` before it integrated), for the
    # observers that ask (:attr:`Observer.wants_contact_counts`); None where not recorded
    contact_counts: np.ndarray | None = None
    # with the counts: the force each actuator applied during each step (``(n, nu)``, all
    # actuators, MuJoCo's ``actuator_force``); None where not recorded
    actuator_forces: np.ndarray | None = None

    def __len__(self) -> int:
        return self.steps if self.steps >= 0 else len(self.time)


class Observer:
    """Something that watches a run. Override what you need; the defaults do nothing.

    * :meth:`next_time`: the simulated time of the next call to :meth:`on_time`
      (``math.inf``: none). Stepping stops at the first step that reaches it.
    * :meth:`on_time`: called with the live model and data; return False to stop the run
      (a viewer that was closed).
    * :meth:`on_steps`: each block of steps, as they are taken, with the phase's name.
    * :meth:`on_start`: once before each run of steps, with the live model and data.
    * :attr:`wants_contact_counts`: True to get each step's contact count and actuator forces
      in the blocks (:attr:`Trace.contact_counts`, :attr:`Trace.actuator_forces`, where the
      kernel can record them).
    """

    wants_contact_counts: bool = False

    def on_start(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        return None

    def next_time(self) -> float:
        return math.inf

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        return True

    def on_steps(self, trace: Trace, phase: str) -> None:
        return None


_wall = time.perf_counter  # the real clock, even while a script's clock follows simulated time


class PacedShowing:
    """What every display that paces a run to the wall clock shares (a desktop viewer, the
    studio's page): the time a script spends between two runs (``input()``, a plot, a solver)
    is not a lag (:meth:`started` re-anchors the pacer), and the first time the showing falls
    behind real time is said once, as a logged warning naming ``shown_in`` (:meth:`waited`).
    Call :meth:`started` at a run's start, :meth:`waited` after each ``pacer.wait`` and
    :meth:`shown` once the frame is shown. A given pacer's earlier lags are not counted."""

    def __init__(self, pacer: Pacer, shown_in: str, *, warn_lag: bool = True, hint: str = ""):
        self.pacer = pacer
        self.shown_in = shown_in
        self.warn_lag = warn_lag
        self.hint = hint  # what might help, appended to the warning
        self._lag0 = (pacer.lag_events, pacer.lag_s)
        self._left: float | None = None  # the pacer's clock when the last frame was shown

    def started(self) -> None:
        """Before a run of steps: re-anchor after the script's own time between two runs."""
        if self._left is not None and (gap := self.pacer.clock() - self._left) > self.pacer.max_lag:
            log.debug("%.3f s between two runs; re-anchoring %s", gap, self.shown_in)
            self.pacer.reset()

    def waited(self, sim_time: float) -> None:
        """After the pacer waited for ``sim_time``: say the first lag, once."""
        if self.warn_lag and self.pacer.lag_events > self._lag0[0]:
            self.warn_lag = False
            log.warning(
                "%s fell behind real time at %.2f s of simulated time (%.2f s behind the wall "
                "clock): this machine cannot step and draw the run at %g x real time, so it "
                "looks slower than it is; the simulated time and every result are exact anyway%s",
                self.shown_in,
                sim_time,
                self.pacer.lag_s - self._lag0[1],
                self.pacer.speed,
                f" ({self.hint})" if self.hint else "",
            )

    def shown(self) -> None:
        """A frame was shown (the time a script takes from here to the next run is its own)."""
        self._left = self.pacer.clock()


MAX_VIEWER_PERIOD = 0.25
"""Simulated seconds between two viewer frames at most, however slowly the viewer draws."""


class ViewerObserver(Observer):
    """Syncs a viewer (anything with ``sync()`` and ``is_running()``) up to ``fps`` times per
    simulated second, paced to the wall clock by a :class:`Pacer`.

    A viewer whose ``sync()`` waits while it draws (MuJoCo's passive viewer: about 25 ms a
    frame with the full meshes on a CPU renderer) would slow the run below real time at 60
    frames a second; so the observer measures what a sync costs (a running mean) and syncs less
    often when needed: drawing then takes at most half the wall-clock time, and the run keeps
    real time (or ``speed`` times it) wherever the machine can step that fast, with fewer
    frames shown (at least one every :data:`MAX_VIEWER_PERIOD` simulated seconds)."""

    def __init__(
        self, viewer: Any, pacer: Pacer | None = None, fps: float = 60.0, *, warn_lag: bool = True
    ) -> None:
        self.viewer = viewer
        self.pacer = pacer if pacer is not None else Pacer()
        # says once (a logged warning) when the showing falls behind
        self.showing = PacedShowing(
            self.pacer, "the viewer", warn_lag=warn_lag, hint="a smaller viewer window draws faster"
        )
        self.period = 1.0 / fps
        self.sync_cost = 0.0  # wall seconds a sync takes (running mean)
        self.syncs = 0
        self._next = -math.inf
        self._last = -math.inf

    def on_start(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        if d.time < self._last:  # the clock went back (a reset): start a new timeline
            log.debug("simulated time went back to %.3f s; re-anchoring the viewer", d.time)
            self._next = -math.inf
            self.pacer.reset()
        else:
            self.showing.started()

    def next_time(self) -> float:
        return self._next

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        if not self.viewer.is_running():
            return False
        self.pacer.wait(d.time)
        self.showing.waited(d.time)
        start = _wall()
        self.viewer.sync()
        cost = _wall() - start
        self.syncs += 1
        self.sync_cost = cost if self.syncs == 1 else 0.8 * self.sync_cost + 0.2 * cost
        period = max(self.period, min(MAX_VIEWER_PERIOD, 2.0 * self.sync_cost * self.pacer.speed))
        self._last = d.time
        self._next = d.time + period - 1e-9
        self.showing.shown()
        return True


__all__ = [
    "MAX_PLAYBACK_SPEED",
    "MAX_VIEWER_PERIOD",
    "MIN_PLAYBACK_SPEED",
    "Observer",
    "PacedShowing",
    "Pacer",
    "Trace",
    "ViewerObserver",
]


# ---------------------------------------------------------------------------- a script's own viewer
_EXIT_WAIT_S = 10.0
"""At the interpreter's exit, how long :func:`close_at_exit` waits for the windows to close."""

_scripts_viewers: list[Any] = []  # the open handles close_at_exit was given, closed at exit
_scripts_windows: weakref.WeakSet[threading.Thread] = weakref.WeakSet()  # their window threads


def _viewer_threads() -> list[threading.Thread]:
    """The threads MuJoCo's ``launch_passive`` draws the windows on (named after their target,
    ``Thread-N (_launch_internal)``, by Python's ``threading``; if MuJoCo renames it, none
    are found and nothing is waited for)."""
    return [t for t in threading.enumerate() if t.name.endswith("(_launch_internal)")]


def _running(handle: Any) -> bool:
    with contextlib.suppress(Exception):  # a handle whose viewer is gone
        return bool(handle.is_running())
    return False


def _close_scripts_viewers() -> None:
    """Close the viewers :func:`close_at_exit` was given and wait (at most
    :data:`_EXIT_WAIT_S` in all) until the window threads that were open when it was called
    are gone."""
    for handle in _scripts_viewers:
        with contextlib.suppress(Exception):  # already closed, or its window failed
            handle.close()
    _scripts_viewers.clear()
    deadline = time.monotonic() + _EXIT_WAIT_S
    for t in list(_scripts_windows):
        if t is not threading.current_thread():
            t.join(timeout=max(0.0, deadline - time.monotonic()))


def close_at_exit(viewer: Any) -> None:
    """Make a script's own passive viewer (``mujoco.viewer.launch_passive``) end cleanly when
    the script ends.

    A script that leaves ``with mujoco.viewer.launch_passive(m, d) as viewer:`` and ends (the
    lab handout's pattern) ends while the viewer's daemon thread is still taking its window
    down, and MuJoCo's exit handler terminates GLFW under it: the process often segfaults
    after the script's last line (exit 139; MuJoCo issue 790; 8 runs of 10 on Mesa's software
    OpenGL here). This registers an exit handler that closes the viewer and waits, at most
    :data:`_EXIT_WAIT_S`, for the viewers' window threads open at this call, and puts it after
    every handler registered so far, so it runs before GLFW is terminated (exit handlers run
    last registered first; each viewer opened registers GLFW's again, so call this for each).
    Only the open handles are kept (a closed one is let go). A second viewer open at this call
    but never given here is waited for too (its window closes only at its own exit handler,
    which runs after this one): up to :data:`_EXIT_WAIT_S` more at exit. Anything but a MuJoCo
    viewer handle (``None``, a recorder standing in for it) is left alone. The lab helpers
    call it with the viewer they are given.
    """
    handle_type = getattr(sys.modules.get("mujoco.viewer"), "Handle", None)
    if handle_type is None or not isinstance(viewer, handle_type):
        return
    _scripts_viewers[:] = [v for v in _scripts_viewers if v is not viewer and _running(v)]
    _scripts_viewers.append(viewer)
    _scripts_windows.update(_viewer_threads())
    atexit.unregister(_close_scripts_viewers)
    atexit.register(_close_scripts_viewers)
