"""A robot as the principal of a request or connection: who the access rules see.

DRF's token authentication (``robots.authentication``) puts one in ``request.user``; the
rosbridge asks the map store's access rules (``maps.access``) which buildings it sees
through one, so neither depends on the other's framework.
"""

from __future__ import annotations

from typing import Any

from .models import Robot


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
