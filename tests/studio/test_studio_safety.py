"""The studio is reachable by nobody else: cross-origin websockets refused, an empty --host
refused, the address it listens on printed (and warned beyond loopback), a plain TCP connect
prints no traceback, and a signal always stops it. Every server here listens on 127.0.0.1."""

from __future__ import annotations

import base64
import os
import signal
import socket
import struct
import subprocess
import sys
import time

import pytest

pytest.importorskip("viser", reason="the web extra is not installed: pip install 'so101sim[web]'")
pytest.importorskip("mjviser", reason="the web extra is not installed: pip install 'so101sim[web]'")

from studio_helpers import cli, env, free_port, start, stop, wait_until

from so101sim import Simulation
from so101sim.errors import SettingError
from so101sim.studio import Studio
from so101sim.studio.net import (
    OriginGuard,
    check_host,
    exposure_warning,
    is_loopback,
    listen_addresses,
)


def handshake(port: int, origin: str | None, host: str | None = None) -> socket.socket:
    """A raw websocket opening handshake to the studio, as a browser on ``origin`` sends it."""
    import viser

    s = socket.create_connection(("127.0.0.1", port), timeout=60)
    key = base64.b64encode(os.urandom(16)).decode()
    lines = [
        "GET / HTTP/1.1",
        f"Host: {host or f'127.0.0.1:{port}'}",
        "Upgrade: websocket",
        "Connection: Upgrade",
        f"Sec-WebSocket-Key: {key}",
        "Sec-WebSocket-Version: 13",
        f"Sec-WebSocket-Protocol: viser-v{viser.__version__}",
    ]
    if origin is not None:
        lines.append(f"Origin: {origin}")
    s.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
    return s


def read_response(s: socket.socket) -> tuple[int, bytes]:
    """The HTTP status of the handshake's answer and the bytes after its headers."""
    data = b""
    while b"\r\n\r\n" not in data:
        chunk = s.recv(4096)
        if not chunk:
            break
        data += chunk
    head, _, rest = data.partition(b"\r\n\r\n")
    return int(head.split(b" ")[1]), rest


def frames(s: socket.socket, rest: bytes, deadline: float = 120.0) -> list[tuple[int, bytes]]:
    """The websocket frames (opcode, payload) the server sends until it closes (or the first
    data frame: enough to know it streams)."""
    out: list[tuple[int, bytes]] = []
    buf = rest
    end = time.monotonic() + deadline
    s.settimeout(5)
    while time.monotonic() < end:
        while len(buf) >= 2:
            op, n = buf[0] & 0x0F, buf[1] & 0x7F
            at = 2
            if n == 126:
                n, at = struct.unpack(">H", buf[2:4])[0], 4
            elif n == 127:
                n, at = struct.unpack(">Q", buf[2:10])[0], 10
            if len(buf) < at + n:
                break
            out.append((op, buf[at : at + n]))
            buf = buf[at + n :]
            if op in (0x8, 0x1, 0x2):  # close, or the first data frame
                return out
        try:
            chunk = s.recv(65536)
        except TimeoutError:
            continue
        if not chunk:
            return out
        buf += chunk
    return out


@pytest.fixture(scope="module")
def studio():
    with Studio(Simulation().model, port=free_port()) as st:
        yield st


def test_a_websocket_from_the_page_itself_streams_the_scene(studio):
    with handshake(studio.port, f"http://127.0.0.1:{studio.port}") as s:
        status, rest = read_response(s)
        assert status == 101
        got = frames(s, rest)
        assert got and got[-1][0] == 0x2, got  # a binary message: the scene


@pytest.mark.parametrize(
    "origin, host",
    [
        ("http://evil.example", None),  # a web page on another site, in the user's browser
        ("http://127.0.0.1:1", None),  # another port of this machine: another origin
        ("null", None),  # a sandboxed frame or a file:// page
        ("http://evil.example:{port}", "evil.example:{port}"),  # DNS rebinding: same "origin"
    ],
)
def test_a_cross_origin_websocket_is_refused_before_anything_is_sent(studio, origin, host):
    port = studio.port
    origin = origin.format(port=port)
    before = studio.guard.refused
    with handshake(port, origin, host.format(port=port) if host else None) as s:
        status, rest = read_response(s)
        if status == 101:  # the first connection the server sees: closed at once (1008)
            got = frames(s, rest)
            assert [op for op, _ in got] == [0x8], got  # a close frame and nothing else
            assert struct.unpack(">H", got[0][1][:2])[0] == 1008
        else:  # once the guard stands in front of the handshake: HTTP 403
            assert status == 403
    assert studio.guard.refused == before + 1


def test_the_guard_judges_origin_and_host_as_a_browser_sends_them():
    local = OriginGuard("127.0.0.1")
    assert local.allowed({"Origin": "http://127.0.0.1:8080", "Host": "127.0.0.1:8080"})
    assert local.allowed({"Origin": "http://localhost:8080", "Host": "localhost:8080"})
    assert local.allowed({"Host": "127.0.0.1:8080"})  # no Origin: a program, not a browser
    assert not local.allowed({"Origin": "http://evil.example", "Host": "127.0.0.1:8080"})
    assert not local.allowed({"Origin": "http://a.example:8080", "Host": "a.example:8080"})
    everywhere = OriginGuard("0.0.0.0")  # on purpose: the page's own host, whatever its name
    assert everywhere.allowed({"Origin": "http://lab-pc:8080", "Host": "lab-pc:8080"})
    assert not everywhere.allowed({"Origin": "http://evil.example", "Host": "lab-pc:8080"})


