"""No MuJoCo call of so101sim is running when the interpreter finalises.

A thread that is inside a MuJoCo call when Python finalises crashes the process (exit 139):
MuJoCo's bindings release the GIL during a call, and when the call returns, CPython 3.11 ends
a daemon thread that wants the GIL back by unwinding its stack through the bindings' C++
frames, which cannot take it. Python joins the threads that are not daemons before it
finalises, but not daemon threads: a user's daemon thread that calls a lockstep robot's
``send_action`` in a loop, or steps a :class:`~so101sim.sim.Simulation`, is killed
wherever it is.

So every long or repeated MuJoCo call of so101sim runs inside :func:`mujoco_call`: the
stepping blocks (:mod:`so101sim.stepping`), an environment's step and reset, the simulated
robot's public methods, inverse kinematics and the preflight rollouts. At exit (an
``atexit`` hook: after Python joined the threads that are not daemons, before anything is torn
down) the gate closes: it waits for the calls in flight to end (at most :data:`EXIT_WAIT_S`;
each is short: a block of steps, one action) and refuses every later one with
:class:`~so101sim.errors.ClosedError`, so a daemon thread still calling gets an exception in
Python instead of a crash. The threads so101sim starts itself are stopped and joined by their
own exit hooks (:mod:`so101sim.robot.threads`, the cameras, the viewer), which run before
this one (the last registered runs first).

MuJoCo calls a program makes itself (``mujoco.mj_step`` in its own daemon thread) are outside
so101sim's reach: such a thread must be stopped (or be no daemon) before the program ends.
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import logging
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from .errors import ClosedError

log = logging.getLogger(__name__)
F = TypeVar("F", bound=Callable[..., Any])

EXIT_WAIT_S = 10.0
"""At exit, the longest wait for the MuJoCo calls in flight to end (wall seconds)."""


class ExitGate:
    """Counts the calls in flight; :meth:`close` waits for them and refuses later ones."""

    def __init__(self) -> None:
        self._cond = threading.Condition(threading.Lock())
        self._active = 0
        self.closed = False

    @contextlib.contextmanager
    def call(self) -> Iterator[None]:
        """Run the block as one call in flight.

        Raises:
            ClosedError: the gate is closed (the interpreter is exiting).
        """
        with self._cond:
            if self.closed:
                raise ClosedError(
                    "so101sim is shutting down (the interpreter is exiting): no more simulation "
                    "calls are made; expected calls before exit (stop the thread that makes "
                    "them, or make it no daemon, before the program ends)"
                )
            self._active += 1
        try:
            yield
        finally:
            with self._cond:
                self._active -= 1
                if not self._active:
                    self._cond.notify_all()

    @property
    def active(self) -> int:
        """The calls in flight now."""
        return self._active

    def close(self, timeout: float = EXIT_WAIT_S) -> bool:
        """Refuse new calls and wait up to ``timeout`` seconds for those in flight; whether
        they all ended. Called from a thread in flight, it does not wait for itself."""
        with self._cond:
            self.closed = True
            ended = self._cond.wait_for(lambda: self._active == 0, timeout)
        if not ended:
            log.warning("so101sim: %d simulation calls still running at exit", self._active)
        return ended

    def reopen(self) -> None:
        """Accept calls again (for tests)."""
        with self._cond:
            self.closed = False


GATE = ExitGate()
"""The process's gate, closed at interpreter exit."""
atexit.register(GATE.close)


def gated(func: F) -> F:
    """Decorate a method that makes MuJoCo calls: each call of it is one call in flight
    (:func:`mujoco_call`)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with GATE.call():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


def mujoco_call() -> contextlib.AbstractContextManager[None]:
    """``with mujoco_call():`` around MuJoCo work that may run in a daemon thread.

    Raises:
        ClosedError: the interpreter is exiting.
    """
    return GATE.call()


__all__ = ["EXIT_WAIT_S", "GATE", "ExitGate", "gated", "mujoco_call"]
