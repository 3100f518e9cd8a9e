"""Scaled mode: rosbridge traffic between server processes, over Redis.

Topics travel on Redis pub/sub, one Redis channel per topic (``names.topic_channel``): a
process subscribes to it while it has subscribers to the topic, whether or not anyone
publishes it yet, so the order of subscribe, advertise, connect and reconnect never
matters; messages published here go out batched, one pipelined round trip per turn of the
event loop however many there are (measured against the channel layer in README.md).
Control messages go over the channel layer: each server process owns one channel, requests
to a service or action advertised on another process go to that process's channel, and
answers come back as ready frames for one connection (``rb.deliver``).

Every loop (receiving, sending, heartbeat, access changes) is supervised: a loop that
fails is restarted, never left dead. A failure because Redis cannot be reached is told to
``REDIS_REPORT`` (``cloudnav_django.outage``: the first, then one line per 10 s naming what
the outage cost), not a traceback per loop per attempt; any other failure is logged with
its traceback. After Redis comes back empty (restarted), the heartbeat writes this
process's part of the shared directory again from what it holds.

What every process must see lives in Redis under ``names.redis_key``: which process
advertises which topic, service and action, which robots it serves, latched messages and
parameters. A process counts as alive while its heartbeat key exists.

Single-process mode has a ``NullRelay`` (``telemetry.rosbridge.cross_process``): the same methods,
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
from typing import Any, Protocol

from redis.exceptions import ConnectionError as RedisDown
from redis.exceptions import TimeoutError as RedisTimeout

from cloudnav_django.outage import REDIS_REPORT
from telemetry.access.review import AccessReview, Client
from telemetry.access.revocation import AccessChange, access_channel
from telemetry.domain import names
from telemetry.domain.bus import Topic
from telemetry.domain.encoding import Wire
from telemetry.domain.protocol import Json
from telemetry.recording.elsewhere import FLUSH_REQUEST, FLUSHED
from telemetry.rosbridge.params import Parameters
from telemetry.rosbridge.service_calls import ServiceCalls
from telemetry.stop import STOP_REQUEST, RobotStop

logger = logging.getLogger(__name__)

HEARTBEAT = 5.0
ALIVE_FOR = 15
MAX_PENDING = 10_000
RESTART_AFTER = 0.5  # a failed loop waits this long before it runs again (Redis may be down)
SETTLE_WITHIN = 2.0  # a subscription waits at most this long for Redis to confirm it
UNREACHABLE = (RedisDown, RedisTimeout, OSError)  # Redis down, restarting or out of reach


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


class RelayHost(Protocol):
    """What the relay asks of its process's hub (``telemetry.rosbridge.hub.Hub``): where
    messages, requests and access changes from other processes go."""

    clients: dict[str, Client]
    params: Parameters
    stop: RobotStop
    calls: ServiceCalls
    review: AccessReview

    def received_from_elsewhere(
        self, name: str, type_name: str | None, msg: dict[str, Json], latched: bool
    ) -> None: ...

    async def flush_recording(self, robots: list[str]) -> None: ...


class Relay:
    """This process's link to the others: a channel, a send queue and the shared directory."""

    def __init__(self, hub: RelayHost, layer: Any, redis: Any) -> None:
        self.hub = hub
        self.layer = layer
        self.redis = redis
        self.channel = ""
        self.process = uuid.uuid4().hex[:12]
        self.topics = TopicChannels(redis, hub.received_from_elsewhere)
        self._outbox: asyncio.Queue[_Call] = asyncio.Queue()
        self._last_queued: asyncio.Future[None] | None = None
        self._tasks: list[asyncio.Task[None]] = []
        # this process's part of the shared directory, to write again after Redis restarts
        self._mine: dict[str, dict[str, str]] = {}
        self._latched: dict[str, str] = {}
        self.dropped = 0

    async def start(self) -> None:
        self.channel = await self.layer.new_channel(names.PROCESS_CHANNEL_PREFIX)
        self.topics.set_origin(self.channel)
        await self.redis.sadd(names.redis_key("processes"), self.channel)
        await self._beat()
        loops = {
            "receive": self._receive_loop,
            "send": self._send_loop,
            "heartbeat": self._heartbeat_loop,
            "access": self._access_loop,
            "topic receive": self.topics.receive_loop,
            "topic send": self.topics.send_loop,
        }
        loop = asyncio.get_running_loop()
        for name, work in loops.items():
            self._tasks.append(loop.create_task(keep_running(name, work)))

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
        self._last_queued = queued.done
        return queued.done

    async def _send_loop(self) -> None:
        while True:
            queued = await self._outbox.get()
            try:
                await queued.call(*queued.args)
            except UNREACHABLE as error:
                REDIS_REPORT.failed("relay messages or directory writes lost", error)
            except Exception:
                logger.exception("relay: a channel-layer or Redis call failed")
            finally:
                if not queued.done.done():
                    queued.done.set_result(None)

    # ------------------------------------------------------------ BusListener

    def published(self, topic: Topic, msg: dict[str, Json]) -> None:
        self.topics.publish(topic, msg)
        if topic.latched:
            value = json.dumps({"type": topic.type, "msg": msg})
            self._latched[topic.name] = value
            self._queue(self.redis.hset, names.redis_key("latched"), topic.name, value)

    def interest(self, topic: str, interested: bool) -> None:
        self.topics.interest(topic, interested)

    def publishers_changed(self, topic: Topic) -> None:
        if topic.publishers:
            self.put("topics", topic.name, topic.type or "")
        else:
            self.remove("topics", topic.name)
            if self._latched.pop(topic.name, None) is not None:
                self._queue(self.redis.hdel, names.redis_key("latched"), topic.name)

    def owner_key(self, conn_key: str) -> str:
        return f"{self.channel}/{conn_key}"

    async def settled(self) -> None:
        """Wait until Redis has confirmed every topic subscription asked for so far (at
        most ``SETTLE_WITHIN`` seconds: with Redis down, subscribing goes on regardless)."""
        await self.topics.settled()

    async def written(self) -> None:
        """Wait until every directory write and message queued so far has reached Redis
        (they run in order; at most ``SETTLE_WITHIN`` seconds: with Redis down, the
        connection goes on regardless)."""
        last = self._last_queued
        if last is not None and not last.done():
            await asyncio.wait([last], timeout=SETTLE_WITHIN)

    # ------------------------------------------------------------ directory

    def _hash(self, kind: str, channel: str | None = None) -> str:
        return names.redis_key(kind, channel or self.channel)

    async def _put(self, kind: str, name: str, value: str) -> None:
        await self.redis.hset(self._hash(kind), name, value)

    async def _remove(self, kind: str, name: str) -> None:
        await self.redis.hdel(self._hash(kind), name)

    def put(self, kind: str, name: str, value: str) -> None:
        self._mine.setdefault(kind, {})[name] = value
        self._queue(self._put, kind, name, value)

    def remove(self, kind: str, name: str) -> None:
        self._mine.get(kind, {}).pop(name, None)
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
        if kind == "rb.deliver":
            client = self.hub.clients.get(message["conn"])
            if client is not None:
                client.conn.deliver(Wire(tuple(message["payloads"]), message["binary"]))
        elif kind == FLUSH_REQUEST:
            await self.hub.flush_recording(message["robots"])
            self.send(message["reply"], {"type": FLUSHED})
        elif kind == STOP_REQUEST:
            await self.hub.stop.halt_here(message["robot"])
        else:
            await self.hub.calls.remote_request(message)

    # ------------------------------------------------------------ access changes

    async def _access_loop(self) -> None:
        """Apply each access change announced by any process (``telemetry.access.revocation``);
        a new subscription each time it (re)starts."""
        access = self.redis.pubsub()
        try:
            await access.subscribe(access_channel(self.redis))
            async for message in access.listen():
                if message.get("type") == "message":
                    change = AccessChange.of(json.loads(message["data"]))
                    try:
                        await self.hub.review.access_changed(change)
                    except Exception:
                        logger.exception("relay: an access change failed")
        finally:
            await access.aclose()

    # ------------------------------------------------------------ liveness

    async def _beat(self) -> None:
        await self.redis.set(names.redis_key("alive", self.channel), self.process, ex=ALIVE_FOR)

    async def _heartbeat_loop(self) -> None:
        while True:
            await asyncio.sleep(HEARTBEAT)
            await self._beat()
            if await self.redis.sadd(names.redis_key("processes"), self.channel):
                await self._rewrite_directory()

    async def _rewrite_directory(self) -> None:
        """Redis lost this process's entry (it restarted empty): write again what this
        process advertises, the robots it serves and its latched messages."""
        logger.warning("relay: Redis forgot this process; writing its directory again")
        for kind, entries in self._mine.items():
            for name, value in list(entries.items()):
                await self._put(kind, name, value)
        for topic, value in list(self._latched.items()):
            await self.redis.hset(names.redis_key("latched"), topic, value)


