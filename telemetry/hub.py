"""The rosbridge state of one server process and one function per operation.

The consumer authorises a frame, then calls one of these. Topics fan out in-process (no
channel-layer hop for local subscribers); in scaled mode ``relay`` carries what other
processes need, one hop per process.
"""

from __future__ import annotations

import asyncio
import logging
import time
import weakref
from collections.abc import Awaitable, Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from channels.db import database_sync_to_async

from robots.fleet import FleetTracker
from robots.missions import Goal
from robots.teleop import MemoryLockStore, RedisLockStore, TeleopLocks
from telemetry.config import RosbridgeConfig
from telemetry.connection import Connection
from telemetry.cross_process import CrossProcess, NullRelay
from telemetry.directory import Directory
from telemetry.domain import names, protocol
from telemetry.domain.bus import SubscribeParams, TopicBus
from telemetry.domain.calls import CallTable, PendingCall
from telemetry.domain.encoding import Outgoing
from telemetry.domain.events import Kind
from telemetry.domain.limits import ByteBudget, Holdings
from telemetry.domain.messages import pose_of, pose_stamped, string_of, twist_2d
from telemetry.domain.protocol import Json
from telemetry.domain.rules import Principal
from telemetry.domain.times import complete_header_stamp
from telemetry.events import OBSERVED, EventLog
from telemetry.exceptions import ActionFailed, NotAllowed, RosbridgeError, ServiceFailed
from telemetry.missions import MissionRunner
from telemetry.params import Parameters, RedisParams
from telemetry.recording.recorder import Recorder
from telemetry.relay import Relay
from telemetry.revocation import AccessChange, RobotRecord, revoked, robot_records
from telemetry.server_services import ServerParts, ServerService, ServiceCall
from telemetry.service_registry import server_services
from telemetry.services import Access, Registry

logger = logging.getLogger(__name__)


def fleet_type(name: str) -> str | None:
    """Return the type of a fleet topic (``/r1/pose`` and the like), None for others."""
    parts = name.split("/", 2)
    return names.ROBOT_TOPIC_TYPES.get(parts[2]) if len(parts) == 3 else None


def fleet_latched(name: str) -> bool:
    parts = name.split("/", 2)
    return len(parts) == 3 and parts[2] in names.LATCHED_TOPICS


@dataclass
class Client:
    """What the hub keeps of a connection besides the connection itself: its decisions,
    and how to close it when what it was admitted with is revoked."""

    conn: Connection
    robot_pk: int | None = None
    access: Access | None = None
    revoke: Callable[[str], Awaitable[None]] | None = None


@dataclass(eq=False)
class Watcher:
    """A video stream as revocation sees it: who watches which robot's camera; ``ended``
    is set when the stream must stop."""

    principal: Principal
    robot: str
    robot_pk: int | None
    ended: asyncio.Event = field(default_factory=asyncio.Event)


