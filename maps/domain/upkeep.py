"""Upkeep of a stored sub-map from the fleet's lasers: evidence per cell, gathered over
passes, and the change it proposes (cells that became occupied, cells that became free).

A robot driving through a sub-map adds each scan at its pose estimate of the scan's own
instant (``add``; the caller pairs them by time stamp). A scan is used only when the pose
is trustworthy: at least ``trust`` of its returns end within a cell of a wall the stored
map has (a robot whose estimate is off sees a map that disagrees everywhere, and its
evidence would be wrong everywhere). Each robot has its own *pass* (its visit, ended by
``end_pass``); within it a cell counts as seen occupied when returns ended in it at
least ``hits_per_pass`` times and at least half as often as beams crossed it, and as
seen free when beams crossed it ``misses_per_pass`` times and returns ended in it at
most a quarter as often (a pose a few centimetres off puts some returns from the
surface beside it there). A
cell is proposed when it disagreed with the stored map on ``min_passes`` passes and
agreed on none:

- **added**: seen occupied where the stored map is free or unknown, and no stored wall
  within one cell (a wall seen a few centimetres off is the same wall);
- **removed**: seen free where the stored map is occupied, and not in or behind the wall
  a printed tag hangs on (``tag_walls``): the fleet finds its way by those tags, and a
  pose a little off at the tag, where every robot starts, makes its beams cross that
  wall; only an admin's edit may open it.

Each proposed cell carries the passes and the robots (distinct) that saw it so.

The stretch of a beam just before its return (``surface_margin``) is not counted as
crossed, so a surface seen from a slightly wrong pose does not erase itself. A return
may end *inside* a stored wall (behind its face cells) for two reasons: the pose is a
little off (a heading a few degrees off, which a tag read close up can give, makes the
wall faced seem askew, and the returns on one side end inside it; the fleet then
proposed freeing that wall), or what stood in front of the wall is gone (furniture
taken from against a wall: the returns now end at the wall behind it). A heading error
moves a return by its range times the error, so how deep is told apart by range
(``wall_tolerance``: 5 cm plus 9 cm per metre, a heading 5 degrees off):

- within the tolerance, the return is the wall seen from a pose a little off: its beam
  crosses no stored wall cell within the tolerance of the wall's face (only deeper
  ones, which no such pose error reaches);
- deeper, the stored wall in front of it is gone, or the pose is far off: its beam
  crosses as any other.

Either way a return inside a wall counts against the scan's trust (a scan with many is
not used). Counting the ones within the tolerance for it instead let scans from poses
a little off in: on the unchanged demo building the fleet then proposed 53 false cells
in 4 simulated minutes, 48 of them in Corridor A's west wall.

A beam whose return ends outside the stored grid is held like one within the tolerance.
Before the tolerance, every return inside a wall was taken for a pose error and its
beam crossed nothing: furniture moved away from a wall was never freed, and
``bench mapping`` recall fell from 0.95 to 0.65 (seed 0) and 0.94 to 0.49 (seed 1).

Each return is moved ``surface_depth`` (half a cell) further along its beam before its
cell is taken: a surface on a cell border, seen with centimetres of range noise and pose
error, puts about half its returns in the free cell in front of it, and that rim of free
cells was proposed as occupied on every pass (on ``bench mapping --seed 0`` it was 153
of the 173 false cells, a fifth of all cells proposed). Half a cell deeper, the returns
land in the surface's own cell.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.ndimage import binary_dilation, distance_transform_edt

from maps.domain.slam import Scan
from maps.domain.versions import cell_classes
from robots.domain.se2 import Pose

Grid = npt.NDArray[np.int8]
Counts = npt.NDArray[np.uint16]
Cells = npt.NDArray[np.intp]


@dataclass(frozen=True)
class UpkeepParams:
    trust: float = 0.5
    hits_per_pass: int = 2
    misses_per_pass: int = 3
    min_passes: int = 2
    surface_margin: float = 0.075  # metres before a return not counted as crossed
    surface_depth: float = 0.025  # metres each return is moved along its beam
    max_range: float = 6.0  # metres: farther returns are not used
    wall_tolerance: float = 0.05  # metres a return may end inside a stored wall at 0 m
    wall_tolerance_per_m: float = 0.09  # ...and per metre of range (about 5 degrees)
    beams: int = 180  # beams used per scan at most (evenly taken)


TAG_WALL_WIDTH = 0.5  # metres either side of a tag's centre along its wall
TAG_WALL_DEPTH = 0.6  # metres behind a tag's face: the wall and what lies behind it


def _no_counts() -> npt.NDArray[np.uint16]:
    return np.zeros(0, np.uint16)


@dataclass(frozen=True)
class Proposal:
    """Cells (row, col) of the stored grid that changed, with the passes and the robots
    backing each; ``unknown`` cells come only from an admin's edit."""

    added: Cells
    removed: Cells
    added_passes: npt.NDArray[np.uint16]
    removed_passes: npt.NDArray[np.uint16]
    passes: int
    unknown: Cells = field(default_factory=lambda: np.zeros((0, 2), np.intp))
    added_robots: npt.NDArray[np.uint16] = field(default_factory=_no_counts)
    removed_robots: npt.NDArray[np.uint16] = field(default_factory=_no_counts)
    robots: int = 0  # distinct robots whose passes saw a proposed cell

    @property
    def empty(self) -> bool:
        return not len(self.added) and not len(self.removed) and not len(self.unknown)

    def applied_to(self, grid: Grid) -> Grid:
        """``grid`` with the change: added cells occupied (100), removed ones free (0),
        unknown ones -1."""
        out = np.array(grid, copy=True)
        for cells, value in ((self.added, 100), (self.removed, 0), (self.unknown, -1)):
            if len(cells):
                out[cells[:, 0], cells[:, 1]] = value
        return out


