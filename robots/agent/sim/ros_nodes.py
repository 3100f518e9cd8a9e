"""A simulated ROS 1 robot, as small rospy nodes (``python -m robots.agent.sim.ros_robot``
runs them): the simulator's body, laser and camera as drivers' topics (``RosBody``), and
a minimal navigation stack (``MoveBaseStandIn``): a localiser that takes ``/initialpose``
with its covariance and follows odometry and the laser from there on the latched ``/map``
(the agent's own AMCL-like particle filter), publishing ``amcl_pose`` and tf ``map ->
odom`` as AMCL does, and a ``move_base`` action server that plans on the
latched ``/map`` and drives with the agent's own A* and dynamic window (``Driver``),
publishing its plan on ``/move_base/NavfnROS/plan`` and ``cmd_vel``.

They stand in for a real robot in the ROS bridge's tests and bench: Debian has no
navigation stack (move_base, AMCL, map_server). Call ``robots.agent.ros.ros_path()``
before importing this module, and ``rospy.init_node`` before using it.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

import actionlib  # type: ignore[import-not-found,unused-ignore]
import numpy as np
import rospy  # type: ignore[import-not-found,unused-ignore]
import tf2_ros  # type: ignore[import-not-found,unused-ignore]
from geometry_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    PoseStamped,
    PoseWithCovarianceStamped,
    TransformStamped,
    Twist,
)
from move_base_msgs.msg import MoveBaseAction  # type: ignore[import-not-found,unused-ignore]
from nav_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    OccupancyGrid,
    Odometry,
    Path,
)
from sensor_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    CameraInfo,
    CompressedImage,
    LaserScan,
)

from robots.agent.bridge import yaw_of
from robots.agent.hardware import encode_jpeg
from robots.agent.navigation import Driver, DriveState, LocalObstacles
from robots.agent.perception import CameraModel
from robots.agent.robot import PoseTracker, particle_filter
from robots.agent.sim.hardware import SimHardware
from robots.agent.supervisor import SubMap
from robots.domain.se2 import Pose, compose, inverse
from telemetry.domain.messages import laser_scan

CAMERA_EVERY = 2
"""Body steps between camera frames (5 Hz at the 10 Hz step)."""
CONTROL_RATE = 10.0
"""Hz of the move_base stand-in's controller."""
PARTICLES = 200
"""The stand-in AMCL's particles after an initial pose."""


# --- the robot's drivers -------------------------------------------------------------


class RosBody:
    """``hardware`` on ROS topics: ``cmd_vel`` in; ``odom`` (and tf ``odom ->
    base_footprint``), ``scan`` and ``camera/image/compressed`` (with
    ``camera/camera_info``, as a camera driver sends its calibration) out."""

    def __init__(self, hardware: SimHardware) -> None:
        self.hardware = hardware
        self._odom = rospy.Publisher("odom", Odometry, queue_size=1)
        self._scan = rospy.Publisher("scan", LaserScan, queue_size=1)
        self._camera = rospy.Publisher("camera/image/compressed", CompressedImage, queue_size=1)
        self._camera_info = rospy.Publisher("camera/camera_info", CameraInfo, queue_size=1)
        self._tf = tf2_ros.TransformBroadcaster()
        self._commands: list[tuple[float, float]] = []
        rospy.Subscriber("cmd_vel", Twist, self._on_cmd_vel, queue_size=1)

    def _on_cmd_vel(self, msg: Any) -> None:
        self._commands.append((msg.linear.x, msg.angular.z))  # obeyed at the next step

    def step(self, seconds: float, ticks: int) -> None:
        """Obey the commands that came, advance ``seconds``, publish what is due."""
        while self._commands:
            self.hardware.command(*self._commands.pop(0))
        self.hardware.advance(seconds)
        stamp = rospy.Time.now()
        self._publish_odometry(stamp)
        self._publish_scan(stamp)
        if ticks % CAMERA_EVERY == 0:
            self._publish_image(stamp)

    def _publish_odometry(self, stamp: Any) -> None:
        msg = Odometry()
        msg.header.stamp, msg.header.frame_id = stamp, "odom"
        msg.child_frame_id = "base_footprint"
        msg.pose.pose = ros_pose(self.hardware.odom_pose)
        linear, angular = self.hardware.reported_velocity
        msg.twist.twist.linear.x, msg.twist.twist.angular.z = linear, angular
        self._odom.publish(msg)
        self._tf.sendTransform(transform(msg.header, "base_footprint", self.hardware.odom_pose))

    def _publish_scan(self, stamp: Any) -> None:
        spec = self.hardware.laser.spec
        msg = LaserScan()
        msg.header.stamp, msg.header.frame_id = stamp, "base_scan"
        msg.angle_min, msg.angle_max = spec.angle_min, spec.angle_max
        msg.angle_increment, msg.scan_time = spec.angle_increment, spec.scan_time
        msg.time_increment = spec.scan_time / spec.beams
        msg.range_min, msg.range_max = spec.range_min, spec.range_max
        msg.ranges = self.hardware.scan().tolist()
        self._scan.publish(msg)

    def _publish_image(self, stamp: Any) -> None:
        msg = CompressedImage()
        msg.header.stamp, msg.header.frame_id = stamp, "camera_optical_frame"
        msg.format, msg.data = "jpeg", encode_jpeg(self.hardware.image(), 90)
        self._camera.publish(msg)
        self._camera_info.publish(camera_info(msg.header, self.hardware.camera_model))


