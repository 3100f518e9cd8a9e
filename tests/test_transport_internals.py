"""The daphne, Autobahn and Twisted internals that ``telemetry/rosbridge/transport.py`` relies on.

``daphne_protocol`` falls back to the generic ASGI sink, silently, when daphne or Autobahn
change what it looks for; the server then still works but loses its back-pressure and
its direct writes. These tests make such a change fail loudly instead: they pin the
versions the module was checked against and assert every name, attribute and signature
it uses, then drive the daphne sink over a real loopback TCP connection.
"""

from __future__ import annotations

import asyncio
import functools
import inspect
import re
import socket
from collections.abc import Iterator
from importlib.metadata import version
from pathlib import Path

import pytest
from autobahn.twisted.websocket import WebSocketServerFactory
from autobahn.websocket.protocol import WebSocketProtocol as AutobahnProtocol
from daphne.server import Server
from daphne.ws_protocol import WebSocketProtocol
from twisted.internet import tcp

from telemetry.domain.encoding import Wire
from telemetry.rosbridge.transport import DaphneSink, cap_incoming, daphne_protocol, next_turn

# The versions whose internals transport.py was read against. A new version in
# requirements.txt fails here: read transport.py's assumptions against it, then update.
CHECKED = {"daphne": "4.2.3", "autobahn": "26.10.2", "Twisted": "26.10.0"}
REQUIREMENTS = Path(__file__).resolve().parent.parent / "requirements.txt"


def pinned(name: str) -> str:
    match = re.search(rf"^{name}==(\S+)$", REQUIREMENTS.read_text(), re.MULTILINE | re.IGNORECASE)
    assert match, f"{name} is not pinned with == in requirements.txt"
    return match.group(1)


@pytest.mark.parametrize("name", sorted(CHECKED))
def test_it_runs_on_the_versions_transport_was_checked_against(name: str) -> None:
    assert pinned(name) == CHECKED[name], (
        f"requirements.txt pins {name}=={pinned(name)} but telemetry/rosbridge/transport.py was "
        f"checked against {CHECKED[name]}: re-check its internals, then update CHECKED"
    )
    assert version(name) == CHECKED[name]


def test_daphne_passes_a_partial_of_handle_reply_with_the_protocol_as_send() -> None:
    assert "send=partial(self.handle_reply, protocol)" in inspect.getsource(
        Server.create_application
    )
    assert list(inspect.signature(Server.handle_reply).parameters) == [
        "self",
        "protocol",
        "message",
    ]


def test_daphne_speaks_websocket_through_autobahn() -> None:
    assert issubclass(WebSocketProtocol, AutobahnProtocol)
    assert WebSocketProtocol.STATE_OPEN == AutobahnProtocol.STATE_OPEN
    parameters = list(inspect.signature(WebSocketProtocol.sendMessage).parameters)
    assert parameters[:3] == ["self", "payload", "isBinary"]


def test_autobahn_reads_its_size_limits_from_the_protocol() -> None:
    for name in ("maxFramePayloadSize", "maxMessagePayloadSize"):
        assert name in AutobahnProtocol.CONFIG_ATTRS_COMMON
        assert f"self.{name}" in inspect.getsource(AutobahnProtocol)


def test_twisted_tcp_transports_have_what_the_sink_touches() -> None:
    assert tcp.Server.TLS is False
    for name in ("registerProducer", "unregisterProducer", "write"):
        assert callable(getattr(tcp.Server, name))
    assert list(inspect.signature(tcp.Server.registerProducer).parameters) == [
        "self",
        "producer",
        "streaming",
    ]


@pytest.fixture
def connection() -> Iterator[tuple[WebSocketProtocol, socket.socket]]:
    """Daphne's protocol on a Twisted TCP transport over a real loopback connection,
    past its handshake; with the client's end of the socket."""
    yield from open_connection()


@pytest.fixture
def another_connection() -> Iterator[tuple[WebSocketProtocol, socket.socket]]:
    yield from open_connection()


def open_connection() -> Iterator[tuple[WebSocketProtocol, socket.socket]]:
    listener = socket.create_server(("127.0.0.1", 0))
    client = socket.create_connection(listener.getsockname())
    accepted, peer = listener.accept()
    listener.close()
    accepted.setblocking(False)
    protocol = WebSocketProtocol()
    protocol.factory = WebSocketServerFactory()
    transport = tcp.Server(accepted, protocol, peer, None, 1, None)  # type: ignore[arg-type]
    protocol.makeConnection(transport)
    protocol.state = protocol.STATE_OPEN  # as after a handshake without compression
    yield protocol, client
    client.close()
    accepted.close()


def test_daphne_protocol_finds_the_protocol_behind_daphnes_send(
    connection: tuple[WebSocketProtocol, socket.socket],
) -> None:
    protocol, _ = connection
    send = functools.partial(Server.__new__(Server).handle_reply, protocol)
    assert protocol._perMessageCompress is None  # what tells the sink to frame itself
    assert daphne_protocol(send) is protocol


def test_cap_incoming_sets_autobahns_limits(
    connection: tuple[WebSocketProtocol, socket.socket],
) -> None:
    protocol, _ = connection
    cap_incoming(protocol, 1000)
    assert protocol.maxFramePayloadSize == protocol.maxMessagePayloadSize == 4000


async def test_the_sink_writes_frames_straight_to_the_socket_as_producer(
    connection: tuple[WebSocketProtocol, socket.socket],
) -> None:
    protocol, client = connection
    sink = DaphneSink(protocol, lambda: None)
    assert protocol.transport.producer is sink
    assert sink.raw
    assert sink.socket is not None
    assert sink.writable()
    assert sink._idle()
    wire = Wire((b'{"op":"publish"}',), binary=False)
    sink.write(wire)
    await asyncio.sleep(0)  # the batch leaves at the next loop turn
    client.settimeout(2)
    assert client.recv(100) == wire.framed()
    sink.pauseProducing()
    assert not sink.writable()
    sink.close()
    assert protocol.transport.producer is None


async def test_sinks_written_in_one_turn_all_leave_at_the_next_by_one_callback(
    connection: tuple[WebSocketProtocol, socket.socket],
    another_connection: tuple[WebSocketProtocol, socket.socket],
) -> None:
    (first, first_client), (second, second_client) = connection, another_connection
    sinks = [DaphneSink(first, lambda: None), DaphneSink(second, lambda: None)]
    loop = asyncio.get_running_loop()
    scheduled = len(loop._ready)  # type: ignore[attr-defined]  # asyncio's run queue
    wires = [Wire((b'{"op":"publish","n":%d}' % n,), binary=False) for n in range(2)]
    for sink in sinks:
        for wire in wires:
            sink.write(wire)
    assert len(loop._ready) == scheduled + 1  # type: ignore[attr-defined]
    assert sinks[0]._turn is sinks[1]._turn is next_turn()
    await asyncio.sleep(0)
    expected = b"".join(wire.framed() for wire in wires)
    for client in (first_client, second_client):
        client.settimeout(2)
        assert client.recv(1000) == expected
