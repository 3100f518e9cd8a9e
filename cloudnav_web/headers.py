"""A request's headers arrive within a deadline, or its connection is closed.

Twisted's HTTP channel only times out a connection that sends nothing for a minute, and
every byte restarts that clock: a client sending its headers a byte at a time holds a
connection (and a slot of the proxy before it) for as long as it likes. ``install`` makes
daphne's factory give each connection ``CLOUDNAV_HEADER_SECONDS`` from the moment it can
take a request (when it opens, and after each answer on a kept-alive connection) to the
end of that request's headers; past it the connection is aborted. The body has its own
rules (``bodies``), and a request being answered (a stream, a WebSocket) is not timed.

The deadline is judged only after the reactor has read what already came: a server held
up past it (a busy machine, a long pause) runs its due timers before it reads its
sockets, and would otherwise abort a connection whose headers came in time and wait in
the kernel's buffer. Expired, the deadline looks once more on the reactor's next turn.
"""

from __future__ import annotations

from typing import Any

from django.conf import settings
from twisted.internet import reactor

clock: Any = reactor  # IReactorTime (its zope interface confuses mypy's view of callLater)


def install() -> None:
    """Time daphne's connections' headers (no-op without daphne); idempotent."""
    try:
        from daphne import http_protocol
    except ImportError:
        return
    factory = http_protocol.HTTPFactory
    if getattr(factory.buildProtocol, "times_headers", False):
        return
    build = factory.buildProtocol

    def build_timed(self: Any, addr: Any) -> Any:
        protocol = build(self, addr)
        channel = getattr(protocol, "_channel", protocol)  # HTTP/1.1 behind Twisted's wrapper
        HeaderDeadline(channel, float(settings.CLOUDNAV_HEADER_SECONDS))
        return protocol

    build_timed.times_headers = True  # type: ignore[attr-defined]
    factory.buildProtocol = build_timed


class HeaderDeadline:
    """Aborts ``channel`` when a request's headers are not all there in ``seconds``."""

    def __init__(self, channel: Any, seconds: float) -> None:
        self.channel, self.seconds = channel, seconds
        self.pending: Any = None  # the reactor's DelayedCall while timing
        self.read_since = False  # expired once: the reactor has since had a turn to read
        headers_done, request_done = channel.allHeadersReceived, channel.requestDone
        lost = channel.connectionLost

        def all_headers_received() -> None:
            self.stop()
            headers_done()

        def request_finished(request: Any) -> None:
            # Kept alive, the next request's headers are timed too; started first, since
            # finishing reads a pipelined request's headers at once (and stops it).
            self.start()
            request_done(request)

        def connection_lost(reason: Any) -> None:
            self.stop()
            lost(reason)

        channel.allHeadersReceived = all_headers_received
        channel.requestDone = request_finished
        channel.connectionLost = connection_lost
        self.start()

    def start(self) -> None:
        self.stop()
        self.read_since = False
        self.pending = clock.callLater(self.seconds, self.expire)

    def stop(self) -> None:
        if self.pending is not None and self.pending.active():
            self.pending.cancel()
        self.pending = None

    def expire(self) -> None:
        if not self.read_since:  # timers run before reads: give the reads one turn
            self.read_since = True
            self.pending = clock.callLater(0, self.expire)
            return
        self.pending = None
        transport = getattr(self.channel, "transport", None)
        if transport is not None:
            transport.abortConnection()
