"""Telemetry keeps no rows of its own yet: the topic bus lives in memory and the channel layer."""
