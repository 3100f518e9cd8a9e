"""A sub-map's versions: the history, one version, its image and grid, rollback, and the
comparison of two."""

from __future__ import annotations

from django.http import HttpResponse, HttpResponseBase
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import status
from rest_framework.parsers import JSONParser
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from .. import versions
from ..access import Role
from ..serializers import VersionComparisonSerializer, VersionSerializer
from .lookups import submap_for
from .map_files import grid_response, image_response


class VersionList(APIView):
    """A sub-map's versions, newest first (who, when, why), the current one's number and
    the tags that stand in an occupied cell of it."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, building: str, map: str) -> Response:
        submap = submap_for(request, building, map)
        return Response(
            {
                "map_id": submap.map_id,
                "current": submap.revision,
                "buried_tags": versions.buried_tags_of(submap),
                "versions": VersionSerializer(versions.history(submap), many=True).data,
            }
        )


class VersionDetail(APIView):
    @extend_schema(responses=VersionSerializer)
    def get(self, request: Request, building: str, map: str, number: int) -> Response:
        submap = submap_for(request, building, map)
        return Response(VersionSerializer(versions.version_of(submap, number)).data)


class VersionImage(APIView):
    """An old version's image, as it was made."""

    @extend_schema(responses={(200, "image/*"): OpenApiTypes.BINARY})
    def get(self, request: Request, building: str, map: str, number: int) -> HttpResponse:
        return image_response(versions.version_of(submap_for(request, building, map), number))


class VersionGrid(APIView):
    """An old version as a ``nav_msgs/OccupancyGrid`` in rosbridge JSON (heavy work)."""

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, building: str, map: str, number: int) -> HttpResponseBase:
        submap = submap_for(request, building, map)
        return grid_response(request, versions.version_of(submap, number), submap.map_id)


class VersionRollback(APIView):
    """Make an earlier version current again: a new version with its map (admins)."""

    parser_classes = [JSONParser]

    @extend_schema(request=OpenApiTypes.OBJECT, responses={201: VersionSerializer})
    def post(self, request: Request, building: str, map: str, number: int) -> Response:
        submap = submap_for(request, building, map, Role.ADMIN)
        note = str(request.data.get("note", "")) if isinstance(request.data, dict) else ""
        made = versions.rollback(submap, number, request.user, note)
        return Response(VersionSerializer(made).data, status=status.HTTP_201_CREATED)


# Changed cells listed in a comparison at most; the counts are always whole.
COMPARISON_CELLS = 50_000


class VersionComparison(APIView):
    """How version ``to`` differs from version ``from``: cells that became occupied
    (``added``) or free (``removed``), as ``[row, col]`` of ``to``'s grid."""

    @extend_schema(
        parameters=[
            OpenApiParameter("from", int, required=True),
            OpenApiParameter("to", int, required=True),
        ],
        responses=VersionComparisonSerializer,
    )
    def get(self, request: Request, building: str, map: str) -> Response:
        submap = submap_for(request, building, map)
        numbers = VersionComparisonSerializer.numbers(request.query_params)
        diff = versions.compare(submap, numbers["from"], numbers["to"])
        return Response(
            {
                "from": numbers["from"],
                "to": numbers["to"],
                "added": len(diff.added),
                "removed": len(diff.removed),
                "unknown_changed": diff.unknown_changed,
                "compared": diff.compared,
                "truncated": len(diff.added) + len(diff.removed) > COMPARISON_CELLS,
                "cells": {
                    "added": diff.added[:COMPARISON_CELLS].tolist(),
                    "removed": diff.removed[: max(0, COMPARISON_CELLS - len(diff.added))].tolist(),
                },
            }
        )


# The visual map
