"""The rosbridge state of one server process and one function per operation.

The consumer authorises a frame, then calls one of these. Topics fan out in-process (no
channel-layer hop for local subscribers); in scaled mode ``relay`` carries what other
processes need, one hop per process.
"""

from __future__ import annotations

import asyncio
import logging
import weakref
from dataclasses import dataclass, field

from robots.fleet import FleetTracker
from robots.teleop import LockStore, MemoryLockStore, TeleopLocks
from telemetry.config import RosbridgeConfig
from telemetry.connection import Connection
from telemetry.domain import names, protocol
from telemetry.domain.bus import SubscribeParams, TopicBus
from telemetry.domain.calls import CallTable, PendingCall
from telemetry.domain.encoding import Outgoing
from telemetry.domain.messages import pose_of, string_of, zero_twist
from telemetry.domain.protocol import Json
from telemetry.exceptions import ActionFailed, NotAllowed, RosbridgeError, ServiceFailed
from telemetry.server_services import ServerService, ServiceCall, server_services
from telemetry.services import Access

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
    """What the hub keeps of a connection besides the connection itself."""

    conn: Connection
    access: Access
    robot_pk: int | None = None
    fleet_topics: dict[str, str] = field(default_factory=dict)


class Hub:
    """Topics, advertised services and actions, parameters, teleop locks and fleet state."""

    def __init__(
        self,
        config: RosbridgeConfig,
        services: dict[str, ServerService],
        lock_store: LockStore | None = None,
    ) -> None:
        loop = asyncio.get_running_loop()
        self.config = config
        self.bus = TopicBus(
            scheduler=loop.call_later,
            clock=loop.time,
            type_hint=fleet_type,
            latch_hint=fleet_latched,
        )
        self.services = CallTable("service_request")
        self.actions = CallTable("action_goal")
        self.server_services = services
        self.params: dict[str, str] = {}
        self.clients: dict[str, Client] = {}
        self.teleop = TeleopLocks(
            lock_store or MemoryLockStore(),
            stop=self.stop_robot,
            ttl=config.teleop_lock_ttl,
            silence=config.teleop_silence,
        )
        self.fleet = FleetTracker(interval=config.fleet_flush_interval)
        self._fleet_topics: dict[str, tuple[int, str]] = {}

    # ------------------------------------------------------------ connections

    def join(self, client: Client) -> None:
        self.clients[client.conn.key] = client
        robot = client.conn.principal.robot
        if robot is not None and client.robot_pk is not None:
            for kind in (names.POSE, names.MAP_ID):
                self._fleet_topics[names.robot_topic(robot, kind)] = (client.robot_pk, kind)
            self.fleet.connected(client.robot_pk)

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
        if client is not None and client.robot_pk is not None:
            self.fleet.disconnected(client.robot_pk)

    # ------------------------------------------------------------ topics

    def advertise(
        self, conn: Connection, name: str, type_name: str, latch: bool, aid: Json
    ) -> None:
        self.bus.advertise(conn, name, type_name, latch, aid)

    def unadvertise(self, conn: Connection, name: str, aid: Json) -> None:
        self.bus.unadvertise(conn, name, aid)

    def publish(self, conn: Connection, name: str, msg: dict[str, Json], latch: bool) -> None:
        self.bus.publish(conn, name, msg, latch)
        tracked = self._fleet_topics.get(name)
        if tracked is not None:
            self._track(tracked[0], tracked[1], msg)

    def _track(self, robot_pk: int, kind: str, msg: dict[str, Json]) -> None:
        if kind == names.POSE:
            pose = pose_of(msg)
            if pose is not None:
                self.fleet.pose(robot_pk, pose)
        elif (map_id := string_of(msg)) is not None:
            self.fleet.map_id(robot_pk, map_id)

    def subscribe(
        self, conn: Connection, name: str, op: protocol.Subscribe, params: SubscribeParams
    ) -> None:
        self.bus.subscribe(conn, name, op.type, params, op.id, spelling=op.topic)

    def unsubscribe(self, conn: Connection, name: str, op: protocol.Unsubscribe) -> None:
        self.bus.unsubscribe(conn, name, op.id, spelling=op.topic)

    # ------------------------------------------------------------ teleop

    def check_command(self, conn: Connection, name: str, msg: dict[str, Json]) -> None:
        """Let a person's ``cmd_vel`` through only from the robot's teleop lock holder.

        Raises NotAllowed otherwise; on success renews the lock and re-arms the watchdog.
        """
        robot = names.first_segment(name)
        if not self.teleop.accepts(robot, conn.key):
            raise NotAllowed(f"{conn.principal.label} does not hold the teleop lock of {robot}")
        self.teleop.commanded(robot, moving=_moving(msg))

    def stop_robot(self, robot: str) -> None:
        """Send ``robot`` a zero Twist from the server itself."""
        self.bus.publish(None, names.robot_topic(robot, names.CMD_VEL), zero_twist())

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
            raise ServiceFailed(f"Service {call.name} does not exist")
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

    def unadvertise_service(self, conn: Connection, name: str) -> None:
        orphans = self.services.unadvertise(name, conn)
        if orphans is None:
            raise RosbridgeError(f"Service {name} has not been advertised by this client")
        for call in orphans:
            self._fail_call(call, f"Service {name} was unadvertised")

    def _fail_call(self, call: PendingCall, reason: str) -> None:
        reply = protocol.service_response(call.caller_spelling, call.caller_id, reason, False)
        call.caller.deliver(Outgoing(reply).wire())

    # ------------------------------------------------------------ actions

    def advertise_action(self, conn: Connection, name: str, op: protocol.AdvertiseAction) -> None:
        for call in self.actions.advertise(name, op.type, conn, op.action):
            self._fail_goal(call, f"Action {name} was advertised again")

    def unadvertise_action(self, conn: Connection, name: str) -> None:
        orphans = self.actions.unadvertise(name, conn)
        if orphans is None:
            raise RosbridgeError(f"Action {name} has not been advertised by this client")
        for call in orphans:
            self._fail_goal(call, f"Action {name} was unadvertised")

    async def send_action_goal(
        self, conn: Connection, access: Access, name: str, op: protocol.SendActionGoal
    ) -> None:
        provider = self.actions.provider(name)
        if provider is None:
            raise ActionFailed(f"Action {name} does not exist")
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


def _moving(twist: dict[str, Json]) -> bool:
    """True if a Twist asks for any motion at all."""
    for part in ("linear", "angular"):
        vector = twist.get(part)
        if isinstance(vector, dict) and any(vector.get(axis) for axis in ("x", "y", "z")):
            return True
    return False


_hubs: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, Hub] = weakref.WeakKeyDictionary()


def get_hub() -> Hub:
    """Return this process's hub (one per event loop), creating it on first use."""
    loop = asyncio.get_running_loop()
    hub = _hubs.get(loop)
    if hub is None:
        hub = _hubs[loop] = Hub(RosbridgeConfig.load(), server_services())
    return hub
