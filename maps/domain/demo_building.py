"""The demo building of the paper's scenario, ``boccioni_1``, generated from a floor plan.

One world layout in metres (walls, rooms, doorways, furniture) is rasterised at 0.05 m/px
into a world occupancy grid; each sub-map is an axis-aligned window cut from that grid,
so every sub-map shares the world frame (origin = world position of the window's
bottom-left cell, yaw 0) and neighbouring sub-maps agree cell for cell where they
overlap. Tags stand on the wall faces beside each doorway, one per direction, inside
the overlap of the two windows.

The floor plan (y up, x east; corridors 2.4 m wide, atria 8 x 8 m)::

                                            +-Atrium3-+-Office7-+
      +-----+---CorridorA---+-Atrium1-+     |         |         |
     start  > =============  |         |     +---D-----+---------+
      porch +---------------+--B------+         D
                               B                D
                               B  +----RoomB----+-Atrium2-+
                               +==CorridorC=====|         |
                                  +-RoomA-+     +---------+

The main route runs CorridorA, Atrium1, CorridorB, CorridorC, Atrium2, CorridorD,
Atrium3, Office7. RoomB is a long laboratory with a back door into Atrium2, so a robot
can also cross from CorridorC to Atrium2 through RoomB: a real, tagged, dearer detour.

Nothing here imports Django: the robot agent and the simulator use it too.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from cloudnav_core.grid import FREE_THRESH, OCCUPIED_THRESH, cell_of
from cloudnav_core.se2 import ahead
from maps.domain.mapfile import MapMetadata, occupancy_from_image, open_map_image

BUILDING_CODE = "boccioni_1"
BUILDING_NAME = "Boccioni building, floor 1"
ZIP_CODE = "56037"
ADDRESS = "Via Boccioni 1, 56037 Peccioli PI, Italy"

RESOLUTION = 0.05
"""Metres per cell of the world grid and of every sub-map image."""
WALL = 0.2
"""Wall thickness: every space's interior is ringed by a wall this thick."""
WINDOW_MARGIN = 1.6
"""How far a sub-map's window reaches past its own outer walls, so that neighbours
overlap by margin + wall + margin = 3.4 m across every shared doorway."""
TAG_SIZE = 0.06
TAG_HEIGHT = 0.3
"""Height of a marker's centre above the floor, in view of the robot's camera."""
PAPER_ROUTE = (
    "CorridorA", "Atrium1", "CorridorB", "CorridorC", "Atrium2", "CorridorD", "Atrium3", "Office7",
)  # fmt: skip
"""The paper's route from Corridor A to Office 7: the cheapest one in this building."""
START_DISTANCE = 1.2
"""How far in front of the entrance tag the paper's robot with no maps begins: it sees the
marker from there, but must drive closer to read the QR code."""
ROBOT_STARTS = ((0.5, 12.0), (0.5, 62.0), (0.45, -40.0))
"""Where the demo's simulated robots begin, as (metres from the entrance tag, degrees off
its outward normal), facing it: near enough to read its QR code at once (a 6 cm code reads
to about 0.7 m head on, less at an angle), so ``make demo``'s robots localise on their own
instead of waiting, lost, for a goal; and over 0.41 m apart, so robots of 0.18 m radius (which
see and bump into one another) stand clear of each other. More robots than places reuse
them in turn."""

OCCUPIED, FREE, UNKNOWN = 100, 0, -1
"""``nav_msgs/OccupancyGrid`` values of the world grid."""
_GREY = {OCCUPIED: 0, FREE: 254, UNKNOWN: 205}
"""map_saver's grey levels: they load the same under every map_server threshold rule."""

Grid = npt.NDArray[np.int8]


@dataclass(frozen=True)
class DemoSubMap:
    """One sub-map: a map_saver PGM (P5, 0/205/254) and its map_server metadata."""

    code: str
    name: str
    pgm: bytes
    resolution: float
    origin: tuple[float, float, float]
    width: int
    height: int
    node_xy: tuple[float, float]
    occupied_thresh: float = OCCUPIED_THRESH
    free_thresh: float = FREE_THRESH
    negate: int = 0
    mode: str = "trinary"


