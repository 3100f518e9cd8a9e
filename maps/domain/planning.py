"""Global path planning on an occupancy grid: inflate the obstacles, search, shortcut.

``inflate`` turns an occupancy grid into a ``Costmap``: the cells where the robot's
centre may not stand (within ``robot_radius`` of an obstacle, unknown cells included by
default) and, optionally, a cost gradient beyond them, as Nav2's inflation layer has,
so that paths keep off walls. ``plan_on`` plans on a costmap; ``plan_path`` inflates
and plans in one call. A caller planning repeatedly on one map inflates once and keeps
the costmap (keyed by the map's content version; that cache is the caller's).

The search is exact on the 8-connected grid (steps of 1 and sqrt 2 cells, no diagonal
step past a blocked cell): Jump Point Search on a plain costmap, A* with the octile
heuristic on one with a gradient (JPS needs uniform step costs). Both run compiled by
numba (``cache=True``: the first process compiles and caches, later ones load; call
``warm_up`` at start-up to pay that before the first plan). Without ``nogil`` a plan
would hold the GIL, so the server's event loop can plan in a worker thread.

The cell path is then shortcut by line of sight (a corner of the path is dropped when
the straight segment past it crosses no blocked cell and, with a gradient, costs no
more), which only shortens it: the result is no longer than the grid optimum.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Literal, TypeAlias

import cv2
import numba
import numpy as np
import numpy.typing as npt

from cloudnav_core.grid import (
    OCCUPIED_AT,
    Cell,
    cell_of,
    cells_to_nearest,
    centre_of,
    contains,
    unstandable,
)
from cloudnav_core.se2 import Point

DEFAULT_ROBOT_RADIUS = 0.2
"""Metres: the radius ``plan_path`` (and the cloud's ``/cloudnav/plan_path``) inflates by
for a caller that gives none. The simulated robot plans with its own
(``cloudnav_core.params.RobotConfig.planning_radius``)."""
DEFAULT_TOLERANCE = 0.5
"""Metres: how far a start or goal inside an obstacle may move to a free cell (Nav2's
planner tolerance)."""

Endpoint: TypeAlias = Literal["start", "goal"]
BoolGrid: TypeAlias = npt.NDArray[np.bool_]
FloatGrid: TypeAlias = npt.NDArray[np.float32]

_SQRT2 = math.sqrt(2.0)
_UNREACHED, _OPEN, _CLOSED = 0, 1, 2


# ---------------------------------------------------------------------------------------
# Errors


class PlanningError(Exception):
    """Base of every planning error."""


class OutOfMapError(PlanningError):
    """The start or goal (``which``) lies outside the grid, or is not a finite point."""

    def __init__(self, which: Endpoint, point: Point) -> None:
        super().__init__(f"The {which} ({point[0]:.3f}, {point[1]:.3f}) is outside the map.")
        self.which = which
        self.point = point


class InObstacleError(PlanningError):
    """The start or goal (``which``) is blocked and no free cell lies within tolerance."""

    def __init__(self, which: Endpoint, point: Point, tolerance: float) -> None:
        super().__init__(
            f"The {which} ({point[0]:.3f}, {point[1]:.3f}) is in an obstacle, "
            f"with no free cell within {tolerance} m."
        )
        self.which = which
        self.point = point


class NoPathError(PlanningError):
    """No path joins the start and the goal."""


class PoseRefused(PlanningError):
    """A goal, waypoint or initial pose no robot could stand at (``GoalCheck.check``)."""

    def __init__(self, what: str, point: Point, reason: str) -> None:
        super().__init__(f"The {what} ({point[0]:.2f}, {point[1]:.2f}) is {reason}.")
        self.what = what
        self.point = point
        self.reason = reason


# ---------------------------------------------------------------------------------------
# Costmaps


@dataclass(frozen=True, eq=False)
class Costmap:
    """An inflated grid, ready to plan on many times; build it with ``inflate``.

    ``blocked`` (shape (height, width), row 0 = bottom) is True where the robot's centre
    may not be. ``penalty`` is None or, per cell, the extra cost of each metre travelled
    there, on top of the metre itself (0 away from walls). Both arrays are read-only.
    """

    blocked: BoolGrid
    penalty: FloatGrid | None
    resolution: float
    origin: tuple[float, float]
    robot_radius: float
    # The search's view: the grid with a blocked border, flattened, so that no step
    # needs a bounds check.
    _free: npt.NDArray[np.uint8] = field(init=False, repr=False)
    _cost: npt.NDArray[np.float32] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        free = np.zeros((self.height + 2, self.width + 2), dtype=np.uint8)
        free[1:-1, 1:-1] = ~self.blocked
        cost = np.zeros(0 if self.penalty is None else free.shape, dtype=np.float32)
        if self.penalty is not None:
            cost[1:-1, 1:-1] = self.penalty
        object.__setattr__(self, "_free", free.ravel())
        object.__setattr__(self, "_cost", cost.ravel())

    @property
    def height(self) -> int:
        return int(self.blocked.shape[0])

    @property
    def width(self) -> int:
        return int(self.blocked.shape[1])


def inflate(
    grid: npt.NDArray[np.int8],
    radius_m: float,
    resolution: float,
    unknown_is_obstacle: bool = True,
    *,
    origin: Sequence[float] = (0.0, 0.0),
    occupied_threshold: int = OCCUPIED_AT,
    gradient_m: float = 0.0,
    gradient_weight: float = 1.0,
) -> Costmap:
    """Return the costmap of an occupancy grid for a round robot of radius ``radius_m``.

    ``grid`` is int8 (height, width), row 0 = bottom: cells >= ``occupied_threshold`` are
    obstacles, and so are unknown (-1) ones if ``unknown_is_obstacle``. A cell is blocked
    when its centre lies within ``radius_m`` of an obstacle cell's centre (Nav2's
    inscribed rule). With ``gradient_m`` > 0, free cells closer than ``radius_m +
    gradient_m`` cost extra, from ``gradient_weight`` per metre at the blocked edge down
    to 0, so paths keep off walls at some cost in length (and the slower A* plans them).
    ``origin`` (x, y[, yaw ignored]) places cell (0, 0)'s corner in the map frame.
    Raises ValueError on a grid that is not 2-D or a non-positive resolution.
    """
    cells = clearance_in_cells(grid, resolution, unknown_is_obstacle, occupied_threshold)
    # Compared in cells, with a hair of slack, so that a radius of exactly k cells blocks
    # the cells k away at every resolution (float32 metres would round either way).
    blocked = cells <= radius_m / resolution + 1e-4
    penalty = None
    if gradient_m > 0:
        ramp = 1.0 - (cells * resolution - radius_m) / gradient_m
        penalty = (gradient_weight * np.clip(ramp, 0.0, 1.0)).astype(np.float32)
        penalty[blocked] = 0.0
        penalty.flags.writeable = False
    blocked.flags.writeable = False
    return Costmap(blocked, penalty, resolution, (origin[0], origin[1]), radius_m)


def clearance_in_cells(
    grid: npt.NDArray[np.int8],
    resolution: float,
    unknown_is_obstacle: bool,
    occupied_threshold: int,
) -> npt.NDArray[np.float32]:
    """Return each cell's distance in cells to the nearest obstacle cell (0 on one)."""
    if grid.ndim != 2:
        raise ValueError(f"an occupancy grid is 2-D, not {grid.ndim}-D")
    if not resolution > 0:
        raise ValueError(f"the resolution must be positive, not {resolution}")
    obstacle = grid >= occupied_threshold
    if unknown_is_obstacle:
        obstacle |= grid < 0
    return cells_to_nearest(obstacle)


