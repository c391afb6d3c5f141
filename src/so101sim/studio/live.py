"""A run shown live in the studio: an observer for so101sim's runs, a viewer for scripts.

:class:`StudioObserver` watches a run (:func:`so101sim.motion.run_motion`,
``Simulation.move_to(..., observers=...)``): 30 times per simulated second it waits for the
wall clock (a :class:`~so101sim.sim.Pacer`: real time, or ``speed`` times it), then puts
the state on the page with the phase and the commanded and measured angles. The page's Pause
holds the run where it is.

:class:`StudioViewer` stands in for ``mujoco.viewer.launch_passive(m, d)`` in a script (its
``sync()``, ``is_running()``, ``lock()``, ``close()``, ``cam``, ``opt``) and is an observer
too, so the lab helpers (``move_to_pose(m, d, viewer, ...)``) show their moves on the page.
"""

from __future__ import annotations

import math
import threading
from typing import Any

import mujoco

from ..sim.observers import PacedShowing
from ..sim.simulation import Observer, Pacer, Trace
from .server import FRAME_RATE, Studio


class StudioObserver(Observer):
    """Shows a run on ``studio``'s page, paced to the wall clock by ``pacer``."""

    def __init__(
        self,
        studio: Studio,
        pacer: Pacer | None = None,
        fps: float = FRAME_RATE,
        *,
        warn_lag: bool = True,
    ):
        self.studio = studio
        self.pacer = pacer if pacer is not None else Pacer()
        # says once (a logged warning) when the page falls behind the wall clock
        self.showing = PacedShowing(self.pacer, "the browser page", warn_lag=warn_lag)
        self.studio.speed = self.pacer.speed
        self.period = 1.0 / fps
        self.phase = ""
        self._next = -math.inf
        self._last = -math.inf

    def on_start(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        if d.time < self._last:  # a reset: a new timeline
            self._next = -math.inf
            self.pacer.reset()
        else:
            self.showing.started()  # the script's own time between two runs is not a lag

    def next_time(self) -> float:
        return self._next

    def on_steps(self, trace: Trace, phase: str) -> None:
        if phase:
            self.phase = phase

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        if self.studio.closed:
            return True  # the page went away; the run goes on (the caller decides)
        if self.studio.wait_while_paused():
            self.pacer.reset()
        self.pacer.wait(d.time)
        self.showing.waited(d.time)
        idx = self.studio._index
        commanded = self.studio.units.from_radians(d.ctrl[idx.actuator])
        self.studio.show(d, self.phase, commanded)
        self._last = d.time
        self._next = d.time + self.period - 1e-9
        self.showing.shown()
        return True


class StudioViewer(StudioObserver):
    """``mujoco.viewer.launch_passive(m, d)`` for a script, drawn in ``studio``'s page."""

    def __init__(
        self, studio: Studio, m: mujoco.MjModel, d: mujoco.MjData, pacer: Pacer | None = None
    ) -> None:
        super().__init__(studio, pacer)
        self.model, self.data = m, d
        self.opt = mujoco.MjvOption()
        self.cam = mujoco.MjvCamera()
        self.perturb = mujoco.MjvPerturb()
        self._lock = threading.RLock()
        self._closed = False

    def sync(self, state_only: bool = False) -> None:
        """Show the data's state now (paced: at most 30 times per simulated second, each
        when its time comes on the wall clock)."""
        if self._closed:
            return
        d = self.data
        if d.time + 1e-12 >= self._next or d.time < self._last:
            # a reset starts a new timeline; a pause in the script's own loop (input(), a
            # plot) is not a lag
            self.on_start(self.model, d)
            self.on_time(self.model, d)

    def is_running(self) -> bool:
        return not self._closed

    def lock(self) -> threading.RLock:
        return self._lock

    def close(self) -> None:
        self._closed = True

    def __enter__(self) -> StudioViewer:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
