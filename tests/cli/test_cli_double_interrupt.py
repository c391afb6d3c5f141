"""A second Ctrl-C right after the first (within 50 ms, while the command finishes and Python
shuts down) ends the command with 130 like one Ctrl-C, not by the signal (issue 23: the
interpreter's shutdown puts the default handler back, and a signal then killed the process,
in about a third of the tries)."""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from so101sim import cli
from so101sim.cli.output import SIGNALS

cli_main = importlib.import_module("so101sim.cli.main")  # the module (cli.main is the function)


def _two_interrupts(after_the_line: bool, gap: float) -> tuple[int, str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "so101sim", "hold", "--duration", "86400", "--headless"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=os.environ.copy(),
    )
    assert "holding the starting pose" in proc.stdout.readline()  # the command runs
    proc.send_signal(signal.SIGINT)  # its handlers were installed before it printed that
    seen = ""
    if after_the_line:  # the second one while Python shuts down: the window that killed it
        while (line := proc.stderr.readline()) and "interrupted" not in line:
            seen += line
        seen += line
    time.sleep(gap)  # the gap between the two signals is what is tested (0 to 30 ms)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    return proc.returncode, seen + err


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_two_ctrl_c_in_quick_succession_exit_130() -> None:
    runs = [(False, gap) for gap in (0.0, 0.02, 0.05)]
    runs += [(True, gap) for gap in (0.0, 0.005, 0.01, 0.01, 0.02, 0.03)]
    codes = []
    for after_the_line, gap in runs:
        code, err = _two_interrupts(after_the_line, gap)
        assert "Traceback" not in err
        codes.append(code)
    assert codes == [130] * len(runs), f"exit codes {codes} (negative: killed by the signal)"


def test_after_an_interrupted_command_a_late_signal_is_not_swallowed(monkeypatch) -> None:
    """In a program that goes on after main() (a test), a signal more than a second after an
    interrupted command does what the handler found before the command does."""
    received = []
    previous = signal.signal(signal.SIGTERM, lambda s, f: received.append(s))
    try:

        def interrupt(args):
            os.kill(os.getpid(), signal.SIGTERM)
            threading.Event().wait(60)  # the handler raises in here, at once

        monkeypatch.setattr(cli_main, "cmd_model_path", interrupt)
        cli_main._parser.cache_clear()  # main()'s parser holds the commands it was built with
        assert cli.main(["model-path"]) == 128 + signal.SIGTERM
        os.kill(os.getpid(), signal.SIGTERM)  # within a second: swallowed
        assert received == []
        SIGNALS._ended_at -= 2.0
        os.kill(os.getpid(), signal.SIGTERM)  # later: the handler found before
        assert received == [signal.SIGTERM]
    finally:
        signal.signal(signal.SIGTERM, previous)
        cli_main._parser.cache_clear()  # not the patched command for the next test
