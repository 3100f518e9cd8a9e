"""A ROS 1 navigation stack fed by the Maps Supervisor (``NavigationStack``): the sub-map
on the latched ``/map``, the tag's pose on ``/initialpose`` and goals as ``move_base``
action goals (actionlib). Call ``robots.agent.ros.ros_path()`` and ``rospy.init_node``
first."""

from __future__ import annotations

import math
from typing import Any

import actionlib  # type: ignore[import-not-found,unused-ignore]
import numpy as np
import rospy  # type: ignore[import-not-found,unused-ignore]
from geometry_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    PoseWithCovarianceStamped,
    Quaternion,
)
from move_base_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    MoveBaseAction,
    MoveBaseGoal,
)
from nav_msgs.msg import OccupancyGrid  # type: ignore[import-not-found,unused-ignore]
from numpy.typing import NDArray

from robots.domain.se2 import Pose


def quaternion(yaw: float) -> Any:
    return Quaternion(0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


class RosNavigationStack:
    """``/map`` (latched), ``/initialpose`` and the ``move_base`` action of one robot; the
    frame of every pose is ``frame`` (the map frame ``/map`` is published in)."""

    def __init__(
        self, frame: str = "map", map_topic: str = "/map", action: str = "move_base"
    ) -> None:
        self.frame = frame
        self.map_id: str | None = None
        self._map = rospy.Publisher(map_topic, OccupancyGrid, queue_size=1, latch=True)
        self._initial = rospy.Publisher(
            "/initialpose", PoseWithCovarianceStamped, queue_size=1, latch=True
        )
        self._move_base = actionlib.SimpleActionClient(action, MoveBaseAction)

    def set_map(self, map_id: str, grid: Any, resolution: float, origin: Pose) -> None:
        cells = np.asarray(grid, dtype=np.int8)
        msg = OccupancyGrid()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self.frame
        msg.info.map_load_time = msg.header.stamp
        msg.info.resolution = float(resolution)
        msg.info.height, msg.info.width = (int(n) for n in cells.shape)
        msg.info.origin.position.x, msg.info.origin.position.y = origin[0], origin[1]
        msg.info.origin.orientation = quaternion(origin[2])
        msg.data = cells.ravel().tolist()
        self.map_id = map_id
        self._map.publish(msg)

    def _held(self, map_id: str) -> None:
        if map_id != self.map_id:
            raise ValueError(f"{map_id} is not the map on /map ({self.map_id})")

    def set_initial_pose(self, map_id: str, pose: Pose, covariance: NDArray[np.float64]) -> None:
        """Raises ValueError unless ``map_id`` is the sub-map on ``/map``."""
        self._held(map_id)
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self.frame
        msg.pose.pose.position.x, msg.pose.pose.position.y = pose[0], pose[1]
        msg.pose.pose.orientation = quaternion(pose[2])
        full = np.zeros((6, 6))
        small = np.asarray(covariance, dtype=np.float64).reshape(3, 3)
        index = (0, 1, 5)  # x, y, yaw of ROS's (x, y, z, roll, pitch, yaw)
        for i, row in enumerate(index):
            for j, column in enumerate(index):
                full[row, column] = small[i, j]
        msg.pose.covariance = full.ravel().tolist()
        self._initial.publish(msg)

    def send_goal(self, map_id: str, pose: Pose) -> None:
        """Raises ValueError unless ``map_id`` is the sub-map on ``/map``."""
        self._held(map_id)
        goal = MoveBaseGoal()
        goal.target_pose.header.stamp = rospy.Time.now()
        goal.target_pose.header.frame_id = self.frame
        goal.target_pose.pose.position.x, goal.target_pose.pose.position.y = pose[0], pose[1]
        goal.target_pose.pose.orientation = quaternion(pose[2])
        self._move_base.send_goal(goal)

    def cancel(self) -> None:
        self._move_base.cancel_all_goals()

    def map_subscribers(self) -> int:
        """How many subscribers ``/map`` has connected."""
        return int(self._map.get_num_connections())

    def wait_for_server(self, seconds: float) -> bool:
        return bool(self._move_base.wait_for_server(rospy.Duration(seconds)))

    def state(self) -> int:
        """The active goal's actionlib status (``actionlib_msgs/GoalStatus``)."""
        return int(self._move_base.get_state())
