"""The fleet feed: what the robots connected to this process publish about themselves,
taken in as fleet state (pose and Map ID, ``telemetry.rosbridge.fleet_state``), the
spots they hold (where they stand, and whether their goal is still active:
``maps.domain.reservations``; a goal that ended may send its robot to a parking spot:
``telemetry.parking``), their routes and poses for right of way in narrow places
(``telemetry.right_of_way``), events (what the event log observes) and mission progress
(navigation status); and which robots this process serves, told to the other
processes."""

from __future__ import annotations

from collections.abc import Callable

from cloudnav_core import topics
from cloudnav_core.messages import goal_live, published_pose_of, string_of
from maps.domain.reservations import Reservations
from telemetry.domain import names
from telemetry.domain.protocol import Json
from telemetry.events import OBSERVED, EventLog
from telemetry.missions import MissionRunner
from telemetry.parking import Parking
from telemetry.right_of_way import RightOfWay
from telemetry.rosbridge.cross_process import CrossProcess
from telemetry.rosbridge.fleet_state import FleetTracker


def fleet_type(name: str) -> str | None:
    """Return the type of a fleet topic (``/r1/pose`` and the like), None for others."""
    parts = name.split("/", 2)
    return topics.ROBOT_TOPIC_TYPES.get(parts[2]) if len(parts) == 3 else None


def fleet_latched(name: str) -> bool:
    parts = name.split("/", 2)
    return len(parts) == 3 and parts[2] in topics.LATCHED_TOPICS


class FleetFeed:
    """The topics of the robots connected here that the server reads, by topic name."""

    def __init__(
        self,
        tracker: FleetTracker,
        events: EventLog,
        missions: MissionRunner,
        spots: Reservations,
        parking: Parking,
        relay: Callable[[], CrossProcess],
        right_of_way: RightOfWay,
    ) -> None:
        self.tracker = tracker
        self.spots = spots
        self.right_of_way = right_of_way
        self._parking = parking
        self._events = events
        self._missions = missions
        self._relay = relay
        self._topics: dict[str, tuple[int, str]] = {}  # topic -> (robot's pk, kind)

    def joined(self, robot: str, robot_pk: int) -> None:
        """A connection of ``robot`` opened here."""
        for kind in {topics.MAP_ID, topics.PLAN, *OBSERVED}:
            self._topics[topics.robot_topic(robot, kind)] = (robot_pk, kind)
        self.tracker.connected(robot_pk)
        self._events.connected(robot)
        self._missions.ensure_running()
        self._relay().put("robots", robot, "1")

    def left(self, robot: str, robot_pk: int, still_here: bool) -> None:
        """A connection of ``robot`` closed; ``still_here`` if another one is still open."""
        self.tracker.disconnected(robot_pk)
        if still_here:
            return
        self._events.disconnected(robot)
        self.spots.leave(robot)
        self.right_of_way.left(robot)
        for kind in {topics.MAP_ID, topics.PLAN, *OBSERVED}:
            self._topics.pop(topics.robot_topic(robot, kind), None)
        self._relay().remove("robots", robot)

    def published(self, name: str, msg: dict[str, Json]) -> None:
        """Take in ``msg``, published here on ``name``, if it is a connected robot's topic
        the server reads."""
        tracked = self._topics.get(name)
        if tracked is None:
            return
        robot_pk, kind = tracked
        robot = names.first_segment(name)
        if kind == topics.POSE:
            pose = published_pose_of(msg)
            if pose is not None:
                self.tracker.pose(robot_pk, pose)
                self.spots.stand(robot, pose.map_id, pose.x, pose.y)
                self.right_of_way.pose(robot, pose.map_id, pose.x, pose.y)
        elif kind == topics.PLAN:
            self.right_of_way.plan(robot, msg)
        elif kind == topics.MAP_ID and (map_id := string_of(msg)) is not None:
            self.tracker.map_id(robot_pk, map_id)
        if kind in OBSERVED:
            self._events.observe(robot, kind, msg)
        if kind == topics.NAV_STATUS:
            self._missions.status(robot, msg)
            if not goal_live(msg):
                self.right_of_way.goal_over(robot)
                if self.spots.goal_over(robot):
                    self._parking.goal_over(robot)
