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

from cloudnav_core.grid import OCCUPIED_AT, cell_of
from maps.domain.demo_building import DemoBuilding, DemoTag, demo_building
from maps.domain.tagart import DEFAULT_DICTIONARY, QR_VERSION
from maps.domain.tagpayload import TagPayload, encode_payload
from robots.agent.sim.wallpaper import Wallpaper, appearance_of, tags_by_face

FREE, WALL, OBSTACLE = 0, 1, 2
"""Cell materials."""

WALL_HEIGHT = 2.5
"""Metres: what the camera draws above the floor for every solid cell."""

_CROSSING_CHUNK = 48
"""Cell boundaries tested per ray per pass; most indoor rays end in the first pass."""

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

        Exact on the grid: a ray ends where it enters the first solid cell. A ray that
        starts inside a solid cell ends at distance 0.
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


Crossing = tuple[Floats, NDArray[np.intp]]
"""Ray parameters of first solid cells across one axis's boundaries, and those cells."""


@dataclass
class _Rays:
    """Rays from one point, in cell units of the padded grid, and the first solid cell
    each has met so far: ray parameter ``best``, its ``cell`` and face."""

    gx: float
    gy: float
    dx: Floats
    dy: Floats
    best: Floats
    cell: NDArray[np.intp]
    x_face: NDArray[np.bool_]

    @classmethod
    def start(cls, world: World, x: float, y: float, angles: Floats) -> _Rays:
        gx = (x - world.origin[0]) / world.resolution + 1  # + 1: the padding ring
        gy = (y - world.origin[1]) / world.resolution + 1
        count = angles.size
        return cls(
            gx, gy, np.cos(angles), np.sin(angles), np.full(count, np.inf),
            np.zeros((count, 2), np.intp), np.zeros(count, bool),
        )  # fmt: skip

    def record(self, rays: NDArray[np.intp], across_x: Crossing, across_y: Crossing) -> None:
        """Keep, for ``rays``, the nearer of the two crossings where it beats ``best``."""
        (tx, x_cell), (ty, y_cell) = across_x, across_y
        through_x = tx <= ty
        found = np.minimum(tx, ty) < self.best[rays]
        self.best[rays[found]] = np.minimum(tx, ty)[found]
        self.cell[rays[found]] = np.where(through_x[:, None], x_cell, y_cell)[found]
        self.x_face[rays[found]] = through_x[found]


def _cast(world: World, x: float, y: float, angles: Floats, max_range: float) -> RayHits:
    """Vectorised grid traversal: for each ray, the first solid cell entered through a
    vertical and through a horizontal cell boundary, whichever comes first."""
    padded = np.pad(world.cells, 1)  # a free ring: clipped indices off the grid stay free
    rays = _Rays.start(world, x, y, angles)
    reach = max_range / world.resolution
    start_cell = (math.floor(rays.gy), math.floor(rays.gx))
    if padded[start_cell] != FREE:
        rays.best[:], rays.cell[:] = 0.0, start_cell
    else:
        _march(padded, rays, reach)
        rays.x_face = _exposed_face(padded, rays)
    return _hits(world, padded, rays, reach)


def _march(padded: Cells, rays: _Rays, reach: float) -> None:
    """Test cell boundaries in chunks along every ray; only rays still unresolved go on
    to the next chunk, so the cost follows the distance to the walls, not ``reach``."""
    pending = np.arange(rays.dx.size)
    for start in range(1, math.ceil(reach) + 2, _CROSSING_CHUNK):
        ks = np.arange(start, start + _CROSSING_CHUNK, dtype=np.float64)
        dx, dy = rays.dx[pending], rays.dy[pending]
        across_x, x_end = _first_crossing(padded, rays.gx, rays.gy, dx, dy, ks, across_x=True)
        across_y, y_end = _first_crossing(padded, rays.gy, rays.gx, dy, dx, ks, across_x=False)
        rays.record(pending, across_x, across_y)
        # A hit counts once no untested boundary on either axis can come before it.
        pending = pending[rays.best[pending] > np.minimum(x_end, y_end)]
        if pending.size == 0:
            return


