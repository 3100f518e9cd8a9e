"""Signals the maps app sends about what it did, for apps above it (the event log)."""

from __future__ import annotations

from django.dispatch import Signal

# A robot was sent a sub-map's bundle (not a 304): ``submap`` (SubMap), ``robot`` (its name).
bundle_fetched = Signal()