@dataclass
class _Pass:
    """One robot's counts in its open pass: returns ended in a cell, beams crossed it."""

    hits: Counts
    misses: Counts


class Evidence:
    """Laser evidence about one stored grid (row 0 at the bottom, cell (0, 0)'s corner at
    ``origin``), gathered pass by pass, each robot's passes its own; ``tags`` are the
    sub-map's printed tags ``(x, y, yaw)`` (yaw: the outward normal of their face)."""

    def __init__(
        self,
        grid: Grid,
        origin: Sequence[float],
        resolution: float,
        params: UpkeepParams | None = None,
        tags: Sequence[Pose] = (),
    ) -> None:
        self.params = params or UpkeepParams()
        self.stored = cell_classes(grid)
        self.origin = (float(origin[0]), float(origin[1]))
        self.resolution = resolution
        self.near_wall = binary_dilation(self.stored == 1, iterations=1)
        self.wall_depth = _wall_depths(self.stored, resolution)
        self.protected = tag_walls(tags, grid.shape, self.origin, resolution)
        shape = grid.shape
        self.occupied_passes: Counts = np.zeros(shape, np.uint16)
        self.free_passes: Counts = np.zeros(shape, np.uint16)
        self.observed = np.zeros(shape, bool)
        self.passes = 0
        self.scans = 0
        self.untrusted = 0
        self._open: dict[str, _Pass] = {}
        self._seen_occupied: dict[str, npt.NDArray[np.bool_]] = {}  # by robot, all passes
        self._seen_free: dict[str, npt.NDArray[np.bool_]] = {}

    def add(self, pose: Pose, scan: Scan, robot: str = "") -> bool:
        """Add one scan ``robot`` took at ``pose`` (the stored map's frame, at the scan's
        own instant); returns whether it was trusted (and used)."""
        p = self.params
        scan = scan.thinned(p.beams)
        good = np.isfinite(scan.ranges) & (scan.ranges <= p.max_range)
        ranges = scan.ranges[good] + p.surface_depth
        angles = scan.angles[good] + pose[2]
        if not len(ranges):
            return False
        ends = np.column_stack(
            (pose[0] + ranges * np.cos(angles), pose[1] + ranges * np.sin(angles))
        )
        hit_cells = self._cells(ends)
        inside = hit_cells[:, 0] >= 0
        in_wall = np.zeros(len(ranges), bool)  # ends behind the face of a stored wall
        deep = np.zeros(len(ranges), bool)  # ...deeper than a pose error could put it
        depth = self.wall_depth[hit_cells[inside, 0], hit_cells[inside, 1]]
        in_wall[inside] = depth > 0
        deep[inside] = depth > wall_tolerance(ranges[inside], p)
        near = self.near_wall[hit_cells[inside, 0], hit_cells[inside, 1]] & ~in_wall[inside]
        if not len(near) or near.mean() < p.trust:
            self.untrusted += 1
            return False
        self.scans += 1
        crossed = self._crossed(pose, ranges, angles, (in_wall & ~deep) | ~inside)
        counts = self._pass_of(robot)
        for cells, counted in ((hit_cells[inside], counts.hits), (crossed, counts.misses)):
            flat = np.unique(cells[:, 0] * self.stored.shape[1] + cells[:, 1])
            counted.reshape(-1)[flat] += 1
            self.observed.reshape(-1)[flat] = True
        return True

    def _pass_of(self, robot: str) -> _Pass:
        found = self._open.get(robot)
        if found is None:
            shape = self.stored.shape
            found = self._open[robot] = _Pass(
                np.zeros(shape, np.uint16), np.zeros(shape, np.uint16)
            )
        return found

    def _crossed(
        self,
        pose: Pose,
        ranges: npt.NDArray[np.float64],
        angles: npt.NDArray[np.float64],
        in_wall: npt.NDArray[np.bool_] | None = None,
    ) -> Cells:
        """Cells the beams crossed, up to ``surface_margin`` before each return. A beam
        whose return ended inside a stored wall (``in_wall``) crosses no stored wall cell
        within ``wall_tolerance`` of that wall's face: a pose error at its range could put
        it there (a wall seen askew); deeper, only a wall gone lets a beam through."""
        p = self.params
        reach = np.clip(ranges - p.surface_margin, 0.0, None)
        samples = math.ceil(float(reach.max(initial=0.0)) / (self.resolution / 2)) + 1
        t = np.linspace(0.0, 1.0, samples)[None, :]
        x = pose[0] + (reach * np.cos(angles))[:, None] * t
        y = pose[1] + (reach * np.sin(angles))[:, None] * t
        cells = self._cells(np.column_stack((x.ravel(), y.ravel())))
        kept = cells[:, 0] >= 0
        if in_wall is not None and in_wall.any():
            allowed = np.repeat(wall_tolerance(ranges, p), samples)
            asked = np.repeat(in_wall, samples) & kept
            depth = self.wall_depth[cells[asked, 0], cells[asked, 1]]
            wall = self.stored[cells[asked, 0], cells[asked, 1]] == 1
            kept[asked] = ~wall | (depth > allowed[asked])
        return cells[kept]

    def _cells(self, points: npt.NDArray[np.float64]) -> Cells:
        """(row, col) of each point; (-1, -1) outside the grid."""
        cols = np.floor((points[:, 0] - self.origin[0]) / self.resolution).astype(np.intp)
        rows = np.floor((points[:, 1] - self.origin[1]) / self.resolution).astype(np.intp)
        height, width = self.stored.shape
        outside = (rows < 0) | (rows >= height) | (cols < 0) | (cols >= width)
        rows[outside] = -1
        cols[outside] = -1
        return np.column_stack((rows, cols))

    def end_pass(self, robot: str | None = None) -> None:
        """Close ``robot``'s open pass (every robot's when None): count what each cell
        looked like in it. A robot with no trusted scan since has no pass to close."""
        for name in list(self._open) if robot is None else [robot]:
            if name in self._open:
                self._close(name, self._open.pop(name))

    def _close(self, robot: str, counts: _Pass) -> None:
        p = self.params
        hits, misses = counts.hits, counts.misses
        seen_occupied = (hits >= p.hits_per_pass) & (2 * hits >= misses)
        seen_free = (misses >= p.misses_per_pass) & (4 * hits <= misses)
        self.occupied_passes += seen_occupied
        self.free_passes += seen_free
        for seen, by_robot in ((seen_occupied, self._seen_occupied), (seen_free, self._seen_free)):
            if robot in by_robot:
                by_robot[robot] |= seen
            else:
                by_robot[robot] = seen
        self.passes += 1

    def proposal(self) -> Proposal:
        """The change the evidence so far backs (see the module's docstring)."""
        n = self.params.min_passes
        added = (
            (self.occupied_passes >= n)
            & (self.free_passes == 0)
            & (self.stored != 1)
            & ~self.near_wall
        )
        removed = (
            (self.free_passes >= n)
            & (self.occupied_passes == 0)
            & (self.stored == 1)
            & ~self.protected
        )
        occupied_robots = _robots_per_cell(self._seen_occupied, self.stored.shape)
        free_robots = _robots_per_cell(self._seen_free, self.stored.shape)
        backing = {
            name
            for name, seen in (*self._seen_occupied.items(), *self._seen_free.items())
            if (seen & (added | removed)).any()
        }
        return Proposal(
            np.argwhere(added),
            np.argwhere(removed),
            self.occupied_passes[added],
            self.free_passes[removed],
            self.passes,
            added_robots=occupied_robots[added],
            removed_robots=free_robots[removed],
            robots=len(backing),
        )


