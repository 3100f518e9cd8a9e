"""A ROS 1 robot as the software's ``Hardware``: ``nav_msgs/Odometry`` on ``odom``,
``sensor_msgs/LaserScan`` on ``scan``, ``sensor_msgs/CompressedImage`` on the camera's
topic (with its ``sensor_msgs/CameraInfo`` on ``camera_info``, if any), ``geometry_msgs/Twist``
on ``cmd_vel``. Call ``robots.agent.ros.ros_path()`` and
``rospy.init_node`` first; ``RosHardware`` waits for the first odometry and scan."""

from __future__ import annotations

import math
import threading
from dataclasses import replace
from typing import Any

import cv2
import numpy as np
import rospy  # type: ignore[import-not-found,unused-ignore]
from geometry_msgs.msg import Twist  # type: ignore[import-not-found,unused-ignore]
from nav_msgs.msg import Odometry as RosOdometry  # type: ignore[import-not-found,unused-ignore]
from numpy.typing import NDArray
from sensor_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    BatteryState,
    CameraInfo,
    CompressedImage,
    LaserScan,
)

from robots.agent.perception import CameraModel
from robots.domain.se2 import Pose
from telemetry.domain.messages import Json, Odometry, laser_scan, odometry


def yaw_of(orientation: Any) -> float:
    q = orientation
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


class RosBattery:
    """The latest ``sensor_msgs/BatteryState`` of the robot's battery topic. Until the
    first arrives it reads full at 0 V (a robot without one never says otherwise)."""

    def __init__(self) -> None:
        self.charge = 1.0
        self.voltage = 0.0

    def on_state(self, msg: Any) -> None:
        if math.isfinite(msg.percentage):
            self.charge = min(1.0, max(0.0, float(msg.percentage)))
        if math.isfinite(msg.voltage):
            self.voltage = float(msg.voltage)


def calibrated_camera(topic: str, wait: float) -> CameraModel:
    """The default camera with the intrinsics of the first ``CameraInfo`` on ``topic``
    within ``wait`` seconds; as it is if none comes or it is uncalibrated (K all zero)."""
    try:
        info: Any = rospy.wait_for_message(topic, CameraInfo, wait)
    except rospy.ROSException:
        return CameraModel()
    return camera_model_of(info)


def camera_model_of(info: Any, mounting: CameraModel | None = None) -> CameraModel:
    """``mounting`` (the default camera) with the size and K matrix of ``info``, a
    ``sensor_msgs/CameraInfo``; as it is if ``info`` is uncalibrated."""
    mounting = mounting or CameraModel()
    k = [float(value) for value in info.K]
    if k[0] <= 0 or k[4] <= 0:
        return mounting
    width, height = int(info.width), int(info.height)
    return replace(mounting, width=width, height=height, fx=k[0], fy=k[4], cx=k[2], cy=k[5])


class RosHardware:
    """The latest odometry, scan and camera frame of a ROS 1 robot, and its ``cmd_vel``.
    ``camera_model`` is the camera's intrinsics and mounting: unless given, the intrinsics
    of the ``CameraInfo`` the camera publishes within ``calibration_wait`` seconds (its K
    matrix and size), else the default robot's, with the default robot's mounting."""

    def __init__(
        self,
        camera_model: CameraModel | None = None,
        odom: str = "odom",
        scan: str = "scan",
        camera: str = "camera/image/compressed",
        cmd_vel: str = "cmd_vel",
        battery: str = "battery_state",
        camera_info: str = "camera/camera_info",
        timeout: float = 30.0,
        calibration_wait: float = 2.0,
    ) -> None:
        self.camera_model = camera_model or calibrated_camera(camera_info, calibration_wait)
        self.battery = RosBattery()
        rospy.Subscriber(battery, BatteryState, self.battery.on_state, queue_size=1)
        self._lock = threading.Lock()
        self._image: NDArray[np.uint8] | None = None
        self._cmd_vel = rospy.Publisher(cmd_vel, Twist, queue_size=1)
        rospy.Subscriber(odom, RosOdometry, self._on_odom, queue_size=1)
        rospy.Subscriber(scan, LaserScan, self._on_scan, queue_size=1)
        rospy.Subscriber(camera, CompressedImage, self._on_image, queue_size=1, buff_size=2**22)
        self._odom: Any = rospy.wait_for_message(odom, RosOdometry, timeout)
        self._scan: Any = rospy.wait_for_message(scan, LaserScan, timeout)
        spec = self._scan
        self.scan_angles = spec.angle_min + spec.angle_increment * np.arange(len(spec.ranges))

    def _on_odom(self, msg: Any) -> None:
        with self._lock:
            self._odom = msg

    def _on_scan(self, msg: Any) -> None:
        with self._lock:
            self._scan = msg

    def _on_image(self, msg: Any) -> None:
        # Decoded here, off the control loop; a frame that does not decode is dropped.
        image = cv2.imdecode(np.frombuffer(msg.data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
        if image is not None:
            with self._lock:
                self._image = np.asarray(image, dtype=np.uint8)

    @property
    def odom_pose(self) -> Pose:
        with self._lock:
            pose = self._odom.pose.pose
        return (pose.position.x, pose.position.y, yaw_of(pose.orientation))

    @property
    def reported_velocity(self) -> tuple[float, float]:
        with self._lock:
            twist = self._odom.twist.twist
        return (twist.linear.x, twist.angular.z)

    def advance(self, seconds: float) -> None:
        """Nothing to do: the robot's clock is the wall clock, which ``Robot.run`` paces
        (and the drivers' callbacks keep the latest data fresh meanwhile)."""

    def command(self, linear: float, angular: float) -> None:
        twist = Twist()
        twist.linear.x, twist.angular.z = float(linear), float(angular)
        self._cmd_vel.publish(twist)

    def scan(self) -> NDArray[np.float32]:
        with self._lock:
            ranges = self._scan.ranges
        return np.asarray(ranges, dtype=np.float32)

    def scan_message(self, ranges: NDArray[np.float32], seconds: float) -> Json:
        with self._lock:
            spec = self._scan
        return dict(
            laser_scan(
                spec.header.frame_id,
                ranges.tolist(),
                seconds,
                angle_min=spec.angle_min,
                angle_max=spec.angle_max,
                angle_increment=spec.angle_increment,
                time_increment=spec.time_increment,
                scan_time=spec.scan_time,
                range_min=spec.range_min,
                range_max=spec.range_max,
            )
        )

    def odometry_message(self, seconds: float) -> Odometry:
        with self._lock:
            msg = self._odom
        covariance = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)
        twist_covariance = np.asarray(msg.twist.covariance, dtype=np.float64).reshape(6, 6)
        index = [0, 1, 5]  # x, y, yaw of ROS's (x, y, z, roll, pitch, yaw)
        return odometry(
            msg.header.frame_id or "odom",
            msg.child_frame_id or "base_footprint",
            seconds,
            pose=self.odom_pose,
            pose_covariance=covariance[np.ix_(index, index)],
            velocity=self.reported_velocity,
            velocity_covariance=twist_covariance[np.ix_(index, index)],
        )

    def image_and_depth(self) -> tuple[NDArray[np.uint8], NDArray[np.float32] | None]:
        """No depth camera: the frame alone."""
        return self.image(), None

    def image(self) -> NDArray[np.uint8]:
        """The latest frame (black until the first one arrives)."""
        with self._lock:
            image = self._image
        if image is None:
            return np.zeros((self.camera_model.height, self.camera_model.width), dtype=np.uint8)
        return image
