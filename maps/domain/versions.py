"""Sub-map versions as data: how a version is named on the wire, how two versions of a
grid differ, and which tags a version buries.

A sub-map's versions are numbered 1, 2, ... in the order they were made. The name a
robot says (``/r/map_id``) and a bundle's ETag carry that number as ``@v<n>`` after the
Map ID, e.g. ``boccioni_1/CorridorA@v3``; a name without it is the plain Map ID (a
robot that says no version).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import numpy.typing as npt

from cloudnav_core.grid import FREE_BELOW, OCCUPIED_AT, cell_of, contains
from cloudnav_core.se2 import Pose, ahead
from maps.exceptions import IncomparableVersions

Grid = npt.NDArray[np.int8]

TAG_FACE_CLEARANCE = 0.075
"""Metres in front of a tag's face that must stay free: tags hang on wall faces, so the
cell holding the tag's own point may be the wall; the one 1.5 cells out must not be."""

_REF = re.compile(r"^(?P<map_id>[^@\s]+)@v(?P<number>[1-9][0-9]{0,8})$")


class Reason(StrEnum):
    """Why a version was made."""

    UPLOAD = "upload"
    EDIT = "edit"  # map_server metadata changed (resolution, origin, thresholds, mode)
    MAPPING = "mapping"  # a mapping session's map published
    CHANGE = "change"  # a proposed change from the fleet's evidence accepted
    ROLLBACK = "rollback"  # an earlier version made current again


def map_ref(map_id: str, number: int) -> str:
    """The name of version ``number`` of ``map_id``: ``building/code@v<number>``."""
    return f"{map_id}@v{number}"


def split_map_ref(text: str) -> tuple[str, int | None]:
    """``(map_id, number)`` of a name ``map_ref`` made; ``(text, None)`` for a plain Map ID."""
    text = text.strip()
    match = _REF.match(text)
    if match is None:
        return text, None
    return match["map_id"], int(match["number"])


def cell_classes(grid: Grid) -> npt.NDArray[np.int8]:
    """Each cell as 1 (occupied), 0 (free) or -1 (unknown), by map_saver's thresholds."""
    classes = np.full(grid.shape, -1, np.int8)
    classes[(grid >= 0) & (grid < FREE_BELOW)] = 0
    classes[grid >= OCCUPIED_AT] = 1
    return classes


@dataclass(frozen=True)
class GridDiff:
    """How grid ``new`` differs from grid ``old`` on the cells they share.

    ``added``: cells occupied in ``new`` and not in ``old`` (free or unknown there);
    ``removed``: occupied in ``old``, free in ``new``; ``unknown_changed``: cells whose
    knowledge changed otherwise (free <-> unknown, occupied -> unknown). Cells are (row,
    col) of ``new``'s grid. ``offset`` is ``old``'s cell (0, 0) in ``new``'s cells.
    """

    added: npt.NDArray[np.intp]
    removed: npt.NDArray[np.intp]
    unknown_changed: int
    compared: int
    offset: tuple[int, int]


def compare_grids(
    old: Grid,
    old_origin: Sequence[float],
    new: Grid,
    new_origin: Sequence[float],
    resolution: float,
    new_resolution: float | None = None,
) -> GridDiff:
    """Compare two versions cell by cell where they overlap in the map frame.

    Raises IncomparableVersions when the cells do not line up: resolutions or yaws differ,
    or the origins differ by a fraction of a cell.
    """
    offset = _offset(old_origin, new_origin, resolution, new_resolution)
    row0, col0 = offset
    rows = slice(max(row0, 0), min(row0 + old.shape[0], new.shape[0]))
    cols = slice(max(col0, 0), min(col0 + old.shape[1], new.shape[1]))
    empty = np.zeros((0, 2), np.intp)
    if rows.start >= rows.stop or cols.start >= cols.stop:
        return GridDiff(empty, empty, 0, 0, offset)
    after = cell_classes(new[rows, cols])
    old_rows = slice(rows.start - row0, rows.stop - row0)
    before = cell_classes(old[old_rows, cols.start - col0 : cols.stop - col0])
    corner = np.array([rows.start, cols.start], np.intp)
    added = np.argwhere((after == 1) & (before != 1)) + corner
    removed = np.argwhere((after == 0) & (before == 1)) + corner
    other = int(np.count_nonzero(after != before)) - len(added) - len(removed)
    return GridDiff(added, removed, other, int(after.size), offset)


def _offset(
    old_origin: Sequence[float],
    new_origin: Sequence[float],
    resolution: float,
    new_resolution: float | None,
) -> tuple[int, int]:
    if new_resolution is not None and not math.isclose(resolution, new_resolution):
        raise IncomparableVersions("The versions have different resolutions.")
    if len(old_origin) > 2 and not math.isclose(old_origin[2], new_origin[2], abs_tol=1e-9):
        raise IncomparableVersions("The versions have different origin yaws.")
    shift = [(o - n) / resolution for o, n in zip(old_origin[:2], new_origin[:2], strict=True)]
    if any(abs(s - round(s)) > 1e-3 for s in shift):
        raise IncomparableVersions("The versions' origins differ by a fraction of a cell.")
    return round(shift[1]), round(shift[0])


@dataclass(frozen=True)
class TagPlace:
    """A tag as versions see it: its marker id and pose in the sub-map's frame."""

    marker_id: int
    pose: Pose


def buried_tags(
    grid: Grid, origin: Sequence[float], resolution: float, tags: Iterable[TagPlace]
) -> list[int]:
    """Marker ids of the tags that stand in an occupied cell of ``grid`` (or outside it):
    the cell ``TAG_FACE_CLEARANCE`` in front of each tag's face is tested, as tags hang on
    wall faces. A robot cannot approach such a tag."""
    buried = []
    for tag in tags:
        cell = cell_of(ahead(tag.pose, TAG_FACE_CLEARANCE), origin, resolution)
        if not contains(grid.shape, cell) or grid[cell] >= OCCUPIED_AT:
            buried.append(tag.marker_id)
    return buried
