"""Keyframes in the database and on disk, and the searchable index of each building.

A keyframe is a ``maps.models.Keyframe`` row (sub-map, robot, pose, sizes) and a file
under ``CLOUDNAV_KEYFRAME_DIR`` (``building/submap/<uuid>.npz``: descriptors, 3D points,
words). Every server process reads the same rows and files, so in the scaled mode a
keyframe sent through one process answers queries on any other: each process keeps an
index per building and brings it up to date before a query (rows newer than it holds
are read; a clear, which removes rows, makes it start again).
"""

from __future__ import annotations

import logging
import math
import threading
import uuid
from dataclasses import dataclass
from pathlib import Path

from django.conf import settings
from django.db import transaction
from django.db.models import Count, Max, QuerySet

from cloudnav_core.grid import cell_of
from maps.domain.keyframes import DUPLICATE_DISTANCE, duplicates
from maps.domain.keyframes import Keyframe as Features
from maps.domain.relocalisation import KeyframeIndex
from maps.domain.vocabulary import default_vocabulary
from maps.exceptions import KeyframeError
from maps.models import Building, Keyframe, SubMap
from maps.services import grid_of

logger = logging.getLogger(__name__)

POSE_SLACK = 0.3
"""Metres: a keyframe's pose must be within this of a free cell of its sub-map."""


def check_pose(submap: SubMap, pose: tuple[float, float, float]) -> None:
    """Raise KeyframeError unless ``pose`` stands on (or within ``POSE_SLACK`` of) a free
    cell of ``submap``'s grid."""
    grid = grid_of(submap)
    reach = math.ceil(POSE_SLACK / submap.resolution)
    origin = (submap.origin_x, submap.origin_y)
    row, col = cell_of(pose[:2], origin, submap.resolution, nudge=0.0)
    rows, cols = grid.shape
    inside = 0 <= row < rows and 0 <= col < cols
    near = grid[max(row - reach, 0) : row + reach + 1, max(col - reach, 0) : col + reach + 1]
    if not inside or not (near == 0).any():
        raise KeyframeError(
            "pose", f"({pose[0]:.2f}, {pose[1]:.2f}) is not on the free floor of {submap.map_id}"
        )


def is_duplicate(submap: SubMap, pose: tuple[float, float, float]) -> bool:
    """Whether a stored keyframe of ``submap`` makes one at ``pose`` a near-duplicate
    (``duplicates``)."""
    x, y, _yaw = pose
    near = submap.keyframes.filter(
        x__gte=x - DUPLICATE_DISTANCE, x__lte=x + DUPLICATE_DISTANCE,
        y__gte=y - DUPLICATE_DISTANCE, y__lte=y + DUPLICATE_DISTANCE,
    ).values_list("x", "y", "yaw")  # fmt: skip
    return any(duplicates(kept, pose) for kept in near)


def save(submap: SubMap, robot: str, features: Features) -> Keyframe | None:
    """Store ``features`` as a keyframe of ``submap`` (file first, then the row); None
    when it is a near-duplicate of one stored."""
    if is_duplicate(submap, features.pose):
        return None
    relative = Path(submap.building.code) / submap.code / f"{uuid.uuid4().hex}.npz"
    path = settings.CLOUDNAV_KEYFRAME_DIR / relative
    path.parent.mkdir(parents=True, exist_ok=True)
    data = features.to_bytes()
    path.write_bytes(data)
    x, y, yaw = features.pose
    try:
        return Keyframe.objects.create(
            submap=submap, robot=robot, x=x, y=y, yaw=yaw,
            points=int(features.points.shape[0]), path=str(relative), size=len(data),
        )  # fmt: skip
    except Exception:
        path.unlink(missing_ok=True)
        raise


def clear(submap: SubMap) -> int:
    """Remove every keyframe of ``submap`` (rows, then files); returns how many."""
    paths = list(submap.keyframes.values_list("path", flat=True))
    with transaction.atomic():
        count, _ = submap.keyframes.all().delete()
    for relative in paths:
        (settings.CLOUDNAV_KEYFRAME_DIR / relative).unlink(missing_ok=True)
    return count


def coverage(submap: SubMap) -> list[dict[str, float | int | str]]:
    """The keyframe poses of ``submap``, oldest first."""
    return [
        {"id": k.pk, "x": k.x, "y": k.y, "yaw": k.yaw, "points": k.points, "robot": k.robot}
        for k in submap.keyframes.all()
    ]


# --- the index of each building ----------------------------------------------------------


@dataclass
class _Held:
    index: KeyframeIndex
    newest: int
    count: int


class Indexes:
    """Each building's ``KeyframeIndex`` in this process, brought up to date on use."""

    def __init__(self) -> None:
        self._held: dict[int, _Held] = {}
        self._lock = threading.Lock()

    def of(self, building: Building) -> KeyframeIndex:
        with self._lock:
            return self._current(building)

    def _current(self, building: Building) -> KeyframeIndex:
        rows = Keyframe.objects.filter(submap__building=building)
        state = rows.aggregate(count=Count("id"), newest=Max("id"))
        count, newest = int(state["count"]), int(state["newest"] or 0)
        held = self._held.get(building.pk)
        if held is None or held.count + _newer(rows, held.newest) != count:
            held = self._held[building.pk] = _Held(KeyframeIndex(default_vocabulary().size), 0, 0)
        for keyframe in rows.filter(id__gt=held.newest).select_related("submap"):
            features = _read(keyframe)
            if features is not None:
                held.index.add(keyframe.pk, keyframe.submap.code, features)
            held.count += 1
        held.newest = max(held.newest, newest)
        return held.index


def _newer(rows: QuerySet[Keyframe], newest: int) -> int:
    return rows.filter(id__gt=newest).count()


def _read(keyframe: Keyframe) -> Features | None:
    try:
        return Features.from_bytes((settings.CLOUDNAV_KEYFRAME_DIR / keyframe.path).read_bytes())
    except (OSError, KeyframeError) as error:
        logger.warning("keyframe %s unreadable: %s", keyframe.pk, error)
        return None


INDEXES = Indexes()
