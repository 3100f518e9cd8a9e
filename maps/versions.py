"""Sub-map versions: history, reading old versions, comparing, rolling back, and
publishing a new map on a known version (mapping sessions, accepted changes).

Every operation that makes a version holds the sub-map's row while it numbers it
(``services.record_version``); one that was prepared on an earlier version is refused
with ``VersionConflict`` and changes nothing.
"""

from __future__ import annotations

from typing import Any

from django.db import transaction
from django.db.models import QuerySet

from . import services
from .domain.mapfile import LoadedMap
from .domain.versions import GridDiff, Reason, TagPlace, buried_tags, compare_grids
from .exceptions import NoSuchVersion, VersionConflict
from .models import SubMap, SubMapVersion


def history(submap: SubMap) -> QuerySet[SubMapVersion]:
    """The sub-map's versions, newest first, without their images."""
    return submap.versions.defer("image").select_related("author")


def version_of(submap: SubMap, number: int) -> SubMapVersion:
    """Version ``number`` of ``submap``; raises NoSuchVersion."""
    version = submap.versions.select_related("author").filter(number=number).first()
    if version is None:
        raise NoSuchVersion(f"{submap.map_id} has no v{number}.")
    return version


def compare(submap: SubMap, older: int, newer: int) -> GridDiff:
    """How version ``newer`` differs from ``older``, cell by cell (cells of ``newer``).

    Raises NoSuchVersion, or IncomparableVersions when their cells do not line up."""
    before, after = version_of(submap, older), version_of(submap, newer)
    return compare_grids(
        services.grid_of(before),
        (before.origin_x, before.origin_y, before.origin_yaw),
        services.grid_of(after),
        (after.origin_x, after.origin_y, after.origin_yaw),
        before.resolution,
        after.resolution,
    )


@transaction.atomic
def rollback(submap: SubMap, number: int, author: Any = None, note: str = "") -> SubMapVersion:
    """Make version ``number``'s map current again, as a new version (reason
    ``rollback``, ``based_on`` = ``number``). Raises NoSuchVersion."""
    locked = SubMap.objects.select_for_update().get(pk=submap.pk)
    source = version_of(locked, number)
    for name in services.MAP_FILE_FIELDS:
        setattr(locked, name, getattr(source, name))
    return services.record_version(
        locked, Reason.ROLLBACK, author, note or f"back to v{number}", based_on=number
    )


@transaction.atomic
def publish(
    submap: SubMap,
    loaded: LoadedMap,
    reason: Reason,
    based_on: int,
    author: Any = None,
    note: str = "",
) -> SubMapVersion:
    """Make ``loaded`` the sub-map's next version, prepared on version ``based_on``.

    Raises VersionConflict (nothing saved) when the sub-map has moved past ``based_on``.
    """
    locked = SubMap.objects.select_for_update().get(pk=submap.pk)
    if locked.revision != based_on:
        raise VersionConflict(based_on, locked.revision)
    services.apply_loaded(locked, loaded)
    return services.record_version(locked, reason, author, note, based_on=based_on)


def buried_tags_of(submap: SubMap) -> list[int]:
    """Marker ids of the sub-map's tags that stand in an occupied cell of its current
    version (see ``domain.versions.buried_tags``)."""
    places = [
        TagPlace(marker, (x, y, yaw))
        for marker, x, y, yaw in submap.tags.values_list("marker_id", "x", "y", "yaw")
    ]
    origin = (submap.origin_x, submap.origin_y)
    return buried_tags(services.grid_of(submap), origin, submap.resolution, places)
