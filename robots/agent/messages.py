"""The robot's own ROS messages as rosbridge JSON, and the commands it reads.

Builders extend the simulator's (``robots.agent.sim.messages``: header, poses, twists);
readers return None for a message they cannot use, since a bad command from the network
must never stop the robot's loop. ``telemetry.domain.messages`` (shared with the server)
reads the ``PoseStamped`` of a goal.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from enum import IntEnum
from itertools import pairwise
from typing import Any

import numpy as np

from robots.agent.sim.messages import Json, header, pose_2d, ros_time
from telemetry.domain.messages import Pose2D, pose_of

Pose = tuple[float, float, float]

CANCEL_SERVICE = "cancel_goal"
CANCEL_SERVICE_TYPE = "std_srvs/Trigger"


class GoalStatus(IntEnum):
    """``actionlib_msgs/GoalStatus`` values."""

    PENDING = 0
    ACTIVE = 1
    PREEMPTED = 2
    SUCCEEDED = 3
    ABORTED = 4
    REJECTED = 5
    PREEMPTING = 6
    RECALLING = 7
    RECALLED = 8
    LOST = 9

    @property
    def terminal(self) -> bool:
        """Whether a goal in this state is finished for good."""
        return self in _TERMINAL


_TERMINAL = frozenset(
    {
        GoalStatus.PREEMPTED,
        GoalStatus.SUCCEEDED,
        GoalStatus.ABORTED,
        GoalStatus.REJECTED,
        GoalStatus.RECALLED,
        GoalStatus.LOST,
    }
)


@dataclass(frozen=True)
class StatusEntry:
    """One goal's line in a ``GoalStatusArray``."""

    goal_id: str
    stamp: float
    status: GoalStatus
    text: str = ""


def pose_stamped(frame_id: str, pose: Pose, seconds: float) -> Json:
    """``geometry_msgs/PoseStamped`` of a planar ``pose`` in ``frame_id`` (a Map ID)."""
    return {"header": header(frame_id, seconds), "pose": pose_2d(*pose)}


def path_message(frame_id: str, points: Sequence[tuple[float, float]], seconds: float) -> Json:
    """``nav_msgs/Path`` through ``points``, each pose facing the next point (the last
    keeps its predecessor's heading); an empty path clears the plan."""
    headings = [math.atan2(b[1] - a[1], b[0] - a[0]) for a, b in pairwise(points)]
    if points:
        headings.append(headings[-1] if headings else 0.0)
    poses = zip(points, headings, strict=True)
    return {
        "header": header(frame_id, seconds),
        "poses": [pose_stamped(frame_id, (*p, yaw), seconds) for p, yaw in poses],
    }


def status_array(entries: Iterable[StatusEntry], seconds: float) -> Json:
    """``actionlib_msgs/GoalStatusArray`` of ``entries``."""
    return {
        "header": header("", seconds),
        "status_list": [
            {
                "goal_id": {"stamp": ros_time(e.stamp), "id": e.goal_id},
                "status": int(e.status),
                "text": e.text,
            }
            for e in entries
        ],
    }


def string_message(data: str) -> Json:
    """``std_msgs/String``."""
    return {"data": data}


def twist_of(msg: Mapping[str, Any]) -> tuple[float, float] | None:
    """``(linear.x, angular.z)`` of a ``geometry_msgs/Twist``; None unless both are finite
    numbers (a missing axis counts as 0)."""
    try:
        linear = float(msg.get("linear", {}).get("x", 0.0) or 0.0)
        angular = float(msg.get("angular", {}).get("z", 0.0) or 0.0)
    except (AttributeError, TypeError, ValueError):
        return None
    return (linear, angular) if math.isfinite(linear) and math.isfinite(angular) else None


def goal_of(msg: Mapping[str, Any]) -> Pose2D | None:
    """The target of a goal ``PoseStamped`` (``map_id`` = its frame), or None if the
    message has no usable pose or no frame."""
    pose = pose_of(msg)
    if pose is None or not pose.map_id or not _finite(pose.x, pose.y, pose.yaw):
        return None
    return pose


def initial_pose_of(msg: Mapping[str, Any]) -> tuple[Pose2D, np.ndarray] | None:
    """Pose and 3x3 covariance (x, y, yaw) of a ``PoseWithCovarianceStamped``; a missing
    or unusable covariance becomes a small default. None without a pose and a frame."""
    try:
        inner = msg["pose"]
        pose = goal_of({"header": msg.get("header", {}), "pose": inner["pose"]})
    except (KeyError, TypeError, AttributeError):
        return None
    if pose is None:
        return None
    return pose, _planar_covariance(inner.get("covariance"))


_DEFAULT_COVARIANCE = np.diag([0.25**2, 0.25**2, math.radians(15) ** 2])
"""Used when an initial pose comes without a covariance (rviz sends this order too)."""


def _planar_covariance(values: Any) -> np.ndarray:
    """The (x, y, yaw) block of a row-major 6x6 covariance."""
    try:
        full = np.asarray(values, np.float64).reshape(6, 6)
    except (TypeError, ValueError):
        return _DEFAULT_COVARIANCE.copy()
    planar = full[np.ix_([0, 1, 5], [0, 1, 5])]
    if not np.isfinite(planar).all() or np.any(np.diag(planar) <= 0):
        return _DEFAULT_COVARIANCE.copy()
    return planar


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)