# ---------------------------------------------------------------------------------------
# Checking goals where they are sent


ENTRY_REACH = 0.5
"""Metres: how far from an entry point (given by the caller: in front of a tag) the free
cells a robot enters by may lie."""


@dataclass(frozen=True, eq=False)
class GoalCheck:
    """A sub-map made ready to check poses on, once per version (``goal_check``).

    ``labels`` numbers the 8-connected regions of free (unblocked) cells; ``reachable``
    holds the labels of the regions a robot can enter (those within ``ENTRY_REACH`` of an
    entry point), or is None when the sub-map has no entry point (every free region
    counts).
    """

    grid: npt.NDArray[np.int8]
    costmap: Costmap
    labels: npt.NDArray[np.int32]
    reachable: frozenset[int] | None

    def check(self, point: Point, what: str = "goal", tolerance: float = DEFAULT_TOLERANCE) -> None:
        """Raise PoseRefused unless a robot could stand at ``point``: inside the grid, on a
        known, unoccupied cell, with a cell its centre fits in within ``tolerance`` (the
        robot's own planner snaps that far), in a region it can enter."""
        if not (math.isfinite(point[0]) and math.isfinite(point[1])):
            raise PoseRefused(what, (math.nan, math.nan), "not a finite point")
        cell = cell_of(point, self.costmap.origin, self.costmap.resolution)
        reason = unstandable(self.grid, cell)
        if reason:
            raise PoseRefused(what, point, reason)
        free = cell if not self.costmap.blocked[cell] else None
        reach = int(tolerance / self.costmap.resolution)
        free = free or _nearest_free(self.costmap.blocked, cell, reach)
        if free is None:
            raise PoseRefused(
                what, point, f"too near obstacles: no room for the robot within {tolerance} m"
            )
        if self.reachable is not None and int(self.labels[free]) not in self.reachable:
            raise PoseRefused(
                what, point, "in a place no robot can reach from where it enters the map"
            )


