"""Scaled mode: rosbridge traffic between server processes, over the Redis channel layer.

Each server process owns one channel. It joins a topic's group while it has subscribers to
that topic, and sends each message published on it to the group once: one channel-layer
hop per process, whatever the number of subscribers, and none at all for local ones.
Requests to a service or action advertised on another process go to that process's
channel; answers come back as ready frames for one connection (``rb.deliver``).

What every process must see lives in Redis under ``names.redis_key``: which process
advertises which topic, service and action, which robots it serves, latched messages and
parameters. A process counts as alive while its heartbeat key exists.

Single-process mode has a ``NullRelay`` (``telemetry.cross_process``): the same methods,
doing nothing and finding nothing, so the hub and its parts never ask which mode they run
in. Only ``Hub.start`` chooses.
"""

from __future__ import annotations

import asyncio
import json
import logging
import uuid
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from telemetry.domain import names
from telemetry.domain.bus import Topic
from telemetry.domain.encoding import Wire
from telemetry.domain.protocol import Json
from telemetry.recording.elsewhere import FLUSH_REQUEST, FLUSHED
from telemetry.revocation import AccessChange, access_channel

if TYPE_CHECKING:
    from telemetry.hub import Hub

logger = logging.getLogger(__name__)

HEARTBEAT = 5.0
ALIVE_FOR = 15
REGROUP_EVERY = 600.0  # channels_redis forgets group members after a day; rejoin well before
MAX_PENDING = 10_000


@dataclass(frozen=True)
class _Call:
    """One queued channel-layer or Redis call, and the future of its completion."""

    call: Callable[..., Awaitable[Any]]
    args: tuple[Any, ...]
    done: asyncio.Future[None]


@dataclass(frozen=True)
class RemotePeer:
    """A connection on another process, as the local bus and call tables see it."""

    relay: Relay
    channel: str
    conn_key: str

    @property
    def key(self) -> str:
        return f"{self.channel}/{self.conn_key}"

    def deliver(self, wire: Wire) -> None:
        self.relay.deliver_to(self.channel, self.conn_key, wire)


