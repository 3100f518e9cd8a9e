"""One rosbridge connection as the bus sees it: a peer with a bounded outbox and a sink.

``deliver`` never blocks and never raises. When the socket can take a frame at once (the
daphne sink, not paused, nothing queued) the frame is written synchronously, so fan-out to
a healthy subscriber costs one buffer append; otherwise it waits in the outbox, which drops
its oldest frames past its bounds, and is written when the socket drains. A message whose
encoding is over ``max_send_bytes`` is never sent (nor queued): it is counted and logged.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
from typing import Any

from telemetry.access.rules import Principal
from telemetry.domain.encoding import Outgoing, Wire
from telemetry.domain.outbox import Outbox
from telemetry.domain.protocol import Json, level_shows, status
from telemetry.rosbridge.transport import (
    AsgiSend,
    DaphneSink,
    cap_incoming,
    daphne_protocol,
    send_via_asgi,
)

_keys = itertools.count(1)
logger = logging.getLogger(__name__)


class Connection:
    """A connected client: who it is, what it wants to hear, and how to reach it."""

    def __init__(
        self,
        principal: Principal,
        asgi_send: AsgiSend,
        transport_send: Any,
        max_frames: int,
        max_bytes: int,
        max_frame_bytes: int,
        max_send_bytes: int,
    ) -> None:
        self.key = f"c{next(_keys)}"
        self.principal = principal
        self.level = "none"
        self.outbox = Outbox(max_frames, max_bytes)
        self.max_send_bytes = max_send_bytes
        self.too_large = 0
        self.open = True
        self._asgi_send = asgi_send
        self._wakeup = asyncio.Event()
        self._writer: asyncio.Task[None] | None = None
        protocol = daphne_protocol(transport_send)
        self._sink = None
        if protocol is not None:
            cap_incoming(protocol, max_frame_bytes)
            self._sink = DaphneSink(protocol, self._drain)

    def __repr__(self) -> str:
        return f"<Connection {self.key} {self.principal.label}>"

    def start(self) -> None:
        """Begin sending; call after the handshake was accepted."""
        if self._sink is None:
            self._writer = asyncio.get_running_loop().create_task(self._write_loop())
        else:
            self._drain()

    def deliver(self, wire: Wire) -> None:
        if wire.nbytes > self.max_send_bytes:
            self._refuse(wire)
            return
        sink = self._sink
        if sink is not None and not self.outbox and sink.writable():
            sink.write(wire)
            return
        if not self.open:
            return
        self.outbox.push(wire)
        if sink is None:
            self._wakeup.set()

    def _refuse(self, wire: Wire) -> None:
        self.too_large += 1
        if self.too_large == 1:
            logger.warning(
                "%s: a message of %d bytes is over the limit of %d and is not sent",
                self.principal.label,
                wire.nbytes,
                self.max_send_bytes,
            )

    def send(self, frame: dict[str, Any]) -> None:
        """Send one control frame (answers, requests, status) as JSON."""
        self.deliver(Outgoing(frame).wire())

    def report(self, level: str, message: str, id: Json = None) -> None:
        """Send a ``status`` frame if the client asked for this level with ``set_level``."""
        if level_shows(self.level, level):
            self.send(dict(status(level, message, id)))

    def _drain(self) -> None:
        sink = self._sink
        while sink is not None and self.outbox and sink.writable():
            wire = self.outbox.pop()
            if wire is not None:
                sink.write(wire)

    async def _write_loop(self) -> None:
        while self.open:
            await self._wakeup.wait()
            self._wakeup.clear()
            while self.open and (wire := self.outbox.pop()) is not None:
                await send_via_asgi(self._asgi_send, wire)

    def close(self) -> None:
        """Stop sending; queued frames are discarded."""
        self.open = False
        self.outbox.clear()
        if self._sink is not None:
            self._sink.close()
        if self._writer is not None:
            self._writer.cancel()