class TopicChannels:
    """Topics between processes on Redis pub/sub: one Redis channel per topic, subscribed
    while this process has subscribers to it; outgoing messages batched per loop turn."""

    def __init__(self, redis: Any, deliver: Callable[[str, str | None, Any, bool], None]) -> None:
        self.redis = redis
        self.deliver = deliver
        self.origin = ""
        self._echo = b""  # how this process's own payloads begin (set_origin)
        self.database = int(redis.connection_pool.connection_kwargs.get("db", 0))
        self._wanted: set[str] = set()  # topic names
        self._pending: list[tuple[str, str]] = []  # (Redis channel, payload)
        self._ready = asyncio.Event()
        self._confirmed: dict[str, asyncio.Future[None]] = {}
        self._pubsub: Any = None
        self._commanding = asyncio.Lock()
        self.sent_batches = 0

    def set_origin(self, origin: str) -> None:
        """Name this process in what it publishes, so that it can tell its own messages,
        which Redis sends back when it has subscribers of the topic too, before parsing."""
        self.origin = origin
        self._echo = json.dumps({"origin": origin})[:-1].encode()

    def publish(self, topic: Topic, msg: dict[str, Json]) -> None:
        # "origin" first: ``_received`` recognises this process's own by their beginning
        payload = {"origin": self.origin, "type": topic.type, "msg": msg, "latched": topic.latched}
        self._pending.append((names.topic_channel(topic.name, self.database), json.dumps(payload)))
        self._ready.set()

    def interest(self, topic: str, interested: bool) -> None:
        channel = names.topic_channel(topic, self.database)
        if interested:
            self._wanted.add(topic)
            self._confirmed[channel] = asyncio.get_running_loop().create_future()
            self._command(lambda pubsub: pubsub.subscribe(channel))
        else:
            self._wanted.discard(topic)
            self._confirmed.pop(channel, None)
            self._command(lambda pubsub: pubsub.unsubscribe(channel))

    def _command(self, command: Callable[[Any], Awaitable[Any]]) -> None:
        if self._pubsub is not None:
            asyncio.get_running_loop().create_task(self._in_order(command, self._pubsub))
        # with no connection yet, ``receive_loop`` subscribes to every wanted topic

    async def _in_order(self, command: Callable[[Any], Awaitable[Any]], pubsub: Any) -> None:
        async with self._commanding:  # a fair lock: (un)subscriptions reach Redis in order
            try:
                await command(pubsub)
            except UNREACHABLE as error:
                # the receive loop fails too, and subscribes to every wanted topic again
                REDIS_REPORT.failed("topic subscription changes made again", error)

    async def settled(self) -> None:
        waiting = [f for f in self._confirmed.values() if not f.done()]
        if waiting:
            await asyncio.wait(waiting, timeout=SETTLE_WITHIN)

    async def send_loop(self) -> None:
        """Send what was published since the last round trip, in one pipeline."""
        while True:
            await self._ready.wait()
            self._ready.clear()
            batch, self._pending = self._pending, []
            try:
                async with self.redis.pipeline(transaction=False) as pipe:
                    for channel, payload in batch:
                        pipe.publish(channel, payload)
                    await pipe.execute()
            finally:
                self.sent_batches += 1

    async def receive_loop(self) -> None:
        """Subscribe to every wanted topic on a new connection, then hand each message
        from another process to the local bus."""
        pubsub = self.redis.pubsub(ignore_subscribe_messages=False)
        try:
            # one connection: a (un)subscription sent while it is made would go on another
            await pubsub.connect()
            self._pubsub = pubsub
            wanted = [names.topic_channel(topic, self.database) for topic in self._wanted]
            if wanted:
                self._command(lambda pubsub: pubsub.subscribe(*wanted))
            while True:
                message = await pubsub.get_message(timeout=None)
                if message is not None:
                    self._received(message)
        finally:
            self._pubsub = None
            await pubsub.aclose()

    def _received(self, message: dict[str, Any]) -> None:
        channel = _text(message["channel"])
        if message["type"] == "subscribe":
            confirmed = self._confirmed.get(channel)
            if confirmed is not None and not confirmed.done():
                confirmed.set_result(None)
        elif message["type"] == "message":
            data = message["data"]
            if self._echo and _bytes(data).startswith(self._echo):
                return  # its own, back from Redis: a parse per message saved
            payload = json.loads(data)
            if payload["origin"] != self.origin:
                topic = names.topic_of_channel(channel)
                self.deliver(topic, payload["type"], payload["msg"], payload["latched"])