def test_an_empty_host_is_refused():
    for host in ("", "  "):
        with pytest.raises(SettingError, match=r"--host .* is empty; expected"):
            check_host(host)


@pytest.mark.parametrize("command", [("view",), ("pose",), ("hold", "--duration", "1")])
def test_an_empty_host_is_one_error_line_and_status_2(command):
    r = subprocess.run(
        cli(*command, "--web", "--host", ""), capture_output=True, text=True, env=env(), timeout=300
    )
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "--host '' is empty" in lines[0], r.stderr


def test_listening_beyond_this_machine_is_warned_and_loopback_is_not():
    assert listen_addresses("127.0.0.1", 8080) == ["127.0.0.1:8080"]
    assert listen_addresses("0.0.0.0", 8080) == ["0.0.0.0:8080"]
    assert exposure_warning("127.0.0.1", 8080) is None
    assert exposure_warning("localhost", 8080) is None
    warning = exposure_warning("0.0.0.0", 8080)
    assert "0.0.0.0:8080 (every network interface)" in warning and "--host 127.0.0.1" in warning
    assert "[::]:8080" in exposure_warning("::", 8080)
    assert is_loopback("::1") and is_loopback("127.0.0.2") and not is_loopback("192.168.1.5")


def test_the_command_prints_the_address_it_listens_on_and_a_plain_connect_is_quiet():
    port = free_port()
    proc, out = start("view", "--web", "--port", str(port))
    try:
        line = out.wait_for(lambda s: f"http://127.0.0.1:{port}" in s)
        assert f"listening on 127.0.0.1:{port}, this machine only" in line
        for payload in (b"", b"hello\r\n\r\n"):  # a port scan; something that is not HTTP
            with socket.create_connection(("127.0.0.1", port), timeout=30) as s:
                s.sendall(payload)
        # the page is still served afterwards (and the connects above were handled first)
        wait_until(lambda: _get(port), 120, "the page being served")
    finally:
        code = stop(proc)
    text = out.rest()
    assert code == 0, text
    assert "Traceback" not in text and "handshake" not in text, text
    assert "warning" not in text


def _get(port: int) -> bytes | None:
    import urllib.request

    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}", timeout=10) as r:
            return r.read()
    except OSError:
        return None


@pytest.mark.parametrize("command", [("view",), ("pose",)])
def test_sigterm_stops_the_serving_studio(command):
    port = free_port()
    proc, out = start(*command, "--web", "--port", str(port))
    try:
        out.wait_for(lambda s: f"http://127.0.0.1:{port}" in s)
        wait_until(lambda: _get(port), 120, "the page being served")
    finally:
        code = stop(proc, signal.SIGTERM, timeout=120)
    assert code == 0, out.rest()
    assert "stopped" in out.rest()
    with pytest.raises(ProcessLookupError):  # nothing of its process group is left
        os.killpg(proc.pid, 0)


def test_sigterm_while_the_studio_starts_stops_it_too():
    """The signal comes at once, before the URL (while Python starts, the model loads or the
    page is built): the command ends all the same, by the signal (before so101sim's handlers
    are in place), as interrupted (143) or as stopped (0)."""
    port = free_port()
    proc, out = start("view", "--web", "--port", str(port))
    code = stop(proc, signal.SIGTERM, timeout=120)
    assert code in (0, 128 + signal.SIGTERM, -signal.SIGTERM), out.rest()


def test_a_signal_while_serving_raises_nowhere_not_even_in_a_weakref_callback():
    """The serving loop's handler only sets a flag: a signal that lands while a WeakSet's (or
    any) callback runs in the main thread cannot be swallowed there ("Exception ignored")."""
    code = """
import os, signal, sys, weakref
from so101sim.cli.studio import _UntilSignal

class Thing: pass

seen = []
with _UntilSignal() as until:
    things = weakref.WeakSet()
    for _ in range(200):
        t = Thing(); things.add(t)
        ref = weakref.ref(t, lambda r: (os.kill(os.getpid(), signal.SIGTERM), seen.append(1)))
        del t  # the callback runs now, in the middle of the WeakSet's bookkeeping
    print("flag", until.signum, len(seen))
print("handler restored", signal.getsignal(signal.SIGTERM) is signal.SIG_DFL)
"""
    r = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env(), timeout=300
    )
    assert r.returncode == 0, r.stderr
    assert f"flag {int(signal.SIGTERM)} 200" in r.stdout and "handler restored True" in r.stdout
    assert "Exception ignored" not in r.stderr and "Interrupted" not in r.stderr, r.stderr


def test_interrupt_ends_a_paused_wait(studio):
    studio.playing = False
    studio.stopping = False
    try:
        studio.interrupt()
        assert studio.wait_while_paused() is False  # returns at once: it was told to stop
    finally:
        studio.stopping = False
        studio.playing = True
