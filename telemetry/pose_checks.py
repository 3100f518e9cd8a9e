"""Goals and initial poses that people send are checked where they are sent, against the
target sub-map's grid (``maps.domain.planning.GoalCheck``): a pose no robot could stand at
is refused at once with the reason, instead of after the robot has driven towards it.

The checks of a sub-map are made once per version (``maps.services.goal_check_of``); which
version is current is read again at most every ``FRESH_S`` seconds per sub-map, so a flood
of goals costs no database work per message.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable, Mapping
from typing import Any

from channels.db import database_sync_to_async

from maps import services as map_services
from maps.domain.planning import GoalCheck
from maps.domain.planning import PoseRefused as Unreachable
from maps.models import SubMap
from telemetry.domain import names
from telemetry.domain.messages import Pose2D, goal_of, initial_pose_of
from telemetry.exceptions import PoseRefused

# The command topics whose poses are checked, and what the refusal calls them.
CHECKED = {names.GOAL: "goal", "initialpose": "initial pose"}
FRESH_S = 2.0
MAX_SUBMAPS = 256


class PoseChecks:
    """This process's checks of the sub-maps goals were sent to (see the module)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._checks: OrderedDict[str, tuple[float, GoalCheck | None]] = OrderedDict()

    async def check_point(self, map_id: str, point: tuple[float, float], what: str) -> None:
        """Raise PoseRefused unless a robot could stand at ``point`` of sub-map ``map_id``."""
        checks = await self._checks_of(map_id)
        if checks is None:
            raise PoseRefused(f"the {what}'s frame_id {map_id!r} names no sub-map")
        try:
            checks.check(point, what)
        except Unreachable as refused:
            raise PoseRefused(f"{refused} ({map_id})") from None

    async def check(self, name: str, msg: Mapping[str, Any]) -> None:
        """Raise PoseRefused unless the goal or initial pose ``msg`` published on ``name``
        (a robot's topic) is a place a robot could stand; other topics pass."""
        what = CHECKED.get(name.rsplit("/", 1)[-1])
        if what is None:
            return
        found = goal_of(msg) if what == "goal" else _initial_pose(msg)
        if found is None:
            raise PoseRefused(f"the {what} needs a frame_id (a Map ID) and a finite pose")
        await self.check_point(found.map_id.split("@", 1)[0], (found.x, found.y), what)

    async def _checks_of(self, map_id: str) -> GoalCheck | None:
        now = self._clock()
        held = self._checks.get(map_id)
        if held is not None and now - held[0] < FRESH_S:
            return held[1]
        checks: GoalCheck | None = await database_sync_to_async(checks_for)(map_id)
        self._checks[map_id] = (now, checks)
        self._checks.move_to_end(map_id)
        while len(self._checks) > MAX_SUBMAPS:
            self._checks.popitem(last=False)
        return checks


def checks_for(map_id: str) -> GoalCheck | None:
    """Return the checks of sub-map ``map_id`` (``building/code``), or None if none is."""
    building, _, code = map_id.partition("/")
    submap = SubMap.objects.filter(building__code=building, code=code).first()
    return map_services.goal_check_of(submap) if submap is not None else None


def _initial_pose(msg: Mapping[str, Any]) -> Pose2D | None:
    found = initial_pose_of(msg)
    return found[0] if found is not None else None
