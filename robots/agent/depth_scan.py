"""A planar scan from a registered depth image, as ROS's ``depthimage_to_laserscan`` makes
one for a robot with an RGB-D camera and no laser.

The scan lies in the camera's horizontal plane. Each image column of the ``scan_height``
rows centred on the optical axis gives one return: the nearest of its rows, turned from
depth along the optical axis into range along the column's ray. Columns are then binned
into ``beams`` evenly spaced bearings across the camera's field of view (a LaserScan has
one angle increment; a pinhole's columns are not evenly spaced in angle), keeping each
bin's nearest return. Readings outside ``[range_min, range_max]`` are no return (``inf``,
REP 117).

``ObstacleMemory`` keeps what the camera saw for a few seconds, moved by odometry, so a
robot whose sensor looks only ahead still knows what stands beside it (the persistence
of Nav2's obstacle layer); a remembered point the camera now sees through is cleared.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from robots.agent.perception import CameraModel
from robots.domain.params import RobotConfig
from robots.domain.se2 import Pose, relative, transform

Floats = NDArray[np.float64]


@dataclass(frozen=True)
class DepthScanSpec:
    """The scan made from depth: rows read, beams, and the depth sensor's range."""

    scan_height: int = 10
    """Image rows read around the optical centre (``depthimage_to_laserscan``'s
    ``scan_height``)."""
    beams: int = 160
    range_min: float = 0.2
    """m: nearer readings are no return (a structured-light or stereo camera's near limit)."""
    range_max: float = 6.0
    """m: farther readings are no return (depth noise grows with the square of range)."""

    def rows(self, model: CameraModel) -> NDArray[np.intp]:
        """The image rows read, centred on the optical axis."""
        first = max(0, round(model.cy - self.scan_height / 2 + 0.5))
        return np.arange(first, min(model.height, first + self.scan_height), dtype=np.intp)

    def field_of_view(self, model: CameraModel) -> tuple[float, float]:
        """``(angle_min, angle_max)``: the bearings of the image's right and left edges,
        counter-clockwise positive as in a LaserScan."""
        right = -math.atan((model.width - 1 - model.cx) / model.fx)
        left = math.atan(model.cx / model.fx)
        return right, left

    def angles(self, model: CameraModel) -> Floats:
        """Each beam's bearing in the camera's frame, radians, increasing."""
        low, high = self.field_of_view(model)
        return np.asarray(np.linspace(low, high, self.beams), np.float64)


def depth_to_scan(
    depth: NDArray[np.floating[Any]], model: CameraModel, spec: DepthScanSpec
) -> NDArray[np.float32]:
    """Ranges (m, ``inf`` for no return) at ``spec.angles(model)`` from ``depth``: the
    scan rows of a registered depth image (metres along the optical axis; non-finite or
    0 where the camera read nothing), or the whole image.

    Raises ValueError when ``depth`` is not as wide as the camera's image."""
    band = np.asarray(depth, np.float64)
    if band.ndim != 2 or band.shape[1] != model.width:
        raise ValueError(f"depth of shape {band.shape} is not {model.width} columns wide")
    if band.shape[0] == model.height:
        band = band[spec.rows(model)]
    columns = np.arange(model.width, dtype=np.float64) - model.cx
    stretch = np.sqrt(1.0 + (columns / model.fx) ** 2)  # depth along the axis -> range
    with np.errstate(invalid="ignore"):
        ranges = band * stretch[None, :]
        readable = np.isfinite(ranges) & (ranges >= spec.range_min) & (ranges <= spec.range_max)
    nearest = np.where(readable, ranges, np.inf).min(axis=0)
    return _binned(nearest, np.arctan2(-columns, model.fx), spec.angles(model))


def _binned(ranges: Floats, bearings: Floats, angles: Floats) -> NDArray[np.float32]:
    """Each beam of ``angles`` takes the nearest of the columns whose bearing is closest
    to it."""
    increment = (angles[-1] - angles[0]) / max(1, len(angles) - 1)
    beam = np.clip(np.rint((bearings - angles[0]) / increment), 0, len(angles) - 1)
    out = np.full(len(angles), np.inf)
    np.minimum.at(out, beam.astype(np.intp), ranges)
    return out.astype(np.float32)


