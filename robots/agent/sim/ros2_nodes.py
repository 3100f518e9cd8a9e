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
server's virtualenv, which has no rclpy.
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

from robots.agent.bridge import planar_covariance, pose_of, set_pose
from robots.agent.hardware import encode_jpeg
from robots.agent.navigation import Driver, DriveState, LocalObstacles
from robots.agent.perception import CameraModel
from robots.agent.robot import PoseTracker, particle_filter
from robots.agent.ros2 import stamp_seconds
from robots.agent.ros2.navigation import LATCHED
from robots.agent.sim.hardware import SimHardware
from robots.agent.supervisor import SubMap
from robots.domain.se2 import Pose, compose, inverse
from telemetry.domain.messages import laser_scan

CAMERA_EVERY = 2
"""Body steps between camera frames (5 Hz at the 10 Hz step)."""
CONTROL_PERIOD = 0.1
"""Seconds between the action server's control steps."""
PARTICLES = 200
"""The stand-in AMCL's particles after an initial pose."""
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


class Ros2Body:
    """``hardware`` on ROS 2 topics (see the module's docstring); ``events`` gets every
    ``cmd_vel`` with the time it came."""

    def __init__(self, node: Node, hardware: SimHardware, events: Events) -> None:
        self.node, self.hardware, self.events = node, hardware, events
        self._odom = node.create_publisher(Odometry, "odom", 10)
        self._scan = node.create_publisher(LaserScan, "scan", qos_profile_sensor_data)
        self._camera = node.create_publisher(CompressedImage, "camera/image/compressed", 1)
        self._camera_info = node.create_publisher(CameraInfo, "camera/camera_info", 1)
        self._tf = node.create_publisher(TFMessage, "/tf", 100)
        self._commands: list[tuple[float, float]] = []
        self._lock = threading.Lock()
        for topic in ("cmd_vel", NAV2_CMD_VEL):
            node.create_subscription(Twist, topic, self._obeying(topic), 10)

    def _obeying(self, topic: str) -> Any:
        return lambda msg: self._on_cmd_vel(topic, msg)

    def _on_cmd_vel(self, topic: str, msg: Any) -> None:
        self.events.write("cmd_vel", topic=topic, linear=msg.linear.x, angular=msg.angular.z)
        with self._lock:
            self._commands.append((msg.linear.x, msg.angular.z))  # obeyed at the next step

    def step(self, seconds: float, ticks: int) -> None:
        """Obey the commands that came, advance ``seconds``, publish what is due."""
        with self._lock:
            commands, self._commands = self._commands, []
        for command in commands:
            self.hardware.command(*command)
        self.hardware.advance(seconds)
        stamp = self.node.get_clock().now().to_msg()
        self._publish_odometry(stamp)
        self._publish_scan(stamp)
        if ticks % CAMERA_EVERY == 0:
            self._publish_image(stamp)

    def _publish_odometry(self, stamp: Any) -> None:
        msg = Odometry()
        msg.header.stamp, msg.header.frame_id = stamp, "odom"
        msg.child_frame_id = "base_footprint"
        set_pose(msg.pose.pose, self.hardware.odom_pose)
        linear, angular = self.hardware.reported_velocity
        msg.twist.twist.linear.x, msg.twist.twist.angular.z = float(linear), float(angular)
        self._odom.publish(msg)
        self._tf.publish(TFMessage(transforms=[transform(msg.header, "base_footprint",
                                                         self.hardware.odom_pose)]))  # fmt: skip

    def _publish_scan(self, stamp: Any) -> None:
        spec = self.hardware.laser.spec
        msg = LaserScan()
        msg.header.stamp, msg.header.frame_id = stamp, "base_scan"
        msg.angle_min, msg.angle_max = spec.angle_min, spec.angle_max
        msg.angle_increment, msg.scan_time = spec.angle_increment, spec.scan_time
        msg.time_increment = spec.scan_time / spec.beams
        msg.range_min, msg.range_max = spec.range_min, spec.range_max
        msg.ranges = [float(r) for r in self.hardware.scan()]
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
    msg.distortion_model, msg.d = "plumb_bob", [0.0] * 5
    msg.k = [model.fx, 0.0, model.cx, 0.0, model.fy, model.cy, 0.0, 0.0, 1.0]
    msg.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    msg.p = [model.fx, 0.0, model.cx, 0.0, 0.0, model.fy, model.cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return msg


def transform(header: Any, child: str, pose: Pose) -> Any:
    """tf ``header.frame_id -> child`` of ``pose``."""
    msg = TransformStamped()
    msg.header, msg.child_frame_id = header, child
    msg.transform.translation.x, msg.transform.translation.y = float(pose[0]), float(pose[1])
    o = msg.transform.rotation
    o.z, o.w = math.sin(pose[2] / 2), math.cos(pose[2] / 2)
    return msg


# --- Nav2, as far as the bridge uses it ------------------------------------------------


class Nav2StandIn:
    """The AMCL stand-in, ``NavigateToPose`` server and ``LoadMap`` service (see the
    module's docstring), writing ``map``, ``initial_pose``, ``goal``, ``result``,
    ``cancel`` and ``load_map`` events."""

    def __init__(self, node: Node, events: Events) -> None:
        self.node, self.events = node, events
        self._lock = threading.Lock()
        self._odom: Any = None
        self._tracker = PoseTracker(particle_filter(PARTICLES, 0))
        self._placed = False
        self._map: SubMap | None = None
        self._obstacles: LocalObstacles | None = None
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
        with self._lock:
            self._tracker.reset(pose_of(msg.pose.pose), covariance, self._tracker.odom)
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
        estimate.header.stamp, estimate.header.frame_id = msg.header.stamp, "map"
        set_pose(estimate.pose.pose, pose)
        self._pose.publish(estimate)
        map_to_odom = transform(estimate.header, "odom", compose(pose, inverse(odom)))
        self._tf.publish(TFMessage(transforms=[map_to_odom]))

    def pose(self) -> Pose | None:
        with self._lock:
            return self._tracker.pose() if self._placed else None

    def _on_map(self, msg: Any) -> None:
        info = msg.info
        grid = np.asarray(msg.data, dtype=np.int8).reshape(info.height, info.width)
        submap = SubMap("", "map", "", "", grid, info.resolution, pose_of(info.origin), {}, (), ())
        self.events.write("map", width=info.width, height=info.height)
        with self._lock:
            self._map = submap
            self._tracker.set_map(submap)

    def _on_scan(self, msg: Any) -> None:
        ranges = np.asarray(msg.ranges, dtype=np.float64)
        angles = msg.angle_min + msg.angle_increment * np.arange(len(ranges))
        self._obstacles = LocalObstacles.from_scan(ranges, angles)
        scan = laser_scan(
            msg.header.frame_id,
            ranges.tolist(),
            stamp_seconds(msg.header.stamp),
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
        pose = self.pose()
        if pose is None:
            return
        feedback = NavigateToPose.Feedback()
        feedback.distance_remaining = float(math.dist(pose[:2], target[:2]))
        set_pose(feedback.current_pose.pose, pose)
        handle.publish_feedback(feedback)

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
            command.linear.x, command.angular.z = (float(v) for v in drive.command)
            self._cmd_vel.publish(command)
        return drive

    def _stop(self) -> None:
        self._cmd_vel.publish(Twist())

    def _publish_plan(self, driver: Driver) -> None:
        msg = RosPath()
        msg.header.stamp, msg.header.frame_id = self.node.get_clock().now().to_msg(), "map"
        for x, y in driver.path:
            stamped = PoseStamped()
            stamped.header = msg.header
            set_pose(stamped.pose, (x, y, 0.0))
            msg.poses.append(stamped)
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
