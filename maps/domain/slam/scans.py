"""A laser scan as SLAM uses it (``Scan``, read from its ``sensor_msgs/LaserScan``) and a
keyframe (``Keyframe``: a scan with the map-frame pose it was taken from).

Bad readings (NaN, inf, out of ``[range_min, range_max]``) are returns of nothing: they
mark no cell, and scans with too few good beams are not matched. A message whose ranges or
angles are not numbers is refused whole (ValueError).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cloudnav_core.messages import scan_ranges
from cloudnav_core.se2 import Floats, Pose


@dataclass(frozen=True)
class Scan:
    """A laser scan reduced to what SLAM uses: beam angles (laser frame = robot frame)
    and ranges in metres, NaN where there was no usable return."""

    angles: Floats
    ranges: Floats

    @classmethod
    def from_message(cls, msg: dict[str, object], usable_range: float = math.inf) -> Scan:
        """From a ``sensor_msgs/LaserScan`` in rosbridge JSON (``null`` for no return).

        Raises ValueError for a message with no beams or unusable angle fields."""
        raw = msg.get("ranges")
        if not isinstance(raw, list) or not raw:
            raise ValueError("a scan with no ranges")
        start, step = _number(msg, "angle_min"), _number(msg, "angle_increment")
        low = _number(msg, "range_min", 0.0)
        high = min(_number(msg, "range_max", math.inf), usable_range)
        if not all(r is None or (type(r) in (int, float)) for r in raw):
            raise ValueError("a scan whose ranges are not all numbers (or null)")
        ranges = scan_ranges(raw)
        ranges[~np.isfinite(ranges) | (ranges < low) | (ranges > high)] = math.nan
        angles = start + step * np.arange(len(ranges), dtype=np.float64)
        if not np.isfinite(angles).all():
            raise ValueError("a scan whose beam angles are not finite")
        return cls(angles, ranges)

    def thinned(self, count: int) -> Scan:
        step = max(1, len(self.ranges) // count)
        return Scan(self.angles[::step], self.ranges[::step])

    def points(self) -> Floats:
        """Returns in the robot frame, shape (n, 2); beams with no return left out."""
        good = np.isfinite(self.ranges)
        r, a = self.ranges[good], self.angles[good]
        return np.column_stack((r * np.cos(a), r * np.sin(a)))


def _number(msg: dict[str, object], key: str, default: float | None = None) -> float:
    value = msg.get(key, default)
    if not isinstance(value, int | float) or not math.isfinite(value):
        if default is not None and value is None:
            return default
        raise ValueError(f"a scan whose {key} is not a number")
    return float(value)


@dataclass
class Keyframe:
    """A node of the pose graph: its pose in the map frame and its scan."""

    pose: Pose
    scan: Scan
    points: Floats  # returns in the robot frame
