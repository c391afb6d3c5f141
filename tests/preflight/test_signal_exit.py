"""No crash on a signal with any thread count (issue 30): ``so101sim check --variants 200
--threads 2`` killed with SIGTERM or SIGHUP segfaulted (exit 139) in 4 of 9 runs. A worker
thread was still inside MuJoCo (freeing its ``MjData``) when the interpreter finalised: the
rollout now stops its workers and waits until each has let go of MuJoCo before the command
returns, however it was interrupted (:func:`so101sim.preflight.threads.run_threads`)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading

import numpy as np
import pytest

from so101sim.preflight import threads as preflight_threads

STARTED = "rolling out"  # the rollout's log line (with -v): the workers are starting


def _interrupted_check(signum: int, threads: int) -> tuple[int, str]:
    """Run a long robust check, send ``signum`` once the rollout started and return its exit
    status and stderr."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "so101sim", "-v", "check", "--variants", "5000",
         "--threads", str(threads)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONFAULTHANDLER": "1"},
    )  # fmt: skip
    seen = ""
    while (line := proc.stderr.readline()) and STARTED not in line:
        seen += line
    assert STARTED in line, f"the check never started: {seen[-2000:]}"
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=300)
    return proc.returncode, seen + line + err


TRIES = [(signal.SIGTERM, 2), (signal.SIGHUP, 2), (signal.SIGINT, 2), (signal.SIGTERM, 1)]
TRIES += [(signal.SIGTERM, 3), (signal.SIGHUP, 4)] + [(signal.SIGTERM, 2)] * 4


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_a_signal_ends_a_threaded_robust_check_cleanly_every_time() -> None:
    codes = []
    for signum, threads in TRIES:
        code, err = _interrupted_check(signum, threads)
        assert "Fatal Python error" not in err and "Traceback" not in err, err[-3000:]
        assert f"interrupted ({signal.Signals(signum).name})" in err
        codes.append(code)
    expected = [128 + signum for signum, _ in TRIES]
    assert codes == expected, f"exit codes {codes} (negative: killed by a signal)"


def _to_the_process() -> None:
    os.kill(os.getpid(), signal.SIGUSR1)  # the kernel picks a thread that does not block it


def _to_this_worker() -> None:
    # what CI saw: the signal landed on a worker while the caller waited without a timeout,
    # so Python never ran the handler and the wait (and the suite) lasted until CI's limit
    signal.pthread_kill(threading.get_ident(), signal.SIGUSR1)


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.timeout(120)
@pytest.mark.parametrize("send", [_to_the_process, _to_this_worker], ids=["process", "worker"])
def test_an_interrupt_while_waiting_stops_the_workers_and_waits_for_them(send) -> None:
    """A signal handler raising in the caller (as the CLI's does): the workers stop at their
    next block, and every one has finished before the interrupt goes on up, whichever thread
    the kernel handed the signal to."""
    started, finished = threading.Barrier(2), []
    errors: list[BaseException] = []

    class Interrupt(KeyboardInterrupt):
        pass

    def work() -> None:
        if started.wait(30) == 0:  # both workers run: interrupt the caller
            send()
        while not errors:  # a worker looks at errors between blocks
            np.linalg.eigvals(np.eye(20))
        finished.append(threading.current_thread().name)

    def interrupt(signum, frame):
        raise Interrupt

    previous = signal.signal(signal.SIGUSR1, interrupt)
    try:
        with pytest.raises(Interrupt):
            preflight_threads.run_threads(work, 2, errors)
    finally:
        signal.signal(signal.SIGUSR1, previous)
    assert len(finished) == 2  # both had ended before the interrupt went on up
    assert isinstance(errors[0], Interrupt)