@dataclass(frozen=True)
class DemoTag:
    """A tag standing in ``submap`` that leads into ``links_to``.

    ``x, y`` is the marker centre on a wall face (world frame = sub-map frame); ``yaw`` is
    its outward normal, pointing into the free space of ``submap``; ``height`` is the
    marker centre above the floor, for the simulator's camera.
    """

    marker_id: int
    submap: str
    links_to: str
    x: float
    y: float
    yaw: float
    size: float = TAG_SIZE
    height: float = TAG_HEIGHT


@dataclass(frozen=True)
class DemoEdge:
    """A topology edge; ``cost`` is the walk in metres from centre to doorway to centre."""

    a: str
    b: str
    cost: float


@dataclass(frozen=True)
class DemoParking:
    """A parking spot: where a robot waits out of the others' way, in a corner of an
    atrium or a room (``PARKING_INSET`` from its walls, away from doorways and tags),
    facing the space's middle."""

    name: str
    submap: str
    x: float
    y: float
    yaw: float


@dataclass(frozen=True)
class DemoBuilding:
    """The whole demo building.

    ``world`` is the building as one read-only int8 occupancy grid (row 0 = bottom row,
    values 0 / 100 / -1, cell (0, 0)'s corner at ``world_origin``): ground truth for the
    simulator's ray casting and for whole-building planning benchmarks. ``start_pose``
    (x, y, yaw) is where the paper's robot with no maps begins, facing the entrance tag
    from beyond QR range; ``robot_starts`` are where the demo's robots begin, within it.
    ``cloud_location`` is what the tags' QR payloads name as the cloud.
    """

    code: str
    name: str
    zip_code: str
    address: str
    submaps: tuple[DemoSubMap, ...]
    tags: tuple[DemoTag, ...]
    edges: tuple[DemoEdge, ...]
    resolution: float
    world_origin: tuple[float, float]
    world: Grid = field(compare=False, repr=False)
    start_pose: tuple[float, float, float]
    cloud_location: str
    robot_starts: tuple[tuple[float, float, float], ...] = ()
    parking: tuple[DemoParking, ...] = ()


# ---------------------------------------------------------------------------------------
# The floor plan, as data. Every coordinate is a multiple of the resolution, so walls
# and doorways fall exactly on cell boundaries.


@dataclass(frozen=True)
class _Rect:
    """An axis-aligned rectangle in world metres, ``x0 < x1`` and ``y0 < y1``."""

    x0: float
    y0: float
    x1: float
    y1: float

    def grown(self, by: float) -> _Rect:
        return _Rect(self.x0 - by, self.y0 - by, self.x1 + by, self.y1 + by)

    @property
    def centre(self) -> tuple[float, float]:
        return ((self.x0 + self.x1) / 2, (self.y0 + self.y1) / 2)


@dataclass(frozen=True)
class _Space:
    """A sub-map's space: free interiors ringed by walls; the first is its main one."""

    code: str
    name: str
    interiors: tuple[_Rect, ...]


@dataclass(frozen=True)
class _Doorway:
    """An opening through the wall shared by spaces ``a`` and ``b``.

    ``tag_at`` is where along the wall the tag pair stands: on the wall beside the
    opening, one plate on each face, so each faces a robot coming to cross.
    """

    a: str
    b: str
    opening: _Rect
    tag_at: float


_SPACES = (
    _Space(
        "CorridorA",
        "Corridor A",
        # The corridor, then the entrance porch outside its west door.
        (_Rect(3.8, 22.0, 17.8, 24.4), _Rect(1.8, 21.0, 3.6, 25.4)),
    ),
    _Space("Atrium1", "Atrium 1", (_Rect(18.0, 19.2, 26.0, 27.2),)),
    _Space("CorridorB", "Corridor B", (_Rect(20.8, 8.6, 23.2, 19.0),)),
    _Space("CorridorC", "Corridor C", (_Rect(20.8, 6.0, 36.8, 8.4),)),
    _Space("Atrium2", "Atrium 2", (_Rect(37.0, 3.0, 45.0, 11.0),)),
    _Space("CorridorD", "Corridor D", (_Rect(39.8, 11.2, 42.2, 23.2),)),
    _Space("Atrium3", "Atrium 3", (_Rect(37.0, 23.4, 45.0, 31.4),)),
    _Space("Office7", "Office 7", (_Rect(45.2, 25.0, 50.2, 30.0),)),
    _Space("RoomA", "Room A", (_Rect(24.8, 1.8, 30.8, 5.8),)),
    _Space("RoomB", "Room B", (_Rect(24.8, 8.6, 36.8, 12.6),)),
)

