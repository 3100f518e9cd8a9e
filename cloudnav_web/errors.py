"""One place that turns domain errors into HTTP answers."""

from __future__ import annotations

from typing import Any

from rest_framework import status
from rest_framework.response import Response
from rest_framework.views import exception_handler as drf_exception_handler

from maps.exceptions import (
    IncomparableVersions,
    KeyframeError,
    MapFileError,
    MappingError,
    NoRouteError,
    NoSuchVersion,
    RelocalisationRefused,
    SubMapExistsError,
    TagPayloadError,
    TopologyError,
    VersionConflict,
)
from maps.visual.lanes import RelocalisationBusy
from maps.visual.service import KeyframeQueueFull


def exception_handler(exc: Exception, context: dict[str, Any]) -> Response | None:
    """Answer map store errors with 400 (404 for no route or version; 409 for an upload
    that would replace a map unasked, a change on a version no longer current, or a
    mapping session that cannot do what was asked; 403 for a relocalisation in no building
    the caller may use; 429 or 503 when relocalisation is busy) and field errors; defer
    the rest."""
    if isinstance(exc, NoRouteError):
        return Response({exc.field: [exc.message]}, status=status.HTTP_404_NOT_FOUND)
    if isinstance(exc, SubMapExistsError):
        return Response({exc.field: [exc.message]}, status=status.HTTP_409_CONFLICT)
    if isinstance(exc, MapFileError | TopologyError):
        return Response({exc.field: [exc.message]}, status=status.HTTP_400_BAD_REQUEST)
    if isinstance(exc, NoSuchVersion):
        return Response({"detail": str(exc)}, status=status.HTTP_404_NOT_FOUND)
    if isinstance(exc, VersionConflict):
        body = {"detail": str(exc), "based_on": exc.based_on, "current": exc.current}
        return Response(body, status=status.HTTP_409_CONFLICT)
    if isinstance(exc, MappingError):
        return Response({"detail": str(exc)}, status=status.HTTP_409_CONFLICT)
    if isinstance(exc, IncomparableVersions):
        return Response({"detail": str(exc)}, status=status.HTTP_400_BAD_REQUEST)
    if isinstance(exc, TagPayloadError):
        return Response({"payload": [str(exc)]}, status=status.HTTP_400_BAD_REQUEST)
    if isinstance(exc, KeyframeError):
        body = {"detail": str(exc), exc.field: [exc.message]}
        return Response(body, status=status.HTTP_400_BAD_REQUEST)
    if isinstance(exc, RelocalisationRefused):
        return Response({"detail": str(exc)}, status=status.HTTP_403_FORBIDDEN)
    if isinstance(exc, RelocalisationBusy):
        code = status.HTTP_429_TOO_MANY_REQUESTS if exc.own else status.HTTP_503_SERVICE_UNAVAILABLE
        return Response({"detail": str(exc)}, code, headers={"Retry-After": "1"})
    if isinstance(exc, KeyframeQueueFull):
        headers = {"Retry-After": "1"}
        return Response({"detail": str(exc)}, status.HTTP_503_SERVICE_UNAVAILABLE, headers=headers)
    return drf_exception_handler(exc, context)
