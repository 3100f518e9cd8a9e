"""The hardware seam: everything the robot's software (client, Maps Supervisor, tag
detector, relocalisation, navigation) knows of its robot.

``Hardware`` is the body and sensors: odometry, a laser, a camera and velocity commands.
The simulator (``robots.agent.sim.hardware.SimHardware``) is one implementation; a real
robot's bridge (ROS topics, a vendor SDK) is another. Nothing but a launcher picks the
implementation, and nothing of the software imports the simulator (import-linter).

``NavigationStack`` is optional: a robot that brings its own navigation (ROS move_base or
Nav2 with AMCL and a map server) takes the Maps Supervisor's maps, initial poses and goals
through it instead of the agent's own planner and controller.

Rates and times are the software's clock (``Robot.seconds``); messages are
``cloudnav_core.messages`` dicts, as the rosbridge client sends them.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import Enum
from typing import Any, Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from cloudnav_core.camera import CameraModel
from cloudnav_core.messages import CompressedImage, Json, Odometry, compressed_image
from cloudnav_core.se2 import Point, Pose


class Battery(Protocol):
    """What ``sensor_msgs/BatteryState`` reports."""

    @property
    def charge(self) -> float:
        """The fraction left, 0..1."""
        ...

    @property
    def voltage(self) -> float: ...


class Hardware(Protocol):
    """A robot's body and sensors as the software sees them."""

    @property
    def battery(self) -> Battery: ...

    camera_model: CameraModel
    """Intrinsics and mounting of the camera whose ``image`` the tag detector reads."""
    scan_angles: NDArray[np.float64]
    """Bearing of each laser beam in the scan's frame, radians."""
    scan_mount: Pose
    """Where the scan's frame sits in the base frame (a laser's mount, or the camera's
    for a scan made from depth)."""

    @property
    def odom_pose(self) -> Pose:
        """Where odometry says the base is, in the odometry frame."""
        ...

    @property
    def reported_velocity(self) -> tuple[float, float]:
        """(linear m/s, angular rad/s) as the wheel encoders report it."""
        ...

    def advance(self, seconds: float) -> None:
        """Let ``seconds`` pass (a simulator steps; real hardware waits for fresh data)."""

    def command(self, linear: float, angular: float) -> None:
        """Ask for a velocity; the base clamps it to its limits and stops by itself when
        commands stop."""

    def scan(self) -> NDArray[np.float32]:
        """The latest laser ranges, one per ``scan_angles`` (inf or NaN: no return)."""
        ...

    def scan_message(self, ranges: NDArray[np.float32], seconds: float) -> Json:
        """``sensor_msgs/LaserScan`` of ``ranges`` stamped ``seconds``."""
        ...

    def odometry_message(self, seconds: float) -> Odometry:
        """``nav_msgs/Odometry`` of the odometry pose and reported velocity."""
        ...

    def image(self) -> NDArray[np.uint8]:
        """The latest camera frame (grey or BGR)."""
        ...

    def image_and_depth(self) -> tuple[NDArray[np.uint8], NDArray[np.float32] | None]:
        """A frame and its registered depth (metres along the optical axis), None for a
        robot without a depth camera."""
        ...


class StackGoal(Enum):
    """Where the navigation stack's latest goal stands (an actionlib or Nav2 action's
    status, folded)."""

    NONE = "none"  # no goal sent, or the last one cancelled
    ACTIVE = "active"  # pending or being driven
    SUCCEEDED = "succeeded"
    FAILED = "failed"  # aborted or rejected by the stack


class NavigationStack(Protocol):
    """A robot's own navigation (move_base or Nav2, AMCL, a map server), fed by the Maps
    Supervisor. ``map_id`` names the sub-map every pose is in; every pose is in the
    building's frame, which all its sub-maps share."""

    def set_map(self, map_id: str, grid: Any, resolution: float, origin: Pose) -> None:
        """Replace the map (``/map`` latched, or a map server's ``load_map``)."""

    def set_initial_pose(self, map_id: str, pose: Pose, covariance: NDArray[np.float64]) -> None:
        """Reset localisation (``/initialpose`` with the tag's covariance)."""

    def send_goal(self, map_id: str, pose: Pose) -> None:
        """Drive to ``pose`` (a ``move_base`` / ``navigate_to_pose`` goal), preempting."""

    def cancel(self) -> None:
        """Cancel the active goal, if any."""

    def goal_state(self) -> StackGoal:
        """How the latest goal sent is going."""
        ...

    def pose(self) -> Pose | None:
        """Where the stack's localisation (AMCL, tf ``map -> base``) puts the robot, once
        it has localised since the last ``set_initial_pose``; None before."""
        ...

    def plan(self) -> tuple[int, Sequence[Point]]:
        """The stack's latest global plan and a number that grows with each new one."""
        ...

    def progress(self) -> str:
        """What the stack last said of the goal's progress (Nav2's feedback: distance
        remaining, recoveries), for ``nav_status``; empty when it says nothing."""
        ...


def encode_jpeg(image: NDArray[np.uint8], quality: int = 80) -> bytes:
    """JPEG bytes of a grey or BGR image; raises ValueError if OpenCV cannot encode it."""
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError("JPEG encoding failed")
    return bytes(data.tobytes())


def compressed_image_message(
    jpeg: bytes, seconds: float, frame_id: str = "camera_optical_frame"
) -> CompressedImage:
    """The camera's ``sensor_msgs/CompressedImage`` of ``jpeg``, stamped ``seconds``."""
    return compressed_image(frame_id, jpeg, seconds)