_DOORWAYS = (
    _Doorway("CorridorA", "Atrium1", _Rect(17.8, 23.2, 18.0, 24.4), tag_at=22.6),
    _Doorway("Atrium1", "CorridorB", _Rect(22.0, 19.0, 23.2, 19.2), tag_at=21.4),
    _Doorway("CorridorB", "CorridorC", _Rect(22.0, 8.4, 23.2, 8.6), tag_at=21.4),
    _Doorway("CorridorC", "Atrium2", _Rect(36.8, 7.2, 37.0, 8.4), tag_at=6.6),
    _Doorway("Atrium2", "CorridorD", _Rect(41.0, 11.0, 42.2, 11.2), tag_at=40.4),
    _Doorway("CorridorD", "Atrium3", _Rect(41.0, 23.2, 42.2, 23.4), tag_at=40.4),
    _Doorway("Atrium3", "Office7", _Rect(45.0, 27.6, 45.2, 28.8), tag_at=26.8),
    _Doorway("CorridorC", "RoomA", _Rect(27.0, 5.8, 28.2, 6.0), tag_at=26.2),
    _Doorway("CorridorC", "RoomB", _Rect(29.8, 8.4, 31.0, 8.6), tag_at=29.2),
    # The detour: RoomB's back door into Atrium2.
    _Doorway("RoomB", "Atrium2", _Rect(36.8, 9.8, 37.0, 11.0), tag_at=9.2),
)

PARKING_INSET = 0.7
"""Metres from a parking spot to the two walls of its corner."""
_PARKING = (
    ("Atrium1", ("SW", "SE", "NW", "NE")),
    ("Atrium2", ("SE", "NE")),  # SW is a cabinet, NW the back door from Room B
    ("Atrium3", ("SW", "SE", "NE")),  # NW is a sofa
    ("RoomA", ("SE", "NE")),
    ("RoomB", ("SW",)),
)
"""Where the parking spots are: corners (compass points) of spaces' main interiors. The
corridors have none: a robot parked there would stand where the others pass."""

_ENTRANCE_DOOR = _Rect(3.6, 23.2, 3.8, 24.4)
_PORCH_FRONT = _Rect(1.6, 21.0, 1.8, 25.4)
"""The porch is open to the street on its west side; the street is outside the map."""

_ENTRANCE_TAG_XY = (3.6, 22.6)
"""On the building's west face, beside the entrance door, facing the street (yaw pi)."""

_FURNITURE = (
    _Rect(8.8, 24.0, 10.0, 24.4),  # CorridorA: a cabinet against the north wall
    _Rect(20.0, 21.2, 20.4, 21.6),  # Atrium1: four pillars and a table
    _Rect(23.6, 21.2, 24.0, 21.6),
    _Rect(20.0, 24.8, 20.4, 25.2),
    _Rect(23.6, 24.8, 24.0, 25.2),
    _Rect(21.4, 22.8, 22.6, 23.6),
    _Rect(20.8, 13.0, 21.2, 14.0),  # CorridorB: a hose reel cabinet
    _Rect(31.8, 6.0, 33.4, 6.4),  # CorridorC: a bench against the south wall
    _Rect(26.8, 2.8, 28.8, 3.8),  # RoomA: a meeting table and a corner cabinet
    _Rect(24.8, 1.8, 25.4, 3.4),
    _Rect(26.0, 11.6, 29.0, 12.6),  # RoomB: a wall bench and an island bench
    _Rect(31.0, 10.4, 34.0, 11.4),
    _Rect(40.4, 5.0, 42.4, 6.2),  # Atrium2: a table, a pillar, a cabinet
    _Rect(43.0, 8.4, 43.4, 8.8),
    _Rect(38.0, 3.0, 39.8, 3.6),
    _Rect(39.8, 17.0, 40.2, 17.8),  # CorridorD: a pillar against the west wall
    _Rect(39.8, 26.8, 40.2, 27.2),  # Atrium3: two pillars, a sofa, a table
    _Rect(42.0, 26.8, 42.4, 27.2),
    _Rect(37.6, 30.6, 39.6, 31.4),
    _Rect(41.4, 29.4, 43.4, 30.4),
    _Rect(47.0, 29.2, 49.0, 30.0),  # Office7: a desk and a filing cabinet
    _Rect(49.6, 25.0, 50.2, 26.6),
)


