"""A simulated ROS 2 robot with a Nav2 stand-in, as rclpy nodes
(``python -m robots.agent.sim.ros2_robot`` runs them), for the ROS 2 bridge's tests and
bench: Debian has no Nav2 and PyPI no nav2 wheels.

- ``Ros2Body``: the simulator's body, laser and camera as drivers' topics: ``cmd_vel``
  (and the stand-in's ``cmd_vel_nav``) in;
  ``odom`` (and tf ``odom -> base_footprint``), ``scan`` (sensor-data QoS, as laser drivers
  publish it), ``camera/image/compressed`` with ``camera/camera_info`` out.
- ``Nav2StandIn``: what the bridge uses of Nav2: an AMCL stand-in (the agent's own
  particle filter on ``/map``, started by ``/initialpose``, publishing ``/amcl_pose`` and tf
  ``map -> odom``), a ``NavigateToPose`` action server on ``navigate_to_pose`` that plans
  and drives with the agent's own A* and dynamic window (feedback, ``/plan``, cancel), and
  map_server's ``LoadMap`` service on ``/map_server/load_map``.

Each writes what it does as JSON lines (``Events``) for the tests to read: they run in the
server's virtualenv, which has no rclpy. What is no rclpy call is shared with the ROS 1
simulated robot (``robots.agent.sim.drivers``, ``robots.agent.sim.stand_in``).
"""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from action_msgs.msg import GoalStatus  # type: ignore[import-not-found,unused-ignore]
from geometry_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    PoseStamped,
    PoseWithCovarianceStamped,
    TransformStamped,
    Twist,
)
from nav2_msgs.action import NavigateToPose  # type: ignore[import-not-found,unused-ignore]
from nav2_msgs.srv import LoadMap  # type: ignore[import-not-found,unused-ignore]
from nav_msgs.msg import OccupancyGrid, Odometry  # type: ignore[import-not-found,unused-ignore]
from nav_msgs.msg import Path as RosPath  # type: ignore[import-not-found,unused-ignore]
from rclpy.action import (  # type: ignore[import-not-found,unused-ignore]
    ActionServer,
    CancelResponse,
    GoalResponse,
)
from rclpy.callback_groups import ReentrantCallbackGroup  # type: ignore[import-not-found,unused-ignore]
from rclpy.node import Node  # type: ignore[import-not-found,unused-ignore]
from rclpy.qos import qos_profile_sensor_data  # type: ignore[import-not-found,unused-ignore]
from sensor_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
    CameraInfo,
    CompressedImage,
    LaserScan,
)
from tf2_msgs.msg import TFMessage  # type: ignore[import-not-found,unused-ignore]

from cloudnav_core.messages import PinholeCalibration
from cloudnav_core.se2 import Pose
from robots.agent.bridge import planar_covariance, pose_of, set_pose
from robots.agent.navigation.driver import Driver
from robots.agent.navigation.legs import DriveState
from robots.agent.perception import pinhole_calibration
from robots.agent.ros2 import stamp_seconds
from robots.agent.ros2.navigation import LATCHED
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

CONTROL_PERIOD = 0.1
"""Seconds between the action server's control steps."""
NAV2_CMD_VEL = "cmd_vel_nav"
"""Where the stand-in's controller publishes, as Nav2's controller server does (Nav2's
velocity smoother passes it on to ``cmd_vel``; the body obeys both): so a test tells the
bridge's own commands from the navigation's."""


class Events:
    """JSON lines ``{"t": monotonic seconds, "event": name, ...}`` to ``out``, flushed."""

    def __init__(self, out: TextIO) -> None:
        self._out, self._lock = out, threading.Lock()

    @classmethod
    def to(cls, path: Path | None) -> Events:
        return cls(path.open("a", buffering=1) if path else open("/dev/null", "w"))

    def write(self, event: str, **fields: Any) -> None:
        with self._lock:
            self._out.write(json.dumps({"t": time.monotonic(), "event": event, **fields}) + "\n")
            self._out.flush()


# --- the robot's drivers -------------------------------------------------------------


