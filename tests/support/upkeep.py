"""The rooms of the map upkeep tests: the stored map, and the truth the robot scans."""

from __future__ import annotations

import numpy as np

RES = 0.05


def room(boxes: list[tuple[int, int, int, int]]) -> np.ndarray:
    """A 6 x 6 m room (120 cells a side) walled round, with boxes (row0, row1, col0, col1)."""
    grid = np.zeros((120, 120), np.int8)
    grid[:2, :] = grid[-2:, :] = grid[:, :2] = grid[:, -2:] = 100
    for r0, r1, c0, c1 in boxes:
        grid[r0:r1, c0:c1] = 100
    return grid


STORED = room([(30, 40, 30, 40)])  # a cabinet at (1.5-2, 1.5-2) m
TRUTH = room([(80, 90, 70, 90)])  # ...gone; a table at (3.5-4.5, 4-4.5) m instead
