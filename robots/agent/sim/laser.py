"""A simulated 2D laser scanner: exact ray casting on the world's grid, plus range noise.

Beams go counter-clockwise from ``angle_min`` in the laser frame, which sits ``mount_x``
metres ahead of the robot's centre and is aligned with it. A beam that hits nothing
between ``range_min`` and ``range_max`` has no return: ``inf`` in ``scan`` (REP 117) and
``null`` in the rosbridge message.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.messages import Json, ScanGeometry, laser_scan
from cloudnav_core.se2 import Pose, ahead
from robots.agent.sim.crowd import Movers, cast_discs
from robots.agent.sim.world import World

Ranges = NDArray[np.float32]


@dataclass(frozen=True)
class LaserSpec:
    """Beam layout and sensor properties (an LDS-01-class scanner by default)."""

    beams: int = 360
    angle_min: float = -math.pi
    range_min: float = 0.12
    range_max: float = 8.0
    noise_sigma: float = 0.01  # metres, Gaussian, per beam
    mount_x: float = 0.0
    scan_time: float = 0.2  # seconds per revolution (5 Hz)

    @property
    def angle_increment(self) -> float:
        return 2 * math.pi / self.beams

    @property
    def angle_max(self) -> float:
        return self.angle_min + (self.beams - 1) * self.angle_increment

    def geometry(self) -> ScanGeometry:
        """Its scans' beams and range, as ``sensor_msgs/LaserScan`` holds them."""
        return {
            "angle_min": self.angle_min,
            "angle_max": self.angle_max,
            "angle_increment": self.angle_increment,
            "time_increment": self.scan_time / self.beams,
            "scan_time": self.scan_time,
            "range_min": self.range_min,
            "range_max": self.range_max,
        }

    def angles(self) -> NDArray[np.float64]:
        """Beam angles in the laser frame, radians."""
        return np.asarray(self.angle_min + np.arange(self.beams) * self.angle_increment, np.float64)


class Laser:
    """Scans of ``world``, and of what ``movers`` returns at each scan (people and other
    robots), with noise drawn from a generator seeded with ``seed``."""

    def __init__(
        self,
        world: World,
        spec: LaserSpec | None = None,
        seed: int = 0,
        movers: Movers | None = None,
    ) -> None:
        self.world = world
        self.movers = movers  # people and other robots, seen like walls
        self.spec = spec or LaserSpec()
        self.rng = np.random.default_rng(seed)
        self._angles = self.spec.angles()

    def scan(self, pose: Pose) -> Ranges:
        """Ranges in metres of one scan from a robot at ``pose`` (map frame).

        ``inf`` where there is no return within ``[range_min, range_max]``.
        """
        spec = self.spec
        origin = ahead(pose, spec.mount_x)
        angles = self._angles + pose[2]
        distance = self.world.cast(*origin, angles, spec.range_max).distance
        if self.movers is not None:
            distance = np.minimum(distance, cast_discs(*origin, angles, self.movers())[0])
        ranges = distance + self.rng.normal(0.0, spec.noise_sigma, spec.beams)
        valid = (ranges >= spec.range_min) & (ranges <= spec.range_max)
        return np.where(valid, ranges, np.inf).astype(np.float32)

    def message(self, ranges: Ranges, seconds: float, frame_id: str = "base_scan") -> Json:
        """``sensor_msgs/LaserScan`` of ``ranges`` stamped ``seconds``; no returns are null.

        A plain dict rather than the ``LaserScan`` schema: experiments narrow a scan's
        field of view by rewriting its fields."""
        return dict(laser_scan(frame_id, ranges.tolist(), seconds, **self.spec.geometry()))
