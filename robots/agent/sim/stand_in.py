"""The navigation stack both simulated ROS robots stand in with
(``robots.agent.sim.ros_nodes.MoveBaseStandIn``, ``robots.agent.sim.ros2_nodes.Nav2StandIn``):
a localiser that starts from ``/initialpose`` with its covariance and follows odometry and
the laser on ``/map`` (the agent's own AMCL-like particle filter), and the controller of
a goal (the agent's own A* and dynamic window, ``Driver``). It reads ROS messages by
attribute, which both versions share, and answers in plain data; the action servers and
the publishing are each version's own.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from cloudnav_core.messages import laser_scan
from cloudnav_core.se2 import Pose, compose, inverse
from robots.agent.bridge import planar_covariance, pose_of, scan_geometry, set_pose
from robots.agent.navigation.clearance import LocalObstacles
from robots.agent.navigation.driver import Driver
from robots.agent.navigation.legs import Drive
from robots.agent.robot import PoseTracker, particle_filter
from robots.agent.supervisor.submaps import SubMap

PARTICLES = 200
"""The stand-in AMCL's particles after an initial pose."""


class StandInStack:
    """The localiser and the controller of one stand-in (see the module's docstring)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._tracker = PoseTracker(particle_filter(PARTICLES, 0))
        self._placed = False
        self._map: SubMap | None = None
        self._obstacles: LocalObstacles | None = None
        self._velocity: tuple[float, float] | None = None

    # --- localisation ------------------------------------------------------------------

    def on_initial_pose(self, msg: Any) -> None:
        """A ``geometry_msgs/PoseWithCovarianceStamped``: the localiser starts there."""
        covariance = planar_covariance(msg.pose.covariance)
        with self._lock:
            self._tracker.reset(pose_of(msg.pose.pose), covariance, self._tracker.odom)
            self._placed = True

    def on_odom(self, msg: Any) -> tuple[Pose, Pose] | None:
        """A ``nav_msgs/Odometry``: the robot's pose in the map after it and tf ``map ->
        odom``; None until an initial pose has placed it."""
        odom, twist = pose_of(msg.pose.pose), msg.twist.twist
        with self._lock:
            self._velocity = (twist.linear.x, twist.angular.z)
            self._tracker.odometry(odom)
            pose = self._tracker.pose() if self._placed else None
        return None if pose is None else (pose, compose(pose, inverse(odom)))

    def pose(self) -> Pose | None:
        with self._lock:
            return self._tracker.pose() if self._placed else None

    def on_map(self, msg: Any) -> None:
        """A ``nav_msgs/OccupancyGrid``: the map to localise and plan on."""
        info = msg.info
        grid = np.asarray(msg.data, dtype=np.int8).reshape(info.height, info.width)
        submap = SubMap("", "map", "", "", grid, info.resolution, pose_of(info.origin), {}, (), ())
        with self._lock:
            self._map = submap
            self._tracker.set_map(submap)

    def on_scan(self, msg: Any, seconds: float) -> None:
        """A ``sensor_msgs/LaserScan`` stamped ``seconds``: obstacles, and the localiser's
        correction."""
        ranges = np.asarray(msg.ranges, dtype=np.float64)
        angles = msg.angle_min + msg.angle_increment * np.arange(len(ranges))
        self._obstacles = LocalObstacles.from_scan(ranges, angles)
        scan = laser_scan(msg.header.frame_id, ranges.tolist(), seconds, **scan_geometry(msg))
        with self._lock:
            self._tracker.scan(dict(scan))

    # --- control -----------------------------------------------------------------------

    def drive(self, driver: Driver, target: Pose) -> Drive | None:
        """One control step of ``driver`` towards ``target`` (its ``command`` is for
        ``cmd_vel``); None while there is no map, pose, scan or odometry yet."""
        pose, submap, obstacles, velocity = self.pose(), self._map, self._obstacles, self._velocity
        if pose is None or submap is None or obstacles is None or velocity is None:
            return None
        return driver.drive(target, submap, pose, velocity, obstacles, time.monotonic())


def write_plan(msg: Any, driver: Driver, pose_stamped: Any) -> None:
    """A ``nav_msgs/Path`` (its header set) of ``driver``'s plan, each pose a new
    ``pose_stamped`` (the version's ``geometry_msgs/PoseStamped``) under the path's
    header, headings left at 0."""
    for x, y in driver.path:
        stamped = pose_stamped(header=msg.header)
        set_pose(stamped.pose, (x, y, 0.0))
        msg.poses.append(stamped)
