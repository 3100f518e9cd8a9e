"""Velocity commands: ``Command`` (linear m/s, angular rad/s), ``STOP``, and ``clamp``
to a limit either way."""

from __future__ import annotations

Command = tuple[float, float]

STOP: Command = (0.0, 0.0)


def clamp(value: float, limit: float) -> float:
    return max(-limit, min(limit, value))
