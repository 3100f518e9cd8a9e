"""How wide the free space is at a point of a sub-map: the one measure, used where a
robot stands (is it in a narrow place others pass through? ``telemetry.parking``) and
along a robot's route (where is it too narrow for two? ``maps.domain.right_of_way``).

The free width across a line through a point is twice the largest clearance (metres to
the nearest obstacle, ``maps.domain.planning.clearance_in_cells``, the one distance
routine) on the free run of cells along that line through the point: a corridor 2 m wide
measures 2 m wherever in it the point is and however the line crosses it, a doorway its
opening. Unknown cells and the grid's edge count as obstacles. Nothing here imports
Django.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from cloudnav_core.grid import BOUNDARY_NUDGE, OCCUPIED_AT, cell_of, cells_of
from cloudnav_core.se2 import Point
from maps.domain.planning import clearance_in_cells

RING, RING_CELLS = 16, 2
"""Directions, and cells out, where ``Widths.narrowest`` looks for the way to the nearest
obstacle."""
REACH = 1.5
"""Metres each side of a point ``Widths.narrowest`` looks along each line by default."""


@dataclass(frozen=True, eq=False)
class Widths:
    """A sub-map's clearance (metres to the nearest obstacle, 0 on one), to measure how
    wide the free space is (see the module)."""

    clearance: npt.NDArray[np.float32]
    origin: tuple[float, float]
    resolution: float

    @classmethod
    def of_grid(
        cls, grid: npt.NDArray[np.int8], origin: Sequence[float], resolution: float
    ) -> Widths:
        """The widths of an occupancy grid (row 0 = bottom; unknown counts as obstacle).
        Raises ValueError as ``clearance_in_cells`` does."""
        cells = clearance_in_cells(grid, resolution, True, OCCUPIED_AT)
        metres = (cells * resolution).astype(np.float32)
        metres.flags.writeable = False
        return cls(metres, (float(origin[0]), float(origin[1])), resolution)

    def clearance_at(self, point: Point) -> float:
        """Metres from ``point`` to the nearest obstacle (0 outside the grid)."""
        row, col = cell_of(point, self.origin, self.resolution)
        height, width = self.clearance.shape
        if not (0 <= row < height and 0 <= col < width):
            return 0.0
        return float(self.clearance[row, col])

    def across(self, point: Point, heading: float, reach: float) -> float:
        """The free width across a route at ``point`` going ``heading`` (radians): twice
        the largest clearance on the free run of cells through ``point`` perpendicular to
        it, looked at out to ``reach`` metres each side (0 in an obstacle)."""
        steps = int(reach / self.resolution)
        offsets = np.arange(-steps, steps + 1) * self.resolution
        xs = point[0] - math.sin(heading) * offsets
        ys = point[1] + math.cos(heading) * offsets
        values = self._sample(xs, ys)
        if values[steps] <= 0.0:
            return 0.0
        walls = np.flatnonzero(values <= 0.0)
        low = walls[walls < steps].max(initial=-1) + 1
        high = walls[walls > steps].min(initial=len(values))
        return 2.0 * float(values[low:high].max())

    def narrowest(self, point: Point, reach: float = REACH) -> float:
        """The free width of the passage ``point`` is in: ``across`` it on the line
        through ``point`` towards its nearest obstacle (looked for on a ring of RING
        directions, ``RING_CELLS`` cells out), so that a doorway measures its opening and
        a corridor its width wherever in it the point is; 0 in an obstacle."""
        angles = np.arange(RING) * (2 * math.pi / RING)
        out = RING_CELLS * self.resolution
        ring = self._sample(point[0] + out * np.cos(angles), point[1] + out * np.sin(angles))
        towards = float(angles[int(np.argmin(ring))])
        return self.across(point, towards - math.pi / 2, reach)

    def _sample(
        self, xs: npt.NDArray[np.floating[Any]], ys: npt.NDArray[np.floating[Any]]
    ) -> npt.NDArray[np.float32]:
        rows, cols = cells_of(xs, ys, self.origin, self.resolution, nudge=BOUNDARY_NUDGE)
        height, width = self.clearance.shape
        inside = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)
        values = np.zeros(len(xs), dtype=np.float32)
        values[inside] = self.clearance[rows[inside], cols[inside]]
        return values