class Ros2Body(SimDrivers):
    """``hardware`` on ROS 2 topics (see the module's docstring); ``events`` gets every
    ``cmd_vel`` with the time it came."""

    def __init__(self, node: Node, hardware: SimHardware, events: Events) -> None:
        super().__init__(hardware)
        self.node, self.events = node, events
        self._odom = node.create_publisher(Odometry, "odom", 10)
        self._scan = node.create_publisher(LaserScan, "scan", qos_profile_sensor_data)
        self._camera = node.create_publisher(CompressedImage, "camera/image/compressed", 1)
        self._camera_info = node.create_publisher(CameraInfo, "camera/camera_info", 1)
        self._tf = node.create_publisher(TFMessage, "/tf", 100)
        for topic in ("cmd_vel", NAV2_CMD_VEL):
            node.create_subscription(Twist, topic, self._obeying(topic), 10)

    def _obeying(self, topic: str) -> Any:
        return lambda msg: self._on_cmd_vel(topic, msg)

    def _on_cmd_vel(self, topic: str, msg: Any) -> None:
        self.events.write("cmd_vel", topic=topic, linear=msg.linear.x, angular=msg.angular.z)
        self.command(msg.linear.x, msg.angular.z)

    def publish(self, camera: bool) -> None:
        stamp = self.node.get_clock().now().to_msg()
        odom = Odometry()
        odom.header.stamp = stamp
        write_odometry(odom, self.hardware)
        self._odom.publish(odom)
        moved = transform(TransformStamped(), odom.header, BASE_FRAME, self.hardware.odom_pose)
        self._tf.publish(TFMessage(transforms=[moved]))
        scan = LaserScan(**scan_fields(self.hardware))
        scan.header.stamp, scan.header.frame_id = stamp, LASER_FRAME
        self._scan.publish(scan)
        if camera:
            image = CompressedImage(**jpeg_fields(self.hardware))
            image.header.stamp, image.header.frame_id = stamp, CAMERA_FRAME
            self._camera.publish(image)
            calibration = pinhole_calibration(self.hardware.camera_model)
            self._camera_info.publish(camera_info(image.header, calibration))


def camera_info(header: Any, calibration: PinholeCalibration) -> Any:
    """The ``sensor_msgs/CameraInfo`` of ``calibration``: ROS 2 spells its matrices in
    lower case (ROS 1's ``K`` is ``k``)."""
    c = calibration
    return CameraInfo(
        header=header, height=c["height"], width=c["width"],
        distortion_model=c["distortion_model"], d=c["D"], k=c["K"], r=c["R"], p=c["P"],
    )  # fmt: skip


# --- Nav2, as far as the bridge uses it ------------------------------------------------


