"""The robot's pose from a tag: its stored pose in the sub-map and how the robot sees it.

If the map says the tag's marker centre is at ``(x, y)`` facing ``yaw`` and the robot
sees it at ``(bx, by)`` facing ``psi`` in its own base frame, the robot is at::

    theta = yaw - psi
    (rx, ry) = (x, y) - R(theta) (bx, by)

The covariance is what an AMCL initial pose wants: the measurement's uncertainty in the
robot frame, propagated through that composition, plus the uncertainty of the stored tag
pose. The measurement model (standard deviations of range, bearing and relative yaw)
grows with distance and changes with the viewing angle as marker poses do: range error
grows with the square of the distance (the marker's apparent size sets it); yaw error
comes from the perspective difference between the marker's near and far edges, which
fades fast with distance (cubed here, which fits the measurements), and is worst
head-on, where a square's two pose solutions nearly coincide; both grow as the marker
is foreshortened. A yaw error of d radians moves the robot sideways by about
``distance * d``, which the propagation carries into x and y.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.messages import covariance_6x6
from cloudnav_core.se2 import Pose, wrap
from robots.agent.perception import TagDetection

Covariance = NDArray[np.float64]


class StoredTagPose(Protocol):
    """A tag's pose in its sub-map's frame (a bundle's tag, a ``DemoTag``)."""

    @property
    def x(self) -> float: ...
    @property
    def y(self) -> float: ...
    @property
    def yaw(self) -> float: ...


@dataclass(frozen=True)
class TagNoiseModel:
    """Standard deviations of a tag measurement (see the module's docstring).

    The defaults cover what the rendered camera measures with ``TagDetector`` for a 6 cm
    tag (over 180 random views, 0.3 to 2 m, 0 to 60 degrees: yaw error rms 0.2 degrees
    to 1.1 m, 0.5 to 1.5 m, 3 to 6 beyond; range error rms 1 cm at 2 m) with room for a
    real camera's calibration error; the stored pose's error (a tag placed by hand) adds
    a centimetre and 0.6 degrees.
    """

    range_base: float = 0.005  # m
    range_per_m2: float = 0.005  # m per m^2 of distance
    bearing: float = 0.002  # rad
    yaw_base: float = 0.005  # rad
    yaw_per_m3: float = 0.02  # rad per m^3 of distance, head-on
    tag_position: float = 0.01  # m, how well the stored pose matches the printed tag
    tag_yaw: float = 0.01  # rad

    def measurement_sigmas(self, distance: float, view_angle: float) -> tuple[float, float, float]:
        """``(range, bearing, relative yaw)`` standard deviations."""
        foreshortening = 1 / max(math.cos(view_angle), 0.3)
        head_on = 0.5 + 0.5 * math.cos(view_angle)  # the two IPPE solutions are closest
        sigma_range = (self.range_base + self.range_per_m2 * distance**2) * foreshortening
        sigma_yaw = (self.yaw_base + self.yaw_per_m3 * distance**3 * head_on) * foreshortening
        return sigma_range, self.bearing * foreshortening, sigma_yaw


@dataclass(frozen=True)
class PoseEstimate:
    """A robot pose ``(x, y, yaw)`` in a sub-map's frame with its 3x3 covariance
    (order x, y, yaw)."""

    x: float
    y: float
    yaw: float
    covariance: Covariance

    def ros_covariance(self) -> list[float]:
        """Row-major 6x6 covariance (x, y, z, roll, pitch, yaw) of
        ``geometry_msgs/PoseWithCovariance``; z, roll and pitch are fixed (zero)."""
        return covariance_6x6(self.covariance)


def robot_pose_from_tag(
    tag: StoredTagPose,
    seen: Pose,
    view_angle: float,
    model: TagNoiseModel | None = None,
    ambiguity: float = 0.0,
) -> PoseEstimate:
    """The robot's pose from the ``tag``'s stored pose and ``seen``, the tag's
    ``(x, y, yaw)`` in the robot base frame, viewed at ``view_angle`` off its normal.

    ``ambiguity`` (radians, a detection's) is added to the relative yaw's standard
    deviation, so that the mirror pose the detector did not choose stays within one sigma.
    """
    model = model or TagNoiseModel()
    bx, by, psi = seen
    theta = wrap(tag.yaw - psi)
    rotation = _rotation(theta)
    rx, ry = np.array([tag.x, tag.y]) - rotation @ np.array([bx, by])
    covariance = _propagated(model, seen, theta, (view_angle, ambiguity))
    return PoseEstimate(float(rx), float(ry), theta, covariance)


def relocalise(
    tag: StoredTagPose, detection: TagDetection, model: TagNoiseModel | None = None
) -> PoseEstimate:
    """The robot's pose in the tag's sub-map from one ``detection`` of that tag."""
    return robot_pose_from_tag(
        tag, detection.base_pose(), detection.view_angle, model, detection.ambiguity
    )


def _propagated(
    model: TagNoiseModel,
    seen: Pose,
    theta: float,
    view: tuple[float, float],
) -> Covariance:
    """Covariance of the composed pose: Jacobians of ``(rx, ry, theta)`` with respect to
    the measurement ``(bx, by, psi)`` and to the stored tag pose, each times its noise."""
    bx, by, _ = seen
    b = np.array([bx, by])
    turned = _rotation_derivative(theta) @ b  # d(R(theta) b) / d theta
    to_measured = np.zeros((3, 3))
    to_measured[:2, :2] = -_rotation(theta)
    to_measured[:2, 2], to_measured[2, 2] = turned, -1.0
    to_tag = np.eye(3)
    to_tag[:2, 2] = -turned
    measured = _measurement_covariance(model, b, *view)
    tag = np.diag([model.tag_position**2, model.tag_position**2, model.tag_yaw**2])
    return to_measured @ measured @ to_measured.T + to_tag @ tag @ to_tag.T


def _measurement_covariance(
    model: TagNoiseModel, b: NDArray[np.float64], view_angle: float, ambiguity: float
) -> Covariance:
    """Covariance of ``(bx, by, psi)``: range along the line of sight, bearing across it."""
    distance = float(np.linalg.norm(b))
    sigma_range, sigma_bearing, sigma_yaw = model.measurement_sigmas(distance, view_angle)
    sigma_yaw += ambiguity
    bearing = math.atan2(b[1], b[0])
    polar_to_xy = _rotation(bearing) @ np.diag([sigma_range, distance * sigma_bearing])
    covariance = np.zeros((3, 3))
    covariance[:2, :2] = polar_to_xy @ polar_to_xy.T
    covariance[2, 2] = sigma_yaw**2
    return covariance


def _rotation(angle: float) -> NDArray[np.float64]:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


def _rotation_derivative(angle: float) -> NDArray[np.float64]:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[-s, -c], [c, -s]])
