"""Where the robots of a building stand and are going: the spots they hold, and the fleet
rule that keeps two robots from being sent to one spot.

A robot holds the spot it stands at and, while it has an active goal, the spot of that
goal, each a disc of its footprint plus margin (``Reservations.radius``) in one sub-map. A goal or
mission waypoint for another robot whose disc would overlap a held one is, by its
building's ``FleetRule``, refused with the reason or moved to the nearest free spot
(``Reservations.place``). The same record names what stands in a stuck robot's way
(``Reservations.neighbour``), and whether a robot that finished its goal stands where
others need to be (``Reservations.in_the_way``: another robot is going there, or it is a
narrow place), and then the nearest free parking spot to send it to
(``Reservations.nearest_parking``).

Everything is in memory and costs a few dictionary operations: the relay feeds it every
pose, and goals are checked against it where they are sent.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from enum import StrEnum
from typing import Literal

from cloudnav_core.se2 import Point

# After a goal is sent, the robot's statuses of the goal before it do not end it.
GOAL_GRACE_S = 1.5
# Metres between a stuck robot's spot and another robot's that may be what blocks it.
BLOCKING_REACH = 1.2
# Metres between the candidate spots tried around a held one, and how far out they go.
MOVE_STEP = 0.1
MOVE_REACH = 2.0


class FleetRule(StrEnum):
    """What a building does with a goal whose spot another robot holds; ``OFF``: nothing,
    every robot plans alone (goals go where asked; the robots sort it out among themselves,
    as before the fleet rules; ``bench fleet`` measures it against them)."""

    REFUSE = "refuse"
    MOVE = "move"
    OFF = "off"


@dataclass(frozen=True)
class Hold:
    """``robot`` holds the spot at (x, y) of sub-map ``map_id``, standing there or going."""

    robot: str
    map_id: str
    x: float
    y: float
    why: Literal["standing", "goal"]

    def describe(self) -> str:
        if self.why == "standing":
            return f"{self.robot} stands at ({self.x:.2f}, {self.y:.2f})"
        return f"{self.robot} is going to ({self.x:.2f}, {self.y:.2f})"


@dataclass(frozen=True)
class ParkingPlace:
    """A building's parking spot ``name`` at (x, y, yaw) of sub-map ``map_id``."""

    name: str
    map_id: str
    x: float
    y: float
    yaw: float = 0.0


@dataclass(frozen=True)
class Placement:
    """Where a goal goes: ``point``, its own or the nearest free spot (``moved_from`` the
    one asked for, held by ``held_by``); ``refusal`` is the reason it goes nowhere."""

    point: Point
    held_by: Hold | None = None
    moved_from: Point | None = None
    refusal: str = ""

    @property
    def message(self) -> str:
        """The sentence for the operator ("" when the goal stands as asked)."""
        if self.refusal:
            return self.refusal
        if self.moved_from is None or self.held_by is None:
            return ""
        (x, y), (fx, fy) = self.point, self.moved_from
        return (
            f"Moved to the nearest free spot ({x:.2f}, {y:.2f}): ({fx:.2f}, {fy:.2f}) is held, "
            f"{self.held_by.describe()}."
        )