class Nav2StandIn:
    """The AMCL stand-in, ``NavigateToPose`` server and ``LoadMap`` service (see the
    module's docstring), writing ``map``, ``initial_pose``, ``goal``, ``result``,
    ``cancel`` and ``load_map`` events."""

    def __init__(self, node: Node, events: Events) -> None:
        self.node, self.events = node, events
        self.stack = StandInStack()
        self._lock = threading.Lock()
        self._goal = 0
        group = ReentrantCallbackGroup()
        self._cmd_vel = node.create_publisher(Twist, NAV2_CMD_VEL, 10)
        self._pose = node.create_publisher(PoseWithCovarianceStamped, "/amcl_pose", LATCHED)
        self._plan = node.create_publisher(RosPath, "/plan", 10)
        self._tf = node.create_publisher(TFMessage, "/tf", 100)
        node.create_subscription(
            PoseWithCovarianceStamped, "/initialpose", self._on_initial, LATCHED
        )
        node.create_subscription(OccupancyGrid, "/map", self._on_map, LATCHED)
        node.create_subscription(Odometry, "odom", self._on_odom, 10)
        node.create_subscription(LaserScan, "scan", self._on_scan, qos_profile_sensor_data)
        node.create_service(LoadMap, "/map_server/load_map", self._on_load_map)
        self.server = ActionServer(
            node,
            NavigateToPose,
            "navigate_to_pose",
            execute_callback=self._execute,
            goal_callback=lambda _goal: GoalResponse.ACCEPT,
            cancel_callback=self._on_cancel,
            callback_group=group,
        )

    # --- localisation ------------------------------------------------------------------

    def _on_initial(self, msg: Any) -> None:
        covariance = planar_covariance(msg.pose.covariance)
        self.events.write("initial_pose", pose=pose_of(msg.pose.pose), xx=covariance[0, 0])
        self.stack.on_initial_pose(msg)

    def _on_odom(self, msg: Any) -> None:
        localised = self.stack.on_odom(msg)
        if localised is None:
            return
        pose, map_to_odom = localised
        estimate = PoseWithCovarianceStamped()
        estimate.header.stamp, estimate.header.frame_id = msg.header.stamp, "map"
        set_pose(estimate.pose.pose, pose)
        self._pose.publish(estimate)
        seen = transform(TransformStamped(), estimate.header, "odom", map_to_odom)
        self._tf.publish(TFMessage(transforms=[seen]))

    def _on_map(self, msg: Any) -> None:
        self.events.write("map", width=msg.info.width, height=msg.info.height)
        self.stack.on_map(msg)

    def _on_scan(self, msg: Any) -> None:
        self.stack.on_scan(msg, stamp_seconds(msg.header.stamp))

    def _on_load_map(self, request: Any, response: Any) -> Any:
        self.events.write("load_map", url=request.map_url)
        response.result = LoadMap.Response.RESULT_SUCCESS
        return response

    # --- navigate_to_pose --------------------------------------------------------------

    def _on_cancel(self, _goal: Any) -> Any:
        self.events.write("cancel")
        return CancelResponse.ACCEPT

    def _execute(self, handle: Any) -> Any:
        """Drive to the goal until there, cancelled, preempted by a newer goal or failed."""
        with self._lock:
            self._goal += 1
            number = self._goal
        target = pose_of(handle.request.pose.pose)
        self.events.write("goal", x=target[0], y=target[1], yaw=target[2])
        driver, published = Driver(), 0
        while True:
            if handle.is_cancel_requested or number != self._goal:
                self._stop()
                return self._end(handle, "canceled" if handle.is_cancel_requested else "abort")
            drive = self._drive(driver, target)
            if driver.plan_version != published:
                published = driver.plan_version
                self._publish_plan(driver)
            if drive is not None:
                self._feedback(handle, target)
                if drive.state is not DriveState.MOVING:
                    self._stop()
                    arrived = drive.state is DriveState.ARRIVED
                    return self._end(handle, "succeed" if arrived else "abort")
            time.sleep(CONTROL_PERIOD)

    def _end(self, handle: Any, how: str) -> Any:
        getattr(handle, how)()
        status = {"succeed": GoalStatus.STATUS_SUCCEEDED, "canceled": GoalStatus.STATUS_CANCELED}
        self.events.write("result", status=status.get(how, GoalStatus.STATUS_ABORTED))
        return NavigateToPose.Result(error_code=0 if how == "succeed" else 9000)

    def _feedback(self, handle: Any, target: Pose) -> None:
        pose = self.stack.pose()
        if pose is None:
            return
        feedback = NavigateToPose.Feedback()
        feedback.distance_remaining = float(math.dist(pose[:2], target[:2]))
        set_pose(feedback.current_pose.pose, pose)
        handle.publish_feedback(feedback)

    def _drive(self, driver: Driver, target: Pose) -> Any:
        """One control step; None while there is no map, pose or scan yet."""
        drive = self.stack.drive(driver, target)
        if drive is not None and drive.command is not None:
            command = Twist()
            command.linear.x, command.angular.z = (float(v) for v in drive.command)
            self._cmd_vel.publish(command)
        return drive

    def _stop(self) -> None:
        self._cmd_vel.publish(Twist())

    def _publish_plan(self, driver: Driver) -> None:
        msg = RosPath()
        msg.header.stamp, msg.header.frame_id = self.node.get_clock().now().to_msg(), "map"
        write_plan(msg, driver, PoseStamped)
        self._plan.publish(msg)


class MapWatcher:
    """A separate subscriber of ``/map`` with transient-local QoS, as a person on the
    robot (or Nav2's costmaps) would read it: each map, cell for cell, as a ``map`` event
    (``cells``: the int8 data as a list)."""

    def __init__(self, node: Node, events: Events) -> None:
        self.events = events
        node.create_subscription(OccupancyGrid, "/map", self._on_map, LATCHED)

    def _on_map(self, msg: Any) -> None:
        info = msg.info
        cells = np.asarray(msg.data, dtype=np.int8).tolist()
        self.events.write("map", width=info.width, height=info.height, cells=cells)
