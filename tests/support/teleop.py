"""Teleop commands as an operator sends them: ``GO`` and the zero Twist ``ZERO``."""

from __future__ import annotations

GO = {"linear": {"x": 0.3, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.1}}
ZERO = {"linear": {"x": 0.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
