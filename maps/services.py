"""Map store operations that touch the ORM: sub-maps, topology, routes, bundles and tag art."""

from __future__ import annotations

import base64
import hashlib
import json
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from functools import lru_cache
from typing import Any

import numpy as np
from django.conf import settings
from django.db import transaction

from cloudnav_core.params import RobotConfig
from cloudnav_core.se2 import Point

from .domain.mapfile import (
    LoadedMap,
    MapMetadata,
    content_version,
    map_yaml_text,
    occupancy_from_image,
    open_map_image,
    validate_metadata,
)
from .domain.planning import Costmap, GoalCheck, goal_check, inflate
from .domain.preview import upload_preview
from .domain.reservations import ParkingPlace
from .domain.tagart import TagArt
from .domain.tagpayload import TagPayload, encode_payload
from .domain.topology import (
    Coverage,
    Edge,
    RouteStep,
    TagLink,
    approach_pose,
    route_between,
    tag_coverage,
)
from .domain.topology import validate_graph as validate_topology
from .domain.versions import Reason, map_ref
from .domain.widths import Widths
from .exceptions import SubMapExistsError, TopologyError
from .models import (
    Building,
    EnvironmentalTag,
    MapFile,
    ParkingSpot,
    SubMap,
    SubMapVersion,
    TopologyEdge,
)

IMAGE_CONTENT_TYPES = {
    "pgm": "image/x-portable-graymap",
    "png": "image/png",
    "bmp": "image/bmp",
    "gif": "image/gif",
    "jpg": "image/jpeg",
    "jpeg": "image/jpeg",
    "tif": "image/tiff",
    "tiff": "image/tiff",
}


MAP_FILE_FIELDS = (
    "image",
    "image_name",
    "width",
    "height",
    "resolution",
    "origin_x",
    "origin_y",
    "origin_yaw",
    "occupied_thresh",
    "free_thresh",
    "negate",
    "mode",
    "version",
)
"""The fields of a map file (``MapFile``): what a version copies from its sub-map and back."""


def metadata_of(submap: MapFile) -> MapMetadata:
    return MapMetadata(
        image=submap.image_name,
        resolution=submap.resolution,
        origin=(submap.origin_x, submap.origin_y, submap.origin_yaw),
        occupied_thresh=submap.occupied_thresh,
        free_thresh=submap.free_thresh,
        negate=submap.negate,
        mode=submap.mode,  # type: ignore[arg-type]
    )


def _apply_metadata(submap: MapFile, meta: MapMetadata) -> None:
    submap.image_name = meta.image
    submap.resolution = meta.resolution
    submap.origin_x, submap.origin_y, submap.origin_yaw = meta.origin
    submap.occupied_thresh = meta.occupied_thresh
    submap.free_thresh = meta.free_thresh
    submap.negate = meta.negate
    submap.mode = meta.mode
    submap.version = content_version(bytes(submap.image), meta)


@contextmanager
def locked_building(building: Building) -> Iterator[Building]:
    """Hold ``building``'s row for the rest of a transaction; yield it as now stored.

    Rules that read several rows of a building before a write (a building keeps an admin)
    run inside, so two requests at once see each other's result, never the same old state:
    PostgreSQL locks the row; SQLite's transactions take the write lock when they begin
    (``transaction_mode`` IMMEDIATE in the settings), which serialises them the same way.
    """
    with transaction.atomic():
        yield Building.objects.select_for_update().get(pk=building.pk)


@transaction.atomic
def save_submap(
    building: Building,
    code: str,
    loaded: LoadedMap,
    *,
    replace: bool = False,
    author: Any = None,
    note: str = "",
    reason: Reason = Reason.UPLOAD,
    **fields: Any,
) -> tuple[SubMap, bool]:
    """Store a map under ``building/code``. An existing one has its map replaced only when
    ``replace`` says so (else SubMapExistsError is raised and nothing changes), as a new
    version (``reason``, by ``author`` saying ``note``) unless it holds that very map
    already.

    Returns the sub-map and whether it was created. ``fields`` sets name and node position.
    """
    submap = SubMap.objects.select_for_update().filter(building=building, code=code).first()
    created = submap is None
    if submap is None:
        submap = SubMap(building=building, code=code)
    elif not replace:
        raise SubMapExistsError(submap.map_id)
    before = submap.version
    for name, value in fields.items():
        setattr(submap, name, value)
    apply_loaded(submap, loaded)
    if created or submap.version != before:
        record_version(submap, reason, author, note)
    else:
        submap.save()
    return submap, created


def apply_loaded(submap: MapFile, loaded: LoadedMap) -> None:
    submap.image = loaded.image_bytes
    submap.width, submap.height = loaded.width, loaded.height
    _apply_metadata(submap, loaded.meta)


