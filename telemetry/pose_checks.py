"""Goals and initial poses that people send are checked where they are sent, against the
target sub-map's grid (``maps.domain.planning.GoalCheck``): a pose no robot could stand at
is refused at once with the reason, instead of after the robot has driven towards it.

A goal is also checked against the spots the other robots hold (standing there, or going
there: ``maps.domain.reservations``, fed by the fleet feed in memory): by the building's
fleet rule it is refused with the reason, or moved to the nearest free spot and the
sender told where. A goal that passes holds its spot until the robot says it is over.

The checks of a sub-map are made once per version (``maps.services.goal_check_of``); which
version is current, and the building's fleet rule, are read again at most every
``FRESH_S`` seconds per sub-map, so a flood of goals costs no database work per message.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from channels.db import database_sync_to_async

from cloudnav_core import topics
from cloudnav_core.messages import Pose2D, goal_of, initial_pose_of, pose_2d
from cloudnav_core.se2 import Point
from maps import services as map_services
from maps.domain.planning import GoalCheck
from maps.domain.planning import PoseRefused as Unreachable
from maps.domain.reservations import FleetRule, Placement, Reservations
from maps.domain.widths import Widths
from maps.models import SubMap
from telemetry.domain import names
from telemetry.exceptions import PoseRefused

# The command topics whose poses are checked, and what the refusal calls them.
CHECKED = {topics.GOAL: "goal", "initialpose": "initial pose"}
FRESH_S = 2.0
MAX_SUBMAPS = 256


class PoseChecks:
    """This process's checks of the sub-maps goals were sent to (see the module)."""

    def __init__(
        self, reservations: Reservations, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.reservations = reservations
        self._clock = clock
        # Told (robot, by whom) when a goal was moved or refused off where a robot stands.
        self.wanted: Callable[[str, str], None] = lambda _robot, _by: None
        self._checks: OrderedDict[str, tuple[float, SubMapChecks | None]] = OrderedDict()

    async def check_point(self, map_id: str, point: Point, what: str) -> None:
        """Raise PoseRefused unless a robot could stand at ``point`` of sub-map ``map_id``."""
        await self._checked(map_id, point, what)

    async def place(self, map_id: str, point: Point, robot: str) -> Placement:
        """Where ``robot``'s goal at ``point`` of ``map_id`` goes: raises PoseRefused
        unless a robot could stand there; else the placement the building's fleet rule
        gives it among the spots other robots hold (its ``refusal`` says why it goes
        nowhere, ``moved_from`` that it was moved)."""
        checks = await self._checked(map_id, point, "goal")
        placed = self.reservations.place(map_id, point, robot, checks.rule, checks.standable)
        if placed.held_by is not None and placed.held_by.why == "standing":
            self.wanted(placed.held_by.robot, robot)
        return placed

    async def check(self, name: str, msg: Mapping[str, Any]) -> tuple[Mapping[str, Any], str]:
        """The goal or initial pose ``msg`` published on ``name`` (a robot's topic) as it
        goes on, and what the sender is told of it ("" or where a goal was moved); other
        topics pass as they are. Raises PoseRefused for a place no robot could stand at
        and, by the building's fleet rule, for a goal another robot holds. A goal that
        passes holds its spot from now on."""
        what = CHECKED.get(name.rsplit("/", 1)[-1])
        if what is None:
            return msg, ""
        found = goal_of(msg) if what == "goal" else _initial_pose(msg)
        if found is None:
            raise PoseRefused(f"the {what} needs a frame_id (a Map ID) and a finite pose")
        map_id, point = found.map_id.split("@", 1)[0], (found.x, found.y)
        if what != "goal":
            await self.check_point(map_id, point, what)
            return msg, ""
        robot = names.first_segment(name)
        placed = await self.place(map_id, point, robot)
        if placed.refusal:
            raise PoseRefused(f"{placed.refusal} ({map_id})")
        self.reservations.aim(robot, map_id, placed.point)
        if placed.moved_from is None:
            return msg, ""
        moved = {**msg, "pose": pose_2d(placed.point[0], placed.point[1], found.yaw)}
        return moved, f"{placed.message} ({map_id})"

    async def checks(self, map_id: str) -> SubMapChecks | None:
        """The checks of sub-map ``map_id`` (``building/code``), None if it names none."""
        return await self._checks_of(map_id)

    async def _checked(self, map_id: str, point: Point, what: str) -> SubMapChecks:
        checks = await self._checks_of(map_id)
        if checks is None:
            raise PoseRefused(f"the {what}'s frame_id {map_id!r} names no sub-map")
        try:
            checks.walls.check(point, what)
        except Unreachable as refused:
            raise PoseRefused(f"{refused} ({map_id})") from None
        return checks

    async def _checks_of(self, map_id: str) -> SubMapChecks | None:
        now = self._clock()
        held = self._checks.get(map_id)
        if held is not None and now - held[0] < FRESH_S:
            return held[1]
        checks: SubMapChecks | None = await database_sync_to_async(checks_for)(map_id)
        self._checks[map_id] = (now, checks)
        self._checks.move_to_end(map_id)
        while len(self._checks) > MAX_SUBMAPS:
            self._checks.popitem(last=False)
        return checks


@dataclass(frozen=True)
class SubMapChecks:
    """What a goal in one sub-map is checked against: its walls and its building's rule;
    and how wide its free space is (``widths``: where a robot stands in the way)."""

    walls: GoalCheck
    rule: FleetRule
    widths: Widths

    def standable(self, point: Point) -> bool:
        """True if a robot's centre fits at ``point`` itself (a goal moved there)."""
        try:
            self.walls.check(point, tolerance=0.0)
        except Unreachable:
            return False
        return True


def checks_for(map_id: str) -> SubMapChecks | None:
    """Return the checks of sub-map ``map_id`` (``building/code``), or None if none is."""
    building, _, code = map_id.partition("/")
    submap = SubMap.objects.filter(building__code=building, code=code).select_related("building")
    found = submap.first()
    if found is None:
        return None
    rule = FleetRule(found.building.fleet_rule)
    return SubMapChecks(map_services.goal_check_of(found), rule, map_services.submap_widths(found))


def _initial_pose(msg: Mapping[str, Any]) -> Pose2D | None:
    found = initial_pose_of(msg)
    return found[0] if found is not None else None
