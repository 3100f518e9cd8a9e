"""The log-odds occupancy grid (``LogOddsGrid``) SLAM builds from its keyframes, and the
occupied cells of a grid as points (``occupied_points``).

The grid adds each keyframe's scan once, by log-odds (``log_hit`` for the cell a beam ends
in, ``log_miss`` for the cells it passes through up to half a cell before its return, by
the core's one traversal ``cloudnav_core.beams.traverse``, clamped). Cells at or above
``occupied_log_odds`` are occupied, at or below ``free_log_odds`` free, the rest unknown:
map_saver's 0.65 and 0.196 thresholds. No well-kept PyPI library does 2D log-odds
occupancy from scans, so it is here, in numpy.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from cloudnav_core.beams import Beams, grid_point, traverse
from cloudnav_core.grid import FREE_BELOW, OCCUPIED_AT, cells_inside, cells_of
from cloudnav_core.se2 import Floats, Pose, transform

from .params import SlamParams
from .scans import Keyframe, Scan

Grid = npt.NDArray[np.int8]


class LogOddsGrid:
    """A growing log-odds grid; each keyframe's scan is added once (``add``; ``add_view``
    for a scan and its pose), ``grid`` reads it as 100, 0, -1 by the thresholds."""

    CHUNK = 256  # cells the grid grows by at a time, so it is seldom copied

    def __init__(self, params: SlamParams, prior: tuple[Grid, tuple[float, float]] | None) -> None:
        self.params = params
        self.values = np.zeros((0, 0), dtype=np.float32)
        self.origin = (0.0, 0.0)
        if prior is not None:
            grid, origin = prior
            self.origin = origin
            self.values = np.where(
                grid >= OCCUPIED_AT,
                params.log_clamp / 2,
                np.where((grid >= 0) & (grid < FREE_BELOW), -params.log_clamp / 2, 0.0),
            ).astype(np.float32)

    def add(self, keyframe: Keyframe) -> None:
        p = self.params
        hits = transform(keyframe.pose, keyframe.points)
        scan = keyframe.scan
        # a beam is free up to half a cell before its return (``free_range`` with none)
        reach = np.where(np.isfinite(scan.ranges), scan.ranges - p.resolution / 2, p.free_range)
        reach = np.clip(reach, 0.0, None)
        headings = scan.angles + keyframe.pose[2]
        x, y = keyframe.pose[0], keyframe.pose[1]
        ends = np.column_stack((x + reach * np.cos(headings), y + reach * np.sin(headings)))
        self._grow(np.concatenate((hits, ends, [(x, y)])))
        start = grid_point((x, y), self.origin, p.resolution)
        free_cells = self._passed(Beams.towards(*start, headings), reach)
        hit_cells = self._cells(hits)
        free_cells = np.setdiff1d(free_cells, hit_cells)
        flat = self.values.reshape(-1)
        flat[free_cells] += p.log_miss
        flat[hit_cells] += p.log_hit
        np.clip(flat, -p.log_clamp, p.log_clamp, out=flat)

    def add_view(self, pose: Pose, scan: Scan) -> None:
        """Add ``scan`` taken from map-frame ``pose``."""
        self.add(Keyframe(pose, scan, scan.points()))

    def _cells(self, points: Floats) -> npt.NDArray[np.intp]:
        res = self.params.resolution
        rows, cols = cells_of(points[:, 0], points[:, 1], self.origin, res, nudge=0.0)
        return np.unique(rows * self.values.shape[1] + cols)

    def _passed(self, beams: Beams, reach: Floats) -> npt.NDArray[np.intp]:
        """Flat indices of the cells ``beams`` pass through up to ``reach`` metres (the
        core's one traversal); a cell a hair off the grid's edge (an end on it) is left
        out."""
        passed = traverse(beams, reach / self.params.resolution)
        rows, cols = passed.rows, passed.cols
        on_grid = cells_inside(self.values.shape, rows, cols)
        return np.unique(rows[on_grid] * self.values.shape[1] + cols[on_grid])

    def _grow(self, points: Floats) -> None:
        """Make the grid hold ``points``, growing it by whole chunks."""
        res = self.params.resolution
        lo, hi = points.min(axis=0), points.max(axis=0)
        height, width = self.values.shape
        x0, y0 = self.origin
        if (
            width
            and lo[0] >= x0
            and lo[1] >= y0
            and hi[0] < x0 + width * res
            and hi[1] < y0 + height * res
        ):
            return
        margin = self.CHUNK // 2 * res
        if not width:
            x0 = math.floor((lo[0] - margin) / res) * res
            y0 = math.floor((lo[1] - margin) / res) * res
            x1, y1 = hi[0] + margin, hi[1] + margin
        else:
            x1, y1 = max(x0 + width * res, hi[0] + margin), max(y0 + height * res, hi[1] + margin)
            x0 = min(x0, x0 - math.ceil((x0 - lo[0] + margin) / res) * res if lo[0] < x0 else x0)
            y0 = min(y0, y0 - math.ceil((y0 - lo[1] + margin) / res) * res if lo[1] < y0 else y0)
        new_w = math.ceil((x1 - x0) / res)
        new_h = math.ceil((y1 - y0) / res)
        grown = np.zeros((new_h, new_w), dtype=np.float32)
        if width:
            c = round((self.origin[0] - x0) / res)
            r = round((self.origin[1] - y0) / res)
            grown[r : r + height, c : c + width] = self.values
        self.values, self.origin = grown, (x0, y0)

    def grid(self) -> tuple[Grid, tuple[float, float]]:
        p = self.params
        out = np.full(self.values.shape, -1, dtype=np.int8)
        out[self.values <= p.free_log_odds] = 0
        out[self.values >= p.occupied_log_odds] = 100
        return out, self.origin


def occupied_points(grid: Grid, origin: tuple[float, float], resolution: float) -> Floats:
    rows, cols = np.nonzero(grid >= OCCUPIED_AT)
    return np.column_stack(
        (origin[0] + (cols + 0.5) * resolution, origin[1] + (rows + 0.5) * resolution)
    )
