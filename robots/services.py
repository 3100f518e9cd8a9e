"""Robot registry operations: registration, token rotation and token lookup."""

from __future__ import annotations

from collections.abc import Iterable

from django.db import transaction

from maps.models import Building

from .models import Robot
from .tokens import new_token, token_digest


@transaction.atomic
def register_robot(
    name: str, buildings: Iterable[Building] = (), description: str = ""
) -> tuple[Robot, str]:
    """Create a robot; return it with its token, which is not stored and cannot be shown again."""
    token = new_token()
    robot = Robot.objects.create(name=name, description=description, token_hash=token_digest(token))
    robot.buildings.set(list(buildings))
    return robot, token


def rotate_token(robot: Robot) -> str:
    """Give ``robot`` a new token and return it; the old one stops working at once."""
    token = new_token()
    robot.token_hash = token_digest(token)
    robot.save(update_fields=["token_hash", "token_rotated"])
    return token


def robot_for_token(token: str) -> Robot | None:
    """Return the robot that owns ``token``, or None for an unknown or empty token."""
    if not token:
        return None
    return Robot.objects.filter(token_hash=token_digest(token)).first()