@transaction.atomic
def update_submap(submap: SubMap, changes: Mapping[str, Any], author: Any = None) -> SubMap:
    """Change a sub-map's map_server metadata, name or node position. Changed metadata
    makes a new version (reason ``edit``, by ``author``).

    Raises MapFileError for metadata that map_server would refuse; nothing is saved then.
    """
    submap = SubMap.objects.select_for_update().get(pk=submap.pk)
    meta_fields = _yaml_fields(metadata_of(submap))
    meta_changes = {k: v for k, v in changes.items() if k in meta_fields}
    meta = validate_metadata({**meta_fields, **meta_changes})
    for name in ("name", "node_x", "node_y"):
        if name in changes:
            setattr(submap, name, changes[name])
    before = submap.version
    _apply_metadata(submap, meta)
    if submap.version != before:
        record_version(submap, Reason.EDIT, author, "map_server metadata edited")
    else:
        submap.save()
    return submap


def record_version(
    submap: SubMap,
    reason: Reason,
    author: Any = None,
    note: str = "",
    based_on: int | None = None,
) -> SubMapVersion:
    """Save ``submap`` with its map file as its next version; call it inside a transaction
    holding the sub-map's row (``select_for_update``), so numbers never clash.

    ``author`` is the person who made it (None: the system, a robot); ``based_on`` the
    version it restores or was built on."""
    last = None
    if submap.pk is not None:
        numbers = SubMapVersion.objects.filter(submap=submap).values_list("number", flat=True)
        last = numbers.order_by("-number").first()
    submap.revision = (last or 0) + 1
    submap.save()
    person = author if getattr(author, "is_authenticated", False) and author.pk else None
    return SubMapVersion.objects.create(
        submap=submap,
        number=submap.revision,
        reason=reason.value,
        note=note[:500],
        author=person,
        based_on=based_on,
        **{name: getattr(submap, name) for name in MAP_FILE_FIELDS},
    )


def _yaml_fields(meta: MapMetadata) -> dict[str, Any]:
    return {
        "image": meta.image,
        "resolution": meta.resolution,
        "origin": list(meta.origin),
        "occupied_thresh": meta.occupied_thresh,
        "free_thresh": meta.free_thresh,
        "negate": meta.negate,
        "mode": meta.mode,
    }


def preview_upload(building: Building, code: str | None, loaded: LoadedMap) -> dict[str, Any]:
    """What uploading ``loaded`` under ``code`` would store, storing nothing (a dry run):
    ``upload_preview``'s document with ``code``, ``map_id`` and ``replaces`` (whether a
    sub-map of that code exists, so the real upload needs replace=true); code may be None
    while a page previews files before a code is chosen."""
    map_id = SubMap(building=building, code=code).map_id if code else None
    return {
        "dry_run": True,
        "code": code,
        "map_id": map_id,
        "replaces": code is not None and building.submaps.filter(code=code).exists(),
        **upload_preview(loaded, frame_id=map_id or ""),
    }


def grid_of(submap: MapFile) -> np.ndarray:
    """Return the occupancy grid (row 0 = bottom row) of a sub-map or one of its versions,
    converted once per content version."""
    return _cached_grid(submap.version, bytes(submap.image), metadata_of(submap))


# version (the content hash) is the cache key only.
@lru_cache(maxsize=32)
def _cached_grid(version: str, image: bytes, meta: MapMetadata) -> np.ndarray:  # noqa: ARG001
    grid = occupancy_from_image(open_map_image(image, settings.CLOUDNAV_MAX_MAP_PIXELS), meta)
    grid.setflags(write=False)
    return grid


def image_content_type(submap: MapFile) -> str:
    extension = submap.image_name.rsplit(".", 1)[-1].lower()
    return IMAGE_CONTENT_TYPES.get(extension, "application/octet-stream")


# Topology


def topology_of(building: Building) -> tuple[list[SubMap], list[Edge]]:
    """Return the building's sub-maps (its nodes) and its edges, by sub-map code."""
    nodes = list(building.submaps.defer("image").order_by("code"))
    codes = {node.pk: node.code for node in nodes}
    rows = building.edges.values_list("a_id", "b_id", "cost")
    edges = [Edge(min(codes[a], codes[b]), max(codes[a], codes[b]), cost) for a, b, cost in rows]
    return nodes, sorted(edges, key=lambda e: (e.a, e.b))


def topology_document(building: Building) -> dict[str, Any]:
    """The topology as served by the API and inside bundles, with the ``crossings`` its
    tags allow (read-only: every tag linking one sub-map to another), so a robot routes
    only where it can cross, as the server does."""
    nodes, edges = topology_of(building)
    links = sorted(tag_links(building), key=lambda t: t.marker_id)
    return {
        "nodes": [{"code": n.code, "name": n.name, "x": n.node_x, "y": n.node_y} for n in nodes],
        "edges": [{"a": e.a, "b": e.b, "cost": e.cost} for e in edges],
        "crossings": [
            {"from": t.submap, "to": t.links_to, "marker_id": t.marker_id}
            for t in links
            if t.submap != t.links_to
        ],
    }


