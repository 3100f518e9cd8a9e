"""A ROS 2 robot as the software's ``Hardware``: ``nav_msgs/Odometry`` on ``odom``,
``sensor_msgs/LaserScan`` on ``scan``, the camera as ``sensor_msgs/CompressedImage`` (or
raw ``sensor_msgs/Image``) with its ``sensor_msgs/CameraInfo``, and ``geometry_msgs/Twist``
(or ``TwistStamped``) on ``cmd_vel``. The drivers' topics are read with the sensor-data
QoS (best effort), which matches reliable and best-effort publishers alike. Spin the node
in another thread: ``Ros2Hardware`` waits for the first odometry and scan. What it does with
the messages is ``robots.agent.bridge.DriverReadings``, shared with ROS 1."""

from __future__ import annotations

import threading
from typing import Any

from geometry_msgs.msg import Twist, TwistStamped  # type: ignore[import-not-found,unused-ignore]
from nav_msgs.msg import Odometry  # type: ignore[import-not-found,unused-ignore]
from rclpy.node import Node  # type: ignore[import-not-found,unused-ignore]
from rclpy.qos import qos_profile_sensor_data  # type: ignore[import-not-found,unused-ignore]
from sensor_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    BatteryState,
    CameraInfo,
    CompressedImage,
    Image,
    LaserScan,
)

from cloudnav_core.camera import CameraModel
from robots.agent.bridge import DriverReadings, camera_model_of, image_of_jpeg, image_of_raw


def first_message(node: Node, kind: Any, topic: str, timeout: float) -> Any:
    """The first ``kind`` on ``topic`` within ``timeout`` seconds (the node spinning
    elsewhere); None if none came. The subscription stays, ignoring what comes later:
    destroying it from this thread while another spins the node can kill that thread's
    executor (rclpy raises InvalidHandle while it builds its wait set), and the robot
    would hear nothing more."""
    came: list[Any] = []
    arrived = threading.Event()

    def take(msg: Any) -> None:
        if not came:
            came.append(msg)
            arrived.set()

    node.create_subscription(kind, topic, take, qos_profile_sensor_data)
    arrived.wait(timeout)
    return came[0] if came else None


class Ros2Hardware(DriverReadings):
    """The latest odometry, scan and camera frame of a ROS 2 robot, and its ``cmd_vel``.
    ``camera_type`` is ``compressed`` or ``raw``; ``stamped`` sends ``TwistStamped`` (a
    Nav2 set with ``enable_stamped_cmd_vel``). Raises TimeoutError when no odometry or
    scan comes within ``timeout`` seconds. The camera's intrinsics are those of its first
    ``CameraInfo`` within ``calibration_wait`` seconds, else the default robot's."""

    def __init__(
        self,
        node: Node,
        odom: str = "odom",
        scan: str = "scan",
        camera: str = "camera/image/compressed",
        camera_type: str = "compressed",
        camera_info: str = "camera/camera_info",
        cmd_vel: str = "cmd_vel",
        stamped: bool = False,
        battery: str = "battery_state",
        timeout: float = 30.0,
        calibration_wait: float = 2.0,
    ) -> None:
        info = first_message(node, CameraInfo, camera_info, calibration_wait)
        model = CameraModel() if info is None else camera_model_of(info.k, info.width, info.height)
        super().__init__(model)
        self._node, self._stamped = node, stamped
        self._cmd_vel = node.create_publisher(TwistStamped if stamped else Twist, cmd_vel, 1)
        sensors = qos_profile_sensor_data
        node.create_subscription(BatteryState, battery, self.battery.on_state, sensors)
        node.create_subscription(Odometry, odom, self.on_odom, sensors)
        node.create_subscription(LaserScan, scan, self.on_scan, sensors)
        if camera_type == "raw":
            node.create_subscription(Image, camera, self._on_raw, sensors)
        else:
            node.create_subscription(CompressedImage, camera, self._on_jpeg, sensors)
        if not self.wait_ready(timeout):
            raise TimeoutError(f"no odometry on {odom} or no scan on {scan} in {timeout} s")

    def _on_jpeg(self, msg: Any) -> None:
        # Decoded here, off the control loop; a frame that does not decode is dropped.
        self.on_image(image_of_jpeg(msg.data))

    def _on_raw(self, msg: Any) -> None:
        try:
            self.on_image(image_of_raw(msg.encoding, msg.height, msg.width, msg.data))
        except ValueError:
            self.on_image(None)

    def command(self, linear: float, angular: float) -> None:
        twist = Twist()
        twist.linear.x, twist.angular.z = float(linear), float(angular)
        if not self._stamped:
            self._cmd_vel.publish(twist)
            return
        stamped = TwistStamped()
        stamped.header.stamp = self._node.get_clock().now().to_msg()
        stamped.header.frame_id, stamped.twist = "base_link", twist
        self._cmd_vel.publish(stamped)