# ---------------------------------------------------------------------------------------
# Public API


@lru_cache(maxsize=8)
def demo_building(cloud_location: str = "http://127.0.0.1:8000") -> DemoBuilding:
    """Return the demo building; the same object (and bytes) for the same argument.

    ``cloud_location`` only names the cloud in the tags' QR payloads; the geometry does
    not depend on it. The world grid is read-only because the result is shared.
    """
    world, origin = _world()
    return DemoBuilding(
        code=BUILDING_CODE,
        name=BUILDING_NAME,
        zip_code=ZIP_CODE,
        address=ADDRESS,
        submaps=tuple(_cut_submap(space, world, origin) for space in _SPACES),
        tags=_tags(),
        edges=tuple(_edge(doorway) for doorway in _DOORWAYS),
        resolution=RESOLUTION,
        world_origin=origin,
        world=world,
        start_pose=_start_pose(),
        robot_starts=tuple(_facing_the_entrance_tag(d, math.radians(a)) for d, a in ROBOT_STARTS),
        parking=_parking(),
        cloud_location=cloud_location,
    )


Rect = tuple[float, float, float, float]
"""``(x0, y0, x1, y1)`` in world metres."""


def furniture_rects() -> tuple[Rect, ...]:
    """The furniture the floor plan places (every sub-map shows it), as rectangles."""
    return tuple((r.x0, r.y0, r.x1, r.y1) for r in _FURNITURE)


def space_interiors() -> dict[str, tuple[Rect, ...]]:
    """Each sub-map's free interiors (its main one first), by sub-map code."""
    return {s.code: tuple((r.x0, r.y0, r.x1, r.y1) for r in s.interiors) for s in _SPACES}


def doorway_openings() -> dict[tuple[str, str], Rect]:
    """The opening of each doorway through the wall two spaces share, by their codes."""
    return {(d.a, d.b): (d.opening.x0, d.opening.y0, d.opening.x1, d.opening.y1) for d in _DOORWAYS}


def world_to_cell(
    x: float, y: float, origin: tuple[float, ...], resolution: float = RESOLUTION
) -> tuple[int, int]:
    """Return ``(row, col)`` of the cell holding world point ``(x, y)``.

    ``origin`` is the world position of cell (0, 0)'s bottom-left corner (a map's YAML
    origin; a yaw after x, y is ignored and must be 0); row 0 is the bottom row. The
    result may lie outside the grid: callers check the bounds.
    """
    return cell_of((x, y), origin, resolution)


def occupancy_to_pgm(grid: Grid) -> bytes:
    """Return ``grid`` (row 0 = bottom, values 0/100/-1) as map_saver's grey P5 PGM.

    Raises ValueError on any other cell value.
    """
    grey = np.full(grid.shape, -1, dtype=np.int16)
    for value, level in _GREY.items():
        grey[grid == value] = level
    if (grey < 0).any():
        raise ValueError("an occupancy grid for a map_saver image holds only 0, 100 and -1")
    height, width = grid.shape
    header = f"P5\n{width} {height}\n255\n".encode("ascii")
    # Image rows run top to bottom, grid rows bottom to top.
    return header + np.flipud(grey).astype(np.uint8).tobytes()


def submap_metadata(submap: DemoSubMap) -> MapMetadata:
    """Return a demo sub-map's map_server metadata, its PGM named after its code."""
    return MapMetadata(
        image=f"{submap.code}.pgm",
        resolution=submap.resolution,
        origin=submap.origin,
        occupied_thresh=submap.occupied_thresh,
        free_thresh=submap.free_thresh,
        negate=bool(submap.negate),
    )


