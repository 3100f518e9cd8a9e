from __future__ import annotations

from django.apps import AppConfig


class TelemetryConfig(AppConfig):
    name = "telemetry"

    def ready(self) -> None:
        from telemetry import map_events
        from telemetry.access import revocation

        revocation.connect_signals()
        map_events.connect_signals()
