"""What the laser sees, as obstacles with velocities: the input of the TEB planner.

Each scan's returns are cut into clusters where neighbouring returns lie more than
``GAP`` apart. A cluster no wider than ``MOVER_SIZE`` (a person's legs, a robot) is a
candidate mover: its centroid, in the odometry frame (which moves smoothly, unlike the
map pose a tag or the particle filter may reset), is matched to the nearest candidate
of the last scan within ``GATE``, and its velocity is the matched centroids' motion over
the time between the scans, low-pass filtered. Velocities under ``STILL`` count as zero:
walls, furniture and things that stand. Every return of a moving cluster moves with it;
the planner predicts each one at constant velocity.

A wall's end or an occluded edge can look like a small cluster whose centroid slides as
the robot moves; the filter and ``STILL`` keep those near zero, and they are at worst
predicted to move slowly.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.se2 import Pose, transform

Floats = NDArray[np.float64]

GAP = 0.2
"""Metres between neighbouring returns that separate two clusters."""
MOVER_SIZE = 0.8
"""Metres: the widest cluster taken for something that may move."""
GATE = 0.4
"""Metres a mover's centroid may move between two scans and be matched."""
STILL = 0.15
"""m/s: slower movers count as standing."""
SMOOTHING = 0.5
"""Weight of the newest measured velocity in the filtered one."""
REACH = 4.0
"""Metres: returns farther than this are not tracked (nor planned around)."""


@dataclass(frozen=True)
class SeenObstacles:
    """Laser returns in the robot's frame, ``points`` (n, 2), each with its ``velocity``
    (n, 2, m/s in the robot's frame at the time of the scan)."""

    points: Floats
    velocities: Floats

    def at(self, seconds: float | Floats) -> Floats:
        """The points predicted ``seconds`` ahead at constant velocity: (n, 2), or
        (k, n, 2) for ``k`` times."""
        t = np.asarray(seconds, np.float64)[..., None, None]
        return np.asarray(self.points + self.velocities * t, np.float64)


_keys = itertools.count()


@dataclass(frozen=True)
class Mover:
    """Where something was last seen moving: ``centroid`` and ``velocity`` (m/s) in the
    odometry frame, and the time it was seen."""

    centroid: tuple[float, float]
    velocity: tuple[float, float]
    seconds: float

    @property
    def speed(self) -> float:
        return math.hypot(*self.velocity)


@dataclass
class _Track:
    centroid: tuple[float, float]  # odometry frame
    velocity: tuple[float, float] = (0.0, 0.0)
    age: int = 0
    key: int = field(default_factory=lambda: next(_keys))


class ObstacleTracker:
    """Tracks the small clusters of successive scans; ``update`` once per scan."""

    def __init__(self) -> None:
        self._tracks: list[_Track] = []
        self._seconds: float | None = None
        self.movers: dict[int, Mover] = {}
        """The last sighting of each moving track, by track; ``forget`` drops old ones."""

    def update(self, points: Floats, odom: Pose, seconds: float) -> SeenObstacles:
        """The returns ``points`` (robot frame, in scan order) with the velocities of
        the clusters they belong to; ``odom`` is the robot's odometry pose then."""
        near = points[np.hypot(points[:, 0], points[:, 1]) <= REACH] if len(points) else points
        clusters = _clusters(near)
        dt = None if self._seconds is None else seconds - self._seconds
        self._seconds = seconds
        velocities = np.zeros((len(near), 2))
        tracks: list[_Track] = []
        for members in clusters:
            cluster = near[members]
            if _width(cluster) > MOVER_SIZE:
                continue
            track = self._follow(transform(odom, cluster).mean(axis=0), dt)
            tracks.append(track)
            speed = math.hypot(*track.velocity)
            if track.age >= 2 and speed >= STILL:
                velocities[members] = _into_robot_frame(track.velocity, odom[2])
                self.movers[track.key] = Mover(track.centroid, track.velocity, seconds)
        self._tracks = tracks
        return SeenObstacles(near, velocities)

    def forget(self, before: float) -> None:
        """Drop the movers last seen before ``before`` (seconds)."""
        self.movers = {k: m for k, m in self.movers.items() if m.seconds >= before}

    def _follow(self, centroid: Floats, dt: float | None) -> _Track:
        """The track ``centroid`` continues (matched within ``GATE``), or a new one."""
        here = (float(centroid[0]), float(centroid[1]))
        match = min(self._tracks, key=lambda t: math.dist(t.centroid, here), default=None)
        if match is None or dt is None or dt <= 0 or math.dist(match.centroid, here) > GATE:
            return _Track(here)
        measured = ((here[0] - match.centroid[0]) / dt, (here[1] - match.centroid[1]) / dt)
        weight = SMOOTHING if match.age else 1.0
        velocity = (
            weight * measured[0] + (1 - weight) * match.velocity[0],
            weight * measured[1] + (1 - weight) * match.velocity[1],
        )
        self._tracks.remove(match)  # one cluster per track
        return _Track(here, velocity, match.age + 1, match.key)


def _clusters(points: Floats) -> list[NDArray[np.intp]]:
    """Indices of each run of neighbouring returns (the scan wraps round: the last run
    joins the first when they touch)."""
    if len(points) == 0:
        return []
    steps = np.hypot(*np.diff(points, axis=0).T)
    breaks = np.flatnonzero(steps > GAP) + 1
    runs = np.split(np.arange(len(points)), breaks)
    if len(runs) > 1 and math.dist(points[-1], points[0]) <= GAP:
        runs = [np.concatenate([runs[-1], runs[0]]), *runs[1:-1]]
    return runs


def _width(cluster: Floats) -> float:
    spread = cluster.max(axis=0) - cluster.min(axis=0)
    return float(math.hypot(*spread))


def _into_robot_frame(velocity: tuple[float, float], yaw: float) -> tuple[float, float]:
    c, s = math.cos(yaw), math.sin(yaw)
    return c * velocity[0] + s * velocity[1], -s * velocity[0] + c * velocity[1]
