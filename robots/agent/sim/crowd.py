"""What moves in the simulated building: people walking seeded routes, and the robots.

Everything that moves is a vertical cylinder (a ``Disc`` on the floor plan, with a
height for the camera): a person is 0.25 m round and 1.7 m tall, a robot its body's
radius and 0.4 m tall. The ``Crowd`` holds them on the simulated clock: robots' bodies
``join`` it, and each robot's laser, camera and body ask it for everyone else
(``others``), so robots see and bump into people and one another as they do walls.

People walk routes of waypoints at their own pace (0.5 to 1.4 m/s by default), pause at
some waypoints, and loop. A person gives way to a robot: while one stands within
``GIVE_WAY`` metres ahead of them, nearer their path than ``PASSING`` (they do not
brush past a robot), they stand still, and after ``TURN_BACK`` seconds of
that they turn round and walk their route the other way. Some people (``seeks_robots``)
walk straight towards a robot they can see within ``SEEK_RANGE``, until they must give
way, then go back to their route. People do not avoid one another: they pass through
each other, which the sensors show as two overlapping cylinders.

``Crowd.seeded`` builds ``count`` people from a seed: routes through the walkable part of
a world (corridors, atria and rooms), planned by the same A* the robots use, between
random points with room to walk. A run is a pure function of the seed and the robots'
commands: people move only when the clock is advanced (``advance_to``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from cloudnav_core.se2 import Point, Pose
from maps.domain.planning import Costmap, PlanningError, inflate, plan_on
from robots.agent.sim.world import FREE, World

Floats = NDArray[np.float64]

PERSON_RADIUS = 0.25
PERSON_HEIGHT = 1.7
ROBOT_HEIGHT = 0.4
WALKING_SPEEDS = (0.5, 1.4)
"""m/s: the range people's paces are drawn from."""
GIVE_WAY = 0.45
"""Metres of free floor a person keeps between themselves and a robot ahead."""
PASSING = 0.05
"""Metres a person keeps between themselves and a robot they walk past: one nearer their
path than that is in their way (people do not brush past a robot)."""
START_CLEARANCE = 1.0
"""Metres between a seeded person's start and the places given to keep clear (robots'
starts)."""
TURN_BACK = 4.0
"""Seconds a person waits for a robot in the way before turning round."""
SEEK_RANGE = 5.0
"""Metres within which a robot-seeking person walks towards a robot in sight."""
SEEK_REST = 10.0
"""Seconds a robot-seeking person keeps to their route after giving way."""
ROUTE_CLEARANCE = 0.45
"""Metres from walls that people's routes keep."""
STEP = 0.05
"""Seconds of one integration step of the people's motion."""


@dataclass(frozen=True)
class Discs:
    """Cylinders standing on the floor: centres ``x, y``, ``radius`` and ``height``
    (metres), and ``person`` True for a person, False for a robot."""

    x: Floats
    y: Floats
    radius: Floats
    height: Floats
    person: NDArray[np.bool_]

    @property
    def count(self) -> int:
        return int(self.x.size)


NO_DISCS = Discs(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, bool))

Movers = Callable[[], Discs]
"""What a sensor or body asks for: everything that moves, except its own robot."""


class Body(Protocol):
    """A robot's body as the crowd sees it."""

    @property
    def pose(self) -> Pose: ...
    @property
    def radius(self) -> float: ...


def cast_discs(x: float, y: float, angles: Floats, discs: Discs) -> tuple[Floats, Floats]:
    """Where rays from ``(x, y)`` at ``angles`` first meet a disc: per ray the distance
    (``inf`` for none) and the disc's index (-1 for none). A ray starting inside a disc
    meets it at 0."""
    if discs.count == 0:
        return np.full(angles.shape, np.inf), np.full(angles.shape, -1.0)
    dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
    cx, cy = discs.x[None, :] - x, discs.y[None, :] - y
    along = dx * cx + dy * cy
    outside = cx * cx + cy * cy - discs.radius[None, :] ** 2
    square = along * along - outside
    with np.errstate(invalid="ignore"):
        entry = along - np.sqrt(square)
    entry = np.where(outside <= 0, 0.0, entry)
    hit = (square >= 0) & (entry >= 0)
    distance = np.where(hit, entry, np.inf)
    nearest = np.argmin(distance, axis=1)
    best = distance[np.arange(angles.size), nearest]
    return best, np.where(np.isfinite(best), nearest, -1).astype(np.float64)


def disc_clearance(x: float, y: float, discs: Discs) -> float:
    """Distance from ``(x, y)`` to the nearest disc's edge (negative inside one; ``inf``
    with none)."""
    if discs.count == 0:
        return math.inf
    return float((np.hypot(discs.x - x, discs.y - y) - discs.radius).min())