HIDDEN_BEHIND = 0.1
"""m: a remembered return this far behind the new scan's return on its beam is hidden
behind it, and stays remembered."""


@dataclass
class _Seen:
    odom: Pose
    seconds: float
    points: Floats  # robot frame at ``odom``, shape (n, 2)


class ObstacleMemory:
    """Returns of the last ``keep`` seconds in the robot's frame now, by odometry.

    ``update`` takes a scan from a sensor at ``mount`` (robot frame) whose beams span
    ``angles``. A remembered point inside the new scan's field of view and nearer than
    ``HIDDEN_BEHIND`` beyond its beam's return (``range_max`` for a beam with none) is
    forgotten: the new scan sees it again, or sees through where it was. One out of view
    (or hidden) stays until it is ``keep`` seconds old. ``keep=0`` remembers nothing:
    the points of the latest scan alone.
    """

    def __init__(
        self, mount: Pose = (0.0, 0.0, 0.0), keep: float = 4.0, range_max: float = math.inf
    ) -> None:
        self.mount, self.keep, self.range_max = mount, keep, range_max
        self._seen: list[_Seen] = []

    def update(
        self, ranges: NDArray[np.floating[Any]], angles: Floats, odom: Pose, seconds: float
    ) -> Floats:
        """The points (robot frame at ``odom``, shape (n, 2)) of this scan and of the
        remembered ones still standing."""
        metres: Floats = np.asarray(ranges, np.float64)
        hit = np.isfinite(metres)
        fresh = _points(self.mount, metres[hit], angles[hit])
        kept = [
            _Seen(odom, seen.seconds, self._cleared(self._moved(seen, odom), metres, angles))
            for seen in self._seen
            if seconds - seen.seconds < self.keep
        ]
        if self.keep > 0:
            self._seen = [s for s in [_Seen(odom, seconds, fresh), *kept] if len(s.points)]
        return np.concatenate([fresh, *(seen.points for seen in kept)])

    @staticmethod
    def _moved(seen: _Seen, odom: Pose) -> Floats:
        """``seen``'s points in the robot frame at ``odom``."""
        return transform(relative(odom, seen.odom), seen.points)

    def _cleared(self, points: Floats, ranges: Floats, angles: Floats) -> Floats:
        """``points`` less those the scan (``ranges`` at ``angles``) sees again or sees
        through."""
        mx, my, myaw = self.mount
        dx, dy = points[:, 0] - mx, points[:, 1] - my
        bearing = np.remainder(np.arctan2(dy, dx) - myaw + math.pi, 2 * math.pi) - math.pi
        increment = (angles[-1] - angles[0]) / max(1, len(angles) - 1)
        beam = np.rint((bearing - angles[0]) / increment).astype(np.intp)
        inside = (beam >= 0) & (beam < len(angles))
        through = np.where(np.isfinite(ranges), ranges, self.range_max)[
            np.clip(beam, 0, len(angles) - 1)
        ]
        # In view now and not hidden behind this scan's return: seen again (the fresh
        # scan has it) or seen through (gone). Only what is out of view or hidden stays.
        in_view = inside & (np.hypot(dx, dy) < through + HIDDEN_BEHIND)
        return np.asarray(points[~in_view], np.float64)


def _points(mount: Pose, ranges: Floats, angles: Floats) -> Floats:
    """Returns at ``ranges`` along ``angles`` from a sensor at ``mount``, robot frame."""
    mx, my, myaw = mount
    heading = angles + myaw
    return np.stack([mx + ranges * np.cos(heading), my + ranges * np.sin(heading)], 1)


def seen_obstacles(mount: Pose, config: RobotConfig) -> ObstacleMemory:
    """What a robot's local planner sees from a scan taken at ``mount``: a laser's
    all-round scan alone; for a scan made from depth, which looks ahead only, what the
    camera saw in the last ``config.obstacle_memory`` seconds too."""
    return ObstacleMemory(mount, config.obstacle_memory if config.sensors == "rgbd" else 0.0)
