"""The 2D occupancy grid a robot navigates on, from an RGB-D camera's keyframes.

Nav2's rule for a depth camera (its voxel and obstacle layers): what stands between the
floor and the robot's height is an obstacle, the floor and what hangs above the robot
(a ceiling, a table top higher than the robot) is not. Each keyframe's registered depth
is lifted to 3D (every ``STRIDE``-th pixel), and each image column becomes one beam from
the robot's centre: it ends at the nearest point of that column within the height band
(a hit), or, when the column saw only floor or things out of the band, it is a beam with
no return, free as far as the laser mapper frees one (``SlamParams.free_range``). A
column with no usable reading at all (too near, too far, no depth) says nothing and is
left out. These planar scans, at the keyframes' optimised poses, go through the laser
mapper's log-odds occupancy (``slam.LogOddsGrid``), so a visual session's grid follows
exactly the same thresholds as a laser session's (map_saver's 0.65 and 0.196).

Nothing here imports Django.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cloudnav_core.camera import Intrinsics, Mount
from cloudnav_core.se2 import Pose
from maps.domain.keyframes import DEPTH_RANGE, Depth
from maps.domain.slam.occupancy import Grid, LogOddsGrid
from maps.domain.slam.params import SlamParams
from maps.domain.slam.scans import Scan

STRIDE = 4
"""Pixels: every STRIDE-th row and column of the depth image is read (160 beams from a
640-pixel-wide camera; 19,200 points a keyframe)."""


@dataclass(frozen=True)
class HeightBand:
    """Metres above the floor: what lies between ``floor`` and ``robot`` is an obstacle."""

    floor: float = 0.05
    """The floor's own readings (and a cable on it) stay below this."""
    robot: float = 0.5
    """The robot's height: anything higher passes over it."""


def obstacle_scan(
    depth: Depth,
    intrinsics: Intrinsics,
    mount: Mount | None = None,
    band: HeightBand | None = None,
) -> Scan:
    """The planar scan (robot frame, from its centre) of the obstacles a registered
    ``depth`` image (metres along the optical axis; NaN, inf or 0 where there is no
    reading) shows within ``band``: NaN ranges for columns that saw no obstacle."""
    mount, band = mount or Mount(), band or HeightBand()
    rows = np.arange(0, depth.shape[0], STRIDE)
    cols = np.arange(0, depth.shape[1], STRIDE)
    z = np.asarray(depth, np.float64)[np.ix_(rows, cols)]
    with np.errstate(invalid="ignore"):
        usable = np.isfinite(z) & (z >= DEPTH_RANGE[0]) & (z <= DEPTH_RANGE[1])
    z = np.where(usable, z, np.nan)
    left = -(cols[None, :] - intrinsics.cx) * z / intrinsics.fx
    height = mount.height - (rows[:, None] - intrinsics.cy) * z / intrinsics.fy
    forward = z + mount.forward
    with np.errstate(invalid="ignore"):
        obstacle = usable & (height >= band.floor) & (height <= band.robot)
    ranges = np.where(obstacle, np.hypot(forward, left), np.inf)
    nearest = np.argmin(ranges, axis=0)
    picked = np.arange(len(cols))
    hit = np.isfinite(ranges[nearest, picked])
    bearing = np.arctan2(-(cols - intrinsics.cx) / intrinsics.fx, 1.0)
    hit_bearing = np.arctan2(left[nearest, picked], forward[nearest, picked])
    angles = np.where(hit, hit_bearing, bearing)
    seen = usable.any(axis=0)
    out = np.where(hit, ranges[nearest, picked], math.nan)
    return Scan(angles[seen].astype(np.float64), out[seen].astype(np.float64))


def grid_of_views(
    views: Sequence[tuple[Pose, Scan]], resolution: float = 0.05
) -> tuple[Grid, tuple[float, float]]:
    """The occupancy grid (row 0 = bottom; 100, 0, -1) of ``obstacle_scan`` views at
    their poses, and the map-frame position of its cell (0, 0)'s corner."""
    log_odds = LogOddsGrid(SlamParams(resolution=resolution), None)
    for pose, scan in views:
        log_odds.add_view(pose, scan)
    return log_odds.grid()
