"""The visual map: a sub-map's keyframes (robots send them) and visual relocalisation over REST."""

from __future__ import annotations

from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import extend_schema
from rest_framework import status
from rest_framework.exceptions import PermissionDenied, ValidationError
from rest_framework.parsers import JSONParser
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

from ..access import Role, buildings_for, buildings_where, robot_of
from ..visual import service as visual
from ..visual import store as visual_store
from ..visual.lanes import Caller
from .lookups import submap_for


class SubMapKeyframes(APIView):
    """A sub-map's keyframes: robots of the building send them (``POST``, queued: 202),
    anyone who sees the building lists their poses (``GET``), admins clear them."""

    parser_classes = [JSONParser]

    @extend_schema(request=OpenApiTypes.OBJECT, responses={202: OpenApiTypes.OBJECT})
    def post(self, request: Request, building: str, map: str) -> Response:
        """``{image, depth, pose: {x, y, yaw}, camera_info?, mount?}``; 503 when the
        ingestion queue is full."""
        submap = submap_for(request, building, map)
        robot = robot_of(request.user)
        if robot is None:
            raise PermissionDenied("Only robots send keyframes.")
        if not isinstance(request.data, dict):
            raise ValidationError({"detail": "a JSON object is required"})
        visual.accept_keyframe(submap, robot.name, request.data)
        return Response({"queued": True}, status=status.HTTP_202_ACCEPTED)

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def get(self, request: Request, building: str, map: str) -> Response:
        submap = submap_for(request, building, map)
        return Response({"map_id": submap.map_id, "keyframes": visual_store.coverage(submap)})

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    def delete(self, request: Request, building: str, map: str) -> Response:
        submap = submap_for(request, building, map, Role.ADMIN)
        return Response({"removed": visual_store.clear(submap)})


class Relocalise(APIView):
    """``/cloudnav/relocalise`` over REST: where the images were taken, among the
    keyframes of the buildings the caller may relocalise in (a robot: its own; a person:
    where they may drive), ``building`` narrowing it; 403 when that is none. Answered on
    the relocalisation lanes the rosbridge service uses (robots first; 429 or 503 with
    Retry-After when the caller's share or the lane is full)."""

    parser_classes = [JSONParser]

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    def post(self, request: Request) -> Response:
        if not isinstance(request.data, dict):
            raise ValidationError({"detail": "a JSON object is required"})
        code = request.data.get("building")
        if code is not None and not isinstance(code, str):
            raise ValidationError({"building": ["a building code is required"]})
        robot = robot_of(request.user)
        if robot is not None:
            allowed = buildings_for(request.user)
            caller = Caller(f"robot:{robot.name}", robot=True)
        else:
            allowed = buildings_where(request.user, Role.OPERATOR)
            caller = Caller(f"user:{request.user.get_username()}", robot=False)
        buildings = visual.buildings_to_search(allowed.values_list("pk", flat=True), code)
        return Response(visual.relocalise_queued(caller, buildings, request.data).result())


# Topology and routes