def submap_grid(submap: DemoSubMap) -> Grid:
    """Decode a demo sub-map's PGM into its occupancy grid, as a robot decodes a bundle."""
    image = open_map_image(submap.pgm, max_pixels=submap.width * submap.height)
    return occupancy_from_image(image, submap_metadata(submap))


# ---------------------------------------------------------------------------------------
# Rasterising the world and cutting the windows


def _world() -> tuple[Grid, tuple[float, float]]:
    """Rasterise the floor plan; return the grid (made read-only) and its origin."""
    bounds = _bounding(_window(space) for space in _SPACES)
    origin = (bounds.x0, bounds.y0)
    width, height = _cells(bounds.x1 - bounds.x0), _cells(bounds.y1 - bounds.y0)
    world = np.full((height, width), UNKNOWN, dtype=np.int8)
    # Order matters: every ring first, so that shared walls survive the interiors painted
    # after them; then openings through the walls; furniture last, on the floor.
    interiors = [rect for space in _SPACES for rect in space.interiors]
    _paint(world, origin, (rect.grown(WALL) for rect in interiors), OCCUPIED)
    _paint(world, origin, interiors, FREE)
    openings = [doorway.opening for doorway in _DOORWAYS]
    _paint(world, origin, [*openings, _ENTRANCE_DOOR, _PORCH_FRONT], FREE)
    _paint(world, origin, _FURNITURE, OCCUPIED)
    world.flags.writeable = False
    return world, origin


def _paint(world: Grid, origin: tuple[float, float], rects: Iterable[_Rect], value: int) -> None:
    for rect in rects:
        rows, cols = _slices(rect, origin)
        world[rows, cols] = value


def _slices(rect: _Rect, origin: tuple[float, float]) -> tuple[slice, slice]:
    """Return the (rows, cols) slices of the cells ``rect`` covers exactly."""
    cols = slice(_cells(rect.x0 - origin[0]), _cells(rect.x1 - origin[0]))
    rows = slice(_cells(rect.y0 - origin[1]), _cells(rect.y1 - origin[1]))
    return rows, cols


def _cells(metres: float) -> int:
    """Return ``metres`` as a whole number of cells; raises ValueError off the grid."""
    cells = round(metres / RESOLUTION)
    if abs(cells * RESOLUTION - metres) > 1e-6:
        raise ValueError(f"{metres} m is not a multiple of the {RESOLUTION} m resolution")
    return cells


def _bounding(rects: Iterable[_Rect]) -> _Rect:
    listed = list(rects)
    return _Rect(
        min(r.x0 for r in listed),
        min(r.y0 for r in listed),
        max(r.x1 for r in listed),
        max(r.y1 for r in listed),
    )


def _window(space: _Space) -> _Rect:
    """The sub-map's window: its outer walls plus the margin that overlaps neighbours."""
    return _bounding(rect.grown(WALL) for rect in space.interiors).grown(WINDOW_MARGIN)


def _cut_submap(space: _Space, world: Grid, origin: tuple[float, float]) -> DemoSubMap:
    window = _window(space)
    rows, cols = _slices(window, origin)
    grid = world[rows, cols]
    height, width = grid.shape
    return DemoSubMap(
        code=space.code,
        name=space.name,
        pgm=occupancy_to_pgm(grid),
        resolution=RESOLUTION,
        # The window's corner, rounded to drop float noise: it lies on the world grid.
        origin=(_metres(window.x0), _metres(window.y0), 0.0),
        width=width,
        height=height,
        node_xy=_node_xy(space),
    )


def _metres(value: float) -> float:
    return round(value, 6)


def _node_xy(space: _Space) -> tuple[float, float]:
    x, y = space.interiors[0].centre
    return _metres(x), _metres(y)


# ---------------------------------------------------------------------------------------
# Tags, edges and the start pose


def _tags() -> tuple[DemoTag, ...]:
    """The entrance tag (id 0), then each doorway's pair: ids 2i + 1 (a's) and 2i + 2."""
    tags = [_entrance_tag()]
    for index, doorway in enumerate(_DOORWAYS):
        tags.extend(_doorway_tags(doorway, first_id=2 * index + 1))
    return tuple(tags)


