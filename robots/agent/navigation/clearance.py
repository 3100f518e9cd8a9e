"""What the laser sees, as clearance: ``LocalObstacles`` (distance from points of the
robot's frame to the nearest return, on a grid around the robot) and ``Clearance`` (the
controller's view: from what stands, near and far, and from what moves)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.grid import cells_of, cells_to_nearest
from cloudnav_core.se2 import Floats
from robots.agent.tracking import SeenObstacles


class LocalObstacles:
    """Clearance around the robot: distance from points of the robot's frame to the
    nearest laser return, on a square grid ``reach`` metres each way.

    Points off that grid are taken as clear (``reach``): the controller never looks that
    far. Distances are between cell centres, less half a cell, so they err short.
    ``may_enter``, for a sensor that looks only ahead (``robots.agent.depth_scan``), says
    which robot-frame points the robot may move onto; ``None`` (a laser's all-round scan):
    all of them.
    """

    def __init__(
        self,
        points: Floats,
        reach: float = 2.5,
        resolution: float = 0.05,
        may_enter: Callable[[Floats], NDArray[np.bool_]] | None = None,
    ) -> None:
        self.points = points  # laser returns, robot frame, shape (n, 2)
        self.may_enter = may_enter
        self.reach, self.resolution = reach, resolution
        self.size = round(2 * reach / resolution)
        cells = self._cells(points[:, 0], points[:, 1]) if len(points) else None
        self._distance = _clearance_grid(self.size, cells, resolution)

    @classmethod
    def from_scan(cls, ranges: Floats, angles: Floats) -> LocalObstacles:
        """From a scan's ranges (``inf`` = no return) at ``angles`` in the robot frame."""
        hit = np.isfinite(ranges)
        distance, angle = ranges[hit], angles[hit]
        return cls(np.stack([distance * np.cos(angle), distance * np.sin(angle)], 1))

    def clearance(self, x: Floats, y: Floats) -> Floats:
        """Clearance in metres at each robot-frame point ``(x, y)`` (arrays of one shape)."""
        rows, cols = self._cells(x, y)
        inside = (rows >= 0) & (rows < self.size) & (cols >= 0) & (cols < self.size)
        found = self._distance[np.where(inside, rows, 0), np.where(inside, cols, 0)]
        return np.where(inside, found, self.reach)

    def _cells(self, x: Floats, y: Floats) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        # The grid is centred on the robot: its corner is at (-reach, -reach).
        corner = (-self.reach, -self.reach)
        return cells_of(np.asarray(x), np.asarray(y), corner, self.resolution, nudge=0.0)


def _clearance_grid(
    size: int, cells: tuple[NDArray[np.intp], NDArray[np.intp]] | None, resolution: float
) -> Floats:
    """Metres from each cell to the nearest marked one (``inf`` with none marked)."""
    if cells is None:
        return np.full((size, size), np.inf)
    rows, cols = cells
    inside = (rows >= 0) & (rows < size) & (cols >= 0) & (cols < size)
    marked = np.zeros((size, size), bool)
    marked[rows[inside], cols[inside]] = True
    if inside.sum() == 0:
        return np.full((size, size), np.inf)
    distance = cells_to_nearest(marked)
    return np.maximum(np.asarray(distance, np.float64) - 0.5, 0.0) * resolution


CELL = 0.05
"""Metres: the clearance grid's cell (``LocalObstacles``' resolution)."""


@dataclass
class Clearance:
    """Clearance from what stands (a ``LocalObstacles`` grid for returns farther than
    ``EXACT_REACH``, exact distances to the nearer ones, so that a robot close to
    something cannot creep nearer within one cell of the grid) and from what moves
    (returns predicted at constant velocity, counted ``margin`` nearer than they are)."""

    still: LocalObstacles
    near: Floats
    movers: SeenObstacles
    margin: float = 0.0

    @classmethod
    def of(cls, seen: SeenObstacles, obstacles: LocalObstacles) -> Clearance:
        """``seen`` split into what stands, far and near, and what moves within
        ``MOVER_REACH``."""
        moving = np.any(seen.velocities != 0, axis=1)
        distance = np.hypot(seen.points[:, 0], seen.points[:, 1])
        near = ~moving & (distance < EXACT_REACH)
        far = ~moving & ~near
        still = LocalObstacles(seen.points[far], obstacles.reach, obstacles.resolution)
        movers = moving & (distance <= MOVER_REACH)
        return cls(
            still, seen.points[near], SeenObstacles(seen.points[movers], seen.velocities[movers])
        )

    def along(self, xs: Floats, ys: Floats, times: Floats) -> Floats:
        """Clearance at each point ``(xs, ys)`` (robot frame, shape (arcs, steps)) at
        the step's time in ``times`` (steps,)."""
        clear = self.still.clearance(xs, ys)
        if len(self.near):
            clear = np.minimum(clear, _nearest(xs, ys, self.near[None, :, :]))
        if len(self.movers.points):
            clear = np.minimum(clear, _nearest(xs, ys, self.movers.at(times)) - self.margin)
        return np.asarray(clear)

    def here(self) -> float:
        """Clearance at the robot now."""
        zero = np.zeros((1, 1))
        return float(self.along(zero, zero, np.zeros(1))[0, 0])


def _nearest(xs: Floats, ys: Floats, points: Floats) -> Floats:
    """Distance from each point ``(xs, ys)`` (arcs, steps) to the nearest of ``points``
    at its step, (steps, n, 2), or the same ``points`` at every step, (1, n, 2)."""
    dx = xs[:, :, None] - points[None, :, :, 0]
    dy = ys[:, :, None] - points[None, :, :, 1]
    return np.asarray(np.sqrt((dx * dx + dy * dy).min(axis=2)))


EXACT_REACH = 0.6
"""Metres: returns that stand nearer than this are measured exactly, not on the grid."""
MOVER_REACH = 3.5
"""Metres: returns that move farther than this are left out (at walking speed and the
robot's, they cannot come within reach over the horizon)."""
