"""DRF authentication for robots: ``Authorization: Token <token>`` makes the request's
user a ``RobotPrincipal`` (``robots.principal``)."""

from __future__ import annotations

from rest_framework import authentication, exceptions
from rest_framework.request import Request
from typing_extensions import override

from .models import Robot
from .principal import RobotPrincipal
from .services import robot_for_token


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
