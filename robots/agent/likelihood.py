"""The laser's likelihood field on one occupancy grid, as AMCL's likelihood field models.

Each beam endpoint is scored by its distance ``d`` to the nearest occupied cell's face::

    pz = z_hit * exp(-d^2 / (2 sigma_hit^2)) + z_rand / range_max

and a pose's likelihood combines the beams used in one of AMCL's two ways (its
``laser_model_type``): ``likelihood_field_prob``, the product of the ``pz`` (the
textbook model, and the default here), or ``likelihood_field``, ``1 + sum(pz^3)``, which
treats beams as far from independent and so discriminates much more weakly (in the demo
corridor, with AMCL's default odometry noise, its cloud spreads to half a metre along the
corridor where the product keeps it near ten centimetres). ``d`` is capped at
``max_distance``, which is also what an endpoint off the map scores, except that a beam
ending beyond the open edge of the map, for most of the particles' weight, is left out
altogether (see ``LikelihoodField.log_likelihood``). Beams without a return (``inf``,
``NaN``, JSON ``null``) or outside ``[range_min, range_max)`` are skipped, as AMCL skips
max-range readings.

The distance transform is computed once per map; scoring is a table lookup per endpoint.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.grid import FREE_BELOW, OCCUPIED_AT, cells_of, cells_to_nearest
from cloudnav_core.messages import scan_ranges
from cloudnav_core.params import BeamModel
from cloudnav_core.se2 import transform_each

Floats = NDArray[np.float64]
Grid = NDArray[np.int8]


@dataclass(frozen=True)
class Beams:
    """The beams of one scan that count: endpoints ``(x, y)`` in the robot frame, the
    laser's position ``origin`` there, and the ``z_rand`` term of the scan (it depends on
    the scan's ``range_max``)."""

    x: Floats
    y: Floats
    floor: float
    origin: tuple[float, float] = (0.0, 0.0)

    @property
    def count(self) -> int:
        return int(self.x.size)


def beams_of(scan: Mapping[str, Any], model: BeamModel) -> Beams:
    """The usable beams of a ``sensor_msgs/LaserScan`` dict, thinned to ``model.max_beams``
    evenly spaced ones before dropping those without a valid return.

    Raises KeyError for a missing field and ValueError for a non-positive ``range_max``.
    """
    ranges = scan_ranges(scan["ranges"])
    range_min, range_max = float(scan["range_min"]), float(scan["range_max"])
    if range_max <= 0:
        raise ValueError("a laser scan needs a positive range_max")
    count = min(model.max_beams, ranges.size)
    picked = np.unique(np.linspace(0, ranges.size - 1, count).round()).astype(np.intp)
    chosen = ranges[picked]
    valid = np.isfinite(chosen) & (chosen >= range_min) & (chosen < range_max)
    angles = float(scan["angle_min"]) + picked[valid] * np.float64(scan["angle_increment"])
    return _in_robot_frame(chosen[valid], angles, model, model.z_rand / range_max)


def _in_robot_frame(ranges: Floats, angles: Floats, model: BeamModel, floor: float) -> Beams:
    mx, my, myaw = model.laser_pose
    x = mx + ranges * np.cos(angles + myaw)
    y = my + ranges * np.sin(angles + myaw)
    return Beams(x, y, floor, (mx, my))


