"""The rosbridge hub of one server process: its connections, composed with the parts
they share, each named by what it does.

- the topic bus (``telemetry.domain.bus``): topics, subscriptions and fan-out; the hub's
  topic methods add what the server reads of a publication and, in scaled mode, the
  topics of other processes;
- service and action calls (``telemetry.rosbridge.service_calls``);
- the teleop gate (``telemetry.rosbridge.teleop_gate``): who may send ``cmd_vel`` now;
- STOP (``telemetry.stop``): halt a robot whatever moves it;
- pose checks (``telemetry.pose_checks``): goals and initial poses no robot could stand
  at are refused where they are sent, and goals another robot's spot holds are refused or
  moved by the building's fleet rule (``maps.domain.reservations``, fed by the fleet feed);
- the fleet feed (``telemetry.rosbridge.fleet_feed``): robots' pose, Map ID, events and missions;
- the access review (``telemetry.access.review``): what an access change withdraws;
- parameters (``telemetry.rosbridge.params``) and the event log (``telemetry.events``);
- the relay to the other server processes (``telemetry.rosbridge.relay``), or in single-process
  mode a ``NullRelay`` that does nothing and finds nothing (``telemetry.rosbridge.cross_process``),
  so no part asks which mode it runs in.

The consumer authorises a frame, then calls one function of the hub or of one of its
parts. Topics fan out in-process (no channel-layer hop for local subscribers).

Tapping the topic bus: the server's own features read topics one way only,
``hub.tap(topic, on_message)`` (``topic`` an absolute name such as ``/r1/scan``, or
``EVERY_TOPIC``), which calls ``on_message(topic, msg)`` with every message of that
topic the bus fans out in this process, until the ``TopicTap`` returned is closed
(``tap.close()``). ``on_message`` runs on the event loop: it must return at once and
never change ``msg`` (see ``telemetry.domain.bus``). The recorder taps every topic;
mapping sessions and map upkeep tap their robots' ``scan``, ``odom`` and ``pose``.
"""

from __future__ import annotations

import asyncio
import contextvars
import time
import weakref
from collections.abc import Callable
from dataclasses import replace

from cloudnav_core import topics
from cloudnav_core.messages import goal_of, pose_stamped
from cloudnav_core.se2 import Pose
from cloudnav_core.times import RobotClocks, complete_header_stamp
from maps.domain.reservations import ParkingPlace, Reservations
from maps.services import GOAL_CHECK_RADIUS
from robots.missions import Goal
from telemetry.access.decisions import Registry
from telemetry.access.review import AccessReview, Client
from telemetry.access.revocation import listen
from telemetry.domain import protocol
from telemetry.domain.bus import EVERY_TOPIC, OnMessage, SubscribeParams, TopicBus, TopicTap
from telemetry.domain.encoding import Outgoing
from telemetry.domain.events import EventDeriver
from telemetry.domain.limits import ByteBudget, Holdings
from telemetry.domain.protocol import Json
from telemetry.events import EventLog
from telemetry.exceptions import PoseRefused
from telemetry.missions import MissionRunner
from telemetry.parking import Parking
from telemetry.pose_checks import PoseChecks
from telemetry.recording.recorder import Recorder
from telemetry.right_of_way import RightOfWay
from telemetry.rosbridge.config import RosbridgeConfig
from telemetry.rosbridge.connection import Connection
from telemetry.rosbridge.cross_process import CrossProcess, NullRelay
from telemetry.rosbridge.directory import Directory
from telemetry.rosbridge.fleet_feed import FleetFeed, fleet_latched, fleet_type
from telemetry.rosbridge.fleet_state import FleetTracker
from telemetry.rosbridge.params import Parameters, RedisParams
from telemetry.rosbridge.relay import Relay, shared_redis
from telemetry.rosbridge.server_services import ServerParts, ServerService
from telemetry.rosbridge.service_calls import ServiceCalls
from telemetry.rosbridge.service_registry import server_services
from telemetry.rosbridge.teleop_gate import TeleopGate
from telemetry.rosbridge.teleop_locks import RedisLockStore
from telemetry.stop import RobotStop
from telemetry.stuck_rule import StuckRule


