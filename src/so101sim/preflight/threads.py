"""The robust preflight's worker threads: started with the termination signals held back and
always waited for, however the caller is interrupted (a thread inside MuJoCo when the
interpreter finalises crashed the process: exit 139, issue 30).

May import: the standard library only.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP back (POSIX, the main thread) while the block runs; one
    that came meanwhile is handled as the block ends. The threads started meanwhile inherit
    the mask: they never take a signal (Python handles them in the main thread anyway)."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None or threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {s for n in ("SIGINT", "SIGTERM", "SIGHUP") if (s := getattr(signal, n, None))}
    previous = mask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, previous)


class Stopped(Exception):
    """A worker told to stop (another failed, or the caller was interrupted)."""


POLL_S = 0.05  # how often the waiting thread wakes up to run Python's signal handlers


def _wait_all(events: list[threading.Event]) -> None:
    """Wait until every event is set, waking every ``POLL_S``: Python runs a signal's handler
    only when the main thread runs bytecode, and a wait without a timeout is not woken by a
    signal the kernel delivered to another thread (a process-wide ``kill`` may go to any
    thread that does not block it), so such a wait could last for ever (a CI hang)."""
    for event in events:
        while not event.wait(POLL_S):
            pass


def run_threads(work: Callable[[], None], count: int, errors: list[BaseException]) -> None:
    """Run ``work`` on ``count`` threads and wait until each has finished with MuJoCo,
    whatever happens meanwhile.

    A signal (Ctrl-C, SIGTERM, SIGHUP: the CLI raises them in this thread) or any error while
    waiting stops the workers (they look at ``errors`` between blocks of steps, so each ends
    within one block) and still waits for them before it goes on up: a thread inside MuJoCo
    (a call, or freeing its ``MjData``) when the interpreter finalises crashed the process
    (exit 139, issue 30). Each worker says it is done with an event of its own, set after its
    MuJoCo objects are freed: ``Thread.join`` cannot be trusted once interrupted (Python 3.11
    may then mark a running thread as stopped). A second interrupt while they stop waits too."""
    done = [threading.Event() for _ in range(count)]

    def run(k: int) -> None:
        try:
            work()
        finally:
            done[k].set()

    pending: BaseException | None = None
    pool = [threading.Thread(target=run, args=(k,), daemon=True) for k in range(count)]
    try:
        with signals_held():  # the usual signals wait until every thread has started
            for th in pool:
                th.start()
        _wait_all(done)
    except BaseException as exc:
        pending = exc
        errors.append(exc)  # the workers stop at their next block
    # the threads that started (an ident), however far the start loop got when an exception
    # (a signal that is not held) interrupted it: each may already be running its work
    started = [done[k] for k, th in enumerate(pool) if th.ident is not None]
    while not all(event.is_set() for event in started):
        try:
            _wait_all(started)
        except BaseException as exc:  # another signal: still wait for them (one block each)
            pending = pending or exc
    if pending is not None:
        raise pending


__all__ = ["Stopped", "run_threads", "signals_held"]
