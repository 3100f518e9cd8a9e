"""Right of way, on the server: the narrow-place arbiter (``maps.domain.right_of_way``)
fed by the fleet feed with the robots connected to this process (their ``plan`` and
``pose``) and each sub-map's widths and tag crossings, its verdicts told to the robots on
``/r/right_of_way`` (latched, so a page opened later sees who waits) and written as
``right_of_way`` events.

Decisions cost no database work per message: a sub-map's widths and crossings are read
once per version (``maps.services.widths_of`` and ``crossings_of``, again at most every
``FRESH_S`` seconds), off the event loop, and the arbiter decides at most every
``DECIDE_EVERY_S`` seconds.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

from channels.db import database_sync_to_async

from cloudnav_core import topics
from cloudnav_core.messages import WaitOrder, path_points_of, right_of_way_message
from cloudnav_core.se2 import Point
from maps import services as map_services
from maps.domain.right_of_way import Arbiter, Verdict
from maps.domain.widths import Widths
from telemetry.domain.protocol import Json
from telemetry.events import EventLog

FRESH_S = 2.0
DECIDE_EVERY_S = 0.2

Tell = Callable[[str, dict[str, Json]], None]
Places = tuple[Widths | None, tuple[Point, ...]]
"""A sub-map's widths (None: no such sub-map) and its tag crossings."""


def _places_of(map_id: str) -> Places:
    return map_services.widths_of(map_id), map_services.crossings_of(map_id)


class RightOfWay:
    """This process's right of way (see the module); ``enabled`` False (the setting
    ``CLOUDNAV_RIGHT_OF_WAY``) tells no robot anything."""

    def __init__(
        self,
        radius: float,
        events: EventLog,
        tell: Tell,
        enabled: bool = True,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.arbiter = Arbiter(radius, clock)
        self.enabled = enabled
        self._events = events
        self._tell = tell
        self._clock = clock
        self._decided = -DECIDE_EVERY_S
        self._places: dict[str, tuple[float, Places]] = {}  # map -> (when read, its places)
        self._plans: dict[str, tuple[str, list[Point]]] = {}  # the newest, while widths load
        self._tasks: set[asyncio.Task[None]] = set()
        self._later: asyncio.TimerHandle | None = None

    def plan(self, robot: str, msg: dict[str, Json]) -> None:
        """``robot`` published a new global plan."""
        found = path_points_of(msg)
        if not self.enabled or found is None:
            return
        map_id, points = found[0].split("@", 1)[0], found[1]
        held = self._places.get(map_id)
        if held is not None and self._clock() - held[0] < FRESH_S:
            self.arbiter.route(robot, map_id, points, *held[1])
            self._decide(force=True)
            return
        self._plans[robot] = (map_id, points)
        task = asyncio.get_running_loop().create_task(self._load(map_id))
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    def pose(self, robot: str, map_id: str, x: float, y: float) -> None:
        if self.enabled:
            self.arbiter.at(robot, map_id.split("@", 1)[0], (x, y))
            self._decide()

    def goal_over(self, robot: str) -> None:
        """``robot`` has no active goal: its route is gone."""
        if self.enabled and self.arbiter.passages(robot):
            verdict = self.arbiter.verdict(robot)
            self.arbiter.route(robot, verdict.map_id if verdict else "", [], None)
            self._decide(force=True)

    def left(self, robot: str) -> None:
        self.arbiter.leave(robot)
        self._plans.pop(robot, None)
        self._decide(force=True)

    def blocking(self, robot: str) -> tuple[str, str] | None:
        """The robot ``robot`` waits for, as a stuck alert names it, or None."""
        verdict = self.arbiter.verdict(robot)
        if verdict is None or not verdict.waits or verdict.place is None:
            return None
        x, y = verdict.place
        return verdict.waiting_for, (
            f"{verdict.waiting_for}, giving it way through the narrow place at ({x:.2f}, {y:.2f})"
        )

    async def _load(self, map_id: str) -> None:
        places = await database_sync_to_async(_places_of)(map_id)
        self._places[map_id] = (self._clock(), places)
        for robot, (planned_in, points) in list(self._plans.items()):
            if planned_in == map_id:
                del self._plans[robot]
                self.arbiter.route(robot, map_id, points, *places)
        self._decide(force=True)

    def _decide(self, force: bool = False) -> None:
        """Decide now if forced or DECIDE_EVERY_S has passed; else once it has."""
        now = self._clock()
        wait = self._decided + DECIDE_EVERY_S - now
        if not force and wait > 0:
            if self._later is None:
                self._later = asyncio.get_running_loop().call_later(wait, self._decide, True)
            return
        if self._later is not None:
            self._later.cancel()
            self._later = None
        self._decided = now
        for verdict in self.arbiter.decide():
            self._announce(verdict)

    def _announce(self, verdict: Verdict) -> None:
        text = verdict.describe()
        order = None
        if verdict.waits and verdict.spot is not None and verdict.place is not None:
            order = WaitOrder(
                verdict.map_id, verdict.spot, verdict.place, verdict.waiting_for, text
            )
        topic = topics.robot_topic(verdict.robot, topics.RIGHT_OF_WAY)
        self._tell(topic, dict(right_of_way_message(order, text)))
        self._events.right_of_way(verdict.robot, text, order)
