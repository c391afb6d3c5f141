"""Where the studio listens and who may talk to it: the host and port checked, the addresses it
really listens on, and the guard that refuses a websocket from another site.

* :func:`check_host` refuses an empty ``--host`` (it would listen on every interface while
  the page's URL says 127.0.0.1); :func:`listen_addresses` is what the server binds
  (``getaddrinfo`` as asyncio does), :func:`exposure_warning` says when that is beyond this
  machine.
* :class:`OriginGuard` refuses a websocket whose ``Origin`` is not the page's own host (a web
  page on another site, open in the user's own browser, would otherwise stream the scene and
  drive the sliders) and, on a studio that listens on loopback only, one whose ``Host`` is not
  a loopback name (DNS rebinding). viser has no public hook for it (its ``on_client_connect``
  runs after its own callback has started sending the scene and shows no request headers):
  :func:`hook_viser`, the one function that reaches into viser's internals, puts the guard
  first among the websocket server's connect callbacks, which closes such a connection (code
  1008) before anything is sent and puts itself in front of the handshake so that later ones
  get HTTP 403. ``tests/studio/test_viser_hook.py`` fails loudly when viser changes them.
* :func:`quiet_handshakes`: a plain TCP connect (a port scan, ``nc``) that sends no HTTP
  request is a debug line in the log, not a traceback on the terminal.
"""

from __future__ import annotations

import contextlib
import errno
import http
import ipaddress
import logging
import socket
from collections.abc import Callable
from typing import Any
from urllib.parse import urlsplit

from ..errors import SettingError, So101SimError
from ..validation import check_range

log = logging.getLogger(__name__)

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8080
LOOPBACK_NAMES = ("localhost", "localhost.localdomain", "ip6-localhost")


class StudioError(So101SimError, RuntimeError):
    """The studio cannot start: viser/mjviser missing, or the port is in use."""


def check_port(port: int) -> int:
    """A TCP port number, 1 to 65535."""
    return int(check_range(port, "port", low=1, high=65535, expected="a TCP port from 1 to 65535"))


def check_host(host: str) -> str:
    """The address to listen on: not empty (an empty host listens on every interface)."""
    if not isinstance(host, str) or not host.strip():
        raise SettingError(
            f"--host {host!r} is empty; expected an address of this machine: 127.0.0.1 (this "
            "machine only, the default) or 0.0.0.0 (every network interface, on purpose)"
        )
    return host.strip()


def listen_addresses(host: str, port: int) -> list[str]:
    """The addresses a server on ``host:port`` binds (as asyncio's ``create_server`` resolves
    them), as ``addr:port`` / ``[addr]:port``; the host itself if it cannot be resolved."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except (OSError, UnicodeError):
        return [f"{host}:{port}"]
    out: list[str] = []
    for family, *_, sockaddr in infos:
        addr = str(sockaddr[0])
        text = f"[{addr}]:{port}" if family == socket.AF_INET6 else f"{addr}:{port}"
        if text not in out:
            out.append(text)
    return out


def _address(text: str) -> str:
    """``addr`` of ``addr:port`` or ``[addr]:port``."""
    return text.rsplit(":", 1)[0].strip("[]")


def is_loopback(address: str) -> bool:
    """Whether ``address`` (an IP or a name) is this machine only."""
    name = address.strip("[]").lower()
    if name in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(name.split("%")[0]).is_loopback
    except ValueError:
        return False


def exposure_warning(host: str, port: int, addresses: list[str] | None = None) -> str | None:
    """A warning when a studio on ``host:port`` can be reached from other machines; None when
    it listens on loopback only."""
    addresses = addresses if addresses is not None else listen_addresses(host, port)
    beyond = [a for a in addresses if not is_loopback(_address(a))]
    if not beyond:
        return None
    every = any(_address(a) in ("0.0.0.0", "::") for a in beyond)
    where = "every network interface" if every else "a network interface"
    return (
        f"the studio listens on {', '.join(beyond)} ({where}): anyone who can reach this "
        "machine can open the page and move the arm's sliders; --host 127.0.0.1 keeps it to "
        "this machine"
    )


def port_in_use_message(host: str, port: int) -> str:
    return (
        f"port {port} on {host} is in use (another studio or server?); "
        f"expected a free port: pass --port with another number"
    )


def ensure_free(host: str, port: int) -> None:
    """Raise :class:`StudioError` if nothing can listen on ``host:port`` (viser itself would
    quietly take the next port; a student must get the URL they asked for)."""
    host = check_host(host)
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise StudioError(port_in_use_message(host, port)) from None
            raise StudioError(
                f"cannot listen on {host}:{port} ({exc.strerror}); expected an address of "
                "this machine for --host (127.0.0.1, or 0.0.0.0 for every interface)"
            ) from None


def page_url(host: str, port: int) -> str:
    """The page's URL for a browser on this machine (127.0.0.1 for every interface)."""
    host = "127.0.0.1" if host in ("", "0.0.0.0") else "::1" if host == "::" else host
    host = f"[{host}]" if ":" in host else host
    return f"http://{host}:{port}"


