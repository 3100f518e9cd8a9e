"""Errors of the map store's domain; DRF's exception handler maps them to HTTP 400/404/409."""

from __future__ import annotations


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


class KeyframeError(MapStoreError):
    """A keyframe or relocalisation request is unusable (its image, depth, camera or
    pose); nothing of it is stored."""