class Hub:
    """One process's connections and the parts they share (see the module's docstring)."""

    def __init__(self, config: RosbridgeConfig, services: dict[str, ServerService]) -> None:
        loop = asyncio.get_running_loop()
        self.config = config
        limits = config.per_connection
        self.bus = TopicBus(
            scheduler=loop.call_later,
            clock=loop.time,
            type_hint=fleet_type,
            latch_hint=fleet_latched,
            limits=limits,
        )
        self.relay: CrossProcess = NullRelay()
        self.calls = ServiceCalls(limits, services, lambda: self.relay)
        held = Holdings("parameters", limits.params, limits.param_bytes)
        self.params = Parameters(held, lambda key: self.relay.owner_key(key))
        self.fragment_budget = ByteBudget(config.fragments_total_bytes)
        self._fragment_shares: dict[str, ByteBudget] = {}
        self.clients: dict[str, Client] = {}
        spots = Reservations(GOAL_CHECK_RADIUS)
        clocks = RobotClocks()  # each robot's own time, for its stuck spells and time limits
        self.events = EventLog(deriver=EventDeriver(config.stuck_after, self._blocking, clocks))
        self.right_of_way = RightOfWay(
            GOAL_CHECK_RADIUS, self.events, self.tell, enabled=config.right_of_way
        )
        self.missions = MissionRunner(
            self._send_goal, self.robots, self._place_goal, self._waypoint_late, robot_clocks=clocks
        )
        self.teleop = TeleopGate(config, self.bus, self.events)
        self.poses = PoseChecks(spots)
        self.parking = Parking(self.poses, self._send_to_parking)
        self.poses.wanted = self.parking.wanted
        self.stop = RobotStop(self.calls, self.teleop, self.events, lambda: self.relay)
        self._goals: dict[str, dict[str, Json]] = {}  # robot -> the last goal sent it here
        self.stuck_rule = StuckRule(
            self.events,
            self.right_of_way,
            config.stuck_give_up_after,
            self._resend_goal,
            self.stop.halt_here,
        )
        self.events.on_stuck = self.stuck_rule.stuck
        self.fleet = FleetFeed(
            FleetTracker(interval=config.fleet_flush_interval),
            self.events,
            self.missions,
            self.poses.reservations,
            self.parking,
            lambda: self.relay,
            self.right_of_way,
        )
        self.registry = Registry()
        self.review = AccessReview(
            self.clients, self.leave, self.registry, self.bus, self.calls, self.fleet.tracker
        )
        self.recorder: Recorder | None = None
        directory = Directory(
            self.bus,
            self.calls.services,
            self.calls.actions,
            own_services=lambda: [(n, s.type) for n, s in services.items()],
            robots=self.robots,
            relay=lambda: self.relay,
        )
        self.server_parts = ServerParts(
            self.teleop.locks, self.params, directory, self.stop, self.poses
        )

    def fragment_share(self, label: str) -> ByteBudget:
        """The fragment budget all connections of principal ``label`` draw on together."""
        share = self._fragment_shares.get(label)
        if share is None:
            share = ByteBudget(self.config.fragments_per_client_bytes)
            self._fragment_shares[label] = share
        return share

    def _blocking(self, robot: str) -> tuple[str, str] | None:
        """What a stuck robot waits for or is blocked by: the robot it gives way to in a
        narrow place, else the robot standing in its way (``Reservations.blocking``)."""
        return self.right_of_way.blocking(robot) or self.poses.reservations.blocking(robot)

    def tap(self, topic: str | None, on_message: OnMessage) -> TopicTap:
        """Call ``on_message(topic, msg)`` with every message of ``topic`` (an absolute
        name, or ``EVERY_TOPIC``) fanned out in this process until the returned tap is
        closed; the one way to tap the topic bus (see the module's docstring)."""
        return self.bus.tap(topic, on_message)

    def tell(self, name: str, msg: dict[str, Json]) -> None:
        """Publish ``msg`` on ``name`` as the server, latched (subscribers that come later
        get the last one)."""
        self.bus.publish(None, name, msg, latch=True)

    def record_with(self, recorder: Recorder) -> None:
        """Record the robots connected here: the recorder taps every topic."""
        self.recorder = recorder
        self.tap(EVERY_TOPIC, recorder.offered)
        self.events.on_event = recorder.event
        for robot in self.robots():
            recorder.connected(robot)

    async def start(self) -> None:
        """Join the other server processes when ``REDIS_URL`` is set (scaled mode)."""
        if not self.config.redis_url:
            return
        from channels.layers import get_channel_layer

        redis = shared_redis(self.config.redis_url)
        relay = Relay(self, get_channel_layer(), redis)
        await relay.start()
        self.relay = self.bus.listener = relay
        self.teleop.locks.store = RedisLockStore(redis)
        self.params.store = RedisParams(redis)

    # ------------------------------------------------------------ connections

    def join(self, client: Client) -> None:
        self.clients[client.conn.key] = client
        robot = client.conn.principal.robot
        if robot is not None and client.robot_pk is not None:
            if self.recorder is not None:
                self.recorder.connected(robot)  # first, so it records the robot's arrival
            self.fleet.joined(robot, client.robot_pk)

    def robots(self) -> set[str]:
        """Names of the robots connected to this process."""
        return {r for c in self.clients.values() if (r := c.conn.principal.robot) is not None}

    async def leave(self, conn: Connection) -> None:
        """Forget a closed connection: its topics, services, actions, locks, fleet state."""
        client = self.clients.pop(conn.key, None)
        conn.close()
        self.bus.drop(conn)
        self.calls.drop(conn)
        await self.teleop.locks.drop(conn.key)
        await self.params.closed(conn)
        robot = conn.principal.robot
        if client is not None and client.robot_pk is not None and robot is not None:
            still_here = robot in self.robots()
            self.fleet.left(robot, client.robot_pk, still_here)
            if not still_here and self.recorder is not None:
                self.recorder.disconnected(robot)  # after the event log's departure
        self.calls.publish_directories()

    # ------------------------------------------------------------ topics

    def received_from_elsewhere(
        self, name: str, type_name: str | None, msg: dict[str, Json], latched: bool
    ) -> None:
        """A message published on another process: fanned out to the subscribers here; a
        ``cmd_vel`` to a robot connected here is watched in case its sender's process dies
        (``TeleopGate.commanded_elsewhere``)."""
        self.bus.receive_remote(name, type_name, msg, latched)
        robot, _, suffix = name[1:].partition("/")
        if suffix == topics.CMD_VEL and robot in self.robots():
            self.teleop.commanded_elsewhere(robot, msg)

    def advertise(
        self, conn: Connection, name: str, type_name: str, latch: bool, aid: Json
    ) -> None:
        self.bus.advertise(conn, name, type_name, latch, aid)

    def unadvertise(self, conn: Connection, name: str, aid: Json) -> None:
        self.bus.unadvertise(conn, name, aid)

    def publish(
        self,
        conn: Connection,
        name: str,
        msg: dict[str, Json],
        latch: bool,
        size: int,
        note: str = "",
    ) -> None:
        """Publish ``msg``; ``note`` is what the server did to it (a goal moved), for the
        event log."""
        complete_header_stamp(msg)
        self.bus.publish(conn, name, msg, latch, size)
        if conn.principal.robot is not None:
            self.events.heard(conn.principal.robot)
        else:
            self._commanded(conn, name, msg, note)
        self.fleet.published(name, msg)

    def _commanded(self, conn: Connection, name: str, msg: dict[str, Json], note: str) -> None:
        """A person's message to a robot: a goal is an event (on this process, which may
        not be the robot's; the robot's recorder reads it from the event log)."""
        robot, _, suffix = name[1:].partition("/")
        if suffix == topics.GOAL:
            self._goals[robot] = msg
            self.events.goal_sent(robot, conn.principal.label, msg, note)

    async def subscribe(
        self, conn: Connection, name: str, op: protocol.Subscribe, params: SubscribeParams
    ) -> None:
        """Subscribe; in scaled mode also subscribe to the topic's Redis channel and replay
        a latched message published on another process."""
        type_name = op.type
        if type_name is None and self.bus.get(name) is None:
            found = await self.relay.find("topics", name)
            type_name = found[1] if found else None
        replayed = self.bus.subscribe(conn, name, type_name, params, op.id, spelling=op.topic)
        await self.relay.settled()
        latched = None if replayed else await self.relay.latched(name)
        if latched is not None:
            frame = protocol.PublishFrame(op="publish", topic=op.topic, msg=latched[1])
            conn.deliver(Outgoing(frame).wire(params.compression, params.fragment_size))

    def unsubscribe(self, conn: Connection, name: str, op: protocol.Unsubscribe) -> None:
        self.bus.unsubscribe(conn, name, op.id, spelling=op.topic)

    async def _place_goal(self, goal: Goal) -> Goal | str:
        """A mission's goal as the fleet rule places it (``PoseChecks.place``), or why it
        is refused."""
        try:
            placed = await self.poses.place(goal.map_id, (goal.x, goal.y), goal.robot)
        except PoseRefused as refused:
            return refused.message
        if placed.refusal:
            return f"{placed.refusal} ({goal.map_id})"
        x, y = placed.point
        return replace(goal, x=x, y=y, note=placed.message)

    async def _waypoint_late(self, goal: Goal) -> None:
        """A mission's goal not reached within its time limit (the waypoint is already
        skipped or its mission paused): a paused mission's robot is halted where it is,
        as STOP would, so it does not go on circling; an event says which."""
        if goal.on_timeout == "skip":
            then = "skipped, on to the next waypoint"
        else:
            halted = await self.stop.halt_here(goal.robot)
            then = f"mission paused, the robot halted (goal {halted})"
        waypoint = {"map_id": goal.map_id, "x": goal.x, "y": goal.y, "time_limit": goal.time_limit}
        self.events.waypoint_timed_out(goal.robot, waypoint, then)

    def _send_goal(self, goal: Goal) -> None:
        """Send a mission's goal to its robot from the server itself; it holds its spot."""
        self._server_goal(goal.robot, goal.map_id, (goal.x, goal.y, goal.yaw), goal.note)

    def _send_to_parking(self, robot: str, place: ParkingPlace, why: str) -> None:
        """Send ``robot`` to parking spot ``place`` (``telemetry.parking``), saying why."""
        note = f"sent to parking spot {place.name}: {why}"
        self._server_goal(robot, place.map_id, (place.x, place.y, place.yaw), note)

    def _server_goal(self, robot: str, map_id: str, pose: Pose, note: str) -> None:
        msg = dict(pose_stamped(map_id, pose, time.time()))
        self.poses.reservations.aim(robot, map_id, pose[:2])
        self.bus.publish(None, topics.robot_topic(robot, topics.GOAL), msg)
        self._goals[robot] = msg
        self.events.goal_sent(robot, "server", msg, note)

    def _resend_goal(self, robot: str, why: str) -> bool:
        """Send ``robot`` the last goal sent it on this process again, freshly stamped, so
        that it plans afresh from where it stands (the stuck rule's replan); False if no
        goal was sent it here or it is no longer connected here."""
        sent = self._goals.get(robot)
        found = goal_of(sent) if sent is not None else None
        if sent is None or found is None or robot not in self.robots():
            return False
        msg = dict(pose_stamped(found.map_id, (found.x, found.y, found.yaw), time.time()))
        self.bus.publish(None, topics.robot_topic(robot, topics.GOAL), msg)
        self.events.goal_sent(robot, "server", msg, f"sent again: {why}")
        return True

    async def flush_recording(self, robots: list[str]) -> None:
        """Write out what this process's recorder holds of ``robots`` (an export on another
        process is about to read their files); on a thread, never the loop."""
        if self.recorder is not None:
            await asyncio.to_thread(self.recorder.flush, robots)


