"""The rosbridge v2 WebSocket consumer: parse a frame, authorise it, call one hub function.

Connections without a valid credential are refused during the handshake (HTTP 403), so no
frame ever flows on them. A frame that fails is answered in ``replies`` and dropped; the
connection stays up.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from typing import Any

from channels.exceptions import StopConsumer
from channels.generic.websocket import AsyncWebsocketConsumer
from typing_extensions import override

from cloudnav_core import topics
from cloudnav_django.batches import UNREACHABLE
from cloudnav_django.outage import REPORT
from telemetry.access.decisions import Access, authenticate
from telemetry.access.review import Client
from telemetry.domain import protocol
from telemetry.domain.bus import SubscribeParams
from telemetry.domain.decoding import decode_frame
from telemetry.domain.fragments import Reassembler
from telemetry.domain.protocol import SUPPORTED_COMPRESSIONS, parse_op
from telemetry.exceptions import BadFrame, RosbridgeError, ServerFault
from telemetry.rosbridge import replies
from telemetry.rosbridge.connection import Connection
from telemetry.rosbridge.hub import Hub, get_hub
from telemetry.rosbridge.server_services import ServiceCall
from telemetry.rosbridge.transport import SCOPE_KEY

logger = logging.getLogger(__name__)


class RosbridgeConsumer(AsyncWebsocketConsumer):  # type: ignore[misc]  # Channels has no types
    """One rosbridge v2 client: robot (by token) or person (by session, from our origin)."""

    # Connections need no channel of their own: fan-out is in-process, and scaled mode has
    # one channel per server process (see ``telemetry.rosbridge.relay``). An alias that names no
    # layer makes Channels skip the per-connection channel.
    channel_layer_alias = "rosbridge-connections-have-no-channel"

    hub: Hub
    conn: Connection | None = None
    access: Access
    fragments: Reassembler
    _frame_size = 0  # of the frame being handled

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        """Take each message straight from ``receive`` and dispatch it.

        Channels' own loop multiplexes the client with the connection's channel-layer
        channel, at the price of a task and an ``asyncio.wait`` per frame; this consumer has
        no such channel, so a plain loop does the same work for much less.
        """
        self.scope = scope
        self.channel_layer = None
        self.base_send = send
        try:
            while True:
                await self.dispatch(await receive())
        except StopConsumer:
            pass

    async def dispatch(self, message: dict[str, Any]) -> None:
        """Frames skip Channels' per-message database-connection cleanup (a thread hop):
        the frame path reads the database only through ``database_sync_to_async``, which
        cleans up itself."""
        if message["type"] == "websocket.receive":
            await self.websocket_receive(message)
        else:
            await super().dispatch(message)

    @override
    async def websocket_connect(self, message: dict[str, Any]) -> None:
        try:
            identity = await authenticate(self.scope)
        except UNREACHABLE as error:  # the database is down: refused, logged once in a while
            REPORT.failed("rosbridge handshakes refused", error)
            identity = None
        if identity is None:
            await self.close()
            return
        self.hub = await get_hub()
        config = self.hub.config
        self.access = Access(identity.principal, self.hub.registry)
        self.fragments = Reassembler(
            config.per_connection.fragment_bytes,
            self.hub.fragment_budget,
            asyncio.get_running_loop().call_later,
            config.fragment_timeout,
            client_share=self.hub.fragment_share(identity.principal.label),
        )
        self.conn = Connection(
            identity.principal,
            self.base_send,
            self.scope.get(SCOPE_KEY),
            config.send_queue_frames,
            config.send_queue_bytes,
            config.max_frame_bytes,
            config.max_send_bytes,
        )
        await self.accept()
        self.conn.start()
        self.hub.join(Client(self.conn, identity.robot_pk, self.access, self.revoke))
        logger.info("%s connected as %s", identity.principal.label, self.conn.key)

    async def revoke(self, reason: str) -> None:
        """Close this connection at once: what it was admitted with no longer holds. The
        hub has forgotten it already; frames still in flight are ignored."""
        conn, self.conn = self.conn, None
        if conn is None:
            return
        self.fragments.clear()
        logger.info("%s (%s) closed: %s", conn.principal.label, conn.key, reason)
        await self.close(code=REVOKED)

    async def websocket_receive(self, message: dict[str, Any]) -> None:
        if self.conn is None:
            return
        data = message.get("text")
        await self.handle(data if data is not None else message.get("bytes") or b"")

    @override
    async def websocket_disconnect(self, message: dict[str, Any]) -> None:
        if self.conn is not None:
            self.fragments.clear()
            await self.hub.leave(self.conn)
            logger.info("%s disconnected (%s)", self.conn.principal.label, self.conn.key)
        raise StopConsumer()

    async def handle(self, data: str | bytes, reassembled: bool = False) -> None:
        """Carry out one frame; any RosbridgeError is answered and the frame dropped."""
        conn = self._conn
        frame = None
        self._frame_size = len(data)
        try:
            frame = decode_frame(data, self.hub.config.frame)
            op = parse_op(frame)
            if reassembled and isinstance(op, protocol.Fragment):
                raise BadFrame("a fragment cannot hold another fragment", op="fragment")
            await _HANDLERS[type(op)](self, op)
        except RosbridgeError as error:
            replies.answer(conn, error, frame)
        except Exception:
            # A frame must never take the connection down with it, even through a bug here;
            # its sender is answered all the same (a call waits for its response).
            logger.exception("%s: frame failed: %.200r", conn.principal.label, data)
            replies.answer(conn, ServerFault("the server could not carry this out"), frame)

    # ------------------------------------------------------------ topics

    async def on_publish(self, op: protocol.Publish) -> None:
        name = await self.access.resolve(op.topic)
        if not self.access.granted("publish", name):
            await self.access.require("publish", name)
        conn, msg, moved = self._conn, op.msg, ""
        if name.endswith(_CMD_VEL_SUFFIX):
            await self.hub.teleop.check_command(conn, name, msg)
        elif conn.principal.robot is None:
            checked, moved = await self.hub.poses.check(name, msg)  # goals and initial poses
            if moved:
                msg = dict(checked)
                conn.report("warning", moved)
        self.hub.publish(conn, name, msg, op.latch, self._frame_size, moved)

    async def on_subscribe(self, op: protocol.Subscribe) -> None:
        name = await self.access.resolve(op.topic)
        await self.access.require("subscribe", name)
        compression = op.compression
        if compression not in SUPPORTED_COMPRESSIONS:
            self._conn.report("warning", f"compression {compression} is not offered; using none")
            compression = "none"
        fragment_size = self._fragment_size(op.fragment_size)
        params = SubscribeParams(op.throttle_rate, op.queue_length, fragment_size, compression)
        await self.hub.subscribe(self._conn, name, op, params)

    async def on_unsubscribe(self, op: protocol.Unsubscribe) -> None:
        self.hub.unsubscribe(self._conn, await self.access.resolve(op.topic), op)

    async def on_advertise(self, op: protocol.Advertise) -> None:
        name = await self.access.resolve(op.topic)
        await self.access.require("advertise", name)
        self.hub.advertise(self._conn, name, op.type, op.latch, op.id)
        await self.hub.relay.written()  # other processes know it before the next frame

    async def on_unadvertise(self, op: protocol.Unadvertise) -> None:
        self.hub.unadvertise(self._conn, await self.access.resolve(op.topic), op.id)
        await self.hub.relay.written()

    # ------------------------------------------------------------ services

    async def on_call_service(self, op: protocol.CallService) -> None:
        name = await self.access.resolve(op.service)
        op.fragment_size = self._fragment_size(op.fragment_size)
        call = ServiceCall(self.hub.server_parts, self._conn, self.access, name, op.args)
        await self.hub.calls.call_service(call, op)

    async def on_service_response(self, op: protocol.ServiceResponse) -> None:
        self.hub.calls.service_response(self._conn, await self.access.resolve(op.service), op)

    async def on_advertise_service(self, op: protocol.AdvertiseService) -> None:
        name = await self.access.resolve(op.service)
        await self.access.require("advertise_service", name)
        self.hub.calls.advertise_service(self._conn, name, op)
        await self.hub.relay.written()

    async def on_unadvertise_service(self, op: protocol.UnadvertiseService) -> None:
        self.hub.calls.unadvertise_service(self._conn, await self.access.resolve(op.service))
        await self.hub.relay.written()

    # ------------------------------------------------------------ actions

    async def on_advertise_action(self, op: protocol.AdvertiseAction) -> None:
        name = await self.access.resolve(op.action)
        await self.access.require("advertise_service", name)
        self.hub.calls.advertise_action(self._conn, name, op)
        await self.hub.relay.written()

    async def on_unadvertise_action(self, op: protocol.UnadvertiseAction) -> None:
        self.hub.calls.unadvertise_action(self._conn, await self.access.resolve(op.action))
        await self.hub.relay.written()

    async def on_send_action_goal(self, op: protocol.SendActionGoal) -> None:
        name = await self.access.resolve(op.action)
        op.fragment_size = self._fragment_size(op.fragment_size)
        await self.hub.calls.send_action_goal(self._conn, self.access, name, op)

    async def on_cancel_action_goal(self, op: protocol.CancelActionGoal) -> None:
        self.hub.calls.cancel_action_goal(self._conn, await self.access.resolve(op.action), op)

    async def on_action_feedback(self, op: protocol.ActionFeedback) -> None:
        self.hub.calls.action_feedback(self._conn, await self.access.resolve(op.action), op)

    async def on_action_result(self, op: protocol.ActionResult) -> None:
        self.hub.calls.action_result(self._conn, await self.access.resolve(op.action), op)

    # ------------------------------------------------------------ framing and status

    async def on_fragment(self, op: protocol.Fragment) -> None:
        text = self.fragments.add(op.id, op.num, op.total, op.data)
        if text is not None:
            await self.handle(text, reassembled=True)

    async def on_set_level(self, op: protocol.SetLevel) -> None:
        self._conn.level = op.level

    def _fragment_size(self, asked: int | None) -> int | None:
        """Return the ``fragment_size`` to use: what was asked, raised to the least allowed.

        Tiny fragments multiply the frames (and the work) a message costs; a client asking
        for them gets fragments of the least size instead, and a warning."""
        least = self.hub.config.per_connection.min_fragment_size
        if asked is None or asked >= least:
            return asked
        self._conn.report("warning", f"fragment_size {asked} is below {least}; using {least}")
        return least

    @property
    def _conn(self) -> Connection:
        if self.conn is None:
            raise RosbridgeError("connection is not open")
        return self.conn


_CMD_VEL_SUFFIX = "/" + topics.CMD_VEL
# WebSocket close code of a connection whose credentials were revoked (daphne allows 1000
# and 3000-4999 only; 4403 reads as HTTP 403)
REVOKED = 4403
_Handler = Callable[[RosbridgeConsumer, Any], Awaitable[None]]
_HANDLERS: dict[type, _Handler] = {
    protocol.Publish: RosbridgeConsumer.on_publish,
    protocol.Subscribe: RosbridgeConsumer.on_subscribe,
    protocol.Unsubscribe: RosbridgeConsumer.on_unsubscribe,
    protocol.Advertise: RosbridgeConsumer.on_advertise,
    protocol.Unadvertise: RosbridgeConsumer.on_unadvertise,
    protocol.CallService: RosbridgeConsumer.on_call_service,
    protocol.ServiceResponse: RosbridgeConsumer.on_service_response,
    protocol.AdvertiseService: RosbridgeConsumer.on_advertise_service,
    protocol.UnadvertiseService: RosbridgeConsumer.on_unadvertise_service,
    protocol.AdvertiseAction: RosbridgeConsumer.on_advertise_action,
    protocol.UnadvertiseAction: RosbridgeConsumer.on_unadvertise_action,
    protocol.SendActionGoal: RosbridgeConsumer.on_send_action_goal,
    protocol.CancelActionGoal: RosbridgeConsumer.on_cancel_action_goal,
    protocol.ActionFeedback: RosbridgeConsumer.on_action_feedback,
    protocol.ActionResult: RosbridgeConsumer.on_action_result,
    protocol.Fragment: RosbridgeConsumer.on_fragment,
    protocol.SetLevel: RosbridgeConsumer.on_set_level,
}