# ---------------------------------------------------------------------------- the guard
class OriginGuard:
    """Refuses cross-origin websockets on a viser server (see the module's docstring)."""

    REASON = "cross-origin websocket refused"

    def __init__(self, host: str) -> None:
        self.loopback_only = all(is_loopback(_address(a)) for a in listen_addresses(host, 1))
        self.host = host.lower()
        self.refused = 0  # connections refused so far
        self._handshake_guarded = False

    def allowed(self, headers: Any) -> bool:
        """Whether a websocket request with these headers comes from the page itself."""
        origin = headers.get("Origin")
        host = (headers.get("Host") or "").strip().lower()
        if self.loopback_only:
            name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
            if not (is_loopback(name) or name.strip("[]") == self.host):
                return False  # a name that resolves here but is not ours: DNS rebinding
        if origin is None:  # not a browser (browsers always send it): a local program
            return True
        return urlsplit(origin.strip()).netloc.lower() == host and bool(host)

    def install(self, viser_server: Any) -> None:
        """Put the guard first among the websocket server's connect callbacks."""
        self._connection_of = hook_viser(viser_server, self._on_connect)

    async def _on_connect(self, client: Any) -> None:
        connection = self._connection_of(client.client_id)
        if connection is None:
            return
        if not self._handshake_guarded:
            self._guard_handshake(connection.server)
        if not self.allowed(connection.request.headers):
            self.refused += 1
            log.warning("refused a websocket from %s", connection.request.headers.get("Origin"))
            await connection.close(1008, self.REASON)

    def _guard_handshake(self, ws_server: Any) -> None:
        """From now on a foreign websocket gets HTTP 403 at the handshake."""
        inner = ws_server.process_request

        def process_request(connection: Any, request: Any) -> Any:
            headers = request.headers
            if headers.get("Upgrade", "").lower() == "websocket" and not self.allowed(headers):
                self.refused += 1
                log.warning("refused a websocket from %s", headers.get("Origin"))
                return connection.respond(http.HTTPStatus.FORBIDDEN, self.REASON + "\n")
            return inner(connection, request) if inner is not None else None

        ws_server.process_request = process_request
        self._handshake_guarded = True


def hook_viser(viser_server: Any, on_connect: Callable[[Any], Any]) -> Callable[[int], Any]:
    """Run ``on_connect(client)`` first among a viser server's websocket connect callbacks, and
    return how to find a client's websocket connection by its ``client_id`` (websockets'
    ``ServerConnection``: its ``request.headers``, its ``server``).

    The one place so101sim uses viser's private attributes (viser 1.x): its websocket server
    (``ViserServer._websock_server``), that server's list of connect callbacks
    (``_client_connect_cb``) and its table of live connections (``_live_connections``, filled
    before the callbacks run). viser offers no public equivalent: ``on_client_connect`` appends
    after viser's own callback and its ``ClientHandle`` carries no request headers.

    Raises:
        StudioError: this viser has no such attributes (the studio would otherwise accept
            pages from any site).
    """
    try:
        infra = viser_server._websock_server
        callbacks, live = infra._client_connect_cb, infra._live_connections
        if not isinstance(callbacks, list) or not isinstance(live, dict):
            raise AttributeError("not a list and a dict")
    except AttributeError:
        raise StudioError(
            "this viser version offers no way to check a websocket's Origin, so the studio "
            "would accept pages from any site; expected viser 1.x: pip install 'viser<2'"
        ) from None
    callbacks.insert(0, on_connect)
    return live.get


class _QuietHandshakes(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        if record.getMessage() == "opening handshake failed":
            exc = record.exc_info[1] if record.exc_info else None
            log.debug("a connection sent no websocket or HTTP request (%s)", exc)
            return False
        return True


_FILTER = _QuietHandshakes()


def quiet_handshakes() -> None:
    """A connection that sends no request (a plain TCP connect) is a debug line, not a
    traceback (websockets logs it as an error with its traceback)."""
    logger = logging.getLogger("websockets.server")
    if _FILTER not in logger.filters:
        logger.addFilter(_FILTER)


@contextlib.contextmanager
def quiet_viser() -> Any:
    """viser prints its address box and "Server stopped" with ``rich.print`` whatever its
    ``verbose``; the library never prints: while starting and stopping, they go to the log."""
    try:
        # rich comes with viser (the optional web extra)
        import rich
    except ImportError:  # viser without rich: nothing to quiet
        yield
        return
    saved = rich.print
    rich.print = lambda *a, **k: log.debug("viser: %s", " ".join(map(str, a)))
    try:
        yield
    finally:
        rich.print = saved
