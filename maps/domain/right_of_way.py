"""Right of way in narrow places: where two robots' routes meet in a place too narrow for
both, one goes first and the other waits at a safe spot before it.

A robot's route is its global plan in one sub-map (``/r/plan``). Along it, a *narrow
part* is a stretch where the free width across the route is under ``narrower_than``
metres (two footprints side by side plus a margin): a doorway, a narrow corridor. The
width across a point is ``Widths.across`` (``maps.domain.widths``, the one width
measure): twice the largest clearance on the free run of cells through it, perpendicular
to the route.

``Arbiter`` grants each narrow part to one robot at a time, in the spirit of Open-RMF's
traffic negotiation, simply: a robot asks for the next narrow part on its route once it
is within ``ASK_AHEAD`` metres of it (or inside it); asks are served first come first
served (a robot already inside first, then by the time it asked, then the nearer), and
a robot whose narrow part overlaps one granted to, or asked earlier by, another robot
waits: none is overtaken by a later ask, so none starves. A grant ends once its robot
is past the narrow part, has no route, or leaves. A wide place is never arbitrated: the
robots' local planners pass each other there as before.

A sub-map crossing is a narrow place too, however wide the room around it: a route that
ends where a robot stands to read a tag (``crossings``, the sub-map's tags' approach
points) ends in a narrow part of its last ``CROSSING_REACH`` metres. One robot at a
time reads a tag; the others wait clear of it instead of crowding round and hiding it.
The grant ends once its robot has entered the sub-map the tag leads to.

A waiting robot is given a spot, chosen once when its wait begins: the nearest point of
its own route before the narrow part that is out of it and clear of the other robot's
remaining route; failing that, a point beside its route there (room for it, clear of
the other's route); failing that, where it stands. Nothing here imports Django.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace

from cloudnav_core.se2 import Point, Pose
from maps.domain.widths import Widths

# Metres of free width, beyond two robots' footprints side by side, a place needs to be
# wide enough for both.
PASSING_MARGIN = 0.3
# Metres along its route before a narrow part where a robot asks for it.
ASK_AHEAD = 3.0
# Metres between a waiting robot's spot and the narrow part (beyond its footprint).
WAIT_GAP = 0.3
# How far back along its route, and out to the side, a waiting robot's spot is looked for.
WAIT_REACH = 5.0
SIDE_REACH = 1.5
SIDE_STEP = 0.1
# Narrow stretches of a route fewer than this many metres apart are one narrow part.
MERGE_GAP = 0.3
# A route ending within this many metres of a crossing point ends at that crossing.
CROSSING_MATCH = 0.3
# Metres of a route, back from its end at a crossing, that are the crossing's narrow part.
CROSSING_REACH = 1.5


def narrow_stretches(
    points: Sequence[Point], widths: Widths, narrower_than: float
) -> list[tuple[int, int]]:
    """The stretches of the route ``points`` where the free width across it is under
    ``narrower_than`` metres, as (first, last) indices into ``points``, inclusive;
    stretches nearer than MERGE_GAP along the route are one."""
    narrow = [
        0.0 < widths.across(p, _heading(points, i), narrower_than) < narrower_than
        for i, p in enumerate(points)
    ]
    stretches: list[tuple[int, int]] = []
    for i, here in enumerate(narrow):
        if not here:
            continue
        if stretches and _length(points, stretches[-1][1], i) <= MERGE_GAP:
            stretches[-1] = (stretches[-1][0], i)
        else:
            stretches.append((i, i))
    return stretches


def with_crossing(
    points: Sequence[Point], stretches: list[tuple[int, int]], crossings: Iterable[Point]
) -> list[tuple[int, int]]:
    """``stretches`` of the route ``points``, and its last ``CROSSING_REACH`` metres when it
    ends at one of ``crossings`` (merged with the stretches it meets)."""
    if not points or not any(math.dist(points[-1], c) <= CROSSING_MATCH for c in crossings):
        return stretches
    last = len(points) - 1
    first = last
    while first > 0 and _length(points, first - 1, last) <= CROSSING_REACH:
        first -= 1
    kept = [(a, b) for a, b in stretches if _length(points, b, first) > MERGE_GAP]
    met = [a for a, b in stretches if (a, b) not in kept]
    return [*kept, (min([first, *met]), last)]


@dataclass(frozen=True)
class Passage:
    """A narrow part of ``robot``'s route in sub-map ``map_id``: route points ``first`` to
    ``last`` (inclusive) of ``points``, the whole route."""

    robot: str
    map_id: str
    points: tuple[Point, ...]
    first: int
    last: int

    @property
    def stretch(self) -> tuple[Point, ...]:
        return self.points[self.first : self.last + 1]

    @property
    def centre(self) -> Point:
        return self.points[(self.first + self.last) // 2]

    def near(self, point: Point) -> float:
        """Metres from ``point`` to the nearest point of the narrow part."""
        return min(math.dist(point, p) for p in self.stretch)

    def same(self, other: Passage) -> bool:
        """True if ``other`` is this narrow part of the same route."""
        return (self.first, self.last, self.points) == (other.first, other.last, other.points)

    def overlaps(self, other: Passage, reach: float) -> bool:
        """True if the two narrow parts, in one sub-map, come within ``reach`` metres."""
        return self.map_id == other.map_id and any(other.near(p) < reach for p in self.stretch)


@dataclass(frozen=True)
class Verdict:
    """What one robot is told: go (``waiting_for`` empty), or wait at ``spot`` (x, y, yaw
    in ``map_id``) until ``waiting_for`` has passed the narrow part at ``place``."""

    robot: str
    map_id: str = ""
    place: Point | None = None
    spot: Pose | None = None
    waiting_for: str = ""
    how: str = ""  # how the spot was found: "on its route", "beside its route", "where it stands"

    @property
    def waits(self) -> bool:
        return bool(self.waiting_for)

    def describe(self) -> str:
        """The sentence for the event log and the building map."""
        if not self.waits or self.spot is None or self.place is None:
            return f"{self.robot} has the right of way"
        (x, y, _), (px, py) = self.spot, self.place
        return (
            f"{self.robot} waits at ({x:.2f}, {y:.2f}) ({self.how}) for {self.waiting_for} "
            f"to pass the narrow place at ({px:.2f}, {py:.2f}) in {self.map_id}"
        )


@dataclass
class _Robot:
    map_id: str = ""
    points: tuple[Point, ...] = ()
    passages: list[Passage] = field(default_factory=list)
    widths: Widths | None = None
    position: Point | None = None
    progress: int = 0  # index of the route point nearest the robot
    asking: Passage | None = None
    asked_at: float = 0.0
    verdict: Verdict | None = None


class Arbiter:
    """Grants the narrow parts of the routes of one building's robots (see the module).

    ``radius`` is a robot's footprint plus margin (metres); two robots' narrow parts are
    the same place when they come within two footprints of each other.
    """

    def __init__(self, radius: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.radius = radius
        self.narrower_than = 4 * radius + PASSING_MARGIN
        self._clock = clock
        self._robots: dict[str, _Robot] = {}
        self._grants: dict[str, Passage] = {}

    def route(
        self,
        robot: str,
        map_id: str,
        points: Sequence[Point],
        widths: Widths | None,
        crossings: Sequence[Point] = (),
    ) -> None:
        """``robot``'s new global plan in ``map_id`` (none: ``points`` empty); its narrow
        parts are measured on ``widths`` (None: the sub-map is unknown, nothing is narrow),
        and its end is one if it is at one of ``crossings`` (see the module). A plan made
        while the robot waits (to its waiting spot) does not replace its route."""
        state = self._robots.setdefault(robot, _Robot())
        if points and state.verdict is not None and state.verdict.waits:
            return  # the plan to its waiting spot: its route stands until it may go
        route = tuple(points)
        stretches = narrow_stretches(route, widths, self.narrower_than) if widths and route else []
        stretches = with_crossing(route, stretches, crossings)
        state.map_id, state.points, state.progress, state.widths = map_id, route, 0, widths
        state.passages = [Passage(robot, map_id, route, a, b) for a, b in stretches]
        if state.position is not None:
            self._advance(state)

    def at(self, robot: str, map_id: str, point: Point) -> None:
        """``robot`` stands at ``point`` of ``map_id``."""
        state = self._robots.setdefault(robot, _Robot())
        state.position = point
        if map_id != state.map_id:
            state.points, state.passages, state.map_id = (), [], map_id
        self._advance(state)

    def leave(self, robot: str) -> None:
        """``robot`` is gone (disconnected): it holds and asks for nothing."""
        self._robots.pop(robot, None)
        self._grants.pop(robot, None)

    def passages(self, robot: str) -> list[Passage]:
        """The narrow parts of ``robot``'s current route."""
        state = self._robots.get(robot)
        return list(state.passages) if state else []

    def holder(self, robot: str) -> Passage | None:
        """The narrow part ``robot`` has the right of way through, if any."""
        return self._grants.get(robot)

    def verdict(self, robot: str) -> Verdict | None:
        state = self._robots.get(robot)
        return state.verdict if state else None

    def decide(self) -> list[Verdict]:
        """Grant and refuse the narrow parts asked for now; return the verdicts that
        changed since the last call (a robot told to wait, or to go again)."""
        now = self._clock()
        asks = {robot: self._ask(state, now) for robot, state in self._robots.items()}
        self._release(asks)
        order = sorted(
            ((robot, ask) for robot, ask in asks.items() if ask is not None),
            key=lambda pair: self._priority(pair[0], pair[1]),
        )
        changed: list[Verdict] = []
        ahead: list[Passage] = []  # granted or waiting already, in order
        for robot, ask in order:
            blocker = self._blocker(robot, ask, ahead)
            ahead.append(ask)
            if blocker is None:
                self._grants[robot] = ask
            changed += self._tell(robot, ask, blocker)
        for robot, state in self._robots.items():
            if asks.get(robot) is None and state.verdict is not None and state.verdict.waits:
                changed += self._set(state, Verdict(robot))
        return changed

    # -- asking and granting -------------------------------------------------------------

    def _ask(self, state: _Robot, now: float) -> Passage | None:
        """The narrow part the robot asks for now (the next on its route, once within
        ASK_AHEAD of it or inside it), if any; keeps when it first asked for it."""
        ask = self._next(state)
        far = ask is not None and _length(state.points, state.progress, ask.first) > ASK_AHEAD
        if ask is not None and far and not self._inside(state, ask):
            ask = None
        if ask is None or state.asking is None or not self._same_place(ask, state.asking):
            state.asked_at = now
        state.asking = ask
        return ask

    def _next(self, state: _Robot) -> Passage | None:
        """The first narrow part of the route the robot is not past (nor inside)."""
        for passage in state.passages:
            if state.progress <= passage.last or self._inside(state, passage):
                return passage
        return None

    def _same_place(self, a: Passage, b: Passage) -> bool:
        """True if ``a`` and ``b`` are one narrow part, as a new plan may redraw it."""
        return a.same(b) or a.overlaps(b, self.radius)

    def _inside(self, state: _Robot, passage: Passage) -> bool:
        return state.position is not None and passage.near(state.position) <= self.radius

    def _release(self, asks: dict[str, Passage | None]) -> None:
        for robot, granted in list(self._grants.items()):
            ask = asks.get(robot)
            if ask is None or not self._same_place(ask, granted):
                del self._grants[robot]

    def _priority(self, robot: str, ask: Passage) -> tuple[int, int, float, float]:
        state = self._robots[robot]
        away = _length(state.points, state.progress, ask.first)
        inside = self._inside(state, ask)
        return (0 if robot in self._grants else 1, 0 if inside else 1, state.asked_at, away)

    def _blocker(self, robot: str, ask: Passage, ahead: list[Passage]) -> Passage | None:
        reach = 2 * self.radius + PASSING_MARGIN
        for other in ahead:
            if other.robot != robot and ask.overlaps(other, reach):
                return other
        return None

    def _tell(self, robot: str, ask: Passage, blocker: Passage | None) -> list[Verdict]:
        state = self._robots[robot]
        if blocker is None:
            return self._set(state, Verdict(robot))
        told = state.verdict
        if told is not None and told.waits and told.place == ask.centre:
            return self._set(state, replace(told, waiting_for=blocker.robot))
        spot, how = self._spot(state, ask, self._robots[blocker.robot])
        return self._set(state, Verdict(robot, ask.map_id, ask.centre, spot, blocker.robot, how))

    def _set(self, state: _Robot, verdict: Verdict) -> list[Verdict]:
        before = state.verdict
        state.verdict = verdict
        if before == verdict or (before is None and not verdict.waits):
            return []
        return [verdict]

    # -- where to wait -------------------------------------------------------------------

    def _spot(self, state: _Robot, ask: Passage, other: _Robot) -> tuple[Pose, str]:
        """Where a robot waits for ``other`` to pass ``ask`` (see the module)."""
        theirs = other.points[other.progress :] or ((other.position,) if other.position else ())
        clear = 2 * self.radius + PASSING_MARGIN

        def safe(point: Point) -> bool:
            return ask.near(point) >= self.radius + WAIT_GAP and all(
                math.dist(point, p) >= clear for p in theirs if p is not None
            )

        back = list(self._back_from(state, ask.first))
        for i in back:
            if safe(state.points[i]):
                return _pose_on(state.points, i), "on its route"
        for i in back:
            for side in _sideways(state.points, i):
                if safe(side) and self._room(state, state.points[i], side):
                    return (*side, _heading(state.points, i)), "beside its route"
        here = state.position or state.points[state.progress]
        return (*here, _heading(state.points, state.progress)), "where it stands"

    def _back_from(self, state: _Robot, first: int) -> Iterable[int]:
        """Route indices from ``first`` back towards the robot, within WAIT_REACH."""
        for i in range(first, state.progress - 1, -1):
            if _length(state.points, i, first) > WAIT_REACH:
                return
            yield i

    def _room(self, state: _Robot, start: Point, side: Point) -> bool:
        """True if a robot fits at ``side`` and on the straight way to it from ``start``."""
        if state.widths is None:
            return False
        steps = max(1, int(math.dist(start, side) / SIDE_STEP))
        return all(
            state.widths.clearance_at(_between(start, side, k / steps)) > self.radius
            for k in range(steps + 1)
        )

    def _advance(self, state: _Robot) -> None:
        if state.position is None or not state.points:
            return
        lo = max(0, state.progress - 5)
        span = state.points[lo:]
        nearest = min(range(len(span)), key=lambda k: math.dist(span[k], state.position or (0, 0)))
        state.progress = max(state.progress, lo + nearest)


def _heading(points: Sequence[Point], i: int) -> float:
    """The route's direction at point ``i`` (radians)."""
    if len(points) < 2:
        return 0.0
    a, b = (points[i], points[i + 1]) if i + 1 < len(points) else (points[i - 1], points[i])
    return math.atan2(b[1] - a[1], b[0] - a[0])


def _pose_on(points: Sequence[Point], i: int) -> Pose:
    return (points[i][0], points[i][1], _heading(points, i))


def _sideways(points: Sequence[Point], i: int) -> Iterable[Point]:
    """Points beside route point ``i``, left and right, nearest first."""
    heading = _heading(points, i)
    normal = (-math.sin(heading), math.cos(heading))
    for k in range(1, int(SIDE_REACH / SIDE_STEP) + 1):
        for sign in (1, -1):
            d = sign * k * SIDE_STEP
            yield (points[i][0] + d * normal[0], points[i][1] + d * normal[1])


def _between(a: Point, b: Point, t: float) -> Point:
    return (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))


def _length(points: Sequence[Point], a: int, b: int) -> float:
    """Metres along the route from point ``a`` to point ``b`` (0 when b <= a)."""
    return sum(math.dist(points[k], points[k + 1]) for k in range(a, b))
