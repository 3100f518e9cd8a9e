"""Where an occupancy grid's cells lie in its map frame, and back.

A grid follows ``nav_msgs/OccupancyGrid``: shape (height, width), row 0 is the bottom
row, and ``origin`` is the map-frame position of cell (0, 0)'s bottom-left corner (the
x, y of a map_server YAML origin; its yaw is ignored, as most of Nav2 ignores it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from robots.domain.se2 import Point

Cell = tuple[int, int]
"""(row, col) of a grid cell; row 0 is the bottom row."""

_BOUNDARY_NUDGE = 1e-6
"""In cells: a point on a cell boundary belongs to the cell above or right of it, even
when float division lands just short (16.2 / 0.05 is 323.99999999999994)."""


def cell_of(point: Point, origin: Sequence[float], resolution: float) -> Cell:
    """Return the (row, col) of the cell holding ``point``; it may lie outside the grid."""
    col = math.floor((point[0] - origin[0]) / resolution + _BOUNDARY_NUDGE)
    row = math.floor((point[1] - origin[1]) / resolution + _BOUNDARY_NUDGE)
    return row, col


def centre_of(cell: Cell, origin: Sequence[float], resolution: float) -> Point:
    """Return the map-frame centre of ``cell``."""
    row, col = cell
    return origin[0] + (col + 0.5) * resolution, origin[1] + (row + 0.5) * resolution


def contains(shape: tuple[int, ...], cell: Cell) -> bool:
    """Whether ``cell`` lies inside a grid of ``shape`` (height, width)."""
    row, col = cell
    return 0 <= row < shape[0] and 0 <= col < shape[1]