_hubs: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, asyncio.Task[Hub]] = (
    weakref.WeakKeyDictionary()
)


async def get_hub() -> Hub:
    """Return this process's hub (one per event loop), creating and starting it on first use."""
    loop = asyncio.get_running_loop()
    task = _hubs.get(loop)
    if task is None or (task.done() and task.exception() is not None):
        # a hub that failed to start (Redis unreachable) is retried by the next connection;
        # in a fresh context: the hub's background tasks outlive whatever asked first, and
        # an HTTP request's asgiref executors quit when it ends (issue 23 point 9)
        task = _hubs[loop] = loop.create_task(_new_hub(), context=contextvars.Context())
    return await asyncio.shield(task)


HubStart = Callable[[Hub], None]
"""Starts workers that tap a hub's topics, given the hub once it has started."""

_hub_starts: list[HubStart] = []


def on_hub_start(start: HubStart) -> None:
    """Have ``start(hub)`` called with each hub of this process once it has started (the
    server's one place that starts workers: ``cloudnav_web.background``)."""
    if start not in _hub_starts:
        _hub_starts.append(start)


async def _new_hub() -> Hub:
    hub = Hub(RosbridgeConfig.load(), server_services())
    await hub.start()
    listen(asyncio.get_running_loop(), hub.review.access_changed)  # embedded mode's changes
    for start in _hub_starts:
        start(hub)
    return hub
