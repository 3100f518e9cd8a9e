"""The server's own services (``/rosapi/...`` and ``/cloudnav/...``): what a handler gets."""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from telemetry.domain.protocol import Json

if TYPE_CHECKING:
    from telemetry.connection import Connection
    from telemetry.hub import Hub
    from telemetry.services import Access


@dataclass
class ServiceCall:
    """One call to a server service. Handlers return the response ``values`` or raise
    ServiceFailed (or NotAllowed), which the caller receives as ``result: false``."""

    hub: Hub
    conn: Connection
    access: Access
    name: str
    args: Json

    def arg(self, key: str, default: Json = None) -> Json:
        """Return one request field; requests may come as an object or a one-item list."""
        args = self.args[0] if isinstance(self.args, list) and self.args else self.args
        return args.get(key, default) if isinstance(args, dict) else default


ServiceHandler = Callable[[ServiceCall], Awaitable[Json]]


@dataclass(frozen=True)
class ServerService:
    type: str
    handler: ServiceHandler


def server_services() -> dict[str, ServerService]:
    """Return every server service by absolute name."""
    from telemetry import cloud, rosapi

    return {**rosapi.services(), **cloud.services()}
