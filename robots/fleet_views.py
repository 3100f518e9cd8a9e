"""``GET /api/fleet/``: the state of every robot the requester may see."""

from __future__ import annotations

import math
from typing import Any

from django.db.models import Prefetch, QuerySet
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import permissions, serializers
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView
from typing_extensions import override

from maps.access import Role, buildings_for, global_role, robot_of
from maps.models import Building

from .models import Robot, RobotState, is_online


class FleetEntrySerializer(serializers.Serializer[Any]):
    robot = serializers.CharField()
    buildings = serializers.ListField(child=serializers.CharField())
    online = serializers.BooleanField()
    map_id = serializers.CharField(allow_blank=True)
    map_version = serializers.IntegerField(allow_null=True)
    x = serializers.FloatField(allow_null=True)
    y = serializers.FloatField(allow_null=True)
    yaw = serializers.FloatField(allow_null=True)
    last_seen = serializers.DateTimeField(allow_null=True)


class SeesFleet(permissions.BasePermission):
    message = "Only people with a role, and robots, see the fleet."

    @override
    def has_permission(self, request: Request, view: Any) -> bool:
        principal = request.user
        return robot_of(principal) is not None or global_role(principal) >= Role.VIEWER


def visible_robots(principal: Any, building: str | None) -> QuerySet[Robot]:
    """Robots registered for a building ``principal`` sees (optionally just ``building``)."""
    buildings = buildings_for(principal)
    if building:
        buildings = buildings.filter(code=building)
    return (
        Robot.objects.filter(buildings__in=buildings)
        .distinct()
        .select_related("state")
        .prefetch_related(Prefetch("buildings", queryset=Building.objects.order_by("code")))
        .order_by("name")
    )


def fleet_entry(robot: Robot, visible: set[str] | None = None) -> dict[str, Any]:
    """The fleet entry of ``robot``; ``buildings`` names only those of ``visible`` (codes
    the requester sees) when given, so no other tenant's building is shown."""
    state: RobotState | None = getattr(robot, "state", None)
    codes = [b.code for b in robot.buildings.all()]
    return {
        "robot": robot.name,
        "buildings": codes if visible is None else [c for c in codes if c in visible],
        "online": bool(state and is_online(state)),
        "map_id": state.map_id if state else "",
        "map_version": state.map_version if state else None,
        "x": _finite(state.x) if state else None,
        "y": _finite(state.y) if state else None,
        "yaw": _finite(state.yaw) if state else None,
        "last_seen": state.last_seen if state else None,
    }


def _finite(value: float | None) -> float | None:
    """A stored coordinate as JSON can carry it: NaN and infinity (kept by a server that
    did not yet refuse them) read as unknown, never as a 500 for everyone."""
    return value if value is not None and math.isfinite(value) else None


class FleetList(APIView):
    """Every visible robot: online, Map ID and the version of it held, pose (x, y, yaw in
    that map) and last seen."""

    permission_classes = [permissions.IsAuthenticated, SeesFleet]

    @extend_schema(
        parameters=[OpenApiParameter("building", str, required=False)],
        responses=FleetEntrySerializer(many=True),
    )
    def get(self, request: Request) -> Response:
        robots = visible_robots(request.user, request.query_params.get("building"))
        visible = set(buildings_for(request.user).values_list("code", flat=True))
        entries = [fleet_entry(robot, visible) for robot in robots]
        return Response(FleetEntrySerializer(entries, many=True).data)