@dataclass
class Person:
    """One walker: ``route`` (waypoints, looped), pace ``speed`` (m/s), ``pauses``
    (seconds to stand at each waypoint, 0 for none), starting at waypoint 0 at
    ``start_after`` seconds."""

    route: list[Point]
    speed: float
    pauses: list[float] = field(default_factory=list)
    radius: float = PERSON_RADIUS
    seeks_robots: bool = False
    start_after: float = 0.0
    x: float = field(init=False)
    y: float = field(init=False)
    heading: float = field(init=False, default=0.0)
    velocity: Point = field(init=False, default=(0.0, 0.0))
    _next: int = field(init=False, default=1)
    _step: int = field(init=False, default=1)
    _resting_until: float = field(init=False, default=0.0)
    _waiting_since: float | None = field(init=False, default=None)
    _seek_again_at: float = field(init=False, default=0.0)

    def __post_init__(self) -> None:
        self.x, self.y = self.route[0]
        self._resting_until = self.start_after
        if len(self.route) < 2:
            self._step = 0

    def position(self) -> Point:
        return self.x, self.y

    def walk(self, now: float, dt: float, world: World, robots: Sequence[Body]) -> None:
        """Move for ``dt`` seconds from ``now``: rest, give way, seek a robot or walk on."""
        self.velocity = (0.0, 0.0)
        if now < self._resting_until or self._step == 0:
            return
        aim = self._seek(robots, world, now) or self.route[self._next]
        heading = math.atan2(aim[1] - self.y, aim[0] - self.x)
        if self._in_the_way(heading, robots):
            self._wait(now)
            return
        self._waiting_since = None
        self._advance(aim, heading, now, dt)

    def _advance(self, aim: Point, heading: float, now: float, dt: float) -> None:
        left = math.dist(self.position(), aim)
        step = min(self.speed * dt, left)
        self.heading = heading
        self.x += step * math.cos(heading)
        self.y += step * math.sin(heading)
        self.velocity = (step / dt * math.cos(heading), step / dt * math.sin(heading))
        if step >= left - 1e-9 and aim == self.route[self._next]:
            self._arrived(now)

    def _arrived(self, now: float) -> None:
        """At waypoint ``_next``: rest if it says so, then head for the following one."""
        if self.pauses:
            self._resting_until = now + self.pauses[self._next % len(self.pauses)]
        self._next = (self._next + self._step) % len(self.route)

    def _in_the_way(self, heading: float, robots: Sequence[Body]) -> bool:
        """Whether a robot stands within ``GIVE_WAY`` ahead, and nearer than ``PASSING``
        to this person's path."""
        for robot in robots:
            rx, ry, _ = robot.pose
            dx, dy = rx - self.x, ry - self.y
            ahead = dx * math.cos(heading) + dy * math.sin(heading)
            aside = abs(-dx * math.sin(heading) + dy * math.cos(heading))
            reach = self.radius + robot.radius
            if ahead > 0 and aside < reach + PASSING and ahead < reach + GIVE_WAY:
                return True
        return False

    def _wait(self, now: float) -> None:
        if self._waiting_since is None:
            self._waiting_since = now
        elif now - self._waiting_since >= TURN_BACK:
            self._turn_back(now)

    def _turn_back(self, now: float) -> None:
        """Walk the route the other way (or, when seeking, give up on the robot)."""
        self._waiting_since = None
        if now < self._seek_again_at or not self.seeks_robots:
            self._step = -self._step
            self._next = (self._next + self._step) % len(self.route)
        self._seek_again_at = now + SEEK_REST

    def _seek(self, robots: Sequence[Body], world: World, now: float) -> Point | None:
        """The nearest robot in sight within ``SEEK_RANGE``, for a person who seeks."""
        if not self.seeks_robots or now < self._seek_again_at:
            return None
        here = self.position()
        near = sorted((math.dist(here, r.pose[:2]), r.pose[:2]) for r in robots)
        seen = (xy for d, xy in near if d < SEEK_RANGE and _in_sight(world, here, xy))
        return next(seen, None)


def _in_sight(world: World, a: Point, b: Point) -> bool:
    distance = math.dist(a, b)
    angle = np.array([math.atan2(b[1] - a[1], b[0] - a[0])])
    return bool(world.cast(a[0], a[1], angle, distance).distance[0] >= distance - 0.3)