def goal_check(grid: npt.NDArray[np.int8], costmap: Costmap, entries: Sequence[Point]) -> GoalCheck:
    """Return ``grid`` (inflated as ``costmap``) ready to check poses on; ``entries`` are
    points where robots enter it, such as in front of the tags standing in it (none:
    every free region counts as reachable)."""
    count, labels = cv2.connectedComponents((~costmap.blocked).astype(np.uint8), connectivity=8)
    del count
    reachable = None
    if entries:
        reach = int(ENTRY_REACH / costmap.resolution)
        found: set[int] = set()
        for point in entries:
            cell = cell_of(point, costmap.origin, costmap.resolution)
            near = _free_cells_near(costmap.blocked, cell, reach)
            found.update(int(labels[c]) for c in near)
        reachable = frozenset(found)
    return GoalCheck(grid, costmap, np.asarray(labels, dtype=np.int32), reachable)


def _free_cells_near(blocked: BoolGrid, cell: Cell, reach: int) -> list[Cell]:
    """Return the free cells within ``reach`` cells of ``cell`` (clipped to the grid)."""
    row, col = cell
    top, left = max(row - reach, 0), max(col - reach, 0)
    window = blocked[top : max(row + reach + 1, 0), left : max(col + reach + 1, 0)]
    rows, cols = np.nonzero(~window)
    near = (rows + top - row) ** 2 + (cols + left - col) ** 2 <= reach * reach
    return [(int(r) + top, int(c) + left) for r, c in zip(rows[near], cols[near], strict=True)]


# ---------------------------------------------------------------------------------------
# Planning


def plan_path(
    grid: npt.NDArray[np.int8],
    start_xy: Point,
    goal_xy: Point,
    resolution: float,
    origin: Sequence[float],
    robot_radius: float = DEFAULT_ROBOT_RADIUS,
    *,
    tolerance: float = DEFAULT_TOLERANCE,
    unknown_is_obstacle: bool = True,
) -> list[Point]:
    """Inflate ``grid`` and plan on it: ``plan_on(inflate(...), start_xy, goal_xy)``.

    Raises what ``inflate`` and ``plan_on`` raise.
    """
    costmap = inflate(grid, robot_radius, resolution, unknown_is_obstacle, origin=origin)
    return plan_on(costmap, start_xy, goal_xy, tolerance=tolerance)


def plan_on(
    costmap: Costmap, start_xy: Point, goal_xy: Point, *, tolerance: float = DEFAULT_TOLERANCE
) -> list[Point]:
    """Return a collision-free path from ``start_xy`` to ``goal_xy``, map-frame metres.

    The path is its corners: the first is the centre of the start's cell, the last the
    centre of the goal's, and every straight segment between them crosses only free
    cells. A start or goal in a blocked cell moves first to the nearest free cell within
    ``tolerance`` metres. Raises OutOfMapError when the start or goal lies outside the
    grid, InObstacleError when it is blocked with no free cell in reach, NoPathError
    when no path joins them.
    """
    start = _endpoint(costmap, start_xy, "start", tolerance)
    goal = _endpoint(costmap, goal_xy, "goal", tolerance)
    corners = _corners(costmap, start, goal)
    return [centre_of(cell, costmap.origin, costmap.resolution) for cell in corners]


