"""The simulated robot's drivers as the ROS 1 and ROS 2 simulated robots publish them
(``robots.agent.sim.ros_nodes``, ``robots.agent.sim.ros2_nodes``): the frames, the
contents of each message as plain data (or written by attribute, which both versions'
messages share), the stepping of the body and the command line of the robot's nodes.
Only the message classes and the publishing are each version's own.
"""

from __future__ import annotations

import argparse
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any

from cloudnav_core.se2 import Pose
from robots.agent.bridge import quaternion_of, set_pose
from robots.agent.fleet import demo_start, parse_pose
from robots.agent.hardware import encode_jpeg
from robots.agent.sim.hardware import SimHardware

ODOM_FRAME = "odom"
BASE_FRAME = "base_footprint"
LASER_FRAME = "base_scan"
CAMERA_FRAME = "camera_optical_frame"
CAMERA_EVERY = 2
"""Body steps between camera frames (5 Hz at the 10 Hz step)."""
JPEG_QUALITY = 90
PERIOD = 0.1
"""Seconds between the body's steps, odometry and scans (10 Hz)."""
LONGEST_STEP = 0.5
"""Seconds: a step the machine held up longer is cut to this (the body never jumps)."""


def write_odometry(msg: Any, hardware: SimHardware) -> None:
    """A ``nav_msgs/Odometry`` (its header's stamp aside) of the body's odometry."""
    msg.header.frame_id, msg.child_frame_id = ODOM_FRAME, BASE_FRAME
    set_pose(msg.pose.pose, hardware.odom_pose)
    linear, angular = hardware.reported_velocity
    msg.twist.twist.linear.x, msg.twist.twist.angular.z = float(linear), float(angular)


def transform(msg: Any, header: Any, child: str, pose: Pose) -> Any:
    """``msg``, a new ``geometry_msgs/TransformStamped``, as tf ``header.frame_id ->
    child`` of ``pose``."""
    msg.header, msg.child_frame_id = header, child
    msg.transform.translation.x, msg.transform.translation.y = float(pose[0]), float(pose[1])
    o = msg.transform.rotation
    o.x, o.y, o.z, o.w = quaternion_of(pose[2])
    return msg


def scan_fields(hardware: SimHardware) -> dict[str, Any]:
    """A ``sensor_msgs/LaserScan`` but its header: the laser's next scan (``inf``: no
    return, REP 117)."""
    return {**hardware.laser.spec.geometry(), "ranges": hardware.scan().tolist()}


def jpeg_fields(hardware: SimHardware) -> dict[str, Any]:
    """A ``sensor_msgs/CompressedImage`` but its header: the camera's frame as JPEG."""
    return {"format": "jpeg", "data": encode_jpeg(hardware.image(), JPEG_QUALITY)}


class SimDrivers(ABC):
    """The body stepped by its drivers: ``cmd_vel`` commands (``command``, from any
    thread) are obeyed at the next ``step``, which then publishes odometry and the scan,
    and the camera's frame every ``CAMERA_EVERY`` steps, through ``publish``."""

    def __init__(self, hardware: SimHardware) -> None:
        self.hardware = hardware
        self._commands: list[tuple[float, float]] = []
        self._lock = threading.Lock()

    def command(self, linear: float, angular: float) -> None:
        with self._lock:
            self._commands.append((linear, angular))

    def step(self, seconds: float, ticks: int) -> None:
        """Obey the commands that came, advance ``seconds``, publish what is due."""
        with self._lock:
            commands, self._commands = self._commands, []
        for command in commands:
            self.hardware.command(*command)
        self.hardware.advance(seconds)
        self.publish(ticks % CAMERA_EVERY == 0)

    @abstractmethod
    def publish(self, camera: bool) -> None:
        """Publish odometry (and tf), the scan and, with ``camera``, the frame."""
        ...


class Pacer:
    """The body's steps on the wall clock: ``tick`` gives the seconds since the last
    (at most ``LONGEST_STEP``) and the step's number."""

    def __init__(self) -> None:
        self.ticks, self._last = 0, time.monotonic()

    def tick(self) -> tuple[float, int]:
        now = time.monotonic()
        self.ticks, seconds, self._last = self.ticks + 1, min(now - self._last, LONGEST_STEP), now
        return seconds, self.ticks


def robot_arguments(prog: str, nodes: Sequence[str]) -> argparse.ArgumentParser:
    """The options of a simulated robot's node, one of ``nodes``."""
    parser = argparse.ArgumentParser(prog=prog)
    parser.add_argument("node", choices=tuple(nodes))
    parser.add_argument("--cloud", default="http://127.0.0.1:8000", help="named by the tags")
    parser.add_argument("--start", type=parse_pose, default=demo_start(0), help="x,y,yaw")
    parser.add_argument("--seed", type=int, default=0)
    return parser


def demo_hardware(options: argparse.Namespace) -> SimHardware:
    """The demo building's robot at ``--start``, its tags naming ``--cloud``."""
    from robots.agent.sim.world import demo_world

    return SimHardware(demo_world(options.cloud), options.start, seed=options.seed)