def camera_info(header: Any, model: CameraModel) -> Any:
    """The ``sensor_msgs/CameraInfo`` of ``model``: a pinhole camera, no distortion."""
    msg = CameraInfo()
    msg.header, msg.width, msg.height = header, model.width, model.height
    msg.distortion_model, msg.D = "plumb_bob", [0.0] * 5
    msg.K = [model.fx, 0.0, model.cx, 0.0, model.fy, model.cy, 0.0, 0.0, 1.0]
    msg.R = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    msg.P = [model.fx, 0.0, model.cx, 0.0, 0.0, model.fy, model.cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return msg


def ros_pose(pose: Pose) -> Any:
    """A ``geometry_msgs/Pose`` of an SE(2) pose."""
    msg = PoseStamped().pose
    msg.position.x, msg.position.y = pose[0], pose[1]
    msg.orientation.z, msg.orientation.w = math.sin(pose[2] / 2), math.cos(pose[2] / 2)
    return msg


def transform(header: Any, child: str, pose: Pose) -> Any:
    """tf ``header.frame_id -> child`` of ``pose``."""
    msg = TransformStamped()
    msg.header, msg.child_frame_id = header, child
    msg.transform.translation.x, msg.transform.translation.y = pose[0], pose[1]
    msg.transform.rotation = ros_pose(pose).orientation
    return msg


def pose_of(msg: Any) -> Pose:
    """The SE(2) pose of a ``geometry_msgs/Pose``."""
    return (msg.position.x, msg.position.y, yaw_of(msg.orientation))


# --- a minimal navigation stack --------------------------------------------------------


class MoveBaseStandIn:
    """The localiser and the ``move_base`` action server (see the module's docstring).

    ``goals`` lists every goal received, ``initial_poses`` every ``/initialpose``, and
    ``maps`` every ``/map``, for tests."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.goals: list[Any] = []
        self.initial_poses: list[Any] = []
        self.maps: list[Any] = []
        self._odom: Odometry | None = None
        self._tracker = PoseTracker(particle_filter(PARTICLES, 0))
        self._placed = False
        self._map: SubMap | None = None
        self._obstacles: LocalObstacles | None = None
        self._cmd_vel = rospy.Publisher("cmd_vel", Twist, queue_size=1)
        self._pose = rospy.Publisher("amcl_pose", PoseWithCovarianceStamped, queue_size=1)
        self._plan = rospy.Publisher("/move_base/NavfnROS/plan", Path, queue_size=1)
        self._tf = tf2_ros.TransformBroadcaster()
        rospy.Subscriber("/initialpose", PoseWithCovarianceStamped, self._on_initial_pose)
        rospy.Subscriber("/map", OccupancyGrid, self._on_map, queue_size=1)
        rospy.Subscriber("odom", Odometry, self._on_odom, queue_size=1)
        rospy.Subscriber("scan", LaserScan, self._on_scan, queue_size=1)
        self.server = actionlib.SimpleActionServer(
            "move_base", MoveBaseAction, self._execute, auto_start=False
        )
        self.server.start()

    # --- localisation ------------------------------------------------------------------

    def _on_initial_pose(self, msg: Any) -> None:
        full = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)
        covariance = full[np.ix_((0, 1, 5), (0, 1, 5))]
        with self._lock:
            self.initial_poses.append(msg)
            tracker = self._tracker
            tracker.reset(pose_of(msg.pose.pose), covariance, tracker.odom)
            self._placed = True

    def _on_odom(self, msg: Any) -> None:
        odom = pose_of(msg.pose.pose)
        with self._lock:
            self._odom = msg
            self._tracker.odometry(odom)
            pose = self._tracker.pose() if self._placed else None
        if pose is None:
            return
        estimate = PoseWithCovarianceStamped()
        estimate.header.stamp, estimate.header.frame_id = rospy.Time.now(), "map"
        estimate.pose.pose = ros_pose(pose)
        self._pose.publish(estimate)
        self._tf.sendTransform(transform(estimate.header, "odom", compose(pose, inverse(odom))))

    def pose(self) -> Pose | None:
        with self._lock:
            return self._tracker.pose() if self._placed else None

    def _on_map(self, msg: Any) -> None:
        info = msg.info
        grid = np.asarray(msg.data, dtype=np.int8).reshape(info.height, info.width)
        origin = pose_of(info.origin)
        submap = SubMap("", "map", "", "", grid, info.resolution, origin, {}, (), ())
        with self._lock:
            self.maps.append(msg)
            self._map = submap
            self._tracker.set_map(submap)

    def _on_scan(self, msg: Any) -> None:
        ranges = np.asarray(msg.ranges, dtype=np.float64)
        angles = msg.angle_min + msg.angle_increment * np.arange(len(ranges))
        self._obstacles = LocalObstacles.from_scan(ranges, angles)
        scan = laser_scan(
            msg.header.frame_id,
            ranges.tolist(),
            msg.header.stamp.to_sec(),
            angle_min=msg.angle_min,
            angle_max=msg.angle_max,
            angle_increment=msg.angle_increment,
            time_increment=msg.time_increment,
            scan_time=msg.scan_time,
            range_min=msg.range_min,
            range_max=msg.range_max,
        )
        with self._lock:
            self._tracker.scan(dict(scan))

    # --- move_base ---------------------------------------------------------------------

    def _execute(self, goal: Any) -> None:
        """Drive to ``goal`` until there, preempted, failed or shut down."""
        with self._lock:
            self.goals.append(goal)
        target = pose_of(goal.target_pose.pose)
        rospy.loginfo("move_base: goal (%.2f, %.2f, %.2f) from %s", *target, self.pose())
        driver, published = Driver(), 0
        rate = rospy.Rate(CONTROL_RATE)
        while not rospy.is_shutdown():
            if self.server.is_preempt_requested():
                self._stop()
                self.server.set_preempted()
                return
            drive = self._drive(driver, target)
            if driver.plan_version != published:
                published = driver.plan_version
                self._publish_plan(driver)
            if drive is not None and drive.state is not DriveState.MOVING:
                rospy.loginfo(
                    "move_base: %s at %s %s", drive.state.value, self.pose(), drive.reason
                )
                self._stop()
                if drive.state is DriveState.ARRIVED:
                    self.server.set_succeeded()
                else:
                    self.server.set_aborted(text=drive.reason)
                return
            rate.sleep()

    def _drive(self, driver: Driver, target: Pose) -> Any:
        """One control step; None while there is no map, pose or scan yet."""
        pose, submap, obstacles, odom = self.pose(), self._map, self._obstacles, self._odom
        if pose is None or submap is None or obstacles is None or odom is None:
            return None
        twist = odom.twist.twist
        velocity = (twist.linear.x, twist.angular.z)
        drive = driver.drive(target, submap, pose, velocity, obstacles, time.monotonic())
        if drive.command is not None:
            command = Twist()
            command.linear.x, command.angular.z = drive.command
            self._cmd_vel.publish(command)
        return drive

    def _stop(self) -> None:
        self._cmd_vel.publish(Twist())

    def _publish_plan(self, driver: Driver) -> None:
        msg = Path()
        msg.header.stamp, msg.header.frame_id = rospy.Time.now(), "map"
        for x, y in driver.path:
            stamped = PoseStamped()
            stamped.header = msg.header
            stamped.pose = ros_pose((x, y, 0.0))
            msg.poses.append(stamped)
        self._plan.publish(msg)
