"""When a viewer's socket can take the next frame: back-pressure for streaming responses.

ASGI's ``send`` has none under daphne: each body chunk is handed to Twisted at once and
buffered there without bound, so a viewer that reads slowly would make the server hold
every frame it cannot take yet. A stream body therefore waits, before each write, until
everything written before has left Twisted's buffer for the kernel, and then writes the
newest frame: a slow viewer skips frames and the server holds at most one write for it.

Under daphne, ``SocketReadiness`` finds the Twisted request behind the ASGI scope (daphne
puts the same ``headers`` list in the scope that its request object keeps), registers as
its streaming producer, and sets the connection's transport to call itself full as soon
as it holds any byte: Twisted then pauses the producer on each write and resumes it when
the write has drained. Both are restored when the stream ends. Under any other server (the
test client, another ASGI server) ``AlwaysReady`` leaves pacing to the server's ``send``.
"""

from __future__ import annotations

import asyncio
import logging
import sys
from collections.abc import Mapping
from typing import Any, Protocol

from twisted.internet.interfaces import IPushProducer
from zope.interface import implementer

logger = logging.getLogger(__name__)


class Readiness(Protocol):
    def ready(self) -> bool:
        """Whether the viewer's socket took everything written before, now."""

    async def wait(self) -> None:
        """Return once the viewer's socket took everything written before."""

    def close(self) -> None:
        """Give the connection back as it was."""


class AlwaysReady:
    """Readiness where the server's own ``send`` paces the stream (or nothing can)."""

    def ready(self) -> bool:
        return True

    async def wait(self) -> None:
        return None

    def close(self) -> None:
        return None


@implementer(IPushProducer)
class SocketReadiness:
    """Readiness of one daphne HTTP response, from Twisted's producer calls."""

    def __init__(self, request: Any) -> None:
        self.request = request
        self.transport = request.channel.transport
        self._ready = asyncio.Event()
        self._ready.set()
        self._own_buffer_size = "bufferSize" in vars(self.transport)
        self._buffer_size = self.transport.bufferSize
        self.transport.bufferSize = 0
        request.registerProducer(self, True)

    def ready(self) -> bool:
        return self._ready.is_set()

    async def wait(self) -> None:
        await self._ready.wait()

    def close(self) -> None:
        # A viewer that left took the registration with it: Twisted detaches the request
        # from its channel when the connection is lost, and there is nothing to undo.
        registered = getattr(self.request, "producer", None) is self
        if registered and self.request.channel is not None:
            self.request.unregisterProducer()
        if self._own_buffer_size:
            self.transport.bufferSize = self._buffer_size
        else:
            vars(self.transport).pop("bufferSize", None)

    # IPushProducer, called by Twisted
    def pauseProducing(self) -> None:
        self._ready.clear()

    def resumeProducing(self) -> None:
        self._ready.set()

    def stopProducing(self) -> None:
        # The connection is gone: let the stream go on to its next write, which daphne
        # drops, while Django notices the disconnect and ends the stream.
        self._ready.set()


def readiness_for(scope: Mapping[str, Any]) -> Readiness:
    """Return the readiness of the response to the request of ``scope``."""
    request = daphne_request(scope)
    if request is None:
        return AlwaysReady()
    try:
        return SocketReadiness(request)
    except (AttributeError, RuntimeError, ValueError):
        logger.warning("video: cannot pace the stream to its socket", exc_info=True)
        return AlwaysReady()


def daphne_request(scope: Mapping[str, Any]) -> Any | None:
    """Return daphne's Twisted request whose scope is ``scope``, or None if there is none
    (another server, or a connection Twisted is not reading)."""
    headers = scope.get("headers")
    # Only look if a reactor runs already (daphne's): importing it would install one.
    reactor = sys.modules.get("twisted.internet.reactor")
    if headers is None or scope.get("type") != "http" or reactor is None:
        return None
    for descriptor in getattr(reactor, "getReaders", list)():
        protocol = getattr(descriptor, "protocol", None)
        channel = getattr(protocol, "_channel", protocol)
        for request in getattr(channel, "requests", ()):
            if getattr(request, "clean_headers", None) is headers:
                return request
    return None
