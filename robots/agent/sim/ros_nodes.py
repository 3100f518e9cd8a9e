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
before importing this module, and ``rospy.init_node`` before using it. What is no rospy
call is shared with the ROS 2 simulated robot (``robots.agent.sim.drivers``,
``robots.agent.sim.stand_in``).
"""

from __future__ import annotations

import threading
from typing import Any

import actionlib  # type: ignore[import-not-found,unused-ignore]
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

from cloudnav_core.se2 import Pose
from robots.agent.bridge import pose_of, set_pose
from robots.agent.navigation.driver import Driver
from robots.agent.navigation.legs import DriveState
from robots.agent.perception import pinhole_calibration
from robots.agent.sim.drivers import (
    BASE_FRAME,
    CAMERA_FRAME,
    LASER_FRAME,
    SimDrivers,
    jpeg_fields,
    scan_fields,
    transform,
    write_odometry,
)
from robots.agent.sim.hardware import SimHardware
from robots.agent.sim.stand_in import StandInStack, write_plan

CONTROL_RATE = 10.0
"""Hz of the move_base stand-in's controller."""


# --- the robot's drivers -------------------------------------------------------------


class RosBody(SimDrivers):
    """``hardware`` on ROS topics: ``cmd_vel`` in; ``odom`` (and tf ``odom ->
    base_footprint``), ``scan`` and ``camera/image/compressed`` (with
    ``camera/camera_info``, as a camera driver sends its calibration) out."""

    def __init__(self, hardware: SimHardware) -> None:
        super().__init__(hardware)
        self._odom = rospy.Publisher("odom", Odometry, queue_size=1)
        self._scan = rospy.Publisher("scan", LaserScan, queue_size=1)
        self._camera = rospy.Publisher("camera/image/compressed", CompressedImage, queue_size=1)
        self._camera_info = rospy.Publisher("camera/camera_info", CameraInfo, queue_size=1)
        self._tf = tf2_ros.TransformBroadcaster()
        rospy.Subscriber("cmd_vel", Twist, self._on_cmd_vel, queue_size=1)

    def _on_cmd_vel(self, msg: Any) -> None:
        self.command(msg.linear.x, msg.angular.z)

    def publish(self, camera: bool) -> None:
        stamp = rospy.Time.now()
        odom = Odometry()
        odom.header.stamp = stamp
        write_odometry(odom, self.hardware)
        self._odom.publish(odom)
        moved = transform(TransformStamped(), odom.header, BASE_FRAME, self.hardware.odom_pose)
        self._tf.sendTransform(moved)
        scan = LaserScan(**scan_fields(self.hardware))
        scan.header.stamp, scan.header.frame_id = stamp, LASER_FRAME
        self._scan.publish(scan)
        if camera:
            image = CompressedImage(**jpeg_fields(self.hardware))
            image.header.stamp, image.header.frame_id = stamp, CAMERA_FRAME
            self._camera.publish(image)
            calibration = pinhole_calibration(self.hardware.camera_model)
            self._camera_info.publish(CameraInfo(header=image.header, **calibration))


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
        self.stack = StandInStack()
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
        with self._lock:
            self.initial_poses.append(msg)
        self.stack.on_initial_pose(msg)

    def _on_odom(self, msg: Any) -> None:
        localised = self.stack.on_odom(msg)
        if localised is None:
            return
        pose, map_to_odom = localised
        estimate = PoseWithCovarianceStamped()
        estimate.header.stamp, estimate.header.frame_id = rospy.Time.now(), "map"
        set_pose(estimate.pose.pose, pose)
        self._pose.publish(estimate)
        self._tf.sendTransform(transform(TransformStamped(), estimate.header, "odom", map_to_odom))

    def _on_map(self, msg: Any) -> None:
        with self._lock:
            self.maps.append(msg)
        self.stack.on_map(msg)

    def _on_scan(self, msg: Any) -> None:
        self.stack.on_scan(msg, msg.header.stamp.to_sec())

    # --- move_base ---------------------------------------------------------------------

    def _execute(self, goal: Any) -> None:
        """Drive to ``goal`` until there, preempted, failed or shut down."""
        with self._lock:
            self.goals.append(goal)
        target = pose_of(goal.target_pose.pose)
        rospy.loginfo("move_base: goal (%.2f, %.2f, %.2f) from %s", *target, self.stack.pose())
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
                    "move_base: %s at %s %s", drive.state.value, self.stack.pose(), drive.reason
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
        drive = self.stack.drive(driver, target)
        if drive is not None and drive.command is not None:
            command = Twist()
            command.linear.x, command.angular.z = drive.command
            self._cmd_vel.publish(command)
        return drive

    def _stop(self) -> None:
        self._cmd_vel.publish(Twist())

    def _publish_plan(self, driver: Driver) -> None:
        msg = Path()
        msg.header.stamp, msg.header.frame_id = rospy.Time.now(), "map"
        write_plan(msg, driver, PoseStamped)
        self._plan.publish(msg)
