"""Errors of the map store's domain; DRF's exception handler maps them to HTTP 400/404/409."""

from __future__ import annotations

import re

# ``<_io.BytesIO object at 0x7f...>``: how Pillow and zipfile name the upload they failed on.
_OBJECT_AT = re.compile(r"<[^<>]*? at 0x[0-9a-fA-F]+>")


def said(error: BaseException) -> str:
    """A library's error as a person may read it: objects named by memory address (which
    tell an attacker about the server's memory layout) become "the file"."""
    return _OBJECT_AT.sub("the file", str(error))


class MapStoreError(Exception):
    """Base of every map store error."""


class MapFileError(MapStoreError):
    """An uploaded map (image, YAML or archive) is unusable; ``field`` names what is at fault."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


class SubMapExistsError(MapStoreError):
    """An upload names the code of a stored sub-map without saying it may replace its map."""

    field = "code"

    def __init__(self, map_id: str) -> None:
        self.message = (
            f"{map_id} already exists; send replace=true to replace its map "
            "(robots get the new one on their next bundle request)."
        )
        super().__init__(f"{self.field}: {self.message}")


class TopologyError(MapStoreError):
    """A topology graph or route request is invalid; ``field`` names what is at fault."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


class NoRouteError(TopologyError):
    """No path joins the two sub-maps in the building's topology."""


class TagPayloadError(MapStoreError):
    """A QR payload cannot be parsed, or is too long for QR version 3."""


class NoSuchVersion(MapStoreError):
    """A sub-map has no version of that number."""


class VersionConflict(MapStoreError):
    """A change was made on a version that is no longer the sub-map's current one.

    ``based_on`` is the version it was made on, ``current`` the sub-map's now."""

    def __init__(self, based_on: int, current: int) -> None:
        super().__init__(
            f"This was made on v{based_on}, but the sub-map is at v{current} "
            "now: review it against the current version."
        )
        self.based_on = based_on
        self.current = current


class IncomparableVersions(MapStoreError):
    """Two versions whose cells do not line up (other resolution, yaw or origin)."""


class MappingError(MapStoreError):
    """A mapping session cannot be started, resumed or published as asked; the message
    says why (an offline robot, a second session on one robot, a session in another state)."""


class KeyframeError(MapStoreError):
    """A keyframe or relocalisation request is unusable (its image, depth, camera or
    pose); nothing of it is stored. ``field`` names what is at fault (``keyframe`` for a
    stored keyframe's file)."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


class RelocalisationRefused(MapStoreError):
    """The caller may relocalise in no building the request names (robots of a building
    and the people who may drive there may): a 403, or a failed service call."""


class OutsideExtent(MapStoreError):
    """A mapping session's robot reports a pose beyond the extent a session may map (from
    where it started); the scan is not used and the map stays as it was."""
