"""Sub-maps as the robot holds them: ``SubMap`` (one decoded bundle: grid, frame, tags and
topology, with its costmaps) and ``StoredTag``, read from a bundle's JSON by
``submap_from_bundle`` (``BundleError`` when it cannot be).

Frames
======

Sub-maps of one building share one frame (each map_server origin places its image in
the building's frame, as the demo's do). A tag's stored pose, found in whichever held
bundle holds that tag, therefore places the robot in the sub-map it enters too.
"""

from __future__ import annotations

import base64
import binascii
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.grid import cells_of
from cloudnav_core.params import PlannerConfig
from maps.domain.mapfile import load_map_upload
from maps.domain.planning import Costmap, inflate
from maps.domain.topology import Edge, TagLink
from maps.domain.versions import map_ref
from maps.exceptions import MapStoreError

Grid = NDArray[np.int8]

MAX_MAP_PIXELS = 16 * 2**20


class BundleError(Exception):
    """A bundle could not be fetched or made sense of."""


@dataclass(frozen=True)
class StoredTag:
    """A tag as its bundle stores it: pose in the building frame, the sub-map it is in
    and the one it leads to."""

    marker_id: int
    x: float
    y: float
    yaw: float
    size: float
    submap: str
    links_to: str


@dataclass(frozen=True, eq=False)
class SubMap:
    """One decoded bundle: grid (int8, row 0 = bottom), its frame, tags and topology."""

    building: str
    code: str
    version: str
    etag: str
    grid: Grid = field(repr=False)
    resolution: float
    origin: tuple[float, float, float]
    tags: Mapping[int, StoredTag]
    nodes: tuple[str, ...]
    edges: tuple[Edge, ...]
    crossings: tuple[TagLink, ...] | None = None  # None: a server that did not send them
    revision: int | None = None  # the version's number; None: a server without versions
    _costmaps: dict[tuple[float, PlannerConfig], Costmap] = field(
        default_factory=dict, init=False, repr=False
    )

    @property
    def map_id(self) -> str:
        return f"{self.building}/{self.code}"

    @property
    def map_ref(self) -> str:
        """The Map ID with the version held (``building/code@v<n>``), what ``map_id`` says."""
        return self.map_id if self.revision is None else map_ref(self.map_id, self.revision)

    def costmap(self, radius: float, planner: PlannerConfig) -> Costmap:
        """The grid inflated for a robot of ``radius`` (metres) by ``planner``, computed
        once per bundle version."""
        key = (radius, planner)
        if key not in self._costmaps:
            self._costmaps[key] = self._inflated(self.grid, radius, planner)
        return self._costmaps[key]

    def costmap_with(
        self, points: NDArray[np.float64], radius: float, planner: PlannerConfig
    ) -> Costmap:
        """The costmap with obstacles at ``points`` (map frame, shape (n, 2)) added."""
        grid = self.grid.copy()
        rows, cols = cells_of(points[:, 0], points[:, 1], self.origin, self.resolution, nudge=0.0)
        inside = (rows >= 0) & (rows < grid.shape[0]) & (cols >= 0) & (cols < grid.shape[1])
        grid[rows[inside], cols[inside]] = 100
        return self._inflated(grid, radius, planner)

    def _inflated(self, grid: Grid, radius: float, planner: PlannerConfig) -> Costmap:
        return inflate(
            grid,
            radius,
            self.resolution,
            origin=self.origin,
            gradient_m=planner.gradient,
            gradient_weight=planner.gradient_weight,
        )


def submap_from_bundle(document: Mapping[str, Any], etag: str) -> SubMap:
    """Decode a bundle (``GET .../bundle``'s JSON). Raises BundleError for anything
    missing or unreadable, map files included."""
    try:
        image = document["image"]
        data = base64.b64decode(image["data"], validate=True)
        loaded = load_map_upload(document["yaml"].encode(), {image["name"]: data}, MAX_MAP_PIXELS)
        code, topology = str(document["map"]), document["topology"]
        return SubMap(
            building=str(document["building"]),
            code=code,
            version=str(document["version"]),
            etag=etag,
            grid=loaded.grid,
            resolution=loaded.meta.resolution,
            origin=loaded.meta.origin,
            tags={int(t["marker_id"]): _stored_tag(t, code) for t in document["tags"]},
            nodes=tuple(str(node["code"]) for node in topology["nodes"]),
            edges=tuple(_edge(e) for e in topology["edges"]),
            crossings=_crossings(topology.get("crossings")),
            revision=_revision(document.get("revision")),
        )
    except (KeyError, TypeError, ValueError, AttributeError, binascii.Error) as error:
        raise BundleError(f"a bundle that cannot be read: {error!r}") from None
    except MapStoreError as error:  # map file errors
        raise BundleError(f"the bundle's map cannot be loaded: {error}") from None


def _revision(value: Any) -> int | None:
    return None if value is None else int(value)


def _edge(document: Mapping[str, Any]) -> Edge:
    return Edge(str(document["a"]), str(document["b"]), float(document["cost"]))


def _crossings(documents: Iterable[Mapping[str, Any]] | None) -> tuple[TagLink, ...] | None:
    if documents is None:
        return None
    return tuple(TagLink(int(c["marker_id"]), str(c["from"]), str(c["to"])) for c in documents)


def _stored_tag(document: Mapping[str, Any], submap: str) -> StoredTag:
    return StoredTag(
        marker_id=int(document["marker_id"]),
        x=float(document["x"]),
        y=float(document["y"]),
        yaw=float(document["yaw"]),
        size=float(document.get("size", 0.06)),
        submap=submap,
        links_to=str(document["links_to"]),
    )
