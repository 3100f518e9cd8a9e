"""A reproducible synthetic occupancy grid for the planner: its tests and its benchmark."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

Grid = npt.NDArray[np.int8]
OBSTACLE = 100


def obstacle_course(size: int, seed: int) -> Grid:
    """Return a reproducible ``size`` x ``size`` occupancy grid (0 free, 100 occupied).

    Seeded random rectangles, then three walls across each axis that cut the grid into
    16 rooms, with one gap at a random place in each wall between two crossings (so a
    path must find the gaps), and the two corners kept clear for start and goal. The
    gaps' approaches are cleared, but rectangles may still wall a corner off: check a
    new seed.
    """
    rng = np.random.default_rng(seed)
    grid = np.zeros((size, size), dtype=np.int8)
    for _ in range(size * size // 6700):
        height, width = rng.integers(size // 100, size // 12, 2)
        row, col = rng.integers(0, size, 2)
        grid[row : row + height, col : col + width] = OBSTACLE
    thick, gap, room = max(size // 160, 1), max(size // 25, 2), size // 4
    for at in range(room, size, room):
        grid[:, at : at + thick] = OBSTACLE
        grid[at : at + thick, :] = OBSTACLE
    for at in range(room, size, room):
        for first in range(0, size - room + 1, room):
            # A gap and its approaches on both sides, so that no rectangle plugs it.
            across, along = slice(at - gap, at + thick + gap), _gap(rng, first, room, gap)
            grid[along, across] = 0
            grid[across, _gap(rng, first, room, gap)] = 0
    corner = size // 25
    grid[:corner, :corner] = grid[-corner:, -corner:] = 0
    return grid


def _gap(rng: np.random.Generator, first: int, room: int, gap: int) -> slice:
    """A gap's span in the stretch of wall from ``first`` that is ``room`` long."""
    opening = int(rng.integers(first + 2 * gap, first + room - 3 * gap))
    return slice(opening, opening + gap)
