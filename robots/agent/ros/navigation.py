"""A ROS 1 navigation stack fed by the Maps Supervisor (``NavigationStack``): the sub-map
on the latched ``/map`` (and, where a map server's ``nav_msgs/LoadMap`` service is
configured, in map_server files it is asked to load), the tag's pose on ``/initialpose``,
goals as ``move_base`` action goals (actionlib); the pose from AMCL's ``amcl_pose`` or
from tf (``map -> base_footprint``), the global planner's plan from its topic. Call
``robots.agent.ros.ros_path()`` and ``rospy.init_node`` first."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import actionlib  # type: ignore[import-not-found,unused-ignore]
import numpy as np
import rospy  # type: ignore[import-not-found,unused-ignore]
from actionlib_msgs.msg import GoalStatus  # type: ignore[import-not-found,unused-ignore]
from geometry_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    PoseWithCovarianceStamped,
)
from move_base_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    MoveBaseAction,
    MoveBaseGoal,
)
from nav_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    OccupancyGrid,
)
from nav_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    Path as RosPath,
)
from nav_msgs.srv import LoadMap  # type: ignore[import-not-found,unused-ignore]
from numpy.typing import NDArray

from cloudnav_core.se2 import Point, Pose
from robots.agent.bridge import (
    StackReadings,
    load_map_files,
    plan_of,
    pose_of,
    pose_of_transform,
    set_pose,
    write_grid_info,
    write_initial_pose,
)
from robots.agent.hardware import StackGoal

logger = logging.getLogger(__name__)

STATES = {
    GoalStatus.PENDING: StackGoal.ACTIVE,
    GoalStatus.ACTIVE: StackGoal.ACTIVE,
    GoalStatus.PREEMPTING: StackGoal.ACTIVE,
    GoalStatus.RECALLING: StackGoal.ACTIVE,
    GoalStatus.SUCCEEDED: StackGoal.SUCCEEDED,
    GoalStatus.ABORTED: StackGoal.FAILED,
    GoalStatus.REJECTED: StackGoal.FAILED,
    GoalStatus.LOST: StackGoal.FAILED,
    GoalStatus.PREEMPTED: StackGoal.NONE,
    GoalStatus.RECALLED: StackGoal.NONE,
}
"""actionlib's statuses as the Maps Supervisor's driver needs them."""


class RosNavigationStack:
    """``/map`` (latched), ``/initialpose`` and the ``move_base`` action of one robot; the
    frame of every pose is ``frame`` (the map frame ``/map`` is published in).

    ``pose_source`` is ``amcl_pose`` (or any ``PoseWithCovarianceStamped`` topic) or
    ``tf`` (``frame -> base_frame``); ``plan_topic`` the global planner's ``nav_msgs/Path``;
    ``load_map`` a ``nav_msgs/LoadMap`` service (map_server's ``change_map``), whose map
    files are written under ``map_dir``, or None."""

    def __init__(
        self,
        frame: str = "map",
        map_topic: str = "/map",
        initial_pose_topic: str = "/initialpose",
        action: str = "move_base",
        pose_source: str = "amcl_pose",
        base_frame: str = "base_footprint",
        plan_topic: str = "/move_base/NavfnROS/plan",
        load_map: str | None = None,
        map_dir: Path | None = None,
    ) -> None:
        self.frame, self.base_frame = frame, base_frame
        self.readings = StackReadings()
        self._map = rospy.Publisher(map_topic, OccupancyGrid, queue_size=1, latch=True)
        self._initial = rospy.Publisher(
            initial_pose_topic, PoseWithCovarianceStamped, queue_size=1, latch=True
        )
        self._move_base = actionlib.SimpleActionClient(action, MoveBaseAction)
        self._goal_sent = False
        self._tf: Any = None
        if pose_source == "tf":
            import tf2_ros  # type: ignore[import-not-found,unused-ignore]

            self._tf = tf2_ros.Buffer()
            self._tf_listener = tf2_ros.TransformListener(self._tf)
        else:
            rospy.Subscriber(pose_source, PoseWithCovarianceStamped, self._on_pose, queue_size=1)
        rospy.Subscriber(plan_topic, RosPath, self._on_plan, queue_size=1)
        self._load_map = rospy.ServiceProxy(load_map, LoadMap) if load_map else None
        self._map_dir = map_dir

    def set_map(self, map_id: str, grid: Any, resolution: float, origin: Pose) -> None:
        cells = np.asarray(grid, dtype=np.int8)
        msg = OccupancyGrid()
        msg.header.stamp, msg.header.frame_id = rospy.Time.now(), self.frame
        msg.info.map_load_time = msg.header.stamp
        write_grid_info(msg, cells, resolution, origin)
        msg.data = cells.ravel().tolist()
        self.readings.map_id = map_id
        self._map.publish(msg)
        ask = None if self._load_map is None else self._ask_map_server
        load_map_files(ask, self._map_dir, map_id, cells, resolution, origin)

    @property
    def map_id(self) -> str | None:
        return self.readings.map_id

    def _ask_map_server(self, url: str) -> None:
        """Call the ``LoadMap`` service (off the control loop); failures are logged."""
        assert self._load_map is not None
        try:
            self._load_map.wait_for_service(10.0)
            answer = self._load_map(url)
        except (rospy.ROSException, rospy.ServiceException) as error:
            logger.warning("load_map %s: %s", url, error)
            return
        if answer.result != 0:  # LoadMap.RESULT_SUCCESS
            logger.warning("load_map %s: the map server answered %d", url, answer.result)

    def set_initial_pose(self, map_id: str, pose: Pose, covariance: NDArray[np.float64]) -> None:
        """Raises ValueError unless ``map_id`` is the sub-map on ``/map``."""
        self.readings.held(map_id)
        msg = PoseWithCovarianceStamped()
        msg.header.stamp, msg.header.frame_id = rospy.Time.now(), self.frame
        write_initial_pose(msg, pose, covariance)
        self.readings.placed(msg.header.stamp.to_sec())
        self._initial.publish(msg)

    def send_goal(self, map_id: str, pose: Pose) -> None:
        """Raises ValueError unless ``map_id`` is the sub-map on ``/map``."""
        self.readings.held(map_id)
        goal = MoveBaseGoal()
        goal.target_pose.header.stamp = rospy.Time.now()
        goal.target_pose.header.frame_id = self.frame
        set_pose(goal.target_pose.pose, pose)
        self._move_base.send_goal(goal)
        self._goal_sent = True

    def cancel(self) -> None:
        self._move_base.cancel_all_goals()

    def goal_state(self) -> StackGoal:
        if not self._goal_sent:
            return StackGoal.NONE
        return STATES.get(self.state(), StackGoal.FAILED)

    def pose(self) -> Pose | None:
        """The pose source's latest pose, if stamped after the last initial pose."""
        if self._tf is not None:
            self._pose_from_tf()
        return self.readings.pose()

    def progress(self) -> str:
        """Nothing: move_base's feedback is its pose, which the pose source gives."""
        return ""

    def _on_pose(self, msg: Any) -> None:
        self.readings.on_pose(msg.header.stamp.to_sec(), pose_of(msg.pose.pose))

    def _pose_from_tf(self) -> None:
        import tf2_ros  # type: ignore[import-not-found,unused-ignore]

        try:
            seen = self._tf.lookup_transform(self.frame, self.base_frame, rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ExtrapolationException,
                tf2_ros.ConnectivityException):  # fmt: skip
            return
        self.readings.on_pose(seen.header.stamp.to_sec(), pose_of_transform(seen.transform))

    def plan(self) -> tuple[int, Sequence[Point]]:
        return self.readings.plan()

    def _on_plan(self, msg: Any) -> None:
        self.readings.on_plan(plan_of(msg))

    def map_subscribers(self) -> int:
        """How many subscribers ``/map`` has connected."""
        return int(self._map.get_num_connections())

    def wait_for_server(self, seconds: float) -> bool:
        return bool(self._move_base.wait_for_server(rospy.Duration(seconds)))

    def state(self) -> int:
        """The active goal's actionlib status (``actionlib_msgs/GoalStatus``)."""
        return int(self._move_base.get_state())