def _wall_depths(stored: npt.NDArray[np.int8], resolution: float) -> npt.NDArray[np.float64]:
    """Metres each stored wall cell lies behind the face of its wall (0 for a face cell and
    for every cell that is not wall)."""
    wall = stored == 1
    if not wall.any():
        return np.zeros(stored.shape)
    cells: npt.NDArray[np.float64] = distance_transform_edt(wall)
    return np.clip(cells - 1.0, 0.0, None) * resolution


def wall_tolerance(
    ranges: npt.NDArray[np.float64], params: UpkeepParams
) -> npt.NDArray[np.float64]:
    """Metres a return at each range may end inside a stored wall and still be the wall
    seen from a true pose: a beam's end moves with the pose's heading error times its
    range (plus the position and range error), so a far return is allowed deeper."""
    return params.wall_tolerance + params.wall_tolerance_per_m * ranges


def _robots_per_cell(
    seen: dict[str, npt.NDArray[np.bool_]], shape: tuple[int, ...]
) -> npt.NDArray[np.uint16]:
    counts = np.zeros(shape, np.uint16)
    for mask in seen.values():
        counts += mask
    return counts


def tag_walls(
    tags: Sequence[Pose], shape: tuple[int, ...], origin: Sequence[float], resolution: float
) -> npt.NDArray[np.bool_]:
    """Cells in or behind the wall each tag ``(x, y, yaw)`` hangs on: up to
    ``TAG_WALL_DEPTH`` behind its face (against its outward normal ``yaw``) and
    ``TAG_WALL_WIDTH`` either side of it."""
    mask = np.zeros(shape, bool)
    if not tags:
        return mask
    rows, cols = np.indices(shape)
    x = origin[0] + (cols + 0.5) * resolution
    y = origin[1] + (rows + 0.5) * resolution
    for tx, ty, yaw in tags:
        out_x, out_y = math.cos(yaw), math.sin(yaw)
        along = (x - tx) * out_x + (y - ty) * out_y  # negative: behind the face
        across = -(x - tx) * out_y + (y - ty) * out_x
        mask |= (along >= -TAG_WALL_DEPTH) & (along <= resolution) & (abs(across) <= TAG_WALL_WIDTH)
    return mask
