"""What the studio's tests share: free ports, the command run as a subprocess whose lines are
read as they come, waits on events with generous deadlines (a busy 2-core machine: load 10),
and screenshots that retry when chromium's renderer is too busy to answer in its 10 s."""

from __future__ import annotations

import os
import queue
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

SRC = str(Path(__file__).resolve().parents[1] / "src")
BROWSER_WAIT = 480.0  # seconds: software WebGL beside other jobs on a 2-core machine
LINE_WAIT = 180.0  # seconds for a line the command prints (a start-up, a pose)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "so101sim", *args]


def env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}


class Lines:
    """A subprocess's stdout, read line by line in a thread (never blocks the test)."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.queue: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        self.thread = threading.Thread(target=self._read, args=(proc.stdout,), daemon=True)
        self.thread.start()

    def _read(self, stream) -> None:
        for line in stream:
            self.queue.put(line)

    def wait_for(self, predicate, timeout: float = LINE_WAIT) -> str:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                line = self.queue.get(timeout=0.2)
            except queue.Empty:
                continue
            self.seen.append(line)
            if predicate(line):
                return line
        raise AssertionError(f"no such line within {timeout} s; got:\n{''.join(self.seen)}")

    def rest(self, timeout: float = 30.0) -> str:
        """Everything printed until the stream ends (after the process did)."""
        self.thread.join(timeout)
        while not self.queue.empty():
            self.seen.append(self.queue.get())
        return "".join(self.seen)


def start(*args: str) -> tuple[subprocess.Popen, Lines]:
    proc = subprocess.Popen(
        cli(*args),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env(),
        start_new_session=True,  # its own process group: the test checks none is left
    )
    return proc, Lines(proc)


def stop(proc: subprocess.Popen, sig: int = signal.SIGINT, timeout: float = 60.0) -> int:
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            return proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            raise AssertionError(f"still running {timeout} s after signal {sig}") from None
    return proc.returncode


def wait_until(check, timeout: float, what: str):
    """Wait for ``check()`` to be true; a browser command that timed out (a starved renderer
    or chromedriver) counts as "not yet", until the deadline."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            value = check()
        except _slow_browser():
            value = None
        if value:
            return value
        time.sleep(0.5)
    raise AssertionError(f"{what} did not happen within {timeout} s")


def _slow_browser() -> tuple[type[BaseException], ...]:
    try:
        from selenium.common.exceptions import TimeoutException
        from urllib3.exceptions import ReadTimeoutError
    except ImportError:
        return (TimeoutError,)
    return (TimeoutException, ReadTimeoutError, TimeoutError)


def page_ready(browser, timeout: float = BROWSER_WAIT) -> None:
    """Wait for the page's own signal that the browser has drawn the arm (studio/ready.py)."""
    wait_until(
        lambda: browser.find_elements("css selector", '#so101sim-ready[data-ready="1"]'),
        timeout,
        "the page's ready signal (the arm drawn)",
    )


def screenshot(browser, timeout: float = BROWSER_WAIT) -> bytes:
    """A PNG of the page; chromium's renderer answers a screenshot within a fixed 10 s or
    fails ("Timed out receiving message from renderer"): on a busy machine, ask again."""
    import base64

    end = time.monotonic() + timeout
    while True:
        try:
            return browser.get_screenshot_as_png()
        except _slow_browser():
            pass
        try:  # DevTools' own capture: chromedriver does not cut it at the renderer's 10 s
            shot = browser.execute_cdp_cmd("Page.captureScreenshot", {"format": "png"})
            return base64.b64decode(shot["data"])
        except _slow_browser():
            if time.monotonic() > end:
                raise
