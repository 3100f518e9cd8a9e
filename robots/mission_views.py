"""``/api/missions/``: missions of the robots in the requester's buildings; operators and
admins start them and pause, resume, skip or cancel them."""

from __future__ import annotations

from typing import Any

from django.db.models import QuerySet
from drf_spectacular.utils import OpenApiParameter, extend_schema
from rest_framework import permissions, serializers, status
from rest_framework.exceptions import NotFound, PermissionDenied, ValidationError
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView
from typing_extensions import override

from maps.access import Role, buildings_for, global_role, role_in
from maps.models import Building

from . import missions
from .models import Mission


class MissionSerializer(serializers.ModelSerializer[Mission]):
    building = serializers.CharField(source="building.code", read_only=True)
    robot = serializers.CharField(source="robot.name", read_only=True)

    class Meta:
        model = Mission
        fields = [
            "id",
            "building",
            "robot",
            "name",
            "waypoints",
            "mode",
            "state",
            "index",
            "laps",
            "time_limit",
            "on_timeout",
            "note",
            "created_by",
            "created",
            "updated",
        ]
        read_only_fields = fields


class NewMissionSerializer(serializers.Serializer[Any]):
    building = serializers.CharField()
    robot = serializers.CharField()
    name = serializers.CharField(
        required=False, allow_blank=True, default="", max_length=Mission.NAME_LENGTH
    )
    mode = serializers.ChoiceField(choices=Mission.Mode.values, default=Mission.Mode.ONCE)
    waypoints = serializers.JSONField()
    time_limit = serializers.FloatField(
        min_value=0.0, max_value=86400.0, default=Mission._meta.get_field("time_limit").default
    )
    on_timeout = serializers.ChoiceField(
        choices=Mission.OnTimeout.values, default=Mission.OnTimeout.PAUSE
    )


class IsPerson(permissions.BasePermission):
    message = "Only people with a role see missions."

    @override
    def has_permission(self, request: Request, view: Any) -> bool:
        return global_role(request.user) >= Role.VIEWER


def visible_missions(user: Any) -> QuerySet[Mission]:
    return Mission.objects.filter(building__in=buildings_for(user)).select_related(
        "building", "robot"
    )


def _operator_in(user: Any, building: Building) -> None:
    if role_in(user, building) < Role.OPERATOR:
        raise PermissionDenied("Only operators and admins run missions.")


class MissionList(APIView):
    permission_classes = [permissions.IsAuthenticated, IsPerson]

    @extend_schema(
        parameters=[
            OpenApiParameter("building", str),
            OpenApiParameter("robot", str),
            OpenApiParameter("active", bool),
        ],
        responses=MissionSerializer(many=True),
    )
    def get(self, request: Request) -> Response:
        """Missions, newest first; ``active=1``: running and paused ones only."""
        found = visible_missions(request.user)
        params = request.query_params
        if params.get("building"):
            found = found.filter(building__code=params["building"])
        if params.get("robot"):
            found = found.filter(robot__name=params["robot"])
        if params.get("active") in ("1", "true"):
            found = found.filter(state__in=Mission.ACTIVE)
        return Response(MissionSerializer(found[:100], many=True).data)

    @extend_schema(request=NewMissionSerializer, responses={201: MissionSerializer})
    def post(self, request: Request) -> Response:
        """Start a mission (the robot's active one is cancelled)."""
        asked = NewMissionSerializer(data=request.data)
        asked.is_valid(raise_exception=True)
        data = asked.validated_data
        building = buildings_for(request.user).filter(code=data["building"]).first()
        # A robot of other buildings only is as absent as one that does not exist.
        robot = building.robots.filter(name=data["robot"]).first() if building else None
        if building is None or robot is None:
            raise NotFound("No such building or robot.")
        _operator_in(request.user, building)
        try:
            mission = missions.start(
                building,
                robot,
                data["waypoints"],
                data["mode"],
                data["name"],
                request.user.get_username(),
                time_limit=data["time_limit"],
                on_timeout=data["on_timeout"],
            )
        except missions.RobotBusyElsewhere as error:
            return Response({"robot": [str(error)]}, status=status.HTTP_409_CONFLICT)
        except missions.MissionError as error:
            raise ValidationError({error.field: [str(error)]}) from None
        return Response(MissionSerializer(mission).data, status=status.HTTP_201_CREATED)


class MissionCommand(APIView):
    """``POST /api/missions/{id}/{pause|resume|skip|cancel}``."""

    permission_classes = [permissions.IsAuthenticated, IsPerson]

    @extend_schema(request=None, responses=MissionSerializer)
    def post(self, request: Request, pk: int, command: str) -> Response:
        mission = visible_missions(request.user).filter(pk=pk).first()
        if mission is None or command not in missions.COMMANDS:
            raise NotFound("No such mission or command.")
        _operator_in(request.user, mission.building)
        try:
            missions.command(mission, command, request.user.get_username())
        except missions.MissionError as error:
            raise ValidationError({"mission": [str(error)]}) from None
        return Response(MissionSerializer(mission).data)
