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


def delete_robot(robot: Robot) -> None:
    """Delete ``robot`` and what is its own (its fleet state, missions, mapping sessions).

    The robot's row is locked first: a fleet state or an event its live connection
    commits meanwhile then waits for the deletion and is refused by the database, instead
    of slipping in between the rows the deletion collected and the robot's own, where it
    failed the deletion at commit (PostgreSQL's deferred foreign-key check: a 500 seen in
    the scaled mode on a loaded machine)."""
    with transaction.atomic():
        Robot.objects.select_for_update().filter(pk=robot.pk).exists()
        robot.delete()


def robot_for_token(token: str) -> Robot | None:
    """Return the robot that owns ``token``, or None for an unknown or empty token."""
    if not token:
        return None
    return Robot.objects.filter(token_hash=token_digest(token)).first()