def path_length(path: Sequence[Point]) -> float:
    """Return the length of a polyline, in its own units."""
    return sum(math.dist(a, b) for a, b in pairwise(path))


def warm_up() -> None:
    """Compile (or load from numba's cache) every search kernel, so no plan pays it."""
    grid = np.zeros((8, 8), dtype=np.int8)
    for gradient_m in (0.0, 1.0):
        costmap = inflate(grid, 0.0, 1.0, gradient_m=gradient_m)
        plan_on(costmap, (0.5, 0.5), (7.5, 7.5))


def _endpoint(costmap: Costmap, point: Point, which: Endpoint, tolerance: float) -> Cell:
    """Return the free cell to plan from or to for ``point``; raises as ``plan_on`` says."""
    if not (math.isfinite(point[0]) and math.isfinite(point[1])):
        raise OutOfMapError(which, point)
    cell = cell_of(point, costmap.origin, costmap.resolution)
    if not contains(costmap.blocked.shape, cell):
        raise OutOfMapError(which, point)
    if not costmap.blocked[cell]:
        return cell
    snapped = _nearest_free(costmap.blocked, cell, int(tolerance / costmap.resolution))
    if snapped is None:
        raise InObstacleError(which, point, tolerance)
    return snapped


def _nearest_free(blocked: BoolGrid, cell: Cell, reach: int) -> Cell | None:
    """Return the free cell nearest ``cell`` within ``reach`` cells, or None.

    Ties go to the lowest (row, col), so the answer is the same on every machine.
    """
    row, col = cell
    top, left = max(row - reach, 0), max(col - reach, 0)
    window = blocked[top : row + reach + 1, left : col + reach + 1]
    rows, cols = np.nonzero(~window)
    squared = (rows + top - row) ** 2 + (cols + left - col) ** 2
    if squared.size == 0 or squared.min() > reach * reach:
        return None
    best = int(np.argmin(squared))
    return int(rows[best]) + top, int(cols[best]) + left


