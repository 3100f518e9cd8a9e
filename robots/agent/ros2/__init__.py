"""The ROS 2 backend of the hardware seam (``robots.agent.hardware``), on stock rclpy: the
same code runs on Humble, Jazzy and Kilted (it uses the rclpy API alone), with Nav2's
``NavigateToPose`` action and ``LoadMap`` service (``nav2_msgs``).

On a robot, source its ROS 2 setup (or, here, use the virtualenv ``scripts/ros2_env.sh``
builds from the pinned wheels) and run ``python -m robots.agent.ros2``. Everything that is
no ROS call is shared with the ROS 1 backend (``robots.agent.bridge``).
"""

from __future__ import annotations


def stamp_seconds(stamp: object) -> float:
    """Seconds of a ``builtin_interfaces/Time``."""
    return float(stamp.sec) + float(stamp.nanosec) * 1e-9  # type: ignore[attr-defined]
