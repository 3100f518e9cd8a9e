"""The few message contents the server reads or writes itself."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True, slots=True)
class Pose2D:
    """Where a robot is: its sub-map (Map ID) and its planar pose in that map's frame."""

    map_id: str
    x: float
    y: float
    yaw: float


def yaw_of(q: Mapping[str, Any]) -> float:
    """Return the rotation about z of a quaternion ``{x, y, z, w}``, in radians."""
    x, y, z, w = (float(q.get(k, 0.0) or 0.0) for k in ("x", "y", "z", "w"))
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def pose_of(msg: Mapping[str, Any]) -> Pose2D | None:
    """Return the planar pose in a ``geometry_msgs/PoseStamped``, or None if it has none."""
    try:
        pose = msg["pose"]
        position = pose["position"]
        return Pose2D(
            map_id=str(msg.get("header", {}).get("frame_id", "")),
            x=float(position["x"]),
            y=float(position["y"]),
            yaw=yaw_of(pose.get("orientation", {})),
        )
    except (KeyError, TypeError, ValueError, AttributeError):
        return None


def string_of(msg: Mapping[str, Any]) -> str | None:
    """Return the ``data`` of a ``std_msgs/String``, or None."""
    data = msg.get("data")
    return data if isinstance(data, str) else None


def zero_twist() -> dict[str, dict[str, float]]:
    """Return a ``geometry_msgs/Twist`` that stops the robot."""
    zero = {"x": 0.0, "y": 0.0, "z": 0.0}
    return {"linear": dict(zero), "angular": dict(zero)}
