"""Which services the server answers itself: rosapi's and the cloud's, by absolute name."""

from __future__ import annotations

from telemetry import cloud, rosapi
from telemetry.server_services import ServerService


def server_services() -> dict[str, ServerService]:
    """Return every server service by absolute name."""
    return {**rosapi.services(), **cloud.services()}