class Hub:
    """Topics, advertised services and actions, parameters, teleop locks and fleet state."""

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
        self.services = CallTable("service_request", limits)
        self.actions = CallTable("action_goal", limits)
        self.server_services = services
        held = Holdings("parameters", limits.params, limits.param_bytes)
        self.params = Parameters(held, lambda key: self.relay.owner_key(key))
        self.fragment_budget = ByteBudget(config.fragments_total_bytes)
        self.clients: dict[str, Client] = {}
        self.relay: CrossProcess = NullRelay()
        self.events = EventLog()
        self.missions = MissionRunner(self._send_goal, self.robots)
        self.teleop = TeleopLocks(
            MemoryLockStore(),
            stop=self.stop_robot,
            on_event=self._teleop_event,
            ttl=config.teleop_lock_ttl,
            silence=config.teleop_silence,
        )
        self.fleet = FleetTracker(interval=config.fleet_flush_interval)
        self._fleet_topics: dict[str, tuple[int, str]] = {}
        # Topic taps: called with each message published here on that topic (mapping
        # sessions and map upkeep take robots' scans); a tap must only queue the message.
        self.taps: dict[str, list[Callable[[dict[str, Json]], None]]] = {}
        # goals this process's connections sent to actions on other processes, by
        # connection: goal id -> that process's channel (the newest ``pending_calls``)
        self._remote_goals: dict[str, dict[Json, str]] = {}
        self._directory: dict[str, set[str]] = {}
        self.registry = Registry()
        self.watchers: set[Watcher] = set()
        self.recorder: Recorder | None = None
        directory = Directory(
            self.bus,
            self.services,
            self.actions,
            own_services=lambda: [(n, s.type) for n, s in self.server_services.items()],
            robots=self.robots,
            relay=lambda: self.relay,
        )
        self.server_parts = ServerParts(self.teleop, self.params, directory)

    def record_with(self, recorder: Recorder) -> None:
        """Record the robots connected here: the recorder taps the bus (its one seam)."""
        self.recorder = recorder
        self.bus.tap = recorder
        self.events.on_event = recorder.event
        for robot in self.robots():
            recorder.connected(robot)

    async def start(self) -> None:
        """Start recording if it is on; join the other server processes when
        ``REDIS_URL`` is set (scaled mode)."""
        from telemetry.recording.service import start_recorder

        recorder = start_recorder()
        if recorder is not None:
            self.record_with(recorder)
        if not self.config.redis_url:
            return
        from channels.layers import get_channel_layer
        from redis.asyncio import from_url

        redis = from_url(self.config.redis_url)
        relay = Relay(self, get_channel_layer(), redis)
        await relay.start()
        self.relay = self.bus.listener = relay
        self.teleop.store = RedisLockStore(redis)
        self.params.store = RedisParams(redis)

    # ------------------------------------------------------------ connections

    def join(self, client: Client) -> None:
        self.clients[client.conn.key] = client
        robot = client.conn.principal.robot
        if robot is not None and client.robot_pk is not None:
            for kind in {names.MAP_ID, *OBSERVED}:
                self._fleet_topics[names.robot_topic(robot, kind)] = (client.robot_pk, kind)
            self.fleet.connected(client.robot_pk)
            if self.recorder is not None:
                self.recorder.connected(robot)  # first, so it records the robot's arrival
            self.events.connected(robot)
            self.missions.ensure_running()
            self.relay.put("robots", robot, "1")

    def robots(self) -> set[str]:
        """Names of the robots connected to this process."""
        return {r for c in self.clients.values() if (r := c.conn.principal.robot) is not None}

    async def leave(self, conn: Connection) -> None:
        """Forget a closed connection: its topics, services, actions, locks, fleet state."""
        client = self.clients.pop(conn.key, None)
        conn.close()
        self.bus.drop(conn)
        for call in self.services.drop(conn):
            self._fail_call(call, f"Service {call.name} was unadvertised")
        for call in self.actions.drop(conn):
            self._fail_goal(call, f"Action {call.name} was unadvertised")
        await self.teleop.drop(conn.key)
        await self.params.closed(conn)
        self._remote_goals.pop(conn.key, None)
        robot = conn.principal.robot
        if client is not None and client.robot_pk is not None and robot is not None:
            self._robot_left(robot, client.robot_pk)
        self._publish_directory("services", self.services)
        self._publish_directory("actions", self.actions)

    def _robot_left(self, robot: str, robot_pk: int) -> None:
        self.fleet.disconnected(robot_pk)
        if robot in self.robots():
            return  # another connection of the same robot is still here
        self.events.disconnected(robot)
        if self.recorder is not None:
            self.recorder.disconnected(robot)
        for kind in {names.MAP_ID, *OBSERVED}:
            self._fleet_topics.pop(names.robot_topic(robot, kind), None)
        self.relay.remove("robots", robot)

    # ------------------------------------------------------------ access changes

    async def access_changed(self, change: AccessChange) -> None:
        """Apply ``change`` (see ``telemetry.revocation``): read the robots it names again,
        close what depended on what was revoked, and take every other connection's
        decisions again, withdrawing what they may no longer hold."""
        logger.info("access changed: %s", change)
        robots: dict[int, RobotRecord | None] = {}
        if change.robots:
            robots = await database_sync_to_async(robot_records)(change.robots)
        for pk, record in robots.items():
            self.registry.update(pk, record.owner if record is not None else None)
        doomed = [c for c in self.clients.values() if revoked(c.conn.principal, change, robots)]
        if robots:  # first, so whoever sees a connection close sees the new grants too
            for client in list(self.clients.values()):
                if client not in doomed:
                    await self._decide_again(client)
        for client in doomed:
            await self._revoke(client, "its credentials were revoked")
        for pk in [pk for pk, record in robots.items() if record is None]:
            self.fleet.forget(pk)  # a deleted robot's row went with it
        for watcher in list(self.watchers):
            if revoked(watcher.principal, change, robots) or not self._may_watch(watcher, robots):
                watcher.ended.set()
                self.watchers.discard(watcher)

    async def _revoke(self, client: Client, reason: str) -> None:
        await self.leave(client.conn)
        if client.revoke is not None:
            await client.revoke(reason)

    @staticmethod
    def _may_watch(watcher: Watcher, robots: dict[int, RobotRecord | None]) -> bool:
        """True if the watcher may still watch its camera: its robot was not deleted or
        renamed, and still shares a building the watcher sees."""
        from telemetry.video.cameras import may_watch

        if watcher.robot_pk not in robots:
            return True
        now = robots[watcher.robot_pk]
        if now is None or now.owner.robot != watcher.robot:
            return False
        return may_watch(watcher.principal, now.owner)

    async def _decide_again(self, client: Client) -> None:
        """Forget ``client``'s decisions and withdraw what it may no longer hold."""
        access, conn = client.access, client.conn
        if access is None:
            return
        access.reset()
        for name, spelling in self.bus.holdings(conn):
            what = "subscribe" if spelling is not None else "advertise"
            written = spelling if spelling is not None else access.shown(name)
            if not await self._still(access, what, name, written):
                self.bus.withdraw(conn, name, spelling)
                conn.report("warning", f"{names.outside_realm(name)}: access was withdrawn")
        for table, fail in ((self.services, self._fail_call), (self.actions, self._fail_goal)):
            for provider in table.served_by(conn):
                if not await self._still(access, "advertise_service", provider.name, None):
                    for call in table.unadvertise(provider.name, conn) or []:
                        fail(call, f"{provider.spelling} is no longer served")
        self._publish_directory("services", self.services)
        self._publish_directory("actions", self.actions)

    @staticmethod
    async def _still(access: Access, what: str, name: str, written: str | None) -> bool:
        """True if ``written`` still names ``name`` for ``access``, which may still ``what``."""
        written = written if written is not None else access.shown(name)
        if written is None or await access.resolve(written) != name:
            return False
        return await access.allows(what, name)

    @contextmanager
    def watching(
        self, principal: Principal, robot: str, robot_pk: int | None
    ) -> Iterator[asyncio.Event]:
        """Count a video stream of ``robot``'s camera watched by ``principal`` while the
        block runs; the event yielded is set when the stream must end (revoked)."""
        watcher = Watcher(principal, robot, robot_pk)
        self.watchers.add(watcher)
        try:
            yield watcher.ended
        finally:
            self.watchers.discard(watcher)

    # ------------------------------------------------------------ topics

    def advertise(
        self, conn: Connection, name: str, type_name: str, latch: bool, aid: Json
    ) -> None:
        self.bus.advertise(conn, name, type_name, latch, aid)

    def unadvertise(self, conn: Connection, name: str, aid: Json) -> None:
        self.bus.unadvertise(conn, name, aid)

    def publish(
        self, conn: Connection, name: str, msg: dict[str, Json], latch: bool, size: int
    ) -> None:
        complete_header_stamp(msg)
        self.bus.publish(conn, name, msg, latch, size)
        if conn.principal.robot is not None:
            self.events.heard(conn.principal.robot)
        else:
            self._commanded(conn, name, msg)
        tracked = self._fleet_topics.get(name)
        if tracked is not None:
            self._track(tracked[0], tracked[1], msg)
            if tracked[1] in OBSERVED:
                self.events.observe(names.first_segment(name), tracked[1], msg)
            if tracked[1] == names.NAV_STATUS:
                self.missions.status(names.first_segment(name), msg)
        for tap in self.taps.get(name, ()):
            tap(msg)

    def _commanded(self, conn: Connection, name: str, msg: dict[str, Json]) -> None:
        """A person's message to a robot: a goal is an event (on this process, which may
        not be the robot's; the robot's recorder reads it from the event log)."""
        robot, _, suffix = name[1:].partition("/")
        if suffix == names.GOAL:
            self.events.goal_sent(robot, conn.principal.label, msg)

    def _track(self, robot_pk: int, kind: str, msg: dict[str, Json]) -> None:
        if kind == names.POSE:
            pose = pose_of(msg)
            if pose is not None:
                self.fleet.pose(robot_pk, pose)
        elif kind == names.MAP_ID and (map_id := string_of(msg)) is not None:
            self.fleet.map_id(robot_pk, map_id)

    def _teleop_event(self, robot: str, kind: Kind, holder: str) -> None:
        self.events.teleop(robot, kind, holder)

    async def subscribe(
        self, conn: Connection, name: str, op: protocol.Subscribe, params: SubscribeParams
    ) -> None:
        """Subscribe; in scaled mode also join the topic's group and replay a latched
        message published on another process."""
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

    # ------------------------------------------------------------ teleop

    async def check_command(self, conn: Connection, name: str, msg: dict[str, Json]) -> None:
        """Let a ``cmd_vel`` through only from the robot's teleop lock holder, or from the
        robot's own token while nobody holds the lock (in any server process).

        Raises NotAllowed otherwise; a holder's command renews the lock and re-arms the
        watchdog.
        """
        robot = names.first_segment(name)
        if conn.principal.robot is not None:
            holder = await self.teleop.holder(robot)
            if holder:
                raise NotAllowed(f"{robot} is driven by {holder}, who holds its teleop lock")
            return
        if not self.teleop.accepts(robot, conn.key):
            raise NotAllowed(f"{conn.principal.label} does not hold the teleop lock of {robot}")
        self.teleop.commanded(robot, moving=_moving(msg))

    def _send_goal(self, goal: Goal) -> None:
        """Send a mission's goal to its robot from the server itself."""
        msg = dict(pose_stamped(goal.map_id, (goal.x, goal.y, goal.yaw), time.time()))
        self.bus.publish(None, names.robot_topic(goal.robot, names.GOAL), msg)
        self.events.goal_sent(goal.robot, "server", msg)

    def stop_robot(self, robot: str) -> None:
        """Send ``robot`` a zero Twist from the server itself."""
        stop = dict(twist_2d(0.0, 0.0))  # the bus takes a plain, mutable message
        self.bus.publish(None, names.robot_topic(robot, names.CMD_VEL), stop)

    # ------------------------------------------------------------ services

    async def call_service(self, call: ServiceCall, op: protocol.CallService) -> None:
        """Answer from a server service, or forward to the client that advertised ``name``.

        Raises ServiceFailed (answered as ``result: false``) when neither exists.
        """
        server = self.server_services.get(call.name)
        if server is not None:
            values = await server.handler(call)
            reply = protocol.service_response(op.service, op.id, values, True)
            call.conn.deliver(Outgoing(reply).wire("none", op.fragment_size))
            return
        provider = self.services.provider(call.name)
        if provider is None:
            await self._call_remote("services", "rb.call", call.conn, call.access, call.name, op)
            return
        await call.access.require("call", call.name)
        pending = self.services.start(
            provider, call.conn, op.id, op.service, op.fragment_size, op.compression
        )
        request = protocol.call_service(provider.spelling, pending.request_id, op.args)
        provider.peer.deliver(Outgoing(request).wire())

    def service_response(self, conn: Connection, name: str, op: protocol.ServiceResponse) -> None:
        call = self.services.finish(name, conn, op.id)
        if call is None:
            raise RosbridgeError(f"no request {op.id!r} of {name} is waiting for an answer")
        reply = protocol.service_response(
            call.caller_spelling, call.caller_id, op.values, op.result
        )
        call.caller.deliver(Outgoing(reply).wire("none", call.fragment_size))

    def advertise_service(self, conn: Connection, name: str, op: protocol.AdvertiseService) -> None:
        if name in self.server_services:
            raise NotAllowed(f"{name} is a service of the server")
        for call in self.services.advertise(name, op.type, conn, op.service):
            self._fail_call(call, f"Service {name} was advertised again")
        self._publish_directory("services", self.services)

    def unadvertise_service(self, conn: Connection, name: str) -> None:
        orphans = self.services.unadvertise(name, conn)
        if orphans is None:
            raise RosbridgeError(f"Service {name} has not been advertised by this client")
        for call in orphans:
            self._fail_call(call, f"Service {name} was unadvertised")
        self._publish_directory("services", self.services)

    def _fail_call(self, call: PendingCall, reason: str) -> None:
        reply = protocol.service_response(call.caller_spelling, call.caller_id, reason, False)
        call.caller.deliver(Outgoing(reply).wire())

    # ------------------------------------------------------------ actions

    def advertise_action(self, conn: Connection, name: str, op: protocol.AdvertiseAction) -> None:
        for call in self.actions.advertise(name, op.type, conn, op.action):
            self._fail_goal(call, f"Action {name} was advertised again")
        self._publish_directory("actions", self.actions)

    def unadvertise_action(self, conn: Connection, name: str) -> None:
        orphans = self.actions.unadvertise(name, conn)
        if orphans is None:
            raise RosbridgeError(f"Action {name} has not been advertised by this client")
        for call in orphans:
            self._fail_goal(call, f"Action {name} was unadvertised")
        self._publish_directory("actions", self.actions)

    async def send_action_goal(
        self, conn: Connection, access: Access, name: str, op: protocol.SendActionGoal
    ) -> None:
        provider = self.actions.provider(name)
        if provider is None:
            channel = await self._call_remote("actions", "rb.goal", conn, access, name, op)
            goals = self._remote_goals.setdefault(conn.key, {})
            if len(goals) >= self.config.per_connection.pending_calls:
                del goals[next(iter(goals))]  # the oldest can no longer be cancelled
            goals[op.id] = channel
            return
        await access.require("call", name)
        pending = self.actions.start(
            provider, conn, op.id, op.action, op.fragment_size, op.compression, op.feedback
        )
        goal = protocol.send_action_goal(
            provider.spelling, pending.request_id, op.action_type, op.args
        )
        provider.peer.deliver(Outgoing(goal).wire())

    def cancel_action_goal(
        self, conn: Connection, name: str, op: protocol.CancelActionGoal
    ) -> None:
        found = self.actions.of_caller(conn, op.id)
        channel = self._remote_goals.get(conn.key, {}).get(op.id)
        if found is None and channel is not None:
            self.relay.send(channel, self._request("rb.cancel", conn, name, op))
            return
        if found is None or found[0].name != name:
            raise RosbridgeError(f"no goal {op.id!r} of {name} is in progress")
        provider, pending = found
        cancel = protocol.cancel_action_goal(provider.spelling, pending.request_id)
        provider.peer.deliver(Outgoing(cancel).wire())

    def action_feedback(self, conn: Connection, name: str, op: protocol.ActionFeedback) -> None:
        call = self.actions.find(name, conn, op.id)
        if call is None:
            raise RosbridgeError(f"no goal {op.id!r} of {name} is in progress")
        if call.feedback:
            feedback = protocol.action_feedback(call.caller_spelling, call.caller_id, op.values)
            call.caller.deliver(Outgoing(feedback).wire("none", call.fragment_size))

    def action_result(self, conn: Connection, name: str, op: protocol.ActionResult) -> None:
        call = self.actions.finish(name, conn, op.id)
        if call is None:
            raise RosbridgeError(f"no goal {op.id!r} of {name} is in progress")
        result = protocol.action_result(
            call.caller_spelling, call.caller_id, op.values, op.status, op.result
        )
        call.caller.deliver(Outgoing(result).wire("none", call.fragment_size))

    def _fail_goal(self, call: PendingCall, reason: str) -> None:
        result = protocol.action_result(
            call.caller_spelling, call.caller_id, reason, protocol.STATUS_UNKNOWN, False
        )
        call.caller.deliver(Outgoing(result).wire())

    # ------------------------------------------------------------ other server processes

    def _publish_directory(self, kind: str, table: CallTable) -> None:
        """Tell the other processes which services (or actions) this one serves."""
        served = dict(table.names())
        for name, type_name in served.items():
            self.relay.put(kind, name, type_name)
        for name in self._directory.get(kind, set()) - set(served):
            self.relay.remove(kind, name)
        self._directory[kind] = set(served)

    async def _call_remote(
        self,
        kind: str,
        request: str,
        conn: Connection,
        access: Access,
        name: str,
        op: protocol.CallService | protocol.SendActionGoal,
    ) -> str:
        """Send a service call or goal to the process serving ``name``; return its channel.

        Raises ServiceFailed (or ActionFailed) when no process serves ``name``.
        """
        found = await self.relay.find(kind, name)
        if found is None:
            what = "Service" if kind == "services" else "Action"
            error = ServiceFailed if kind == "services" else ActionFailed
            raise error(f"{what} {name} does not exist")
        await access.require("call", name)
        self.relay.send(found[0], self._request(request, conn, name, op))
        return found[0]

    def _request(self, kind: str, conn: Connection, name: str, op: Any) -> dict[str, Any]:
        return {
            "type": kind,
            "name": name,
            "caller": conn.key,
            "caller_channel": self.relay.channel,
            "caller_id": op.id,
            "spelling": getattr(op, "service", None) or getattr(op, "action", None),
            "args": getattr(op, "args", None),
            "action_type": getattr(op, "action_type", None),
            "feedback": getattr(op, "feedback", False),
            "fragment_size": getattr(op, "fragment_size", None),
        }

    async def flush_recording(self, robots: list[str]) -> None:
        """Write out what this process's recorder holds of ``robots`` (an export on another
        process is about to read their files); on a thread, never the loop."""
        if self.recorder is not None:
            await asyncio.to_thread(self.recorder.flush, robots)

    async def remote_request(self, message: dict[str, Any]) -> None:
        """Carry out a call, goal or cancel that a connection on another process sent."""
        caller = self.relay.remote(message["caller_channel"], message["caller"])
        if message["type"] == "rb.cancel":
            self._remote_cancel(caller, message)
        else:
            self._remote_start(caller, message)

    def _remote_cancel(self, caller: Any, message: dict[str, Any]) -> None:
        found = self.actions.of_caller(caller, message["caller_id"])
        if found is not None:
            provider, pending = found
            cancel = protocol.cancel_action_goal(provider.spelling, pending.request_id)
            provider.peer.deliver(Outgoing(cancel).wire())

    def _remote_start(self, caller: Any, message: dict[str, Any]) -> None:
        is_call = message["type"] == "rb.call"
        table = self.services if is_call else self.actions
        provider = table.provider(message["name"])
        if provider is None:
            orphan = PendingCall(
                message["name"], caller, message["caller_id"], "", message["spelling"]
            )
            fail = self._fail_call if is_call else self._fail_goal
            fail(orphan, f"{message['name']} is no longer served")
            return
        pending = table.start(
            provider,
            caller,
            message["caller_id"],
            message["spelling"],
            message["fragment_size"],
            "none",
            bool(message["feedback"]),
        )
        if is_call:
            frame: Any = protocol.call_service(
                provider.spelling, pending.request_id, message["args"]
            )
        else:
            frame = protocol.send_action_goal(
                provider.spelling, pending.request_id, message["action_type"], message["args"]
            )
        provider.peer.deliver(Outgoing(frame).wire())


