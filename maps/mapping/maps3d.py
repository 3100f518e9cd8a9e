"""The 3D maps of visual sessions: made from a session's saved state (each keyframe's
cloud at its optimised pose, ``maps.domain.visual_cloud``), and kept on disk beside the
sub-map version a session was published as (``CLOUDNAV_MAP3D_DIR/<version id>-<the
microsecond it was made>/``: ``cloud.ply`` and ``octomap.bt``; never its number, so a
sub-map made again under the same code, or a database made again, never finds another
version's files). A file is
written under a temporary name and renamed, so a reader finds it whole or not at all.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from django.conf import settings

from cloudnav_core.camera import Mount

from ..domain.visual_cloud import map_cloud, octomap_bytes, ply_bytes
from ..domain.visual_mapping import SavedView, stored_view
from ..exceptions import MappingError
from ..models import MappingSession, SubMapVersion

CLOUD, OCTOMAP = "cloud.ply", "octomap.bt"


def view_of(session: MappingSession) -> SavedView:
    """What a visual session's saved state holds for the 3D maps. Raises MappingError
    for a laser session or a state that cannot be read."""
    if session.kind != MappingSession.VISUAL:
        raise MappingError("A laser session makes no 3D map: map with the robot's camera.")
    try:
        return stored_view(bytes(session.keyframes)) if session.keyframes else SavedView([], [], [])
    except ValueError as error:
        raise MappingError(f"The session's saved map cannot be read: {error}") from None


def made(view: SavedView, name: str) -> bytes:
    """The ``name`` file (``CLOUD`` or ``OCTOMAP``) of ``view``."""
    if name == CLOUD:
        return ply_bytes(map_cloud(view.clouds, view.poses))
    return octomap_bytes(view.clouds, view.poses, Mount())


def store(version: SubMapVersion, view: SavedView) -> None:
    """Write both 3D maps of ``view`` beside ``version``."""
    for name in (CLOUD, OCTOMAP):
        _write(path_of(version, name), made(view, name))


def stored(version: SubMapVersion, name: str) -> bytes | None:
    """The ``name`` file stored with ``version``, or None (a laser version has none)."""
    try:
        return path_of(version, name).read_bytes()
    except FileNotFoundError:
        return None


def path_of(version: SubMapVersion, name: str) -> Path:
    """Where ``version``'s ``name`` file is: named by its id and the microsecond it was
    made, which no other version shares, even in a database made again from scratch."""
    made_at = round(version.created.timestamp() * 1e6)
    return Path(settings.CLOUDNAV_MAP3D_DIR) / f"{version.pk}-{made_at}" / name


def _write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(handle, "wb") as out:
            out.write(data)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
