"""How a connection's frames reach its socket: straight into daphne's transport, or via ASGI.

ASGI's ``send`` has no back-pressure: daphne accepts every frame at once and buffers it
in Twisted without bound, so a client that stops reading would grow the server's memory,
and each frame costs a trip through the middleware and Autobahn. Under daphne the sink
therefore writes ready-made WebSocket frames (the same bytes for every subscriber, see
``encoding.Wire.framed``) to the Twisted transport itself, and registers as the
transport's producer so Twisted says when its buffer is full (``pauseProducing``) and when
it has drained (``resumeProducing``). The connection keeps frames in its bounded outbox
meanwhile. Under any other server (the test communicator, another ASGI server) the generic
sink awaits ``send`` from a writer task.

The daphne sink relies on daphne passing ``functools.partial(Server.handle_reply,
protocol)`` as ``send`` and on Autobahn's protocol attributes; ``daphne_protocol`` checks
both and falls back to the generic sink when they are not there.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import weakref
from collections.abc import Awaitable, Callable
from typing import Any

from twisted.internet.interfaces import IPushProducer
from zope.interface import implementer

from telemetry.domain.encoding import Wire

AsgiSend = Callable[[dict[str, Any]], Awaitable[None]]
# Frames held for the next loop turn, per connection, before it counts as not writable.
PENDING_LIMIT = 256 * 1024
SCOPE_KEY = "cloudnav.transport_send"
logger = logging.getLogger(__name__)


class TransportProbe:
    """Outermost ASGI middleware: keeps the server's own ``send`` in the scope.

    Middlewares further in (sessions) wrap ``send``; the daphne sink needs the original.
    """

    def __init__(self, inner: Any) -> None:
        self.inner = inner

    async def __call__(self, scope: dict[str, Any], receive: Any, send: AsgiSend) -> Any:
        if scope.get("type") == "websocket":
            scope = dict(scope, **{SCOPE_KEY: send})
        return await self.inner(scope, receive, send)


def daphne_protocol(send: Any) -> Any | None:
    """Return daphne's Autobahn protocol behind ``send``, or None if ``send`` is not daphne's."""
    if not isinstance(send, functools.partial) or not send.args:
        return None
    protocol = send.args[0]
    transport = getattr(protocol, "transport", None)
    needed = ("state", "STATE_OPEN", "sendMessage", "_perMessageCompress")
    if not all(hasattr(protocol, name) for name in needed):
        return None
    if transport is None or not hasattr(transport, "registerProducer"):
        return None
    return protocol


# Frames up to this many times the rosbridge size limit are read, then dropped politely by
# the consumer; larger ones make Autobahn drop the connection as soon as it reads the frame
# header, before the payload, so no client can make the server buffer an arbitrarily large frame.
HARD_LIMIT_FACTOR = 4


def cap_incoming(protocol: Any, max_frame_bytes: int) -> None:
    """Set Autobahn's own frame and message size limits on daphne's protocol."""
    limit = HARD_LIMIT_FACTOR * max_frame_bytes
    protocol.maxFramePayloadSize = protocol.maxMessagePayloadSize = limit


class NextTurn:
    """The sinks of one event loop that have frames waiting, flushed together by one
    callback at the start of the loop's next turn: a message fanned out to many
    connections schedules one callback, not one per connection."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self._sinks: list[DaphneSink] = []

    def flush_soon(self, sink: DaphneSink) -> None:
        self._sinks.append(sink)
        if len(self._sinks) == 1:
            self.loop.call_soon(self._flush)

    def _flush(self) -> None:
        sinks, self._sinks = self._sinks, []
        for sink in sinks:
            try:
                sink.flush()
            except Exception:  # one connection's failure must not hold the others' frames
                logger.exception("a WebSocket flush failed")


_turns: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, NextTurn] = weakref.WeakKeyDictionary()


def next_turn() -> NextTurn:
    """Return the running loop's ``NextTurn``."""
    loop = asyncio.get_running_loop()
    turn = _turns.get(loop)
    if turn is None:
        turn = _turns[loop] = NextTurn(loop)
    return turn


@implementer(IPushProducer)
class DaphneSink:
    """Synchronous writes to a daphne WebSocket, paused while Twisted's buffer is full.

    ``on_writable`` is called when a full buffer has drained.
    """

    def __init__(self, protocol: Any, on_writable: Callable[[], None]) -> None:
        self.protocol = protocol
        self.transport = protocol.transport
        self.on_writable = on_writable
        self.paused = False
        # Autobahn frames and compresses itself when permessage-deflate was negotiated.
        self.raw = protocol._perMessageCompress is None
        # A plain TCP socket (not TLS) can take a frame at once while Twisted holds nothing
        # for it, which spares the writer registration and the wait for the next loop turn.
        plain = self.raw and not getattr(self.transport, "TLS", True)
        self.socket = getattr(self.transport, "socket", None) if plain else None
        self._pending: list[bytes] = []
        self._pending_bytes = 0
        self._turn = next_turn()
        # daphne leaves its HTTP channel registered as the producer of the upgraded
        # transport, where it no longer does anything; take its place.
        if self.transport.producer is not None:
            self.transport.unregisterProducer()
        self.transport.registerProducer(self, True)

    def writable(self) -> bool:
        return (
            not self.paused
            and self._pending_bytes < PENDING_LIMIT
            and self.protocol.state == self.protocol.STATE_OPEN
        )

    def write(self, wire: Wire) -> None:
        """Write ``wire``'s frames; the caller checked ``writable``.

        Frames written during one turn of the event loop leave together at the start of
        the next: one system call per connection per turn however many messages fan out
        to it, and no wait when only one does.
        """
        if not self.raw:
            for payload in wire.payloads:
                self.protocol.sendMessage(payload, wire.binary)
            return
        data = wire.framed()
        self._pending.append(data)
        self._pending_bytes += len(data)
        if len(self._pending) == 1:
            self._turn.flush_soon(self)

    def flush(self) -> None:
        """Write the frames of this turn (``NextTurn`` calls this at the start of the next)."""
        data = b"".join(self._pending)
        self._pending.clear()
        self._pending_bytes = 0
        if self.socket is not None and self._idle():
            try:
                sent = self.socket.send(data)
            except (BlockingIOError, InterruptedError):
                sent = 0
            except OSError:
                return  # the connection is gone; Twisted notices and closes it
            data = data[sent:]
        if data:
            # What the socket did not take goes after anything Twisted still holds, in
            # order; past Twisted's buffer size this pauses us (``pauseProducing``).
            self.transport.write(data)
        if not self.paused:
            self.on_writable()  # frames that waited while this turn's batch was full

    def _idle(self) -> bool:
        """True if Twisted has nothing buffered for this socket, so a direct send keeps order."""
        t = self.transport
        return (
            not t._tempDataLen
            and len(t.dataBuffer) == t.offset
            and t.connected
            and not t.disconnecting
        )

    # IPushProducer, called by Twisted
    def pauseProducing(self) -> None:
        self.paused = True

    def resumeProducing(self) -> None:
        self.paused = False
        self.on_writable()

    def stopProducing(self) -> None:
        self.paused = True

    def close(self) -> None:
        if getattr(self.transport, "producer", None) is self:
            self.transport.unregisterProducer()


async def send_via_asgi(send: AsgiSend, wire: Wire) -> None:
    """Send ``wire``'s frames through plain ASGI ``send`` calls."""
    if wire.binary:
        for payload in wire.payloads:
            await send({"type": "websocket.send", "bytes": payload})
    else:
        for text in wire.texts():
            await send({"type": "websocket.send", "text": text})