class LikelihoodField:
    """The likelihood field of one occupancy ``grid`` (int8, row 0 the bottom row) whose
    cell (0, 0) has its bottom-left corner at ``origin`` (x, y; a yaw is ignored, as most of
    Nav2 ignores it) and whose cells are ``resolution`` metres square."""

    def __init__(
        self,
        grid: Grid,
        resolution: float,
        origin: Sequence[float],
        model: BeamModel,
    ) -> None:
        grid = np.asarray(grid)
        if grid.ndim != 2 or grid.size == 0 or resolution <= 0:
            raise ValueError(
                "a likelihood field needs a non-empty 2D grid and a positive resolution"
            )
        self.model = model
        self.resolution = float(resolution)
        self.origin = (float(origin[0]), float(origin[1]))
        self.shape = grid.shape
        self.free = (grid >= 0) & (grid < FREE_BELOW)
        distance = _obstacle_distance(grid, self.resolution)
        self._hit = _hit_term(distance, model).ravel()
        self._far = model.z_hit * math.exp(-(model.max_distance**2) / (2 * model.sigma_hit**2))
        self._unseen = _unseen(grid, distance, self.resolution).ravel()
        self._free_cells = np.flatnonzero(self.free)

    def log_likelihood(self, poses: Floats, beams: Beams, weights: Floats | None = None) -> Floats:
        """Log-likelihood of ``beams`` from each of ``poses`` (N x 3, map frame), the
        particles' ``weights`` (uniform if None) deciding which beams count; zeros when no
        beam counts.

        A beam whose endpoint, for most of the weight, lies where the map cannot tell (see
        ``_unseen``), or off the map past an open stretch of its edge, is left out for
        every pose. A sub-map is a window cut from the building: scoring such beams
        against what the window shows (as AMCL does with its whole-building maps) pulls
        the cloud toward poses that bring them onto walls drawn inside it, a bias of tens
        of centimetres near the window's edge, which is where the tags and doors are.
        Other endpoints off the map (past a wall drawn on the edge) score as misses.
        """
        cells, inside = self._endpoint_cells(poses, beams)
        share = np.full(len(poses), 1 / len(poses)) if weights is None else weights
        counted = share @ self._unseen[cells] <= 0.5
        cells, inside = cells[:, counted], inside[:, counted]
        pz = np.where(inside, self._hit[cells], self._far) + beams.floor
        if self.model.laser_model == "likelihood_field":
            return np.asarray(np.log1p((pz * pz * pz).sum(axis=1)), np.float64)
        return np.asarray(np.log(pz).sum(axis=1), np.float64)

    def _endpoint_cells(
        self, poses: Floats, beams: Beams
    ) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
        """For each pose and beam (N x B): the cell under the endpoint, or for an endpoint
        off the map the border cell where the beam leaves it; and whether it is on the map."""
        x, y = transform_each(poses, beams.x, beams.y)
        cells, inside = self._cells_under(x, y)
        if not inside.all():
            off = ~inside
            laser_x, laser_y = transform_each(poses, *beams.origin)
            lx = np.broadcast_to(laser_x, x.shape)[off]
            ly = np.broadcast_to(laser_y, y.shape)[off]
            cells[off] = self._exit_cells(lx, ly, x[off], y[off])
        return cells, inside

    def _cells_under(self, x: Floats, y: Floats) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
        """Flat index of the cell under each point, clipped to the grid, and whether the
        point is on the map."""
        height, width = self.shape
        row, col = cells_of(x, y, self.origin, self.resolution, nudge=0.0)
        inside = (col >= 0) & (col < width) & (row >= 0) & (row < height)
        np.clip(col, 0, width - 1, out=col)
        np.clip(row, 0, height - 1, out=row)
        return row * width + col, inside

    def _exit_cells(self, ox: Floats, oy: Floats, x: Floats, y: Floats) -> NDArray[np.intp]:
        """The border cell where each segment from ``(ox, oy)`` to ``(x, y)`` (off the map)
        leaves the map."""
        height, width = self.shape
        x0, y0 = self.origin
        x1, y1 = x0 + width * self.resolution, y0 + height * self.resolution
        dx, dy = x - ox, y - oy
        with np.errstate(divide="ignore", invalid="ignore"):
            tx = np.where(dx > 0, (x1 - ox) / dx, np.where(dx < 0, (x0 - ox) / dx, np.inf))
            ty = np.where(dy > 0, (y1 - oy) / dy, np.where(dy < 0, (y0 - oy) / dy, np.inf))
        t = np.clip(np.minimum(tx, ty), 0.0, 1.0)
        return self._cells_under(ox + t * dx, oy + t * dy)[0]

    def free_poses(self, count: int, rng: np.random.Generator) -> Floats:
        """``count`` poses spread uniformly over the free cells, with uniform yaw.

        Raises ValueError when the map has no free cell.
        """
        if self._free_cells.size == 0:
            raise ValueError("the map has no free cell to spread particles over")
        cells = rng.choice(self._free_cells, size=count)
        rows, cols = np.divmod(cells, self.shape[1])
        jitter = rng.random((count, 2))  # anywhere inside the cell, not on its centre
        x = self.origin[0] + (cols + jitter[:, 0]) * self.resolution
        y = self.origin[1] + (rows + jitter[:, 1]) * self.resolution
        yaw = rng.uniform(-math.pi, math.pi, count)
        return np.stack([x, y, yaw], axis=1)


def _obstacle_distance(grid: Grid, resolution: float) -> NDArray[np.float32]:
    """Metres from each cell's centre to the nearest obstacle cell's face (the distance
    between centres less half a cell: a beam ends on the face, and without this the
    cloud leans half a cell into the walls); 0 on obstacles, ``inf`` with none."""
    obstacles = grid >= OCCUPIED_AT
    if not obstacles.any():
        return np.full(grid.shape, np.inf, np.float32)
    cells = cells_to_nearest(obstacles)
    return np.asarray(np.maximum(cells - 0.5, 0) * resolution, np.float32)


def _unseen(grid: Grid, distance: NDArray[np.float32], resolution: float) -> NDArray[np.bool_]:
    """Cells nearer to an open stretch of the map's edge (a border cell that is not an
    obstacle) than to any obstacle: the nearest obstacle may lie beyond the edge, unseen,
    so what the field says there is not known. Behind a walled edge nothing is unseen:
    an endpoint past a wall is a miss."""
    border = np.zeros(grid.shape, bool)
    border[[0, -1], :] = border[:, [0, -1]] = True
    open_edge = border & (grid < OCCUPIED_AT)
    if not open_edge.any():
        return np.zeros(grid.shape, bool)
    cells = cells_to_nearest(open_edge)
    return np.asarray(distance > cells * resolution, np.bool_)


def _hit_term(distance: NDArray[np.float32], model: BeamModel) -> Floats:
    """``z_hit * exp(-d^2 / (2 sigma^2))`` with ``d`` capped at ``max_distance``."""
    d = np.minimum(distance.astype(np.float64), model.max_distance)
    return np.asarray(model.z_hit * np.exp(-(d * d) / (2 * model.sigma_hit**2)), np.float64)