@transaction.atomic
def replace_topology(
    building: Building, positions: Mapping[str, tuple[float, float]], edges: list[Edge]
) -> None:
    """Replace the building's whole graph: node positions and edges.

    Raises TopologyError (nothing saved) for edges naming unknown sub-maps, self-loops,
    duplicates or costs that are not positive.
    """
    submaps = {s.code: s for s in building.submaps.defer("image")}
    validate_topology(submaps, edges)
    for index, (code, (x, y)) in enumerate(positions.items()):
        if code not in submaps:
            raise TopologyError(f"nodes[{index}]", f"'{code}' is not a sub-map of this building.")
        SubMap.objects.filter(pk=submaps[code].pk).update(node_x=x, node_y=y)
    _store_edges(building, submaps, edges)


def _store_edges(building: Building, submaps: Mapping[str, SubMap], edges: Iterable[Edge]) -> None:
    """Make the stored edges equal ``edges``, keeping the rows of edges that stay."""
    stored = {frozenset((row.a_id, row.b_id)): row for row in building.edges.all()}
    for edge in edges:
        a, b = sorted((submaps[edge.a].pk, submaps[edge.b].pk))
        row = stored.pop(frozenset((a, b)), None)
        if row is None:
            TopologyEdge.objects.create(building=building, a_id=a, b_id=b, cost=edge.cost)
        elif row.cost != edge.cost:
            row.cost = edge.cost
            row.save(update_fields=["cost"])
    TopologyEdge.objects.filter(pk__in=[row.pk for row in stored.values()]).delete()


def tag_links(building: Building) -> list[TagLink]:
    rows = building.tags.values_list("marker_id", "submap__code", "links_to__code")
    return [TagLink(marker, here, there) for marker, here, there in rows]


def visible_buildings(visible: Iterable[int]) -> list[Building]:
    """Return the buildings whose pks are among ``visible``."""
    return list(Building.objects.filter(pk__in=visible))


def visible_building(visible: Iterable[int], code: str) -> Building | None:
    """Return the building ``code`` if its pk is among ``visible``, else None."""
    return Building.objects.filter(code=code, pk__in=visible).first()


def visible_submap(visible: Iterable[int], building: str, code: str) -> SubMap | None:
    """Return sub-map ``building/code`` (its building loaded) if its building's pk is among
    ``visible``, else None."""
    return (
        SubMap.objects.filter(building__code=building, building__pk__in=visible, code=code)
        .select_related("building")
        .first()
    )


def costmap_of(submap: SubMap, radius: float) -> Costmap:
    """Return ``submap``'s grid inflated for a robot of ``radius`` metres, cached per
    version (an edited map is inflated afresh)."""
    return _cached_costmap(submap.pk, submap.version, radius)


@lru_cache(maxsize=16)
def _cached_costmap(pk: int, version: str, radius: float) -> Costmap:  # noqa: ARG001 (the cache key)
    submap = SubMap.objects.get(pk=pk)
    origin = (submap.origin_x, submap.origin_y)
    return inflate(grid_of(submap), radius, submap.resolution, origin=origin)


# Poses sent to robots are checked for a robot of the default build (body and margin).
GOAL_CHECK_RADIUS = RobotConfig().planning_radius


def widths_of(map_id: str) -> Widths | None:
    """The clearance of sub-map ``map_id`` (``building/code``, a version ignored), to find
    the narrow parts of robots' routes in it, made once per version; None if no such
    sub-map is."""
    building, _, code = map_id.split("@", 1)[0].partition("/")
    found = SubMap.objects.filter(building__code=building, code=code).first()
    return None if found is None else submap_widths(found)


def submap_widths(submap: SubMap) -> Widths:
    """``submap``'s clearance, to measure how wide its free space is, cached per version."""
    return _cached_widths(submap.pk, submap.version)


@lru_cache(maxsize=16)
def _cached_widths(pk: int, version: str) -> Widths:  # noqa: ARG001 (the cache key)
    submap = SubMap.objects.get(pk=pk)
    return Widths.of_grid(grid_of(submap), (submap.origin_x, submap.origin_y), submap.resolution)


def crossings_in(submap: SubMap) -> tuple[Point, ...]:
    """Where robots stand to read the tags standing in ``submap`` (``approach_pose``):
    where they enter it, and where they cross to the sub-maps the tags lead to."""
    tags = submap.tags.order_by("pk").values_list("x", "y", "yaw")
    return tuple(approach_pose((x, y, yaw))[:2] for x, y, yaw in tags)


