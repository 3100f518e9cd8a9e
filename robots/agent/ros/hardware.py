"""A ROS 1 robot as the software's ``Hardware``: ``nav_msgs/Odometry`` on ``odom``,
``sensor_msgs/LaserScan`` on ``scan``, ``sensor_msgs/CompressedImage`` on the camera's
topic (with its ``sensor_msgs/CameraInfo`` on ``camera_info``, if any), ``geometry_msgs/Twist``
on ``cmd_vel``. Call ``robots.agent.ros.ros_path()`` and
``rospy.init_node`` first; ``RosHardware`` waits for the first odometry and scan. What it
does with the messages is ``robots.agent.bridge.DriverReadings``, shared with ROS 2."""

from __future__ import annotations

from typing import Any

import rospy  # type: ignore[import-not-found,unused-ignore]
from geometry_msgs.msg import Twist  # type: ignore[import-not-found,unused-ignore]
from nav_msgs.msg import Odometry as RosOdometry  # type: ignore[import-not-found,unused-ignore]
from sensor_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    BatteryState,
    CameraInfo,
    CompressedImage,
    LaserScan,
)

from cloudnav_core.camera import CameraModel
from robots.agent.bridge import DriverReadings, camera_model_of, image_of_jpeg


def calibrated_camera(topic: str, wait: float) -> CameraModel:
    """The default camera with the intrinsics of the first ``CameraInfo`` on ``topic``
    within ``wait`` seconds; as it is if none comes or it is uncalibrated (K all zero)."""
    try:
        info: Any = rospy.wait_for_message(topic, CameraInfo, wait)
    except rospy.ROSException:
        return CameraModel()
    return camera_model_of(info.K, info.width, info.height)


class RosHardware(DriverReadings):
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
        super().__init__(camera_model or calibrated_camera(camera_info, calibration_wait))
        rospy.Subscriber(battery, BatteryState, self.battery.on_state, queue_size=1)
        self._cmd_vel = rospy.Publisher(cmd_vel, Twist, queue_size=1)
        rospy.Subscriber(odom, RosOdometry, self.on_odom, queue_size=1)
        rospy.Subscriber(scan, LaserScan, self.on_scan, queue_size=1)
        rospy.Subscriber(camera, CompressedImage, self._on_image, queue_size=1, buff_size=2**22)
        self.ready(
            rospy.wait_for_message(odom, RosOdometry, timeout),
            rospy.wait_for_message(scan, LaserScan, timeout),
        )

    def _on_image(self, msg: Any) -> None:
        # Decoded here, off the control loop; a frame that does not decode is dropped.
        self.on_image(image_of_jpeg(msg.data))

    def command(self, linear: float, angular: float) -> None:
        twist = Twist()
        twist.linear.x, twist.angular.z = float(linear), float(angular)
        self._cmd_vel.publish(twist)
