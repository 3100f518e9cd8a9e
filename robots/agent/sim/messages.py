"""ROS messages of the simulated sensors as rosbridge JSON (plain dicts).

Conventions (FACTS.md, rosbridge's JSON): times are ``{"sec", "nanosec"}``; ``uint8[]``
fields are base64 text; NaN and infinity cannot be written in JSON and become ``null``.
A ``LaserScan`` range with no return (REP 117's ``+inf``) is therefore ``null``.
"""

from __future__ import annotations

import base64
import math
from collections.abc import Iterable
from typing import Any

Json = dict[str, Any]

NANOS = 1_000_000_000


def ros_time(seconds: float) -> dict[str, int]:
    """``builtin_interfaces/Time`` of ``seconds`` (since the epoch, or a simulated clock)."""
    nanos = round(seconds * NANOS)
    return {"sec": nanos // NANOS, "nanosec": nanos % NANOS}


def header(frame_id: str, seconds: float) -> Json:
    """``std_msgs/Header``."""
    return {"stamp": ros_time(seconds), "frame_id": frame_id}


def quaternion_from_yaw(yaw: float) -> dict[str, float]:
    """``geometry_msgs/Quaternion`` of a rotation by ``yaw`` about z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}


def pose_2d(x: float, y: float, yaw: float) -> Json:
    """``geometry_msgs/Pose`` on the floor plane."""
    return {"position": {"x": x, "y": y, "z": 0.0}, "orientation": quaternion_from_yaw(yaw)}


def twist_2d(linear: float, angular: float) -> Json:
    """``geometry_msgs/Twist`` of a planar robot."""
    return {
        "linear": {"x": linear, "y": 0.0, "z": 0.0},
        "angular": {"x": 0.0, "y": 0.0, "z": angular},
    }


def covariance_6x6(x: float, y: float, yaw: float) -> list[float]:
    """Row-major 6x6 covariance (x, y, z, roll, pitch, yaw) with only planar variances set."""
    values = [0.0] * 36
    values[0], values[7], values[35] = x, y, yaw
    return values


def json_floats(values: Iterable[float]) -> list[float | None]:
    """``values`` as JSON numbers, with NaN and infinities as ``None`` (``null``)."""
    return [float(v) if math.isfinite(v) else None for v in values]


def base64_bytes(data: bytes) -> str:
    """A ``uint8[]`` field as rosbridge writes it."""
    return base64.b64encode(data).decode("ascii")
