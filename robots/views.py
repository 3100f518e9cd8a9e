"""REST adapters of the robot registry (admins only)."""

from __future__ import annotations

from typing import Any

from django.db import IntegrityError, transaction
from django.db.models import QuerySet
from drf_spectacular.utils import extend_schema
from rest_framework import generics, permissions, status
from rest_framework.exceptions import NotFound, PermissionDenied, ValidationError
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView
from typing_extensions import override

from maps.access import Role, buildings_where, global_role

from . import services
from .models import Robot
from .serializers import NAME_UNAVAILABLE, RobotCreatedSerializer, RobotSerializer, TokenSerializer


class IsAdmin(permissions.BasePermission):
    message = "Only admins manage robots."

    @override
    def has_permission(self, request: Request, view: Any) -> bool:
        return global_role(request.user) >= Role.ADMIN


def administers_all(user: Any, robot: Robot) -> bool:
    """True if ``user`` administers every building ``robot`` is registered for."""
    if user.is_superuser:
        return True
    return not robot.buildings.exclude(pk__in=buildings_where(user, Role.ADMIN)).exists()


def require_whole_robot(user: Any, robot: Robot, what: str) -> None:
    """Raise PermissionDenied unless ``user`` may ``what`` the robot as a whole: renaming,
    describing, rotating or deleting a robot shared with buildings of others is theirs too."""
    if not administers_all(user, robot):
        raise PermissionDenied(
            f"Only an admin of every building of this robot may {what} it; "
            "you may link it to or unlink it from your own buildings."
        )


def robots_for(user: Any) -> QuerySet[Robot]:
    """Robots registered for at least one building the admin administers (all, for superusers)."""
    if user.is_superuser:
        return Robot.objects.all()
    return Robot.objects.filter(buildings__in=buildings_where(user, Role.ADMIN)).distinct()


class RobotList(generics.ListCreateAPIView[Robot]):
    serializer_class = RobotSerializer
    permission_classes = [permissions.IsAuthenticated, IsAdmin]

    def get_queryset(self) -> QuerySet[Robot]:
        return robots_for(self.request.user).prefetch_related("buildings")

    @extend_schema(request=RobotSerializer, responses={201: RobotCreatedSerializer})
    def post(self, request: Request) -> Response:
        """Register a robot; the answer carries its token, which is never shown again."""
        form = RobotSerializer(data=request.data, context={"request": request})
        form.is_valid(raise_exception=True)
        try:
            with transaction.atomic():
                robot, token = services.register_robot(**form.validated_data)
        except IntegrityError:  # the same name registered at the same moment
            raise ValidationError({"name": [NAME_UNAVAILABLE]}) from None
        shown = RobotSerializer(robot, context={"request": request}).data
        answer = {**shown, "token": token}
        return Response(answer, status=status.HTTP_201_CREATED)


class RobotDetail(generics.RetrieveUpdateDestroyAPIView[Robot]):
    serializer_class = RobotSerializer
    permission_classes = [permissions.IsAuthenticated, IsAdmin]
    lookup_field = "name"

    def get_queryset(self) -> QuerySet[Robot]:
        return robots_for(self.request.user)

    def perform_update(self, serializer: Any) -> None:
        robot, changes = serializer.instance, serializer.validated_data
        renamed = "name" in changes and changes["name"] != robot.name
        described = "description" in changes and changes["description"] != robot.description
        if renamed or described:
            require_whole_robot(self.request.user, robot, "rename or describe")
        serializer.save()

    def perform_destroy(self, instance: Robot) -> None:
        require_whole_robot(self.request.user, instance, "delete")
        services.delete_robot(instance)


class RotateToken(APIView):
    permission_classes = [permissions.IsAuthenticated, IsAdmin]

    @extend_schema(request=None, responses=TokenSerializer)
    def post(self, request: Request, name: str) -> Response:
        """Give the robot a new token; the old one stops working at once."""
        robot = robots_for(request.user).filter(name=name).first()
        if robot is None:
            raise NotFound("No such robot.")
        require_whole_robot(request.user, robot, "rotate the token of")
        return Response({"name": robot.name, "token": services.rotate_token(robot)})
