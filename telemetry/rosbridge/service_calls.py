"""Service and action calls: each call or goal goes to whoever serves it (a server
service, a connection of this process, or through the relay a connection of another
process), and its answers come back the same way."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from telemetry.access.decisions import Access
from telemetry.domain import protocol
from telemetry.domain.bus import Peer
from telemetry.domain.calls import CallTable, PendingCall
from telemetry.domain.encoding import Outgoing
from telemetry.domain.limits import ConnectionLimits
from telemetry.domain.protocol import Json
from telemetry.exceptions import ActionFailed, NotAllowed, RosbridgeError, ServiceFailed
from telemetry.rosbridge.connection import Connection
from telemetry.rosbridge.cross_process import CrossProcess
from telemetry.rosbridge.server_services import ServerService, ServiceCall


class ServiceCalls:
    """The advertised services and actions of this process, and the calls and goals in
    flight to them, from here or from other processes."""

    def __init__(
        self,
        limits: ConnectionLimits,
        server_services: dict[str, ServerService],
        relay: Callable[[], CrossProcess],
    ) -> None:
        self.services = CallTable("service_request", limits)
        self.actions = CallTable("action_goal", limits)
        self.server_services = server_services
        self._relay = relay
        self._pending_calls = limits.pending_calls
        # goals this process's connections sent to actions on other processes, by
        # connection: goal id -> that process's channel (the newest ``pending_calls``)
        self._remote_goals: dict[str, dict[Json, str]] = {}
        self._directory: dict[str, set[str]] = {}

    @property
    def relay(self) -> CrossProcess:
        return self._relay()

    def drop(self, conn: Connection) -> None:
        """Fail what waits on ``conn``'s services and actions; forget its remote goals."""
        for call in self.services.drop(conn):
            self.fail_call(call, f"Service {call.name} was unadvertised")
        for call in self.actions.drop(conn):
            self.fail_goal(call, f"Action {call.name} was unadvertised")
        self._remote_goals.pop(conn.key, None)

    def publish_directories(self) -> None:
        self.publish_directory("services", self.services)
        self.publish_directory("actions", self.actions)

    def tables(self) -> tuple[tuple[CallTable, Callable[[PendingCall, str], None]], ...]:
        """The services and the actions, each with how to fail a call waiting on them."""
        return (self.services, self.fail_call), (self.actions, self.fail_goal)

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

    def call_as_server(self, name: str, args: Json, caller: Peer) -> bool:
        """Call ``name``, served by a connection of this process, as the server itself: the
        answer is delivered to ``caller``. False if no connection here serves ``name``."""
        provider = self.services.provider(name)
        if provider is None:
            return False
        pending = self.services.start(provider, caller, None, name)
        request = protocol.call_service(provider.spelling, pending.request_id, args)
        provider.peer.deliver(Outgoing(request).wire())
        return True

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
            self.fail_call(call, f"Service {name} was advertised again")
        self.publish_directory("services", self.services)

    def unadvertise_service(self, conn: Connection, name: str) -> None:
        orphans = self.services.unadvertise(name, conn)
        if orphans is None:
            raise RosbridgeError(f"Service {name} has not been advertised by this client")
        for call in orphans:
            self.fail_call(call, f"Service {name} was unadvertised")
        self.publish_directory("services", self.services)

    def fail_call(self, call: PendingCall, reason: str) -> None:
        reply = protocol.service_response(call.caller_spelling, call.caller_id, reason, False)
        call.caller.deliver(Outgoing(reply).wire())

    # ------------------------------------------------------------ actions

    def advertise_action(self, conn: Connection, name: str, op: protocol.AdvertiseAction) -> None:
        for call in self.actions.advertise(name, op.type, conn, op.action):
            self.fail_goal(call, f"Action {name} was advertised again")
        self.publish_directory("actions", self.actions)

    def unadvertise_action(self, conn: Connection, name: str) -> None:
        orphans = self.actions.unadvertise(name, conn)
        if orphans is None:
            raise RosbridgeError(f"Action {name} has not been advertised by this client")
        for call in orphans:
            self.fail_goal(call, f"Action {name} was unadvertised")
        self.publish_directory("actions", self.actions)

    async def send_action_goal(
        self, conn: Connection, access: Access, name: str, op: protocol.SendActionGoal
    ) -> None:
        provider = self.actions.provider(name)
        if provider is None:
            channel = await self._call_remote("actions", "rb.goal", conn, access, name, op)
            goals = self._remote_goals.setdefault(conn.key, {})
            if len(goals) >= self._pending_calls:
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

    def fail_goal(self, call: PendingCall, reason: str) -> None:
        result = protocol.action_result(
            call.caller_spelling, call.caller_id, reason, protocol.STATUS_UNKNOWN, False
        )
        call.caller.deliver(Outgoing(result).wire())

    # ------------------------------------------------------------ other server processes

    def publish_directory(self, kind: str, table: CallTable) -> None:
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
            fail = self.fail_call if is_call else self.fail_goal
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
