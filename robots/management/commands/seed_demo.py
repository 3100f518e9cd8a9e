"""``python manage.py seed_demo``: the paper's demo building, its people and its robots.

It creates what is missing and leaves everything else alone, so running it again (every
``make demo`` does) keeps what people did since: sub-maps, tags and users that exist are
not touched (a tag an admin moved or placed stays, a changed password stays), and the
topology is seeded only into a building that has no edges yet. The demo's parking spots
are added where missing, never over people's: one whose name is taken, or with a spot
already within ``PARKING_SPACING`` of it in its sub-map, is left out, and no spot is
changed or removed. Robot tokens are kept in a
file (``--tokens-file``) so the simulated robots can read them; a robot whose token in that
file no longer matches gets a new one.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from django.conf import settings
from django.contrib.auth.models import Group, User
from django.core.management.base import BaseCommand, CommandParser
from django.db import transaction

from maps import services
from maps.domain.demo_building import DemoBuilding, demo_building, submap_metadata
from maps.domain.mapfile import load_map_upload, map_yaml_text
from maps.domain.topology import Edge
from maps.models import Building, EnvironmentalTag, ParkingSpot
from robots.models import Robot
from robots.services import register_robot, rotate_token
from robots.tokens import token_digest

DEMO_USERS = ("admin", "operator", "viewer")
PARKING_SPACING = 1.0
"""Metres: a demo parking spot nearer than this to a spot people made is not added."""


class Command(BaseCommand):
    help = "Create or update the demo building boccioni_1, users admin/operator/viewer and robots."

    def add_arguments(self, parser: CommandParser) -> None:
        parser.add_argument("--robots", type=int, default=3, help="how many demo robots")
        parser.add_argument(
            "--tokens-file",
            default=str(settings.BASE_DIR / "var" / "demo_tokens.json"),
            help="where robot tokens are kept for the simulated robots",
        )

    def handle(self, *args: Any, robots: int, tokens_file: str, **options: Any) -> None:
        demo = demo_building(settings.CLOUDNAV_PUBLIC_URL)
        with transaction.atomic():
            building = self._building(demo)
            self._submaps(building, demo)
            self._tags(building, demo)
            self._parking(building, demo)
            if not building.edges.exists():
                self._topology(building, demo)
            passwords = self._users(building)
        tokens = self._robots(building, robots, Path(tokens_file))
        self._report(building, passwords, tokens, tokens_file)

    def _building(self, demo: DemoBuilding) -> Building:
        building, _ = Building.objects.get_or_create(
            code=demo.code,
            defaults={"name": demo.name, "zip_code": demo.zip_code, "address": demo.address},
        )
        return building

    def _submaps(self, building: Building, demo: DemoBuilding) -> None:
        existing = set(building.submaps.values_list("code", flat=True))
        for sub in demo.submaps:
            if sub.code in existing:
                continue
            meta = submap_metadata(sub)
            loaded = load_map_upload(map_yaml_text(meta).encode(), {meta.image: sub.pgm}, 10**8)
            fields: dict[str, Any] = {
                "name": sub.name,
                "node_x": sub.node_xy[0],
                "node_y": sub.node_xy[1],
            }
            services.save_submap(building, sub.code, loaded, replace=False, **fields)

    def _tags(self, building: Building, demo: DemoBuilding) -> None:
        submaps = {s.code: s for s in building.submaps.defer("image")}
        existing = set(building.tags.values_list("marker_id", flat=True))
        for tag in demo.tags:
            if tag.marker_id in existing:
                continue
            EnvironmentalTag.objects.create(
                building=building,
                marker_id=tag.marker_id,
                submap=submaps[tag.submap],
                links_to=submaps[tag.links_to],
                x=tag.x,
                y=tag.y,
                yaw=tag.yaw,
                size=tag.size,
            )

    def _parking(self, building: Building, demo: DemoBuilding) -> None:
        submaps = {s.code: s for s in building.submaps.defer("image")}
        spots = building.parking_spots.values_list("name", "submap__code", "x", "y")
        taken = list(spots)
        for spot in demo.parking:
            if spot.submap not in submaps or any(
                name == spot.name
                or (code == spot.submap and math.dist((x, y), (spot.x, spot.y)) < PARKING_SPACING)
                for name, code, x, y in taken
            ):
                continue
            ParkingSpot.objects.create(
                building=building,
                submap=submaps[spot.submap],
                name=spot.name,
                x=spot.x,
                y=spot.y,
                yaw=spot.yaw,
            )

    def _topology(self, building: Building, demo: DemoBuilding) -> None:
        edges = [Edge(e.a, e.b, e.cost) for e in demo.edges]
        positions = {s.code: s.node_xy for s in demo.submaps}
        services.replace_topology(building, positions, edges)

    def _users(self, building: Building) -> dict[str, str | None]:
        """Create the demo users that are missing; return each one's password, or None
        for a user that was there already (whose password, groups and buildings stay)."""
        passwords: dict[str, str | None] = {}
        for name in DEMO_USERS:
            if User.objects.filter(username=name).exists():
                passwords[name] = None
                continue
            password = os.environ.get("CLOUDNAV_DEMO_PASSWORD", f"{name}-demo")
            user = User.objects.create_user(name, password=password, is_staff=name == "admin")
            user.groups.add(Group.objects.get_or_create(name=name)[0])
            building.members.add(user, through_defaults={"role": name})
            passwords[name] = password
        return passwords

    def _robots(self, building: Building, count: int, path: Path) -> dict[str, str]:
        known = json.loads(path.read_text()) if path.exists() else {}
        tokens = {}
        for index in range(count):
            name = f"robot_{index}"
            robot = Robot.objects.filter(name=name).first()
            if robot is None:
                robot, token = register_robot(name, [building], "Simulated demo robot")
            elif robot.token_hash == token_digest(known.get(name, "")):
                token = known[name]
            else:
                token = rotate_token(robot)
            robot.buildings.add(building)
            tokens[name] = token
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(tokens, indent=2) + "\n")
        path.chmod(0o600)
        return tokens

    def _report(
        self,
        building: Building,
        passwords: dict[str, str | None],
        tokens: dict[str, str],
        path: str,
    ) -> None:
        write = self.stdout.write
        write(
            f"Demo building {building.code}: {building.submaps.count()} sub-maps, "
            f"{building.tags.count()} tags, {building.edges.count()} edges, "
            f"{building.parking_spots.count()} parking spots."
        )
        for name, password in passwords.items():
            kept = "(was there: its password is unchanged)"
            write(f"  user {name:9} password {password or kept}")
        for name, token in tokens.items():
            write(f"  robot {name:8} token {token}")
        write(f"Robot tokens saved to {path}")
