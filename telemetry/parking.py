"""The parking rule: a robot that finished its goal where others need to be (another
robot is going there, or a narrow place others pass through) is sent to the nearest free
parking spot of its building, and an event says so.

Looked at ``SETTLE_S`` after the robot's goal ended (a mission's next waypoint, sent
within a tick, moves it on instead: a robot on a mission is never parked), and when
another robot's goal was moved or refused off the spot where it stands idle. Nothing
happens in a building whose fleet rule is ``off`` (robots planning alone), nor for a robot
whose building has no free spot.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable

from channels.db import database_sync_to_async

from maps import services as map_services
from maps.domain.reservations import FleetRule, Hold, ParkingPlace
from robots import missions
from telemetry.pose_checks import PoseChecks

SETTLE_S = 2.0
# A passage narrower than this many planning radii is a narrow place: a robot standing in
# its middle leaves less than another robot's planning width on either side.
NARROW_RADII = 6.0


class Parking:
    """``send(robot, place, why)`` sends a robot to a parking place (see the module)."""

    def __init__(
        self,
        poses: PoseChecks,
        send: Callable[[str, ParkingPlace, str], None],
        settle: float = SETTLE_S,
    ) -> None:
        self.poses = poses
        self.spots = poses.reservations
        self.send = send
        self.settle = settle
        self._pending: dict[str, asyncio.Task[None]] = {}

    def goal_over(self, robot: str) -> None:
        """``robot``'s goal ended: look where it stands once it settled."""
        self._look(robot, "")

    def wanted(self, robot: str, by: str) -> None:
        """Another robot's goal was moved or refused off where ``robot`` stands (``by``
        says whose)."""
        self._look(robot, f"{by} was sent where it stands")

    def _look(self, robot: str, why: str) -> None:
        if robot in self._pending and not self._pending[robot].done():
            return
        self._pending[robot] = asyncio.get_running_loop().create_task(self._park(robot, why))

    async def _park(self, robot: str, why: str) -> None:
        await asyncio.sleep(self.settle)
        here = self.spots.standing(robot)
        if here is None or self.spots.going(robot):
            return
        checks = await self.poses.checks(here.map_id)
        if checks is None or checks.rule is FleetRule.OFF:
            return
        limit = NARROW_RADII * self.spots.radius
        reason = why or self.spots.in_the_way(
            robot, lambda _map, point: checks.widths.narrowest(point) < limit
        )
        if not reason or await database_sync_to_async(missions.on_a_mission)(robot):
            return
        building = here.map_id.split("/", 1)[0]
        places = await database_sync_to_async(map_services.parking_places)(building)
        if any(_on(here, p, self.spots.radius) for p in places):
            return  # parked already: a parking spot is where a robot waits
        place = self.spots.nearest_parking(robot, places)
        if place is not None and not self.spots.going(robot):
            self.send(robot, place, reason)


def _on(here: Hold, place: ParkingPlace, radius: float) -> bool:
    return here.map_id == place.map_id and math.dist((here.x, here.y), (place.x, place.y)) < radius
