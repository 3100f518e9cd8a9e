"""REST adapters of the robot registry (admins only)."""

from __future__ import annotations

from typing import Any

from django.db.models import QuerySet
from drf_spectacular.utils import extend_schema
from rest_framework import generics, permissions, status
from rest_framework.exceptions import NotFound
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView
from typing_extensions import override

from maps.access import Role, buildings_for, global_role

from . import services
from .models import Robot
from .serializers import RobotCreatedSerializer, RobotSerializer, TokenSerializer


class IsAdmin(permissions.BasePermission):
    message = "Only admins manage robots."

    @override
    def has_permission(self, request: Request, view: Any) -> bool:
        return global_role(request.user) >= Role.ADMIN


def robots_for(user: Any) -> QuerySet[Robot]:
    """Robots registered for at least one building the admin administers (all, for superusers)."""
    if user.is_superuser:
        return Robot.objects.all()
    return Robot.objects.filter(buildings__in=buildings_for(user)).distinct()


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
        robot, token = services.register_robot(**form.validated_data)
        answer = {**RobotSerializer(robot).data, "token": token}
        return Response(answer, status=status.HTTP_201_CREATED)


class RobotDetail(generics.RetrieveUpdateDestroyAPIView[Robot]):
    serializer_class = RobotSerializer
    permission_classes = [permissions.IsAuthenticated, IsAdmin]
    lookup_field = "name"

    def get_queryset(self) -> QuerySet[Robot]:
        return robots_for(self.request.user)


class RotateToken(APIView):
    permission_classes = [permissions.IsAuthenticated, IsAdmin]

    @extend_schema(request=None, responses=TokenSerializer)
    def post(self, request: Request, name: str) -> Response:
        """Give the robot a new token; the old one stops working at once."""
        robot = robots_for(request.user).filter(name=name).first()
        if robot is None:
            raise NotFound("No such robot.")
        return Response({"name": robot.name, "token": services.rotate_token(robot)})