class Reservations:
    """The spots the robots of one server process hold (see the module)."""

    def __init__(self, radius: float, clock: Callable[[], float] = time.monotonic) -> None:
        # Metres: a robot's spot is its planner's footprint (body plus margin); two spots
        # overlap when their centres are nearer than twice this.
        self.radius = radius
        self._clock = clock
        self._standing: dict[str, Hold] = {}
        self._goals: dict[str, tuple[Hold, float]] = {}  # robot -> (its goal, sent at)

    def stand(self, robot: str, map_id: str, x: float, y: float) -> None:
        """``robot`` is at (x, y) of ``map_id`` (``building/code``, a version ignored)."""
        self._standing[robot] = Hold(robot, map_id.split("@", 1)[0], x, y, "standing")

    def aim(self, robot: str, map_id: str, point: Point) -> None:
        """``robot`` was sent a goal at ``point`` of ``map_id``."""
        hold = Hold(robot, map_id.split("@", 1)[0], point[0], point[1], "goal")
        self._goals[robot] = (hold, self._clock())

    def goal_over(self, robot: str) -> bool:
        """``robot`` says it has no active goal; statuses within GOAL_GRACE_S of a goal
        being sent are those of the goal before it, and end nothing. True if this ended
        the goal it held (False: it held none, or this is too soon)."""
        held = self._goals.get(robot)
        if held is not None and self._clock() - held[1] >= GOAL_GRACE_S:
            del self._goals[robot]
            return True
        return False

    def standing(self, robot: str) -> Hold | None:
        """Where ``robot`` stands, if it said."""
        return self._standing.get(robot)

    def going(self, robot: str) -> bool:
        """Whether ``robot`` holds an active goal."""
        return robot in self._goals

    def in_the_way(self, robot: str, narrow: Callable[[str, Point], bool]) -> str:
        """Why ``robot``, standing with no goal, stands where others need to be: another
        robot is going to its spot, or ``narrow`` says its spot is a narrow place (of its
        sub-map) others pass through; "" when it is in nobody's way."""
        me = self._standing.get(robot)
        if me is None or robot in self._goals:
            return ""
        spot = (me.x, me.y)
        going = [
            h
            for h, _ in self._goals.values()
            if h.robot != robot
            and h.map_id == me.map_id
            and math.dist((h.x, h.y), spot) < 2 * self.radius
        ]
        if going:
            return f"{going[0].robot} is going to where it stands"
        if narrow(me.map_id, spot):
            return "it stands in a narrow place others pass through"
        return ""

    def nearest_parking(self, robot: str, places: Iterable[ParkingPlace]) -> ParkingPlace | None:
        """The parking place nearest ``robot`` that no other robot holds: in its own sub-map
        first, then in the others by straight distance (a building's sub-maps share its
        frame); None when every one is held or it stands nowhere known."""
        me = self._standing.get(robot)
        if me is None:
            return None
        free = [p for p in places if self.holder(p.map_id, (p.x, p.y), robot) is None]
        ranked = sorted(
            free, key=lambda p: (p.map_id != me.map_id, math.dist((p.x, p.y), (me.x, me.y)))
        )
        return ranked[0] if ranked else None

    def leave(self, robot: str) -> None:
        """``robot`` is gone from this process: it holds nothing here any more."""
        self._standing.pop(robot, None)
        self._goals.pop(robot, None)

    def holds(self) -> Iterator[Hold]:
        """Every spot held: where each robot stands, and its active goal's. A robot that
        gave no pose here (not connected to this process) holds nothing."""
        yield from self._standing.values()
        yield from (hold for hold, _ in self._goals.values() if hold.robot in self._standing)

    def holder(self, map_id: str, point: Point, robot: str) -> Hold | None:
        """The nearest spot of another robot than ``robot`` that a robot at ``point`` of
        ``map_id`` would overlap, or None."""
        reach = 2 * self.radius
        found = [
            (math.dist((h.x, h.y), point), h)
            for h in self.holds()
            if h.robot != robot and h.map_id == map_id
        ]
        near = [(d, h) for d, h in found if d < reach]
        return min(near, key=lambda pair: pair[0])[1] if near else None

    def place(
        self,
        map_id: str,
        point: Point,
        robot: str,
        rule: FleetRule,
        standable: Callable[[Point], bool],
    ) -> Placement:
        """Where ``robot``'s goal at ``point`` of ``map_id`` goes by ``rule``: as asked when
        no other robot holds it; else refused with the reason, or moved to the nearest
        spot within MOVE_REACH that nobody holds and ``standable`` accepts (refused when
        there is none). ``FleetRule.OFF`` takes every goal as asked."""
        held = None if rule is FleetRule.OFF else self.holder(map_id, point, robot)
        if held is None:
            return Placement(point)
        asked = f"The goal ({point[0]:.2f}, {point[1]:.2f}) is held: {held.describe()}"
        if rule is FleetRule.REFUSE:
            return Placement(point, held, refusal=f"{asked} (this building refuses such goals).")
        for candidate in _around(point, MOVE_STEP, MOVE_REACH):
            if self.holder(map_id, candidate, robot) is None and standable(candidate):
                return Placement(candidate, held, moved_from=point)
        return Placement(
            point, held, refusal=f"{asked}, and no free spot is within {MOVE_REACH} m."
        )

    def neighbour(self, robot: str, reach: float) -> Hold | None:
        """The nearest other robot standing within ``reach`` metres of ``robot`` in its
        sub-map (what blocks a stuck robot, if a robot does), or None."""
        me = self._standing.get(robot)
        if me is None:
            return None
        near = [
            (math.dist((h.x, h.y), (me.x, me.y)), h)
            for h in self._standing.values()
            if h.robot != robot and h.map_id == me.map_id
        ]
        near = [(d, h) for d, h in near if d <= reach]
        return min(near, key=lambda pair: pair[0])[1] if near else None

    def blocking(self, robot: str) -> tuple[str, str] | None:
        """The robot standing in ``robot``'s way (within BLOCKING_REACH), as its name and
        a phrase for a stuck alert, or None (``telemetry.domain.events.Blocker``)."""
        found = self.neighbour(robot, BLOCKING_REACH)
        if found is None:
            return None
        me = self._standing[robot]
        away = math.dist((found.x, found.y), (me.x, me.y))
        return found.robot, f"{found.robot} standing {away:.1f} m away"


def _around(point: Point, step: float, reach: float) -> Iterator[Point]:
    """Points on rings ``step`` apart around ``point``, nearest first, out to ``reach``."""
    rings = int(reach / step)
    for ring in range(1, rings + 1):
        radius = ring * step
        count = max(8, int(2 * math.pi * radius / step))
        for k in range(count):
            angle = 2 * math.pi * k / count
            yield (point[0] + radius * math.cos(angle), point[1] + radius * math.sin(angle))