def _first_crossing(
    padded: Cells,
    g_along: float,
    g_other: float,
    d_along: Floats,
    d_other: Floats,
    ks: Floats,
    *,
    across_x: bool,
) -> tuple[Crossing, Floats]:
    """For the ``ks``-th cell boundaries perpendicular to one axis (x when ``across_x``):
    the ray parameter (cells travelled) of the first solid cell entered across one of
    them (``inf`` if none) with that cell's ``(row, col)``, and the parameter of the last
    boundary (how far this chunk has looked).

    From cell ``floor(g)`` a ray moving up that axis crosses boundaries ``floor(g) + k``
    into the cell of that index; moving down, ``floor(g) - k + 1`` into the cell below.
    """
    forward = (d_along > 0)[:, None]
    base = math.floor(g_along)
    boundary = np.where(forward, base + ks[None, :], base - ks[None, :] + 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (boundary - g_along) / d_along[:, None]
    t[~np.isfinite(t)] = np.inf
    entered = np.where(forward, boundary, boundary - 1)
    across = np.floor(g_other + np.where(np.isfinite(t), t, 0.0) * d_other[:, None])
    rows, cols = (across, entered) if across_x else (entered, across)
    solid = _lookup(padded, rows, cols) & np.isfinite(t)
    first = np.argmax(solid, axis=1)
    picked = np.arange(t.shape[0])
    hit = np.where(solid[picked, first], t[picked, first], np.inf)
    cell = np.stack([rows[picked, first], cols[picked, first]], axis=1)
    return (hit, _clipped(padded, cell)), t[:, -1]


def _clipped(padded: Cells, cell: Floats) -> NDArray[np.intp]:
    """Cell indices clipped into the padded grid (non-finite ones to 0)."""
    safe = np.nan_to_num(cell, nan=0, posinf=0, neginf=0)
    limit = np.array(padded.shape) - 1
    return np.clip(safe, 0, limit).astype(np.intp)


def _lookup(padded: Cells, rows: Floats, cols: Floats) -> NDArray[np.bool_]:
    """Whether the cells at (possibly off-grid, possibly non-finite) indices are solid."""
    height, width = padded.shape
    safe_rows = np.clip(np.nan_to_num(rows, posinf=0, neginf=0), 0, height - 1).astype(np.intp)
    safe_cols = np.clip(np.nan_to_num(cols, posinf=0, neginf=0), 0, width - 1).astype(np.intp)
    blocked: NDArray[np.bool_] = padded[safe_rows, safe_cols] != FREE
    return blocked


def _exposed_face(padded: Cells, rays: _Rays) -> NDArray[np.bool_]:
    """Which face of the hit cell each ray met. A ray through a cell corner crosses both
    boundaries at once, and rounding picks either; the face it sees is the one whose
    neighbour (on the ray's side) is free, so a flat wall shades evenly."""
    rows, cols = rays.cell[:, 0], rays.cell[:, 1]
    side_x = np.clip(cols - np.sign(rays.dx).astype(np.intp), 0, padded.shape[1] - 1)
    side_y = np.clip(rows - np.sign(rays.dy).astype(np.intp), 0, padded.shape[0] - 1)
    x_open = (padded[rows, side_x] == FREE) & (rays.dx != 0)
    y_open = (padded[side_y, cols] == FREE) & (rays.dy != 0)
    return np.where(x_open != y_open, x_open, rays.x_face)


def _hits(world: World, padded: Cells, rays: _Rays, reach: float) -> RayHits:
    """Distances in metres and the materials of the cells hit, for hits within reach."""
    t = np.where(rays.best <= reach, rays.best, np.inf)
    finite = np.isfinite(t)
    material = np.where(finite, padded[rays.cell[:, 0], rays.cell[:, 1]], FREE)
    return RayHits(t * world.resolution, material.astype(np.uint8), rays.x_face & finite)
