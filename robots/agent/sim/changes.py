"""A building whose truth differs from its stored maps, in seeded, configurable ways.

Buildings change after they are mapped: furniture is moved or brought in, a door is
closed, a partition wall goes up, a room is added off a corridor. ``plan_changes`` draws
such changes for the demo building from a seed; ``WorldChanges.apply`` paints them on an
occupancy grid (the building's ground truth), so the simulator's world
(``changed_demo_world``) and the evaluation of mapping and change detection read the same
truth. The stored sub-maps are not touched: they are what the robots believe.

Changes keep the paper's route passable: no change stands within ``CLEARANCE`` of a
doorway or a tag, and only doors off the main route are closed.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from maps.domain.demo_building import (
    FREE,
    OCCUPIED,
    PAPER_ROUTE,
    WALL,
    DemoBuilding,
    Rect,
    demo_building,
    doorway_openings,
    furniture_rects,
    space_interiors,
)
from robots.agent.sim.world import Obstacle, World, demo_sim_tag, world_from_grid

Grid = npt.NDArray[np.int8]

CLEARANCE = 1.0
"""Metres a change keeps from every doorway opening and every tag."""
ATTEMPTS = 200
"""Random placements tried for each change before it is given up."""


@dataclass(frozen=True)
class Room:
    """A room added off a space: its free ``interior``, ringed by a wall, and the ``door``
    opened through the wall it shares with that space."""

    interior: Rect
    door: Rect
    off: str  # the sub-map it opens off


ROOM_SITES = (
    Room((11.0, 24.6, 16.6, 29.0), (13.0, 24.4, 14.0, 24.6), "CorridorA"),
    Room((6.0, 17.4, 12.0, 21.8), (8.0, 21.8, 9.0, 22.0), "CorridorA"),
    Room((23.4, 13.2, 28.4, 17.4), (23.2, 14.6, 23.4, 15.6), "CorridorB"),
)
"""Where a room no sub-map covers can be added (each off a corridor, in the street)."""


@dataclass(frozen=True)
class ChangeConfig:
    """How many changes of each kind ``plan_changes`` draws."""

    moved: int = 2  # furniture moved 0.6 to 1.2 m
    added: int = 2  # new furniture, 0.5 to 1.2 m a side
    closed_doors: int = 1  # doors off the paper's route, closed
    walls: int = 1  # new partition walls, 1.2 to 2.4 m long
    rooms: int = 1  # unmapped rooms (at most ``len(ROOM_SITES)``)


@dataclass(frozen=True)
class WorldChanges:
    """What differs from the stored maps: rectangles emptied (furniture taken away),
    filled (furniture put down), walls (partitions, closed doors) and rooms added."""

    emptied: tuple[Rect, ...] = ()
    filled: tuple[Rect, ...] = ()
    walls: tuple[Rect, ...] = ()
    rooms: tuple[Room, ...] = ()
    notes: tuple[str, ...] = field(default=(), compare=False)  # what each change is, in words

    def apply(self, grid: Grid, origin: Sequence[float], resolution: float) -> Grid:
        """A copy of ``grid`` (int8 occupancy, row 0 at the bottom) with the changes."""
        out = np.array(grid, dtype=np.int8, copy=True)
        for room in self.rooms:
            _paint(out, origin, resolution, [_grown(room.interior, WALL)], OCCUPIED, FREE)
            _paint(out, origin, resolution, [room.interior, room.door], FREE)
        _paint(out, origin, resolution, self.emptied, FREE)
        _paint(out, origin, resolution, [*self.filled, *self.walls], OCCUPIED)
        return out


def plan_changes(
    seed: int, config: ChangeConfig | None = None, building: DemoBuilding | None = None
) -> WorldChanges:
    """Changes to the demo building drawn from ``seed`` (the same seed, the same changes)."""
    config = config or ChangeConfig()
    building = building or demo_building()
    rng = np.random.default_rng(seed)
    planner = _Planner(building, rng)
    for _ in range(config.rooms):
        planner.add_room()
    for _ in range(config.closed_doors):
        planner.close_door()
    for _ in range(config.moved):
        planner.move_furniture()
    for _ in range(config.added):
        planner.add_furniture()
    for _ in range(config.walls):
        planner.add_wall()
    return planner.changes()


def changed_grid(changes: WorldChanges, building: DemoBuilding | None = None) -> Grid:
    """The demo building's ground truth with ``changes``."""
    building = building or demo_building()
    return changes.apply(building.world, building.world_origin, building.resolution)