class Relay:
    """This process's link to the others: a channel, a send queue and the shared directory."""

    def __init__(self, hub: Hub, layer: Any, redis: Any) -> None:
        self.hub = hub
        self.layer = layer
        self.redis = redis
        self.channel = ""
        self.process = uuid.uuid4().hex[:12]
        self._outbox: asyncio.Queue[_Call] = asyncio.Queue()
        self._settled: asyncio.Future[None] | None = None
        self._groups: set[str] = set()
        self._tasks: list[asyncio.Task[None]] = []
        self.dropped = 0

    async def start(self) -> None:
        self.channel = await self.layer.new_channel(names.PROCESS_CHANNEL_PREFIX)
        await self.redis.sadd(names.redis_key("processes"), self.channel)
        # access changes (``telemetry.revocation``) reach every process on this Redis channel
        access = self.redis.pubsub()
        await access.subscribe(access_channel(self.redis))
        await self._beat()
        loop = asyncio.get_running_loop()
        works = (self._receive_loop(), self._send_loop(), self._heartbeat_loop())
        for work in (*works, self._access_loop(access)):
            self._tasks.append(loop.create_task(work))

    # ------------------------------------------------------------ ordered sending

    def _queue(self, call: Callable[..., Awaitable[Any]], *args: Any) -> asyncio.Future[None]:
        """Queue one channel-layer or Redis call; calls run one at a time, in order.

        Past ``MAX_PENDING`` (Redis too slow) the oldest queued call is dropped.
        """
        if self._outbox.qsize() >= MAX_PENDING:
            self._outbox.get_nowait().done.set_result(None)  # no one waits on it forever
            self.dropped += 1
        queued = _Call(call, args, asyncio.get_running_loop().create_future())
        self._outbox.put_nowait(queued)
        return queued.done

    async def _send_loop(self) -> None:
        while True:
            queued = await self._outbox.get()
            try:
                await queued.call(*queued.args)
            except Exception:
                logger.exception("relay: a channel-layer call failed")
            finally:
                if not queued.done.done():
                    queued.done.set_result(None)

    # ------------------------------------------------------------ BusListener

    def published(self, topic: Topic, msg: dict[str, Json]) -> None:
        message = {
            "type": "rb.publish",
            "origin": self.channel,
            "topic": topic.name,
            "topic_type": topic.type,
            "msg": msg,
            "latched": topic.latched,
        }
        self._queue(self.layer.group_send, names.topic_group(topic.name), message)
        if topic.latched:
            value = json.dumps({"type": topic.type, "msg": msg})
            self._queue(self.redis.hset, names.redis_key("latched"), topic.name, value)

    def interest(self, topic: str, interested: bool) -> None:
        group = names.topic_group(topic)
        if interested:
            self._groups.add(group)
            self._settled = self._queue(self.layer.group_add, group, self.channel)
        else:
            self._groups.discard(group)
            self._queue(self.layer.group_discard, group, self.channel)

    def publishers_changed(self, topic: Topic) -> None:
        if topic.publishers:
            self._queue(self._put, "topics", topic.name, topic.type or "")
        else:
            self._queue(self._remove, "topics", topic.name)
            self._queue(self.redis.hdel, names.redis_key("latched"), topic.name)

    def owner_key(self, conn_key: str) -> str:
        return f"{self.channel}/{conn_key}"

    async def settled(self) -> None:
        """Wait until this process has joined every topic group it asked for so far."""
        if self._settled is not None:
            await self._settled

    # ------------------------------------------------------------ directory

    def _hash(self, kind: str, channel: str | None = None) -> str:
        return names.redis_key(kind, channel or self.channel)

    async def _put(self, kind: str, name: str, value: str) -> None:
        await self.redis.hset(self._hash(kind), name, value)

    async def _remove(self, kind: str, name: str) -> None:
        await self.redis.hdel(self._hash(kind), name)

    def put(self, kind: str, name: str, value: str) -> None:
        self._queue(self._put, kind, name, value)

    def remove(self, kind: str, name: str) -> None:
        self._queue(self._remove, kind, name)

    async def _live_processes(self) -> list[str]:
        members = [
            m.decode() if isinstance(m, bytes) else m
            for m in await self.redis.smembers(names.redis_key("processes"))
        ]
        alive = []
        for channel in members:
            if await self.redis.exists(names.redis_key("alive", channel)):
                alive.append(channel)
            else:
                await self.redis.srem(names.redis_key("processes"), channel)
                # its connections' parameters would otherwise outlive them
                await self.hub.params.store.release_all(f"{channel}/")
        return alive

    async def entries(self, kind: str, others_only: bool = True) -> list[tuple[str, str, str]]:
        """Return ``(name, value, channel)`` of ``kind`` from every live process."""
        found = []
        for channel in await self._live_processes():
            if others_only and channel == self.channel:
                continue
            for name, value in (await self.redis.hgetall(self._hash(kind, channel))).items():
                found.append((_text(name), _text(value), channel))
        return found

    async def find(self, kind: str, name: str) -> tuple[str, str] | None:
        """Return ``(channel, value)`` of another live process that has ``name`` of ``kind``."""
        for channel in await self._live_processes():
            if channel != self.channel:
                value = await self.redis.hget(self._hash(kind, channel), name)
                if value is not None:
                    return channel, _text(value)
        return None

    async def latched(self, topic: str) -> tuple[str, dict[str, Json]] | None:
        value = await self.redis.hget(names.redis_key("latched"), topic)
        if value is None:
            return None
        stored = json.loads(value)
        return stored["type"], stored["msg"]

    # ------------------------------------------------------------ requests to other processes

    def send(self, channel: str, message: dict[str, Any]) -> None:
        self._queue(self.layer.send, channel, message)

    def deliver_to(self, channel: str, conn_key: str, wire: Wire) -> None:
        message = {
            "type": "rb.deliver",
            "conn": conn_key,
            "payloads": list(wire.payloads),
            "binary": wire.binary,
        }
        self.send(channel, message)

    def remote(self, channel: str, conn_key: str) -> RemotePeer:
        return RemotePeer(self, channel, conn_key)

    # ------------------------------------------------------------ receiving

    async def _receive_loop(self) -> None:
        while True:
            message = await self.layer.receive(self.channel)
            try:
                await self._dispatch(message)
            except Exception:
                logger.exception("relay: could not handle %s", message.get("type"))

    async def _dispatch(self, message: dict[str, Any]) -> None:
        kind = message.get("type")
        if kind == "rb.publish":
            if message["origin"] != self.channel:
                self.hub.bus.receive_remote(
                    message["topic"], message["topic_type"], message["msg"], message["latched"]
                )
        elif kind == "rb.deliver":
            client = self.hub.clients.get(message["conn"])
            if client is not None:
                client.conn.deliver(Wire(tuple(message["payloads"]), message["binary"]))
        elif kind == FLUSH_REQUEST:
            await self.hub.flush_recording(message["robots"])
            self.send(message["reply"], {"type": FLUSHED})
        else:
            await self.hub.calls.remote_request(message)

    # ------------------------------------------------------------ access changes

    async def _access_loop(self, access: Any) -> None:
        """Apply each access change announced by any process (``telemetry.revocation``)."""
        while True:
            try:
                async for message in access.listen():
                    if message.get("type") == "message":
                        change = AccessChange.of(json.loads(message["data"]))
                        await self.hub.review.access_changed(change)
            except asyncio.CancelledError:
                raise
            except Exception:
                logger.exception("relay: an access change failed")
                await asyncio.sleep(1.0)

    # ------------------------------------------------------------ liveness

    async def _beat(self) -> None:
        await self.redis.set(names.redis_key("alive", self.channel), self.process, ex=ALIVE_FOR)

    async def _heartbeat_loop(self) -> None:
        since_regroup = 0.0
        while True:
            await asyncio.sleep(HEARTBEAT)
            since_regroup += HEARTBEAT
            try:
                await self._beat()
                if since_regroup >= REGROUP_EVERY:
                    since_regroup = 0.0
                    for group in list(self._groups):
                        self._queue(self.layer.group_add, group, self.channel)
            except Exception:
                logger.exception("relay: heartbeat failed")


def _text(value: Any) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)