def _moving(twist: dict[str, Json]) -> bool:
    """True if a Twist asks for any motion at all."""
    for part in ("linear", "angular"):
        vector = twist.get(part)
        if isinstance(vector, dict) and any(vector.get(axis) for axis in ("x", "y", "z")):
            return True
    return False


_hubs: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, asyncio.Task[Hub]] = (
    weakref.WeakKeyDictionary()
)


def running_hubs() -> list[tuple[asyncio.AbstractEventLoop, Hub]]:
    """Return the hubs of this process that have started, with their event loops."""
    found = []
    for loop, task in list(_hubs.items()):
        if (
            task.done()
            and not task.cancelled()
            and task.exception() is None
            and not loop.is_closed()
        ):
            found.append((loop, task.result()))
    return found


async def get_hub() -> Hub:
    """Return this process's hub (one per event loop), creating and starting it on first use."""
    loop = asyncio.get_running_loop()
    task = _hubs.get(loop)
    if task is None or (task.done() and task.exception() is not None):
        # a hub that failed to start (Redis unreachable) is retried by the next connection
        task = _hubs[loop] = loop.create_task(_new_hub())
    return await asyncio.shield(task)


async def _new_hub() -> Hub:
    from maps.mapping.runner import MappingRunner
    from maps.mapping.upkeep import UpkeepRunner

    hub = Hub(RosbridgeConfig.load(), server_services())
    await hub.start()
    MappingRunner(hub).start()  # mapping sessions of the robots connected here
    UpkeepRunner(hub).start()  # laser evidence about the stored maps, from the same robots
    return hub
