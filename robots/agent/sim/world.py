"""Ground truth of the simulator: a solid-cell grid, the tags on its walls, extra obstacles.

The grid follows ``nav_msgs/OccupancyGrid``: row 0 is the bottom row, cell ``(0, 0)``'s
bottom-left corner is at ``origin`` and cells are ``resolution`` metres square. Each cell
holds a material: ``FREE``, ``WALL`` (occupied on the map) or ``OBSTACLE`` (an extra
box or cylinder that no map shows, for avoidance and occlusion tests). Unknown map cells
are free: outside the demo building's walls is the street.

The laser, the camera and collisions all read this one grid, so whatever blocks a laser
beam also hides a tag from the camera and stops the body. Obstacles are rasterised at the
grid's resolution and are as tall as the walls for the camera.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.beams import Beams, Hits, first_solid, grid_point, solid_at
from cloudnav_core.grid import OCCUPIED_AT, cell_of
from maps.domain.demo_building import DemoBuilding, DemoTag, demo_building
from maps.domain.tagart import DEFAULT_DICTIONARY, QR_VERSION
from maps.domain.tagpayload import TagPayload, encode_payload
from robots.agent.sim.wallpaper import Wallpaper, appearance_of, tags_by_face

FREE, WALL, OBSTACLE = 0, 1, 2
"""Cell materials."""

WALL_HEIGHT = 2.5
"""Metres: what the camera draws above the floor for every solid cell."""

Cells = NDArray[np.uint8]
Floats = NDArray[np.float64]


@dataclass(frozen=True)
class Box:
    """An axis-aligned box obstacle covering ``x0..x1`` by ``y0..y1`` metres."""

    x0: float
    y0: float
    x1: float
    y1: float


@dataclass(frozen=True)
class Cylinder:
    """A round obstacle (a bin, a person's legs taken together) of ``radius`` at ``(x, y)``."""

    x: float
    y: float
    radius: float


Obstacle = Box | Cylinder


@dataclass(frozen=True)
class SimTag:
    """A tag as the camera draws it: marker centre ``(x, y)`` on a wall face, ``yaw`` its
    outward normal, ``height`` of the marker centre above the floor, and the QR text."""

    marker_id: int
    x: float
    y: float
    yaw: float
    payload: str
    size: float = 0.06
    height: float = 0.3
    dictionary: str = DEFAULT_DICTIONARY
    qr_version: int = QR_VERSION


@dataclass(frozen=True)
class RayHits:
    """First solid cell along each ray: ``distance`` in metres (``inf`` for none within
    range), its ``material``, and ``x_face`` True where the ray entered through a cell side
    perpendicular to x (a wall face running north-south)."""

    distance: Floats
    material: Cells
    x_face: NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class World:
    """The simulated building; build it with ``world_from_grid`` or ``demo_world``."""

    cells: Cells = field(repr=False)
    origin: tuple[float, float]
    resolution: float
    tags: tuple[SimTag, ...] = ()
    obstacles: tuple[Obstacle, ...] = ()
    wall_height: float = WALL_HEIGHT
    appearance: int = 0
    """Seeds what the walls look like (``wallpaper.appearance_of``)."""
    plain: tuple[tuple[float, float, float], ...] = ()
    """Places ``(x, y, yaw)`` on walls kept plain around (where tags hang)."""

    @cached_property
    def wallpaper(self) -> Wallpaper:
        """The walls' panels; shared by every world of the same appearance and plain places."""
        return _wallpaper(
            self.appearance, self.wall_height, self.plain, self.origin, self.resolution
        )

    def with_obstacles(self, *obstacles: Obstacle) -> World:
        """A copy of this world with ``obstacles`` added to its grid."""
        cells = self.cells.copy()
        for obstacle in obstacles:
            _paint_obstacle(cells, self.origin, self.resolution, obstacle)
        return replace(self, cells=cells, obstacles=(*self.obstacles, *obstacles))

    def with_tags(self, *tags: SimTag) -> World:
        """A copy of this world with ``tags`` added (and the wall around them plain)."""
        places = tuple((tag.x, tag.y, tag.yaw) for tag in tags)
        return replace(self, tags=(*self.tags, *tags), plain=(*self.plain, *places))

    @cached_property
    def solid(self) -> NDArray[np.bool_]:
        """The cells no ray or body passes: walls and obstacles."""
        return np.asarray(self.cells != FREE)

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """``(row, col)`` of the cell holding ``(x, y)``; may lie outside the grid."""
        return cell_of((x, y), self.origin, self.resolution, nudge=0.0)

    def disc_is_free(self, x: float, y: float, radius: float) -> bool:
        """True unless a solid cell lies closer than ``radius`` to ``(x, y)``."""
        return self.clearance(x, y, radius) >= radius

    def clearance(self, x: float, y: float, reach: float) -> float:
        """Distance from ``(x, y)`` to the nearest solid cell, or ``inf`` beyond ``reach``."""
        return _nearest_solid(self, x, y, reach)

    def cast(self, x: float, y: float, angles: Floats, max_range: float) -> RayHits:
        """Cast rays from ``(x, y)`` at ``angles`` (radians, map frame) up to ``max_range``.

        Exact on the grid (the core's one traversal, ``first_solid``): a ray ends where it
        enters the first solid cell, or touches one at a cell corner it passes through. A
        ray that starts inside a solid cell ends at distance 0.
        """
        return _cast(self, x, y, np.asarray(angles, np.float64), max_range)


def world_from_grid(
    grid: NDArray[np.int8],
    origin: Sequence[float],
    resolution: float,
    tags: Iterable[SimTag] = (),
    obstacles: Iterable[Obstacle] = (),
) -> World:
    """A world whose walls are the cells of ``grid`` (an occupancy grid) at ``OCCUPIED_AT`` or
    above (-1, unknown, is free), with ``tags`` and extra ``obstacles``."""
    cells = np.where(np.asarray(grid) >= OCCUPIED_AT, WALL, FREE).astype(np.uint8)
    world = World(cells, (float(origin[0]), float(origin[1])), float(resolution))
    return world.with_tags(*tags).with_obstacles(*obstacles)


def demo_world(
    cloud_location: str = "http://127.0.0.1:8000",
    obstacles: Iterable[Obstacle] = (),
    *,
    seed: int = 0,
    building_code: str | None = None,
) -> World:
    """The demo building's ground truth, its tags naming ``cloud_location`` in their QR;
    its walls look as ``seed`` and ``building_code`` (the demo's own by default) make
    them: the same floor plan under another code is another building to the camera."""
    building = demo_building(cloud_location)
    tags = (demo_sim_tag(building, tag) for tag in building.tags)
    world = world_from_grid(
        building.world, building.world_origin, building.resolution, tags, obstacles
    )
    return replace(world, appearance=appearance_of(building_code or building.code, seed))


@lru_cache(maxsize=16)
def _wallpaper(
    appearance: int,
    wall_height: float,
    plain: tuple[tuple[float, float, float], ...],
    origin: tuple[float, float],
    resolution: float,
) -> Wallpaper:
    return Wallpaper(appearance, wall_height, tags_by_face(plain, origin, resolution))


def demo_sim_tag(building: DemoBuilding, tag: DemoTag) -> SimTag:
    """The demo ``tag`` as drawn: its QR names the sub-map it links to (the one a robot
    reading it enters)."""
    payload = TagPayload(building.cloud_location, building.zip_code, building.code, tag.links_to)
    return SimTag(
        tag.marker_id, tag.x, tag.y, tag.yaw, encode_payload(payload), tag.size, tag.height
    )


# --- obstacles -------------------------------------------------------------------------


def _paint_obstacle(
    cells: Cells, origin: tuple[float, float], resolution: float, obstacle: Obstacle
) -> None:
    """Mark as ``OBSTACLE`` every free cell whose centre lies inside ``obstacle``."""
    rows, cols = np.indices(cells.shape)
    x = origin[0] + (cols + 0.5) * resolution
    y = origin[1] + (rows + 0.5) * resolution
    if isinstance(obstacle, Box):
        inside = (x >= obstacle.x0) & (x <= obstacle.x1) & (y >= obstacle.y0) & (y <= obstacle.y1)
    else:
        inside = (x - obstacle.x) ** 2 + (y - obstacle.y) ** 2 <= obstacle.radius**2
    cells[inside & (cells == FREE)] = OBSTACLE


# --- collision -------------------------------------------------------------------------


def _nearest_solid(world: World, x: float, y: float, reach: float) -> float:
    """Distance from ``(x, y)`` to the nearest solid cell within ``reach`` (else ``inf``)."""
    res, (ox, oy) = world.resolution, world.origin
    col0, row0 = math.floor((x - reach - ox) / res), math.floor((y - reach - oy) / res)
    col1, row1 = math.floor((x + reach - ox) / res), math.floor((y + reach - oy) / res)
    rows, cols = np.nonzero(
        world.cells[max(row0, 0) : max(row1 + 1, 0), max(col0, 0) : max(col1 + 1, 0)]
    )
    if rows.size == 0:
        return math.inf
    left = ox + (cols + max(col0, 0)) * res
    bottom = oy + (rows + max(row0, 0)) * res
    # Distance to a square: how far the point lies outside it along each axis.
    dx = np.maximum(np.maximum(left - x, x - (left + res)), 0.0)
    dy = np.maximum(np.maximum(bottom - y, y - (bottom + res)), 0.0)
    return float(np.sqrt(dx * dx + dy * dy).min())


# --- ray casting -----------------------------------------------------------------------


def _cast(world: World, x: float, y: float, angles: Floats, max_range: float) -> RayHits:
    """The core's traversal (``cloudnav_core.beams.first_solid``) on the world's solid
    cells, in metres, with the materials hit and the faces they show."""
    beams = Beams.towards(*grid_point((x, y), world.origin, world.resolution), angles)
    hits = first_solid(world.solid, beams, max_range / world.resolution)
    found = np.isfinite(hits.t)
    rows, cols = hits.cells[:, 0], hits.cells[:, 1]
    material = np.where(found, world.cells[rows, cols], FREE).astype(np.uint8)
    x_face = np.where(hits.t > 0, _exposed_face(world.solid, beams, hits), hits.across_x)
    return RayHits(hits.t * world.resolution, material, x_face & found)


def _exposed_face(solid: NDArray[np.bool_], beams: Beams, hits: Hits) -> NDArray[np.bool_]:
    """Which face of the hit cell each ray met. A ray through a cell corner crosses both
    boundaries at once, and rounding picks either; the face it sees is the one whose
    neighbour (on the ray's side) is free, so a flat wall shades evenly."""
    rows, cols = hits.cells[:, 0].astype(np.float64), hits.cells[:, 1].astype(np.float64)
    x_open = ~solid_at(solid, rows, cols - np.sign(beams.dx)) & (beams.dx != 0)
    y_open = ~solid_at(solid, rows - np.sign(beams.dy), cols) & (beams.dy != 0)
    return np.where(x_open != y_open, x_open, hits.across_x)
