"""Upkeep of a stored sub-map from the fleet's lasers: evidence per cell, gathered over
passes, and the change it proposes (cells that became occupied, cells that became free).

A robot driving through a sub-map adds each scan at its pose estimate of the scan's own
instant (``add``; the caller pairs them by time stamp). A scan is used only when its pose
is trustworthy at that instant:

- at least ``trust`` of its returns end within a cell of a wall the stored map has (a
  robot whose estimate is far off sees a map that disagrees everywhere);
- and no pose near it fits the returns to the stored walls' faces (``face_field``: the
  distance to the nearest occupied cell beside a free one) clearly better: a correlative
  search (``maps.domain.slam.matching.search``, the mapper's) over ``align_window_xy`` and
  ``align_window_yaw`` around it finds the best pose, and a scan whose best pose lies
  more than ``align_shift`` (6 cm) or ``align_turn`` (2 degrees) away and fits better by
  more than ``align_gain`` (0.5 cm of mean residual) is dropped (``misaligned``). A
  pose 10 cm or 3 degrees off still passes the first check, and on the live no-change
  run such scans (a robot's clock behind, a tag read close up) freed walls that were
  there;
- and, when the scan would free a stored wall cell, it frees one from the pose that
  fits its returns best within the wider ``free_window_xy`` and ``free_window_yaw`` too
  (``_frees_from_best_pose``): a pose half a metre off along a corridor fits every pose
  of the narrow window alike and most returns nearly as well as the truth, yet its beams
  run through the door frames it passes (on the live no-change run, seed 1, two robots
  0.56 m off in Office7 freed a wall cell). A wall truly gone is freed from any pose
  near the truth. Only the scans that free a wall pay for the wide search.

Each robot has its own *pass* (its visit, ended by
``end_pass``); within it a cell counts as seen occupied when returns ended in it at
least ``hits_per_pass`` times and at least half as often as beams crossed it, and as
seen free when beams crossed it ``misses_per_pass`` times and returns ended in it at
most a quarter as often (a pose a few centimetres off puts some returns from the
surface beside it there). A
cell is proposed when it disagreed with the stored map on ``min_passes`` passes and
agreed on none:

- **added**: seen occupied where the stored map is free or unknown, no stored wall
  within one cell, diagonals included (a wall seen a few centimetres off is the same
  wall; on the live no-change run the cells diagonal to a wall's corner were proposed,
  Atrium 2's and Corridor C's), and not on the
  grid's rim (a sub-map cut from the building may end at the face of a wall it leaves
  out: on the live no-change run Office7's grid ended at Atrium 3's sofa, and its rim
  cells were proposed);
- **removed**: seen free where the stored map is occupied, and not in or behind the wall
  a printed tag hangs on (``tag_walls``): the fleet finds its way by those tags, and a
  pose a little off at the tag, where every robot starts, makes its beams cross that
  wall; only an admin's edit may open it.

Each proposed cell carries the passes and the robots (distinct) that saw it so.

The stretch of a beam just before its return (``surface_margin``) is not counted as
crossed, so a surface seen from a slightly wrong pose does not erase itself. A beam
frees a stored wall cell (``_beam_frees``) only when its return lies beyond the cell by
``free_margin`` plus ``free_margin_per_m`` per metre of range (2.5 cm + 2 cm/m: what is
left of a pose error after the check above), and the beam moved sideways by half that
margin either way still runs through stored wall there: a beam grazing a wall's face
or clipping its corner, from a pose a centimetre or a degree off, is a beam that passed
beside the wall, and it frees nothing. Cells on the grid's rim and wall cells touching
free space only at a corner are never freed. Furniture taken from against a wall is
freed (the returns from the wall behind end deeper than the margin).

Before the alignment check (main at issue 23, point 3) a range-dependent tolerance held
returns ending inside a wall (5 cm + 9 cm/m): ``bench mapping`` recall was 0.794 (seed 0)
and 0.774 (seed 1), and the live no-change run still proposed 18 false cells in 3
simulated minutes, mostly Corridor A's walls.

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

from cloudnav_core.beams import Beams, grid_point, traverse
from cloudnav_core.grid import cells_inside, cells_of
from cloudnav_core.se2 import Pose
from maps.domain.slam.matching import Field, search
from maps.domain.slam.scans import Scan
from maps.domain.versions import cell_classes

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
    beams: int = 180  # beams used per scan at most (evenly taken)
    align_window_xy: float = 0.2  # metres either way the alignment check looks
    align_window_yaw: float = math.radians(4.0)  # ...and radians
    align_step: float = 0.04  # metres between the poses it tries first
    align_cap: float = 0.3  # metres: a return farther from a wall face counts as this far
    align_gain: float = 0.005  # metres of mean residual a nearby pose may fit better by
    align_shift: float = 0.06  # ...when it lies this far (metres) from the scan's own
    align_turn: float = math.radians(2.0)  # ...or turned this far from it
    # A scan that would free a stored wall must free one from the best pose of a wider
    # window too (``_frees_from_best_pose``).
    free_window_xy: float = 0.8  # metres either way
    free_window_yaw: float = math.radians(10.0)  # ...and radians
    free_step: float = 0.08  # metres between the poses it tries first
    free_margin: float = 0.025  # metres a return lies beyond a wall cell to free it
    free_margin_per_m: float = 0.02  # ...and per metre of range
    free_beside: float = 0.5  # share of that margin a beam moved sideways still frees it
    robot_clearance: float = 0.45  # metres round another robot where returns are its body


TAG_WALL_WIDTH = 0.5  # metres either side of a tag's centre along its wall
TAG_WALL_DEPTH = 0.6  # metres behind a tag's face: the wall and what lies behind it


Point = tuple[float, float]


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
        # 8-neighbours: a cell diagonal to a wall's corner catches that corner's returns
        # from a pose a few centimetres off (3 false cells of the live no-change run)
        self.near_wall = binary_dilation(self.stored == 1, structure=np.ones((3, 3), bool))
        self.faces = face_field(self.stored, self.origin, resolution, self.params.align_cap)
        self.protected = tag_walls(tags, grid.shape, self.origin, resolution)
        self.rim = _rim(grid.shape)
        self.never_freed = _rim_and_corners(self.stored) | self.protected
        shape = grid.shape
        self.occupied_passes: Counts = np.zeros(shape, np.uint16)
        self.free_passes: Counts = np.zeros(shape, np.uint16)
        self.observed = np.zeros(shape, bool)
        self.passes = 0
        self.scans = 0
        self.untrusted = 0
        self.misaligned = 0  # scans a pose nearby fits better than their own
        self._open: dict[str, _Pass] = {}
        self._seen_occupied: dict[str, npt.NDArray[np.bool_]] = {}  # by robot, all passes
        self._seen_free: dict[str, npt.NDArray[np.bool_]] = {}

    def add(self, pose: Pose, scan: Scan, robot: str = "", others: Sequence[Point] = ()) -> bool:
        """Add one scan ``robot`` took at ``pose`` (the stored map's frame, at the scan's
        own instant), the other robots then at ``others`` (x, y); returns whether it was
        trusted (and used)."""
        p = self.params
        scan = scan.thinned(p.beams)
        good = np.isfinite(scan.ranges) & (scan.ranges <= p.max_range)
        measured = scan.ranges[good]
        ranges = measured + p.surface_depth
        angles = scan.angles[good] + pose[2]
        if not len(ranges):
            return False
        ends = np.column_stack(
            (pose[0] + ranges * np.cos(angles), pose[1] + ranges * np.sin(angles))
        )
        hit_cells = self._cells(ends)
        inside = hit_cells[:, 0] >= 0
        near = self.near_wall[hit_cells[inside, 0], hit_cells[inside, 1]]
        inside &= ~_near_any(ends, others, p.robot_clearance)
        if not len(near) or near.mean() < p.trust:
            self.untrusted += 1
            return False
        deepened = Scan(scan.angles[good], ranges)
        window = (p.align_window_xy, p.align_window_yaw, p.align_step)
        if not self._aligned(pose, deepened, window):
            self.misaligned += 1
            return False
        crossed, frees_wall = self._crossed(pose, measured, angles)
        if frees_wall and not self._frees_from_best_pose(pose, deepened, measured):
            self.misaligned += 1
            return False
        self.scans += 1
        counts = self._pass_of(robot)
        for cells, counted in ((hit_cells[inside], counts.hits), (crossed, counts.misses)):
            flat = np.unique(cells[:, 0] * self.stored.shape[1] + cells[:, 1])
            counted.reshape(-1)[flat] += 1
            self.observed.reshape(-1)[flat] = True
        return True

    def _aligned(self, pose: Pose, scan: Scan, window: tuple[float, float, float]) -> bool:
        """Whether ``pose`` fits ``scan``'s returns to the stored wall faces as well as
        any pose within ``window`` (metres and radians either way, the first step): the
        best one there lies within ``align_shift`` and ``align_turn`` of it, or fits
        better by no more than ``align_gain`` (mean residual; a corridor's length leaves
        poses along it alike)."""
        there, gain = self._best_nearby(pose, scan, window)
        return gain <= self.params.align_gain or not self._apart(there, pose)

    def _frees_from_best_pose(
        self,
        pose: Pose,
        scan: Scan,
        measured: npt.NDArray[np.float64],
    ) -> bool:
        """Whether a scan that frees a stored wall cell from ``pose`` frees one from the
        pose within the wide window that fits its returns best, too: a pose half a metre
        off along a corridor fits the narrow window's poses alike and most returns
        nearly as well as the true pose (a few centimetres of mean residual at most), yet
        its beams run through the door frames it passed. A wall truly gone is freed from
        any pose near the truth."""
        p = self.params
        wide = (p.free_window_xy, p.free_window_yaw, p.free_step)
        there, gain = self._best_nearby(pose, scan, wide)
        if gain <= 0.0 or not self._apart(there, pose):
            return True
        _cells, frees = self._crossed(there, measured, scan.angles + there[2])
        return frees

    def _best_nearby(
        self, pose: Pose, scan: Scan, window: tuple[float, float, float]
    ) -> tuple[Pose, float]:
        """The pose within ``window`` of ``pose`` fitting ``scan``'s returns to the stored
        wall faces best, and how much better than ``pose`` (mean residual, metres)."""
        points = scan.points()
        own = float(self.faces.score(points, np.array([pose], np.float64))[0])
        there, best = search(self.faces, points, pose, *window)
        return there, best - own

    def _apart(self, there: Pose, pose: Pose) -> bool:
        p = self.params
        moved = math.hypot(there[0] - pose[0], there[1] - pose[1]) > p.align_shift
        turned = abs(math.remainder(there[2] - pose[2], math.tau)) > p.align_turn
        return moved or turned

    def _pass_of(self, robot: str) -> _Pass:
        found = self._open.get(robot)
        if found is None:
            shape = self.stored.shape
            found = self._open[robot] = _Pass(
                np.zeros(shape, np.uint16), np.zeros(shape, np.uint16)
            )
        return found

    def _crossed(
        self, pose: Pose, ranges: npt.NDArray[np.float64], angles: npt.NDArray[np.float64]
    ) -> tuple[Cells, bool]:
        """Cells the beams (``ranges`` as measured) passed through (the core's one
        traversal), up to ``surface_margin`` before each return, a stored wall cell only as
        ``_beam_frees`` allows; and whether any stored wall cell is among them."""
        p, res = self.params, self.resolution
        reach = np.clip(ranges - p.surface_margin, 0.0, None)
        beams = Beams.towards(*grid_point(pose[:2], self.origin, res), angles)
        passed = traverse(beams, reach / res)
        cells = np.column_stack((passed.rows, passed.cols))
        kept = cells_inside(self.stored.shape, passed.rows, passed.cols)
        wall = np.zeros_like(kept)
        wall[kept] = self.stored[cells[kept, 0], cells[kept, 1]] == 1
        frees_wall = False
        if wall.any():
            gx, gy = passed.middles(beams)
            middles = np.column_stack((gx, gy))[wall] * res + self.origin
            beam = passed.beam[wall]
            freed = self._beam_frees(pose, cells[wall], middles, ranges[beam], angles[beam])
            kept[wall] = freed
            frees_wall = bool(freed.any())
        return cells[kept], frees_wall

    def _beam_frees(
        self,
        pose: Pose,
        cells: Cells,
        middles: npt.NDArray[np.float64],
        ranges: npt.NDArray[np.float64],
        angles: npt.NDArray[np.float64],
    ) -> npt.NDArray[np.bool_]:
        """Whether each beam (its range, its heading) frees the stored wall cell of
        ``cells`` it passed through, ``middles`` the midpoint of its stretch there: only
        when its return lies beyond the cell by the margin (``free_margin`` plus
        ``free_margin_per_m`` per metre of range), and the beam moved sideways by
        ``free_beside`` of that margin either way would still run through stored wall
        there. A beam grazing a wall's face, or clipping its corner, is what a pose a
        little off makes of a beam that passed beside the wall: it frees nothing."""
        p, res = self.params, self.resolution
        margin = p.free_margin + p.free_margin_per_m * ranges
        dx, dy = np.cos(angles), np.sin(angles)
        cx = self.origin[0] + (cells[:, 1] + 0.5) * res - pose[0]
        cy = self.origin[1] + (cells[:, 0] + 0.5) * res - pose[1]
        leaves = cx * dx + cy * dy + res / 2 * (np.abs(dx) + np.abs(dy))  # its far corner
        frees = (ranges - leaves >= margin) & ~self.never_freed[cells[:, 0], cells[:, 1]]
        beside_by = p.free_beside * margin
        for side in (-1.0, 1.0):
            moved = middles + side * beside_by[:, None] * np.column_stack((-dy, dx))
            beside = self._cells(moved)
            on_grid = beside[:, 0] >= 0
            frees[~on_grid] = False
            frees[on_grid] &= self.stored[beside[on_grid, 0], beside[on_grid, 1]] == 1
        return frees

    def _cells(self, points: npt.NDArray[np.float64]) -> Cells:
        """(row, col) of each point; (-1, -1) outside the grid."""
        rows, cols = cells_of(points[:, 0], points[:, 1], self.origin, self.resolution, nudge=0.0)
        outside = ~cells_inside(self.stored.shape, rows, cols)
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
            & ~self.rim
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


def face_field(
    stored: npt.NDArray[np.int8], origin: Sequence[float], resolution: float, cap: float
) -> Field:
    """Minus the distance (metres, at most ``cap``) from each cell's centre to the nearest
    face of a stored wall: an occupied cell with a free one beside it (4-neighbours)."""
    wall = stored == 1
    free = stored == 0
    beside = np.zeros_like(free)
    beside[1:, :] |= free[:-1, :]
    beside[:-1, :] |= free[1:, :]
    beside[:, 1:] |= free[:, :-1]
    beside[:, :-1] |= free[:, 1:]
    faces = wall & beside
    if not faces.any():
        return Field(np.full(stored.shape, -cap), (origin[0], origin[1]), resolution)
    distance = distance_transform_edt(~faces) * resolution
    return Field(-np.minimum(distance, cap), (origin[0], origin[1]), resolution)


def _near_any(
    points: npt.NDArray[np.float64], centres: Sequence[Point], radius: float
) -> npt.NDArray[np.bool_]:
    """Whether each point lies within ``radius`` of any of ``centres``."""
    near = np.zeros(len(points), bool)
    for x, y in centres:
        near |= np.hypot(points[:, 0] - x, points[:, 1] - y) < radius
    return near


def _rim_and_corners(stored: npt.NDArray[np.int8]) -> npt.NDArray[np.bool_]:
    """Stored wall cells the fleet never frees: those on the grid's rim (beyond them the
    map says nothing) and those touching free space only at a corner (diagonal to it:
    the cell in a wall's bend, which beams into that corner clip)."""
    wall = stored == 1
    rim = _rim(stored.shape)
    free = np.pad(stored == 0, 1)
    side = free[:-2, 1:-1] | free[2:, 1:-1] | free[1:-1, :-2] | free[1:-1, 2:]
    diagonal = free[:-2, :-2] | free[:-2, 2:] | free[2:, :-2] | free[2:, 2:]
    never: npt.NDArray[np.bool_] = wall & (rim | (diagonal & ~side))
    return never


def _rim(shape: tuple[int, ...]) -> npt.NDArray[np.bool_]:
    """The grid's outermost cells: beyond them the map says nothing (a sub-map cut from a
    building may end at the face of a wall it leaves out)."""
    rim = np.zeros(shape, bool)
    rim[0, :] = rim[-1, :] = rim[:, 0] = rim[:, -1] = True
    return rim


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
