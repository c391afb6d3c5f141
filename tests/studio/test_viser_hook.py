"""The studio's websocket guard reaches into viser's internals in one function,
:func:`so101sim.studio.net.hook_viser` (viser offers no public hook that runs before it sends
the scene or shows a request's headers). These tests fail loudly when the installed viser or
websockets changes what the guard relies on; then the guard must be rewritten, not loosened."""

from __future__ import annotations

import inspect
import re

import pytest

viser = pytest.importorskip("viser", reason="the web extra is not installed")

from viser.infra import WebsockServer  # noqa: E402

from so101sim.studio.net import StudioError, hook_viser  # noqa: E402


def test_viser_runs_connect_callbacks_after_registering_the_connection():
    source = inspect.getsource(WebsockServer)
    live = source.find("self._live_connections[client_id] = connection")
    loop = source.find("for cb in self._client_connect_cb:")
    assert live != -1 and loop != -1, (
        "viser's WebsockServer no longer registers live connections or runs its connect "
        "callbacks as so101sim.studio.net.hook_viser expects: rewrite the Origin guard"
    )
    assert live < loop  # the guard finds the connection it is called for


def test_viser_server_holds_its_websocket_server_where_the_hook_looks():
    source = inspect.getsource(viser.ViserServer.__init__)
    assert re.search(r"self\._websock_server = server\b", source), (
        "viser.ViserServer no longer keeps its websocket server in _websock_server: rewrite "
        "so101sim.studio.net.hook_viser"
    )


def test_websockets_keeps_process_request_on_the_server():
    from websockets.asyncio.server import Server

    assert "self.process_request = process_request" in inspect.getsource(Server.__init__), (
        "websockets' Server no longer keeps process_request: the guard's HTTP 403 at the "
        "handshake (OriginGuard._guard_handshake) must be rewritten"
    )


class _Viser:
    def __init__(self, infra: object) -> None:
        self._websock_server = infra


def test_the_hook_goes_first_and_finds_connections_on_a_real_websocket_server():
    infra = WebsockServer("127.0.0.1", 0, message_class=viser.infra.Message, verbose=False)
    first = object()
    infra._client_connect_cb.append(first)  # viser's own callback, registered before

    def guard(client: object) -> None:
        return None

    find = hook_viser(_Viser(infra), guard)
    assert infra._client_connect_cb == [guard, first]
    infra._live_connections[7] = "the connection"
    assert find(7) == "the connection" and find(8) is None


@pytest.mark.parametrize("infra", [object(), type("Old", (), {"_client_connect_cb": ()})()])
def test_a_viser_without_the_internals_is_refused_loudly(infra):
    with pytest.raises(StudioError, match="no way to check a websocket's Origin"):
        hook_viser(_Viser(infra), lambda client: None)