class Crowd:
    """The people of ``world`` and the robots' bodies, on one simulated clock."""

    def __init__(self, world: World, people: Sequence[Person] = ()) -> None:
        self.world = world
        self.people = list(people)
        self.robots: list[Body] = []
        self.time = 0.0

    @classmethod
    def seeded(
        cls, world: World, count: int, seed: int, walkable: NDArray[np.bool_] | None = None
    ) -> Crowd:
        """``count`` people on routes drawn from ``seed`` through ``walkable`` (a mask of
        the world's cells; by default every free one). Every fourth person seeks robots."""
        return cls(world, seeded_people(world, count, seed, walkable))

    def join(self, body: Body) -> None:
        """Add a robot's body: from now on the others see it and it sees them."""
        self.robots.append(body)

    def advance_to(self, seconds: float) -> None:
        """Walk everyone on to ``seconds`` of simulated time (never backwards)."""
        while self.time + STEP <= seconds + 1e-9:
            for person in self.people:
                person.walk(self.time, STEP, self.world, self.robots)
            self.time += STEP

    def others(self, body: Body | None) -> Discs:
        """Everyone that moves except ``body``: the people, then the other robots."""
        robots = [robot for robot in self.robots if robot is not body]
        people = self.people
        return Discs(
            np.array([p.x for p in people] + [r.pose[0] for r in robots], np.float64),
            np.array([p.y for p in people] + [r.pose[1] for r in robots], np.float64),
            np.array([p.radius for p in people] + [r.radius for r in robots], np.float64),
            np.array([PERSON_HEIGHT] * len(people) + [ROBOT_HEIGHT] * len(robots), np.float64),
            np.array([True] * len(people) + [False] * len(robots), bool),
        )

    def movers_for(self, body: Body | None) -> Movers:
        """What ``body``'s sensors ask for: everyone else, now."""
        return lambda: self.others(body)


# --- seeded routes ---------------------------------------------------------------------


def seeded_people(
    world: World,
    count: int,
    seed: int,
    walkable: NDArray[np.bool_] | None = None,
    keep_clear: Sequence[Point] = (),
) -> list[Person]:
    """``count`` people with routes of 3 or 4 random places joined by planned paths,
    a pace in ``WALKING_SPEEDS``, a pause of 1 to 4 s at half their waypoints, and
    start times spread over the first 5 s. Each starts at the first waypoint of their
    loop at least ``START_CLEARANCE`` from every place of ``keep_clear`` (the robots'
    starts), or the farthest from them."""
    rng = np.random.default_rng(seed)
    mask = (world.cells == FREE) if walkable is None else walkable & (world.cells == FREE)
    grid = np.where(mask, 0, 100).astype(np.int8)
    costmap = inflate(grid, ROUTE_CLEARANCE, world.resolution, origin=world.origin)
    spots = np.argwhere(~costmap.blocked)
    people = []
    for index in range(count):
        route = _starting_clear(_route(costmap, spots, rng), keep_clear)
        pauses = [float(rng.uniform(1.0, 4.0)) if rng.random() < 0.5 else 0.0 for _ in route]
        speed = float(rng.uniform(*WALKING_SPEEDS))
        start = float(rng.uniform(0.0, 5.0))
        people.append(Person(route, speed, pauses, seeks_robots=index % 4 == 3, start_after=start))
    return people


def _starting_clear(route: list[Point], keep_clear: Sequence[Point]) -> list[Point]:
    """The loop ``route`` started at its first waypoint ``START_CLEARANCE`` from every
    place of ``keep_clear``, or the farthest from them."""
    if not keep_clear:
        return route
    room = [min(math.dist(point, place) for place in keep_clear) for point in route]
    clear = [index for index, gap in enumerate(room) if gap >= START_CLEARANCE]
    first = clear[0] if clear else int(np.argmax(room))
    return route[first:] + route[:first]


def _route(costmap: Costmap, spots: NDArray[np.intp], rng: np.random.Generator) -> list[Point]:
    """A loop through 3 or 4 random spots of ``costmap`` that paths join (waypoints: the
    paths' corners)."""
    for _ in range(50):
        cells = spots[rng.choice(len(spots), int(rng.integers(3, 5)))]
        places = [_centre(costmap, row, col) for row, col in cells]
        try:
            legs = [plan_on(costmap, a, b) for a, b in pairwise([*places, places[0]])]
        except PlanningError:
            continue
        return [point for leg in legs for point in leg[:-1]]
    raise ValueError("no route joins the walkable places: is the walkable area connected?")


def _centre(costmap: Costmap, row: int, col: int) -> Point:
    res = costmap.resolution
    return costmap.origin[0] + (col + 0.5) * res, costmap.origin[1] + (row + 0.5) * res