async def keep_running(name: str, work: Callable[[], Awaitable[None]]) -> None:
    """Run ``work`` for ever: when it fails, start it again after ``RESTART_AFTER``
    seconds. Redis out of reach (timed out, restarted, down) is counted by
    ``REDIS_REPORT``, which logs once per outage interval; anything else is logged here."""
    while True:
        try:
            await work()
            logger.error("relay: the %s loop ended; starting it again", name)
        except asyncio.CancelledError:
            raise
        except UNREACHABLE as error:
            REDIS_REPORT.failed(f"{name} loop restarts", error)
        except Exception:
            logger.exception("relay: the %s loop failed; starting it again", name)
        await asyncio.sleep(RESTART_AFTER)


def shared_redis(url: str) -> Any:
    """The asyncio Redis client of the relay and of the state it shares (locks, parameters).

    After Redis restarts, each pooled connection fails once on its next use ("Connection
    closed by server"): a command that meets a dropped connection is tried again on a new
    one (up to 3 times, backing off to 0.5 s) instead of losing a message or a lock."""
    from redis.asyncio import from_url
    from redis.asyncio.retry import Retry
    from redis.backoff import ExponentialBackoff
    from redis.exceptions import ConnectionError as DroppedConnection

    retry = Retry(ExponentialBackoff(cap=0.5, base=0.05), 3)
    return from_url(url, retry=retry, retry_on_error=[DroppedConnection])


def _bytes(value: Any) -> bytes:
    return value if isinstance(value, bytes) else str(value).encode()


def _text(value: Any) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)
