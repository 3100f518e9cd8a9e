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

import functools
import logging
from collections.abc import Awaitable, Callable
from typing import Any

from twisted.internet.interfaces import IPushProducer
from zope.interface import implementer

from telemetry.domain.encoding import Wire

logger = logging.getLogger(__name__)

AsgiSend = Callable[[dict[str, Any]], Awaitable[None]]
SCOPE_KEY = "cloudnav.transport_send"


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
        # daphne leaves its HTTP channel registered as the producer of the upgraded
        # transport, where it no longer does anything; take its place.
        if self.transport.producer is not None:
            self.transport.unregisterProducer()
        self.transport.registerProducer(self, True)

    def writable(self) -> bool:
        return not self.paused and self.protocol.state == self.protocol.STATE_OPEN

    def write(self, wire: Wire) -> None:
        """Write ``wire``'s frames now; the caller checked ``writable``."""
        if self.raw:
            self.transport.write(wire.framed())
        else:
            for payload in wire.payloads:
                self.protocol.sendMessage(payload, wire.binary)

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