def changed_demo_world(
    changes: WorldChanges,
    cloud_location: str = "http://127.0.0.1:8000",
    obstacles: Iterable[Obstacle] = (),
) -> World:
    """The simulated demo building as it is after ``changes`` (its stored maps are not)."""
    building = demo_building(cloud_location)
    tags = (demo_sim_tag(building, tag) for tag in building.tags)
    grid = changed_grid(changes, building)
    return world_from_grid(grid, building.world_origin, building.resolution, tags, obstacles)


# --- drawing the changes ---------------------------------------------------------------


class _Planner:
    def __init__(self, building: DemoBuilding, rng: np.random.Generator) -> None:
        self.building = building
        self.rng = rng
        self.grid = np.array(building.world, copy=True)
        self.keep_clear = [*doorway_openings().values()]
        self.keep_clear += [(t.x, t.y, t.x, t.y) for t in building.tags]
        self.emptied: list[Rect] = []
        self.filled: list[Rect] = []
        self.walls: list[Rect] = []
        self.rooms: list[Room] = []
        self.notes: list[str] = []
        # Furniture and walls change in rooms and atria only: corridors stay passable.
        self.interiors = {
            code: rects for code, rects in space_interiors().items() if "Corridor" not in code
        }

    def changes(self) -> WorldChanges:
        return WorldChanges(
            tuple(self.emptied),
            tuple(self.filled),
            tuple(self.walls),
            tuple(self.rooms),
            tuple(self.notes),
        )

    def add_room(self) -> None:
        free = [site for site in ROOM_SITES if site not in self.rooms]
        if not free:
            return
        room = free[int(self.rng.integers(len(free)))]
        self.rooms.append(room)
        self.keep_clear += [room.door, _grown(room.interior, WALL)]
        self._paint_now(WorldChanges(rooms=(room,)))
        self.notes.append(f"a room off {room.off}, interior {_shown(room.interior)}")

    def close_door(self) -> None:
        doors = [
            (pair, opening)
            for pair, opening in doorway_openings().items()
            if not (pair[0] in PAPER_ROUTE and pair[1] in PAPER_ROUTE) and opening not in self.walls
        ]
        if not doors:
            return
        pair, opening = doors[int(self.rng.integers(len(doors)))]
        self.walls.append(opening)
        self._paint_now(WorldChanges(walls=(opening,)))
        self.notes.append(f"the door between {pair[0]} and {pair[1]} closed")

    def move_furniture(self) -> None:
        pieces = [r for r in furniture_rects() if r not in self.emptied and self._inside(r)]
        for _ in range(ATTEMPTS):
            piece = pieces[int(self.rng.integers(len(pieces)))]
            angle = float(self.rng.uniform(0, 2 * math.pi))
            shift = float(self.rng.uniform(0.6, 1.2))
            dx, dy = _snap(shift * math.cos(angle)), _snap(shift * math.sin(angle))
            moved = (piece[0] + dx, piece[1] + dy, piece[2] + dx, piece[3] + dy)
            # Free where it goes, once the piece itself is taken away.
            self._paint_now(WorldChanges(emptied=(piece,)))
            if self._fits(moved):
                self.emptied.append(piece)
                self._put(moved, f"furniture {_shown(piece)} moved to {_shown(moved)}")
                return
            self._paint_now(WorldChanges(filled=(piece,)))

    def add_furniture(self) -> None:
        for _ in range(ATTEMPTS):
            width, depth = (_snap(float(self.rng.uniform(0.5, 1.2))) for _ in range(2))
            x, y = self._random_point()
            box = (x, y, x + width, y + depth)
            if self._fits(box):
                self._put(box, f"new furniture {_shown(box)}")
                return

    def add_wall(self) -> None:
        for _ in range(ATTEMPTS):
            length = _snap(float(self.rng.uniform(1.2, 2.4)))
            x, y = self._random_point()
            across = self.rng.random() < 0.5
            wall = (x, y, x + length, y + WALL) if across else (x, y, x + WALL, y + length)
            if self._fits(wall):
                self.walls.append(wall)
                self._paint_now(WorldChanges(walls=(wall,)))
                self.keep_clear.append(wall)
                self.notes.append(f"a new wall {_shown(wall)}")
                return

    def _random_point(self) -> tuple[float, float]:
        """A cell corner in a random space's main interior."""
        codes = sorted(self.interiors)
        x0, y0, x1, y1 = self.interiors[codes[int(self.rng.integers(len(codes)))]][0]
        return _snap(float(self.rng.uniform(x0, x1))), _snap(float(self.rng.uniform(y0, y1)))

    def _put(self, box: Rect, note: str) -> None:
        self.filled.append(box)
        self.keep_clear.append(box)
        self._paint_now(WorldChanges(filled=(box,)))
        self.notes.append(note)

    def _fits(self, box: Rect) -> bool:
        """Whether ``box`` lies on free floor inside one space, clear of doorways, tags and
        earlier changes."""
        if not self._inside(box) or any(_near(box, other, CLEARANCE) for other in self.keep_clear):
            return False
        rows, cols = _slices(box, self.building.world_origin, self.building.resolution)
        return bool(np.all(self.grid[rows, cols] == FREE))

    def _inside(self, box: Rect) -> bool:
        return any(_contains(i, box) for rects in self.interiors.values() for i in rects)

    def _paint_now(self, change: WorldChanges) -> None:
        b = self.building
        self.grid = change.apply(self.grid, b.world_origin, b.resolution)


