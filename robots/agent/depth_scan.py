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
It also answers where the robot may move (``may_enter``): near where it saw a person
(or anything) moving in the last ``keep`` seconds, only onto floor the camera saw free in
the last ``FRESH_FLOOR`` seconds, since that person may since have stepped, unseen, beside
it (``robots.agent.navigation.driver``'s blind-side guard). Away from movers, anywhere.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.camera import CameraModel
from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Pose, compose, relative, transform
from robots.agent.tracking import Mover, ObstacleTracker

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
FRESH_FLOOR = 1.5
"""s: floor the camera saw free this long ago still counts as free (a person walking at
1 m/s crosses a robot's safety margin in well under that; see ``seen_free``)."""
FREE_SHORT_OF = 0.05
"""m: floor counts as seen free only this far short of its beam's return."""
MOVER_SPREAD = 0.5
"""m/s: how fast a mover may since have strayed from the way it was walking (turned,
sped up)."""
MOVER_REACH = 0.6
"""m: a mover's reach beyond its centroid (a person's radius, 0.25 m, and a margin)."""
WALKING = 0.3
"""m/s: slower movers are not followed out of view (an occluded wall's edge slides as
the robot moves; a person walks at 0.5 to 1.4 m/s)."""


@dataclass
class _Seen:
    odom: Pose
    seconds: float
    points: Floats  # robot frame at ``odom``, shape (n, 2)


@dataclass
class _Looked:
    """One scan as floor seen free: each beam's free range, from the sensor at ``odom``."""

    odom: Pose
    seconds: float
    free: Floats  # per beam: metres seen free (``range_max`` where nothing was returned)


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
        self,
        mount: Pose = (0.0, 0.0, 0.0),
        keep: float = 4.0,
        range_max: float = math.inf,
        range_min: float = 0.0,
    ) -> None:
        self.mount, self.keep = mount, keep
        self.range_min, self.range_max = range_min, range_max
        self._seen: list[_Seen] = []
        self._looked: list[_Looked] = []
        self._angles: Floats = np.zeros(0)
        self._movers = ObstacleTracker()
        self._unseen: list[Mover] = []
        self._seconds = 0.0

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
            free = np.where(hit, metres, self.range_max) - FREE_SHORT_OF
            self._looked = [
                _Looked(odom, seconds, free),
                *(looked for looked in self._looked if seconds - looked.seconds < FRESH_FLOOR),
            ]
            self._angles = angles
            self._movers.update(fresh, odom, seconds)
            self._movers.forget(seconds - self.keep)
            self._seconds = seconds
            self._unseen = self._movers_out_of_view()
        return np.concatenate([fresh, *(seen.points for seen in kept)])

    def entry_check(self, odom: Pose) -> Callable[[Floats], NDArray[np.bool_]] | None:
        """``may_enter`` at ``odom`` for a memory that looks only ahead; ``None`` (the
        robot sees all round) for one that remembers nothing (a laser's scan)."""
        return partial(self.may_enter, odom=odom) if self.keep > 0 else None

    def may_enter(self, points: Floats, odom: Pose) -> NDArray[np.bool_]:
        """For each point (robot frame at ``odom``, shape (n, 2)): whether the robot may
        move onto it: it was seen free lately (``seen_free``), or nothing seen moving in
        the last ``keep`` seconds could have got there since, at its pace plus
        ``MOVER_PACE``."""
        allowed = np.ones(len(points), bool)
        if not self._unseen or not len(points):
            return allowed
        world = transform(odom, points)
        for mover in self._unseen:
            allowed &= self._out_of_reach(mover, world)
        if allowed.all():
            return allowed
        return allowed | self.seen_free(points, odom)

    def _out_of_reach(self, mover: Mover, world: Floats) -> NDArray[np.bool_]:
        """Whether each odometry-frame point lies beyond where ``mover`` may be now: on
        its way since it was last seen (walking on, or stopped anywhere along it), or
        within ``MOVER_SPREAD`` times the time since of that way, plus ``MOVER_REACH``."""
        age = self._seconds - mover.seconds
        start = np.array(mover.centroid)
        way = np.array(mover.velocity) * age
        length = float(way @ way)
        along = np.clip((world - start) @ way / length, 0.0, 1.0) if length > 0 else 0.0
        nearest = start + np.multiply.outer(along, way)
        reach = MOVER_REACH + MOVER_SPREAD * age
        return np.asarray(np.hypot(*(world - nearest).T) > reach, bool)

    def _movers_out_of_view(self) -> list[Mover]:
        """Walkers seen lately and not in this scan, less those this scan sees again
        (one now moving within their reach: the tracker may have given them a new track)."""
        movers = [m for m in self._movers.movers.values() if m.speed >= WALKING]
        seen = [m for m in movers if m.seconds == self._seconds]
        again = np.array([s.centroid for s in seen]).reshape(-1, 2)
        return [
            m for m in movers if m.seconds < self._seconds and self._out_of_reach(m, again).all()
        ]

    def seen_free(self, points: Floats, odom: Pose) -> NDArray[np.bool_]:
        """For each point (robot frame at ``odom``, shape (n, 2)): whether a scan of the
        last ``FRESH_FLOOR`` seconds saw it free, inside its field of view, beyond the
        sensor's near limit and short of its beam's return. With no memory (``keep=0``:
        a laser's all-round scan) every point counts as seen."""
        if self.keep <= 0:
            return np.ones(len(points), bool)
        seen = np.zeros(len(points), bool)
        angles = self._angles
        if not len(angles) or not len(points):
            return seen
        increment = (angles[-1] - angles[0]) / max(1, len(angles) - 1)
        for looked in self._looked:
            there = transform(relative(compose(looked.odom, self.mount), odom), points)
            bearing = np.arctan2(there[:, 1], there[:, 0])
            distance = np.hypot(there[:, 0], there[:, 1])
            beam = np.rint((bearing - angles[0]) / increment).astype(np.intp)
            inside = (beam >= 0) & (beam < len(angles))
            free = looked.free[np.clip(beam, 0, len(angles) - 1)]
            seen |= inside & (distance >= self.range_min) & (distance <= free)
        return seen

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
    camera saw in the last ``config.obstacle_memory`` seconds too, and the floor it saw
    free lately."""
    if config.sensors != "rgbd":
        return ObstacleMemory(mount, 0.0)
    spec = DepthScanSpec()
    return ObstacleMemory(mount, config.obstacle_memory, spec.range_max, spec.range_min)
