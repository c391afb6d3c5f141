"""A clock that follows simulated time, for running wall-clock scripts unchanged.

The lab handout times its moves with the wall clock (``while time.time() - start < duration``)
while stepping MuJoCo as fast as it can, so a "2 s" move is however many physics steps the
machine manages in 2 wall seconds. Under :func:`simulated_time`, the script's clock follows the
*simulated* time of the ``MjData`` it steps instead, so the same loop runs exactly 2 s of
simulated time, whatever the machine's speed:

* ``time.time``, ``time.monotonic``, ``time.perf_counter`` (and their ``_ns`` forms) return
  the value they had when the run started plus the simulated seconds elapsed since;
* ``time.sleep(x)`` returns at once and moves the clock on by ``x``: a script that sleeps to
  keep pace (the handout's ``time.sleep(time_until_next_step)``) then steps, sees its clock
  advance by the larger of the two, never by both; a script that only waits does not hang.

Simulated time is read from the data the clock follows (:meth:`SimClock.follow`), which the
recording viewer sets when the script opens it. Time going back (``mj_resetData``) does not
move the clock back.
"""

from __future__ import annotations

import contextlib
import threading
import time as _time
from collections.abc import Iterator
from typing import Any

_NAMES = ("time", "monotonic", "perf_counter", "sleep", "time_ns", "monotonic_ns",
          "perf_counter_ns")  # fmt: skip


class SimClock:
    """Clock values that advance with a followed ``MjData``'s ``time`` (and with sleeps)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._origin = {
            "time": _time.time(),
            "monotonic": _time.monotonic(),
            "perf_counter": _time.perf_counter(),
        }
        self._data: Any = None
        self._last_sim = 0.0
        self._elapsed = 0.0  # seconds the clock has moved since the start
        self._credit = 0.0  # slept seconds that the next simulated steps will cover

    def follow(self, data: Any) -> None:
        """Follow ``data.time`` from now on (an ``MjData``, or anything with ``time``)."""
        with self._lock:
            self._update()
            self._data = data
            self._last_sim = float(data.time)

    def _update(self) -> None:
        if self._data is None:
            return
        now = float(self._data.time)
        delta = now - self._last_sim
        self._last_sim = now
        if delta <= 0:  # no step, or a reset: the clock does not go back
            return
        covered = min(delta, self._credit)
        self._credit -= covered
        self._elapsed += delta - covered

    def elapsed(self) -> float:
        """Seconds this clock has moved since it started."""
        with self._lock:
            self._update()
            return self._elapsed

    def sleep(self, seconds: float) -> None:
        """Move the clock on by ``seconds`` at once (no real waiting)."""
        seconds = float(seconds)
        if seconds < 0:
            raise ValueError("sleep length must be non-negative")
        with self._lock:
            self._update()
            self._elapsed += seconds
            self._credit += seconds

    def time(self) -> float:
        return self._origin["time"] + self.elapsed()

    def monotonic(self) -> float:
        return self._origin["monotonic"] + self.elapsed()

    def perf_counter(self) -> float:
        return self._origin["perf_counter"] + self.elapsed()

    def time_ns(self) -> int:
        return int(self.time() * 1e9)

    def monotonic_ns(self) -> int:
        return int(self.monotonic() * 1e9)

    def perf_counter_ns(self) -> int:
        return int(self.perf_counter() * 1e9)


@contextlib.contextmanager
def simulated_time(clock: SimClock) -> Iterator[SimClock]:
    """Replace the ``time`` module's clocks and ``sleep`` with ``clock``'s while the block runs
    (for every caller: the script and anything it imports), and put them back after."""
    saved = {name: getattr(_time, name) for name in _NAMES}
    try:
        for name in _NAMES:
            setattr(_time, name, getattr(clock, name))
        yield clock
    finally:
        for name, fn in saved.items():
            setattr(_time, name, fn)