def _entrance_tag() -> DemoTag:
    x, y = _ENTRANCE_TAG_XY
    return DemoTag(marker_id=0, submap="CorridorA", links_to="CorridorA", x=x, y=y, yaw=math.pi)


def _doorway_tags(doorway: _Doorway, first_id: int) -> tuple[DemoTag, DemoTag]:
    """One plate on each face of the wall beside the opening, each facing its own space.

    The wall runs along the opening's longer side; ``a`` is on the side of the wall where
    its main interior's centre lies.
    """
    rect = doorway.opening
    a_x, a_y = _space(doorway.a).interiors[0].centre
    if rect.x1 - rect.x0 < rect.y1 - rect.y0:  # a wall running north-south
        a_west = a_x < rect.x0
        a_face, b_face = (rect.x0, rect.x1) if a_west else (rect.x1, rect.x0)
        a_yaw = math.pi if a_west else 0.0
        a_xy, b_xy = (a_face, doorway.tag_at), (b_face, doorway.tag_at)
    else:  # a wall running east-west
        a_south = a_y < rect.y0
        a_face, b_face = (rect.y0, rect.y1) if a_south else (rect.y1, rect.y0)
        a_yaw = -math.pi / 2 if a_south else math.pi / 2
        a_xy, b_xy = (doorway.tag_at, a_face), (doorway.tag_at, b_face)
    b_yaw = _opposite(a_yaw)
    return (
        DemoTag(first_id, doorway.a, doorway.b, a_xy[0], a_xy[1], a_yaw),
        DemoTag(first_id + 1, doorway.b, doorway.a, b_xy[0], b_xy[1], b_yaw),
    )


def _opposite(yaw: float) -> float:
    """``yaw`` turned half a circle, kept in (-pi, pi]."""
    turned = yaw + math.pi
    return turned - 2 * math.pi if turned > math.pi else turned


def _space(code: str) -> _Space:
    return next(space for space in _SPACES if space.code == code)


def _edge(doorway: _Doorway) -> DemoEdge:
    """The edge through ``doorway``: centre of ``a`` to the opening to centre of ``b``."""
    door = doorway.opening.centre
    a = _space(doorway.a).interiors[0].centre
    b = _space(doorway.b).interiors[0].centre
    cost = math.dist(a, door) + math.dist(door, b)
    return DemoEdge(doorway.a, doorway.b, round(cost, 2))


def _parking() -> tuple[DemoParking, ...]:
    """The parking spots of ``_PARKING``, named ``P-<sub-map>-<corner>``."""
    return tuple(
        _parking_in(_space(code), corner) for code, corners in _PARKING for corner in corners
    )


def _parking_in(space: _Space, corner: str) -> DemoParking:
    room = space.interiors[0]
    x = room.x0 + PARKING_INSET if corner.endswith("W") else room.x1 - PARKING_INSET
    y = room.y0 + PARKING_INSET if corner.startswith("S") else room.y1 - PARKING_INSET
    middle_x, middle_y = room.centre
    yaw = round(math.atan2(middle_y - y, middle_x - x), 6)
    return DemoParking(f"P-{space.code}-{corner}", space.code, _metres(x), _metres(y), yaw)


def _start_pose() -> tuple[float, float, float]:
    """In the porch, ``START_DISTANCE`` in front of the entrance tag, facing it."""
    tag = _entrance_tag()
    x, y = ahead((tag.x, tag.y, tag.yaw), START_DISTANCE)
    return _metres(x), _metres(y), _opposite(tag.yaw)


def _facing_the_entrance_tag(distance: float, off_normal: float) -> tuple[float, float, float]:
    """``distance`` metres from the entrance tag, ``off_normal`` radians off its outward
    normal, facing the tag."""
    tag = _entrance_tag()
    x = tag.x + distance * math.cos(tag.yaw + off_normal)
    y = tag.y + distance * math.sin(tag.yaw + off_normal)
    return round(x, 3), round(y, 3), math.atan2(tag.y - y, tag.x - x)
