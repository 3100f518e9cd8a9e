"""``manage.py create_robot NAME --building CODE``: register a robot, print its token once."""

from __future__ import annotations

from typing import Any

from django.core.exceptions import ValidationError
from django.core.management.base import BaseCommand, CommandError, CommandParser

from cloudnav_core.topics import GLOBAL_NAMESPACES
from maps.models import Building
from robots.models import Robot, ros_name_validator
from robots.services import register_robot


class Command(BaseCommand):
    help = "Register a robot for one or more buildings and print its token (shown only once)."

    def add_arguments(self, parser: CommandParser) -> None:
        parser.add_argument("name", help="a ROS name segment, e.g. tb3_0")
        parser.add_argument("--building", action="append", default=[], help="building code")
        parser.add_argument("--description", default="")

    def handle(
        self, *args: Any, name: str, building: list[str], description: str, **kw: Any
    ) -> None:
        try:
            ros_name_validator(name)
        except ValidationError as exc:
            raise CommandError(exc.messages[0]) from None
        if name in GLOBAL_NAMESPACES:
            raise CommandError(f"{name} is a namespace of the server's own; choose another name.")
        if Robot.objects.filter(name=name).exists():
            raise CommandError(f"A robot named {name} already exists; rotate its token instead.")
        buildings = list(Building.objects.filter(code__in=building))
        unknown = set(building) - {b.code for b in buildings}
        if unknown:
            raise CommandError(f"Unknown building: {', '.join(sorted(unknown))}")
        robot, token = register_robot(name, buildings, description)
        self.stdout.write(f"Registered robot {robot.name}. Its token (shown once):")
        self.stdout.write(token)