def _corners(costmap: Costmap, start: Cell, goal: Cell) -> list[Cell]:
    """Return the shortcut cell path from ``start`` to ``goal``; raises NoPathError."""
    stride = costmap.width + 2
    start_index = (start[0] + 1) * stride + start[1] + 1
    goal_index = (goal[0] + 1) * stride + goal[1] + 1
    if costmap.penalty is None:
        jumps = _jump_point_search(costmap._free, stride, start_index, goal_index)
        cells = _steps_between(jumps, stride)
    else:
        cells = _astar(costmap._free, costmap._cost, stride, start_index, goal_index)
    if cells.size == 0:
        raise NoPathError(f"No path joins {start} and {goal}.")
    corners = _shortcut(costmap._free, costmap._cost, stride, cells)
    return [(int(index // stride) - 1, int(index % stride) - 1) for index in corners]


# ---------------------------------------------------------------------------------------
# Compiled kernels. Cells are indices into the padded, flattened grid (``stride`` = width
# + 2, a blocked border all round), so a neighbour is ``index + step`` with no bounds
# check. The open list is a binary heap of rows (f, g, cell) ordered by f, and by larger
# g on ties: among equally promising cells the one nearer the goal goes first, which
# keeps A* from widening across the many equal-f cells of an open grid.

_jit = numba.njit(cache=True, nogil=True)


@_jit
def _heap_push(heap, size, f, g, cell):
    """Insert (f, g, cell) at ``size``; return the heap (reallocated when full)."""
    if size == heap.shape[0]:
        heap = _doubled(heap)
    i = size
    while i > 0:
        parent = (i - 1) >> 1
        if heap[parent, 0] < f or (heap[parent, 0] == f and heap[parent, 1] >= g):
            break
        _heap_move(heap, parent, i)
        i = parent
    heap[i, 0], heap[i, 1], heap[i, 2] = f, g, cell
    return heap


@_jit
def _doubled(heap):
    """A heap twice as long holding the same rows."""
    bigger = np.empty((2 * heap.shape[0], 3), dtype=np.float64)
    # A plain loop: a slice assignment costs numba seconds of compiling.
    for row in range(heap.shape[0]):
        for column in range(3):
            bigger[row, column] = heap[row, column]
    return bigger


@_jit
def _heap_move(heap, source, target):
    # Element by element: a row assignment makes numba build slices, three times slower.
    heap[target, 0] = heap[source, 0]
    heap[target, 1] = heap[source, 1]
    heap[target, 2] = heap[source, 2]


@_jit
def _heap_pop(heap, size):
    """Remove the first row of a heap of ``size`` rows; return its cell."""
    top = int(heap[0, 2])
    last = size - 1
    f, g, cell = heap[last, 0], heap[last, 1], heap[last, 2]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= last:
            break
        right = child + 1
        if right < last and (
            heap[right, 0] < heap[child, 0]
            or (heap[right, 0] == heap[child, 0] and heap[right, 1] > heap[child, 1])
        ):
            child = right
        if heap[child, 0] < f or (heap[child, 0] == f and heap[child, 1] > g):
            _heap_move(heap, child, i)
            i = child
        else:
            break
    heap[i, 0], heap[i, 1], heap[i, 2] = f, g, cell
    return top


@_jit
def _octile(a, b, stride):
    """The 8-connected distance between two cells with nothing in the way."""
    rows = abs(a // stride - b // stride)
    cols = abs(a % stride - b % stride)
    return max(rows, cols) + (_SQRT2 - 1.0) * min(rows, cols)


@_jit
def _chain(parent, goal):
    """The cells from the search's start to ``goal``, following ``parent`` (-1 at start)."""
    count = 0
    cell = goal
    while cell != -1:
        count += 1
        cell = parent[cell]
    chain = np.empty(count, dtype=np.int64)
    cell = goal
    for i in range(count - 1, -1, -1):
        chain[i] = cell
        cell = parent[cell]
    return chain


@_jit
def _jump_straight(free, cell, step, side, goal):
    """Scan from ``cell`` along ``step``; return the first jump point, or -1 at a wall.

    ``side`` is the perpendicular step. A cell is a jump point when it is the goal or has
    a forced neighbour: a free side cell whose counterpart one step back is blocked, so
    the only shortest way into it turns here (diagonals never cut corners, which is why
    the rule looks back, not forward).
    """
    while True:
        cell += step
        if not free[cell]:
            return -1
        if cell == goal:
            return cell
        if (free[cell + side] and not free[cell - step + side]) or (
            free[cell - side] and not free[cell - step - side]
        ):
            return cell


@_jit
def _jump_diagonal(free, cell, row_step, col_step, goal):
    """Step diagonally from ``cell``; return the first jump point, or -1.

    A diagonal step needs both cells beside it free. A cell is a jump point when it is the
    goal or a straight scan from it along either component finds one.
    """
    while True:
        if not (free[cell + col_step] and free[cell + row_step]):
            return -1
        cell += row_step + col_step
        if not free[cell]:
            return -1
        if cell == goal:
            return cell
        if (
            _jump_straight(free, cell, col_step, abs(row_step), goal) != -1
            or _jump_straight(free, cell, row_step, 1, goal) != -1
        ):
            return cell


@_jit
def _directions(free, parent, cell, stride, out):
    """Write the (row, col) sign pairs JPS scans from ``cell`` into ``out``; return how many.

    From the start, all eight; after a diagonal move, its two components and itself;
    after a straight move, itself plus, for each side with a forced neighbour, the side
    and the diagonal ahead on that side.
    """
    if parent == -1:
        count = 0
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                if dr != 0 or dc != 0:
                    out[count, 0], out[count, 1] = dr, dc
                    count += 1
        return count
    dr = np.sign(cell // stride - parent // stride)
    dc = np.sign(cell % stride - parent % stride)
    out[0, 0], out[0, 1] = dr, dc
    if dr != 0 and dc != 0:
        out[1, 0], out[1, 1] = dr, 0
        out[2, 0], out[2, 1] = 0, dc
        return 3
    count = 1
    back = dr * stride + dc
    for side in (-1, 1):
        side_step = side if dr != 0 else side * stride
        if free[cell + side_step] and not free[cell - back + side_step]:
            side_dr, side_dc = (0, side) if dr != 0 else (side, 0)
            out[count, 0], out[count, 1] = side_dr, side_dc
            out[count + 1, 0], out[count + 1, 1] = dr + side_dr, dc + side_dc
            count += 2
    return count


@_jit
def _jump(free, cell, dr, dc, stride, goal):
    """The next jump point from ``cell`` in direction (dr, dc), or -1."""
    if dr != 0 and dc != 0:
        return _jump_diagonal(free, cell, dr * stride, dc, goal)
    if dr == 0:
        return _jump_straight(free, cell, dc, stride, goal)
    return _jump_straight(free, cell, dr * stride, 1, goal)


@_jit
def _jump_point_search(free, stride, start, goal):
    """Return the jump points of a shortest path from ``start`` to ``goal`` (empty if none).

    Jump Point Search (Harabor and Grastien) without corner cutting: A* whose successors
    are the jump points scanned from each expanded cell, which it reaches by straight or
    diagonal runs; it finds the same cost as A* on every 8-connected grid.
    """
    g = np.empty(free.size, dtype=np.float64)
    state = np.zeros(free.size, dtype=np.uint8)
    parent = np.empty(free.size, dtype=np.int64)
    heap = np.empty((1024, 3), dtype=np.float64)
    directions = np.empty((8, 2), dtype=np.int64)
    g[start], parent[start], state[start] = 0.0, -1, _OPEN
    heap = _heap_push(heap, 0, 0.0, 0.0, start)
    size = 1
    while size > 0:
        cell = _heap_pop(heap, size)
        size -= 1
        if state[cell] == _CLOSED:
            continue  # a stale entry: the cell was pushed again with a smaller g
        state[cell] = _CLOSED
        if cell == goal:
            return _chain(parent, goal)
        count = _directions(free, parent[cell], cell, stride, directions)
        for k in range(count):
            jump = _jump(free, cell, directions[k, 0], directions[k, 1], stride, goal)
            if jump == -1 or state[jump] == _CLOSED:
                continue
            new_g = g[cell] + _octile(cell, jump, stride)
            if state[jump] == _OPEN and new_g >= g[jump]:
                continue
            g[jump], parent[jump], state[jump] = new_g, cell, _OPEN
            heap = _heap_push(heap, size, new_g + _octile(jump, goal, stride), new_g, jump)
            size += 1
    return np.empty(0, dtype=np.int64)


@_jit
def _steps_between(jumps, stride):
    """Every cell along the straight and diagonal runs joining consecutive jump points."""
    if jumps.size == 0:
        return jumps
    total = 1
    for i in range(jumps.size - 1):
        total += _run_length(jumps[i], jumps[i + 1], stride)
    cells = np.empty(total, dtype=np.int64)
    cells[0] = jumps[0]
    k = 1
    for i in range(jumps.size - 1):
        a, b = jumps[i], jumps[i + 1]
        step = np.sign(b // stride - a // stride) * stride + np.sign(b % stride - a % stride)
        for n in range(1, _run_length(a, b, stride) + 1):
            cells[k] = a + n * step
            k += 1
    return cells


@_jit
def _run_length(a, b, stride):
    return max(abs(b // stride - a // stride), abs(b % stride - a % stride))


@_jit
def _astar(free, cost, stride, start, goal):
    """Return the cells of a cheapest path from ``start`` to ``goal`` (empty if none).

    A step of length L (1 or sqrt 2) between cells a and b costs L (1 + (cost[a] +
    cost[b]) / 2); the octile heuristic stays admissible because every cost is >= 0.
    """
    g = np.empty(free.size, dtype=np.float64)
    state = np.zeros(free.size, dtype=np.uint8)
    parent = np.empty(free.size, dtype=np.int64)
    heap = np.empty((1024, 3), dtype=np.float64)
    moves, lengths = _moves(stride)
    g[start], parent[start], state[start] = 0.0, -1, _OPEN
    heap = _heap_push(heap, 0, 0.0, 0.0, start)
    size = 1
    while size > 0:
        cell = _heap_pop(heap, size)
        size -= 1
        if state[cell] == _CLOSED:
            continue
        state[cell] = _CLOSED
        if cell == goal:
            return _chain(parent, goal)
        for k in range(8):
            nxt = cell + moves[k, 0]
            # A straight move's "sides" are the move itself, so one test serves both kinds.
            if state[nxt] == _CLOSED or not (
                free[nxt] and free[cell + moves[k, 1]] and free[cell + moves[k, 2]]
            ):
                continue
            new_g = g[cell] + lengths[k] * (1.0 + 0.5 * (cost[cell] + cost[nxt]))
            if state[nxt] == _OPEN and new_g >= g[nxt]:
                continue
            g[nxt], parent[nxt], state[nxt] = new_g, cell, _OPEN
            heap = _heap_push(heap, size, new_g + _octile(nxt, goal, stride), new_g, nxt)
            size += 1
    return np.empty(0, dtype=np.int64)


@_jit
def _moves(stride):
    """The eight moves as rows (step, side, side) with their lengths.

    A diagonal's sides are its row and column components, which must both be free (no
    corner cutting); a straight move's are the move itself.
    """
    moves = np.empty((8, 3), dtype=np.int64)
    lengths = np.empty(8, dtype=np.float64)
    k = 0
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr == 0 and dc == 0:
                continue
            step = dr * stride + dc
            diagonal = dr != 0 and dc != 0
            moves[k, 0] = step
            moves[k, 1] = dr * stride if diagonal else step
            moves[k, 2] = dc if diagonal else step
            lengths[k] = _SQRT2 if diagonal else 1.0
            k += 1
    return moves, lengths


@_jit
def _shortcut(free, cost, stride, cells):
    """Return the corners left of a cell path after line-of-sight pruning.

    From each kept corner, the path runs straight to the farthest following cell that is
    in sight (and, with costs, no dearer than the path it replaces); that cell before the
    first one out of sight becomes the next corner. Greedy, so not the best any-angle
    path, but never longer than the cell path.
    """
    n = cells.size
    along = _cost_along(cost, cells, stride)
    keep = np.empty(n, dtype=np.int64)
    keep[0] = cells[0]
    kept = 1
    anchor = 0
    for i in range(2, n):
        if not _in_sight(free, cost, stride, cells[anchor], cells[i], along[i] - along[anchor]):
            anchor = i - 1
            keep[kept] = cells[anchor]
            kept += 1
    if n > 1:
        keep[kept] = cells[n - 1]
        kept += 1
    return keep[:kept]


@_jit
def _cost_along(cost, cells, stride):
    """Cumulative cost of a cell path at each of its cells, as ``_astar`` counts it."""
    along = np.zeros(cells.size, dtype=np.float64)
    for i in range(1, cells.size):
        a, b = cells[i - 1], cells[i]
        step = _octile(a, b, stride)
        if cost.size:
            step *= 1.0 + 0.5 * (cost[a] + cost[b])
        along[i] = along[i - 1] + step
    return along


@_jit
def _in_sight(free, cost, stride, a, b, budget):
    """Whether the segment between the centres of ``a`` and ``b`` crosses only free cells.

    Walks every cell the segment touches; where it passes exactly through a cell corner,
    both cells beside the corner must be free too, as for a diagonal step. With costs,
    the segment must also cost no more than ``budget`` (its length times one plus the
    mean cost of the cells it crosses).
    """
    rows, cols = b // stride - a // stride, b % stride - a % stride
    row_step, col_step = np.sign(rows) * stride, np.sign(cols)
    rows, cols = abs(rows), abs(cols)
    i_row = i_col = 0
    cell = a
    penalty = cost[a] if cost.size else 0.0
    crossed = 1
    while i_row < rows or i_col < cols:
        # Compare where the segment next crosses a column line and a row line.
        toward = (1 + 2 * i_col) * rows - (1 + 2 * i_row) * cols
        if toward == 0:
            if not (free[cell + col_step] and free[cell + row_step]):
                return False
            cell += row_step + col_step
            i_row += 1
            i_col += 1
        elif toward < 0:
            cell += col_step
            i_col += 1
        else:
            cell += row_step
            i_row += 1
        if not free[cell]:
            return False
        if cost.size:
            penalty += cost[cell]
            crossed += 1
    if not cost.size:
        return True
    return math.hypot(rows, cols) * (1.0 + penalty / crossed) <= budget + 1e-9
