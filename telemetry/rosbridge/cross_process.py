"""What the hub asks of the other server processes: the Redis relay in scaled mode
(``telemetry.rosbridge.relay.Relay``), or ``NullRelay`` in single-process mode, which does nothing
and finds nothing, so no caller asks which mode it runs in."""

from __future__ import annotations

from typing import Any, Protocol

from telemetry.domain.bus import Peer
from telemetry.domain.protocol import Json


class CrossProcess(Protocol):
    """What the hub asks of the other server processes (``Relay``), or of none
    (``NullRelay``)."""

    channel: str

    def owner_key(self, conn_key: str) -> str:
        """A connection's key made unique across server processes."""

    def put(self, kind: str, name: str, value: str) -> None: ...

    def remove(self, kind: str, name: str) -> None: ...

    async def entries(self, kind: str, others_only: bool = True) -> list[tuple[str, str, str]]:
        """Return ``(name, value, channel)`` of ``kind`` from other live processes."""

    async def find(self, kind: str, name: str) -> tuple[str, str] | None:
        """Return ``(channel, value)`` of another live process that has ``name`` of ``kind``."""

    async def latched(self, topic: str) -> tuple[str, dict[str, Json]] | None: ...

    async def settled(self) -> None: ...

    async def written(self) -> None:
        """Wait until what was queued for the other processes so far has reached them."""

    def send(self, channel: str, message: dict[str, Any]) -> None: ...

    def remote(self, channel: str, conn_key: str) -> Peer:
        """A connection on another process, as the bus and call tables see it."""


class NullRelay:
    """Single-process mode: no other process to tell, none to ask, nothing ever found."""

    channel = ""

    def owner_key(self, conn_key: str) -> str:
        return conn_key

    def put(self, kind: str, name: str, value: str) -> None:
        pass

    def remove(self, kind: str, name: str) -> None:
        pass

    async def entries(self, kind: str, others_only: bool = True) -> list[tuple[str, str, str]]:  # noqa: ARG002 (the interface)
        return []

    async def find(self, kind: str, name: str) -> tuple[str, str] | None:  # noqa: ARG002
        return None

    async def latched(self, topic: str) -> tuple[str, dict[str, Json]] | None:  # noqa: ARG002
        return None

    async def settled(self) -> None:
        pass

    async def written(self) -> None:
        pass

    def send(self, channel: str, message: dict[str, Any]) -> None:
        pass

    def remote(self, channel: str, conn_key: str) -> Peer:
        raise RuntimeError(f"no other process ({channel}) in single-process mode: {conn_key}")
