"""Occupancy grids: where their cells lie in the map frame and back, and what their values
mean.

A grid follows ``nav_msgs/OccupancyGrid``: shape (height, width), row 0 is the bottom
row, and ``origin`` is the map-frame position of cell (0, 0)'s bottom-left corner (the
x, y of a map_server YAML origin; its yaw is ignored, as most of Nav2 ignores it). Its
values are 0..100 (occupancy in percent) or -1 (unknown).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from cloudnav_core.se2 import Point

Cell = tuple[int, int]
"""(row, col) of a grid cell; row 0 is the bottom row."""
Indices = npt.NDArray[np.intp]
Mask = npt.NDArray[np.bool_]

OCCUPIED_THRESH = 0.65
"""map_saver's ``occupied_thresh``: a cell this likely occupied or more is an obstacle."""
FREE_THRESH = 0.196
"""map_saver's ``free_thresh``: a cell this likely occupied or less is free."""
OCCUPIED_AT = 65
"""Occupancy values (0..100) at or above this are obstacles (``OCCUPIED_THRESH``)."""
FREE_BELOW = 20
"""Occupancy values from 0 up to below this are free (``FREE_THRESH``: 19.6 rounds up)."""

BOUNDARY_NUDGE = 1e-6
"""In cells: a point on a cell boundary belongs to the cell above or right of it, even
when float division lands just short (16.2 / 0.05 is 323.99999999999994)."""


def cell_of(
    point: Point, origin: Sequence[float], resolution: float, nudge: float = BOUNDARY_NUDGE
) -> Cell:
    """Return the (row, col) of the cell holding ``point``; it may lie outside the grid.
    ``nudge`` 0 floors the exact quotient (a point a hair short of a boundary stays
    below it)."""
    col = math.floor((point[0] - origin[0]) / resolution + nudge)
    row = math.floor((point[1] - origin[1]) / resolution + nudge)
    return row, col


def cells_of(
    xs: npt.NDArray[np.floating[Any]],
    ys: npt.NDArray[np.floating[Any]],
    origin: Sequence[float],
    resolution: float,
    *,
    nudge: float,
) -> tuple[Indices, Indices]:
    """Return the rows and columns of the cells holding points ``xs``, ``ys`` (``cell_of``
    for arrays; they may lie outside the grid). Callers say their ``nudge``: 0 or
    ``BOUNDARY_NUDGE``."""
    cols = np.floor((xs - origin[0]) / resolution + nudge).astype(np.intp)
    rows = np.floor((ys - origin[1]) / resolution + nudge).astype(np.intp)
    return rows, cols


def cells_to_nearest(marked: npt.NDArray[np.bool_]) -> npt.NDArray[np.float32]:
    """Each cell's distance in cells, centre to centre, to the nearest ``marked`` cell (0 on
    one; with none marked, OpenCV's large finite stand-in for infinity)."""
    # The exact Euclidean transform (Felzenszwalb's, in OpenCV) costs ~5 ms a megacell.
    unmarked = (~marked).astype(np.uint8)
    cells = cv2.distanceTransform(unmarked, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return np.asarray(cells, dtype=np.float32)


def centre_of(cell: Cell, origin: Sequence[float], resolution: float) -> Point:
    """Return the map-frame centre of ``cell``."""
    row, col = cell
    return origin[0] + (col + 0.5) * resolution, origin[1] + (row + 0.5) * resolution


def contains(shape: tuple[int, ...], cell: Cell) -> bool:
    """Whether ``cell`` lies inside a grid of ``shape`` (height, width)."""
    row, col = cell
    return 0 <= row < shape[0] and 0 <= col < shape[1]


def cells_inside(shape: tuple[int, ...], rows: npt.NDArray[Any], cols: npt.NDArray[Any]) -> Mask:
    """Whether each cell ``(rows, cols)`` lies inside a grid of ``shape`` (``contains`` for
    arrays)."""
    found: Mask = (rows >= 0) & (rows < shape[0]) & (cols >= 0) & (cols < shape[1])
    return found


def unstandable(grid: npt.NDArray[np.int8], cell: Cell) -> str:
    """Why no robot's centre can be in ``cell`` of occupancy ``grid`` ("outside the map",
    "in unknown space" or "in an obstacle"); "" when one can (a known cell below
    ``OCCUPIED_AT``)."""
    if not contains(grid.shape, cell):
        return "outside the map"
    value = int(grid[cell])
    if value < 0:
        return "in unknown space"
    return "in an obstacle" if value >= OCCUPIED_AT else ""