# --- rectangles ------------------------------------------------------------------------


def _paint(
    grid: Grid,
    origin: Sequence[float],
    resolution: float,
    rects: Iterable[Rect],
    value: int,
    keep: int | None = None,
) -> None:
    """Set the cells of ``rects`` to ``value``, except cells already ``keep``."""
    for rect in rects:
        rows, cols = _slices(rect, origin, resolution)
        window = grid[rows, cols]
        if keep is None:
            window[...] = value
        else:
            window[window != keep] = value


def _slices(rect: Rect, origin: Sequence[float], resolution: float) -> tuple[slice, slice]:
    """The cells whose centres lie in ``rect`` (every coordinate is a multiple of the
    resolution, so its edges fall on cell boundaries)."""
    col0, col1 = (round((v - origin[0]) / resolution) for v in (rect[0], rect[2]))
    row0, row1 = (round((v - origin[1]) / resolution) for v in (rect[1], rect[3]))
    return slice(max(row0, 0), max(row1, 0)), slice(max(col0, 0), max(col1, 0))


def _grown(rect: Rect, by: float) -> Rect:
    return (rect[0] - by, rect[1] - by, rect[2] + by, rect[3] + by)


def _contains(outer: Rect, inner: Rect) -> bool:
    x0, y0, x1, y1 = outer
    return x0 <= inner[0] and y0 <= inner[1] and inner[2] <= x1 and inner[3] <= y1


def _near(a: Rect, b: Rect, gap: float) -> bool:
    """Whether ``a`` and ``b`` come closer than ``gap``."""
    dx = max(b[0] - a[2], a[0] - b[2], 0.0)
    dy = max(b[1] - a[3], a[1] - b[3], 0.0)
    return math.hypot(dx, dy) < gap


def _snap(metres: float, step: float = 0.05) -> float:
    """Metres rounded to whole cells, so rectangles fall on cell boundaries."""
    return round(round(metres / step) * step, 2)


def _shown(rect: Rect) -> str:
    return "({:.2f}, {:.2f})-({:.2f}, {:.2f}) m".format(*rect)