def crossings_of(map_id: str) -> tuple[Point, ...]:
    """``crossings_in`` sub-map ``map_id`` (``building/code``, a version ignored); none if
    no such sub-map is."""
    building, _, code = map_id.split("@", 1)[0].partition("/")
    found = SubMap.objects.filter(building__code=building, code=code).first()
    return () if found is None else crossings_in(found)


def goal_check_of(submap: SubMap) -> GoalCheck:
    """Return ``submap`` ready to check goals, waypoints and initial poses on (see
    ``GoalCheck.check``), entered in front of the tags standing in it; cached per
    version and tag poses."""
    return _cached_goal_check(submap.pk, submap.version, crossings_in(submap))


@lru_cache(maxsize=16)
def _cached_goal_check(
    pk: int, version: str, entries: tuple[tuple[float, float], ...]
) -> GoalCheck:
    submap = SubMap.objects.get(pk=pk)
    return goal_check(grid_of(submap), _cached_costmap(pk, version, GOAL_CHECK_RADIUS), entries)


def route_in(building: Building, start: str, goal: str) -> list[RouteStep]:
    """Route across sub-maps; raises TopologyError or NoRouteError (see ``route_between``)."""
    nodes, edges = topology_of(building)
    return route_between([n.code for n in nodes], edges, tag_links(building), start, goal)


def coverage_of(building: Building, edges: list[Edge] | None = None) -> Coverage:
    """What the building's tags leave uncovered in its graph, or in ``edges`` proposed for
    it (checked first: raises TopologyError as ``replace_topology`` would; nothing saved)."""
    if edges is None:
        edges = topology_of(building)[1]
    else:
        validate_topology(building.submaps.values_list("code", flat=True), edges)
    return tag_coverage(edges, tag_links(building))


# Robot bundles


def bundle_etag(submap: SubMap) -> str:
    """A strong validator over everything a bundle holds: image, YAML fields, tags, topology.
    It starts with the version's name (``v<n>-``), so a robot's request says what it holds.
    """
    state = {
        "version": submap.version,
        "revision": submap.revision,
        "tags": [_tag_document(t) for t in submap.tags.select_related("links_to")],
        "topology": topology_document(submap.building),
        "dictionary": submap.building.marker_dictionary,
    }
    digest = hashlib.sha256(json.dumps(state, sort_keys=True).encode()).hexdigest()
    return f'"v{submap.revision}-{digest[:40]}"'


def bundle_of(submap: SubMap) -> dict[str, Any]:
    """The robot's bundle: the map_server pair, the sub-map's tags and the building's topology."""
    meta = metadata_of(submap)
    return {
        "map_id": submap.map_id,
        "building": submap.building.code,
        "map": submap.code,
        "version": submap.version,
        "revision": submap.revision,
        "map_ref": map_ref(submap.map_id, submap.revision),
        "image": {
            "name": submap.image_name,
            "content_type": image_content_type(submap),
            "data": base64.b64encode(bytes(submap.image)).decode("ascii"),
        },
        "yaml": map_yaml_text(meta),
        "marker_dictionary": submap.building.marker_dictionary,
        "tags": [_tag_document(t) for t in submap.tags.select_related("links_to")],
        "topology": topology_document(submap.building),
    }


def _tag_document(tag: EnvironmentalTag) -> dict[str, Any]:
    return {
        "id": tag.pk,
        "marker_id": tag.marker_id,
        "x": tag.x,
        "y": tag.y,
        "yaw": tag.yaw,
        "size": tag.size,
        "links_to": tag.links_to.code,
    }


# Tags


def tag_payload(tag: EnvironmentalTag) -> TagPayload:
    """The QR payload of a tag: it names the sub-map a robot enters by crossing at this tag."""
    building = tag.building
    return TagPayload(
        cloud_location=settings.CLOUDNAV_PUBLIC_URL,
        zip_code=building.zip_code,
        building_code=building.code,
        map_code=tag.links_to.code,
    )


def tag_art(tag: EnvironmentalTag) -> TagArt:
    return TagArt(
        marker_id=tag.marker_id,
        payload=encode_payload(tag_payload(tag)),
        map_id=tag.submap.map_id,
        links_to=tag.links_to.map_id,
        size=tag.size,
        dictionary=tag.building.marker_dictionary,
    )


def check_tag_payload(building: Building, links_to: SubMap) -> None:
    """Raise TagPayloadError when the tag's QR payload would not fit QR version 3."""
    encode_payload(
        TagPayload(settings.CLOUDNAV_PUBLIC_URL, building.zip_code, building.code, links_to.code)
    )


def parking_places(building: str) -> list[ParkingPlace]:
    """The parking spots of building ``building`` (its code), as the fleet rules use them."""
    spots = ParkingSpot.objects.filter(building__code=building).select_related("submap__building")
    return [ParkingPlace(s.name, s.submap.map_id, s.x, s.y, s.yaw) for s in spots]
