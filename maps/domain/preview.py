"""What an upload would store, before it is stored: the cells of each kind it holds, and
its occupancy grid shrunk to a size a page can draw.

The page that uploads a sub-map draws this answer of a dry-run upload, so the browser
never converts a map itself: ``maps.domain.mapfile`` is the only implementation of the
rule.
"""

from __future__ import annotations

import math
from dataclasses import asdict, replace
from typing import Any, TypedDict

import numpy as np

from .mapfile import FREE, OCCUPIED, UNKNOWN, Grid, LoadedMap, occupancy_grid_message

# At most 512 x 512 preview cells: a few hundred kB of JSON for the largest map.
PREVIEW_MAX_SIDE = 512


class CellCounts(TypedDict):
    """Cells of a grid by kind; ``other`` holds 1..99 (scale and raw modes)."""

    free: int
    occupied: int
    unknown: int
    other: int


def cell_counts(grid: Grid) -> CellCounts:
    """Return how many cells of ``grid`` are free, occupied, unknown and in between."""
    free = int(np.count_nonzero(grid == FREE))
    occupied = int(np.count_nonzero(grid == OCCUPIED))
    unknown = int(np.count_nonzero(grid == UNKNOWN))
    return CellCounts(
        free=free, occupied=occupied, unknown=unknown, other=grid.size - free - occupied - unknown
    )


def downsampled(grid: Grid, max_side: int = PREVIEW_MAX_SIDE) -> tuple[Grid, int]:
    """Return ``grid`` shrunk by a whole factor until neither side exceeds max_side, and
    the factor (1: ``grid`` itself).

    Each preview cell is the most occupied cell of its block, unknown ranking above free
    and below any other value, so one-cell walls stay visible. Blocks start at cell
    (0, 0), the bottom-left one, so the origin is unchanged; the last row and column of
    blocks may be partial.
    """
    height, width = grid.shape
    factor = max(1, math.ceil(max(height, width) / max_side))
    if factor == 1:
        return grid, 1
    rows, cols = math.ceil(height / factor), math.ceil(width / factor)
    # Rank 2v for a value v and 1 for unknown; padding ranks 0 and never wins a block
    # that holds a cell of the map.
    ranks = np.zeros((rows * factor, cols * factor), dtype=np.int16)
    ranks[:height, :width] = np.where(grid == UNKNOWN, 1, grid.astype(np.int16) * 2)
    best = ranks.reshape(rows, factor, cols, factor).max(axis=(1, 3))
    return np.where(best == 1, UNKNOWN, best // 2).astype(np.int8), factor


def upload_preview(
    loaded: LoadedMap, frame_id: str, max_side: int = PREVIEW_MAX_SIDE
) -> dict[str, Any]:
    """Return what storing ``loaded`` would store, for a page to show.

    ``image_name``, ``width`` and ``height`` (in cells), the map_server metadata as the
    sub-map API lists it, ``counts`` of the whole grid (``cell_counts``), and
    ``preview``: a ``nav_msgs/OccupancyGrid`` (rosbridge JSON, frame ``frame_id``) of the
    grid ``downsampled`` to max_side, its resolution multiplied by ``preview_factor``.
    """
    small, factor = downsampled(loaded.grid, max_side)
    metadata = asdict(loaded.meta)
    del metadata["image"]  # the same as image_name
    coarse = replace(loaded.meta, resolution=loaded.meta.resolution * factor)
    return {
        "image_name": loaded.image_name,
        "width": loaded.width,
        "height": loaded.height,
        **metadata,
        "counts": cell_counts(loaded.grid),
        "preview_factor": factor,
        "preview": occupancy_grid_message(small, coarse, frame_id),
    }
