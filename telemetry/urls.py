"""HTTP routes of telemetry: video relays and statistics (added as they are built)."""

from __future__ import annotations

from django.urls import URLPattern

urlpatterns: list[URLPattern] = []
