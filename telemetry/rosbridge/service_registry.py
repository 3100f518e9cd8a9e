"""Which services the server answers itself: rosapi's and the cloud's, by absolute name."""

from __future__ import annotations

from telemetry.rosbridge import cloud, rosapi
from telemetry.rosbridge.server_services import ServerService


def server_services() -> dict[str, ServerService]:
    """Return every server service by absolute name."""
    return {**rosapi.services(), **cloud.services()}
