"""DRF authentication for robots: ``Authorization: Token <token>``."""

from __future__ import annotations

from typing import Any

from rest_framework import authentication, exceptions
from rest_framework.request import Request
from typing_extensions import override

from .models import Robot
from .services import robot_for_token


class RobotPrincipal:
    """Stands in ``request.user`` for a robot, so DRF's ``IsAuthenticated`` lets it through."""

    is_authenticated = True
    is_anonymous = False
    is_active = True
    is_superuser = False
    is_staff = False

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.pk = None
        self.username = f"robot:{robot.name}"

    def __str__(self) -> str:
        return self.username

    def has_perm(self, *args: Any, **kwargs: Any) -> bool:
        return False


class RobotTokenAuthentication(authentication.BaseAuthentication):
    keyword = "Token"

    def authenticate(self, request: Request) -> tuple[RobotPrincipal, Robot] | None:
        parts = authentication.get_authorization_header(request).split()
        if not parts or parts[0].decode("latin-1").lower() != self.keyword.lower():
            return None
        if len(parts) != 2:
            raise exceptions.AuthenticationFailed("Token header must be 'Token <token>'.")
        robot = robot_for_token(parts[1].decode("latin-1"))
        if robot is None:
            raise exceptions.AuthenticationFailed("Unknown robot token.")
        return RobotPrincipal(robot), robot

    @override
    def authenticate_header(self, request: Request) -> str:
        return self.keyword
