"""An asyncio rosbridge v2 client for a robot: publish, subscribe, serve and call services,
and stay connected.

The client keeps what the robot declared (advertised topics, subscriptions, services) and
declares it all again on every connection, since a restarted server remembers nothing.
It authenticates with the robot's token in an ``Authorization: Token`` header (a URL
would put the secret in access logs).

Connection loss: ``run`` reconnects with exponential backoff and full jitter (so a fleet
does not reconnect in lock step after a server restart). While disconnected, ``publish``
drops the message and returns False: a robot's pose from ten seconds ago is worth less
than nothing to an operator. Latched topics (``map_id``) are the exception: their latest
message is kept and sent again after each reconnection. Nothing else is queued.

A link that stalls without closing (Wi-Fi gone, no FIN ever comes) is the same case: once
``WRITE_LIMIT`` bytes wait for it (past a kernel buffer bounded to ``SEND_BUFFER``),
``publish`` drops telemetry instead of waiting, so the robot's loop never blocks on the
cloud and no backlog builds up to be flushed on return. A link that takes nothing for ``keepalive``
seconds, or leaves a ping unanswered that long, is aborted (what it still holds is
discarded, never delivered late) and reconnected.
"""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import itertools
import json
import logging
import random
import socket
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit, urlunsplit

import websockets
from websockets.asyncio.client import ClientConnection
from websockets.exceptions import ConnectionClosed, InvalidHandshake

from cloudnav_core.messages import Json, Message

logger = logging.getLogger(__name__)

# Bytes a connection may hold for a slow link before publications are dropped (also the
# websockets flow-control mark, above which a send would wait).
WRITE_LIMIT = 2**15
# The kernel's send buffer of a connection (Linux doubles it): what a link that stalls
# can take before ``WRITE_LIMIT`` applies, and so what it could deliver late. Autotuned,
# it grows to megabytes (seconds of telemetry); this still carries 1.3 MB/s at 100 ms RTT.
SEND_BUFFER = 2**16

Callback = Callable[[Json], None]
Handler = Callable[[Any], Json | Awaitable[Json]]


class ServiceError(Exception):
    """A service call answered ``result: false``; the message is the server's reason."""


class NotConnected(ConnectionError):
    """The client has no connection now (or lost it while a call was waiting)."""


@dataclass(frozen=True)
class Backoff:
    """Reconnection delays: ``initial * factor**attempt`` capped at ``maximum``, each
    drawn uniformly between half of that and all of it (jitter)."""

    initial: float = 0.5
    factor: float = 2.0
    maximum: float = 10.0

    def delay(self, attempt: int, rng: random.Random) -> float:
        """Seconds to wait before reconnection attempt number ``attempt`` (0 first)."""
        ceiling = min(self.maximum, self.initial * self.factor**attempt)
        return rng.uniform(ceiling / 2, ceiling)


@dataclass
class _Topic:
    type: str
    latch: bool
    last: Message | None = None  # the latest message of a latched topic


@dataclass
class _Subscription:
    type: str
    callbacks: list[Callback] = field(default_factory=list)
    throttle_rate: int = 0
    queue_length: int = 1


class RosbridgeClient:
    """One robot's connection to ``url`` (``ws://host:port/rosbridge``) with ``token``.

    Declare topics and services at any time, then ``await run()`` (it returns after
    ``close``). ``call_timeout`` bounds service calls that name no timeout; ``keepalive``
    is how long a link may stay silent or stalled before it is given up.
    """

    def __init__(
        self,
        url: str,
        token: str,
        *,
        backoff: Backoff | None = None,
        call_timeout: float = 5.0,
        keepalive: float = 5.0,
        seed: int | None = None,
    ) -> None:
        self.url = url
        self.token = token
        self.backoff = backoff or Backoff()
        self.call_timeout = call_timeout
        self.keepalive = keepalive
        self.connections = 0  # how many times a connection opened
        # The handshake response's headers of the connection opened last (a front may name
        # the server process that took it).
        self.response_headers: Any = None
        self._rng = random.Random(seed)
        self._topics: dict[str, _Topic] = {}
        self._subscriptions: dict[str, _Subscription] = {}
        self._services: dict[str, tuple[str, Handler]] = {}
        self._calls: dict[str, asyncio.Future[Json]] = {}
        self._ids = itertools.count(1)
        self._ws: ClientConnection | None = None
        self._connected = asyncio.Event()
        self._closing = False
        self._serving: set[asyncio.Task[None]] = set()  # held so they are not collected

    # --- declarations (kept across reconnections) --------------------------------------

    def advertise(self, topic: str, type_name: str, *, latch: bool = False) -> None:
        """Declare a topic this robot publishes."""
        self._topics[topic] = _Topic(type_name, latch)

    def subscribe(
        self,
        topic: str,
        type_name: str,
        callback: Callback,
        *,
        throttle_rate: int = 0,
        queue_length: int = 1,
    ) -> None:
        """Call ``callback(msg)`` for each message on ``topic``; exceptions it raises are
        logged, never propagated into the connection."""
        subscription = self._subscriptions.setdefault(
            topic, _Subscription(type_name, [], throttle_rate, queue_length)
        )
        subscription.callbacks.append(callback)

    def advertise_service(self, service: str, type_name: str, handler: Handler) -> None:
        """Serve ``service``: ``handler(args)`` (plain or async) returns the response
        values; an exception answers ``result: false`` with its text."""
        self._services[service] = (type_name, handler)

    # --- traffic -----------------------------------------------------------------------

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    async def wait_connected(self) -> None:
        """Return once connected (bound it with ``asyncio.timeout``)."""
        await self._connected.wait()

    async def publish(self, topic: str, msg: Message) -> bool:
        """Send ``msg`` on the advertised ``topic`` now; False (and dropped) when not
        connected, or when the link is not keeping up. A latched topic's message is kept
        for the next connection, and never dropped for a slow link (such messages are
        rare and small).

        Raises KeyError for a topic never advertised."""
        declared = self._topics[topic]
        if declared.latch:
            declared.last = msg
        elif self._congested():
            return False  # a slow link gets no backlog of telemetry to flush later
        return await self._send({"op": "publish", "topic": topic, "msg": msg})

    async def call_service(
        self, service: str, args: Json | None = None, within: float | None = None
    ) -> Json:
        """Call ``service`` and return its response values.

        Raises NotConnected when there is no connection (or it drops while waiting),
        ServiceError when the call fails, TimeoutError after ``within`` (default
        ``call_timeout``) seconds.
        """
        call_id = f"call:{next(self._ids)}"
        future: asyncio.Future[Json] = asyncio.get_running_loop().create_future()
        self._calls[call_id] = future
        try:
            frame = {"op": "call_service", "id": call_id, "service": service, "args": args or {}}
            if not await self._send(frame):
                raise NotConnected(f"cannot call {service}: not connected")
            async with asyncio.timeout(self.call_timeout if within is None else within):
                return await future
        finally:
            self._calls.pop(call_id, None)

    # --- connection --------------------------------------------------------------------

    async def run(self) -> None:
        """Connect, declare everything, dispatch incoming frames; on loss, wait a backoff
        delay and do it again, until ``close``."""
        attempt = 0
        while not self._closing:
            if await self._session():
                attempt = 0  # a connection that opened starts the backoff afresh
            if self._closing:
                break
            delay = self.backoff.delay(attempt, self._rng)
            attempt += 1
            logger.info("rosbridge: reconnecting to %s in %.1f s", self.url, delay)
            await asyncio.sleep(delay)

    async def close(self) -> None:
        """Stop reconnecting and close the connection; ``run`` then returns."""
        self._closing = True
        if self._ws is not None:
            await self._ws.close()

    async def _session(self) -> bool:
        """One connection's life; True if it opened."""
        try:
            async with websockets.connect(
                self.url,
                additional_headers={"Authorization": f"Token {self.token}"},
                open_timeout=10,
                max_size=None,
                ping_interval=self.keepalive,
                ping_timeout=self.keepalive,
                close_timeout=self.keepalive,
                write_limit=WRITE_LIMIT,
            ) as ws:
                watchdog = asyncio.create_task(self._watch(ws))
                try:
                    await self._opened(ws)
                    await self._receive(ws)
                finally:
                    watchdog.cancel()
                    ws.transport.abort()  # what a dead link still holds is never sent late
        except (OSError, InvalidHandshake, ConnectionClosed, TimeoutError) as error:
            logger.warning("rosbridge: connection to %s: %s", self.url, error)
        finally:
            opened = self._ws is not None
            self._lost()
        return opened

    async def _opened(self, ws: ClientConnection) -> None:
        """Declare everything on a new connection, then let publishing through."""
        self._ws = ws
        self.connections += 1
        self.response_headers = ws.response.headers if ws.response is not None else None
        connected = ws.transport.get_extra_info("socket")
        if connected is not None:
            connected.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER)
        for frame in self._declarations():
            await ws.send(json.dumps(frame))
        self._connected.set()
        logger.info("rosbridge: connected to %s", self.url)

    async def _watch(self, ws: ClientConnection) -> None:
        """Abort ``ws`` once its link has held ``WRITE_LIMIT`` bytes for ``keepalive``
        seconds: a stalled link (websockets' pings wait behind the data then, so they
        cannot tell)."""
        stalled = 0.0
        while stalled < self.keepalive:
            await asyncio.sleep(self.keepalive / 10)
            congested = ws.transport.get_write_buffer_size() >= WRITE_LIMIT
            stalled = stalled + self.keepalive / 10 if congested else 0.0
        logger.warning("rosbridge: the link to %s stalled", self.url)
        ws.transport.abort()

    def _declarations(self) -> list[Json]:
        """Frames that re-create this robot's state on a server that knows nothing of it:
        advertisements and latched messages, subscriptions, services."""
        return [*self._advertisements(), *self._subscribe_frames(), *self._service_frames()]

    def _advertisements(self) -> list[Json]:
        frames: list[Json] = []
        for topic, declared in self._topics.items():
            frames.append({"op": "advertise", "topic": topic, "type": declared.type})
            if declared.latch:
                frames[-1]["latch"] = True
                if declared.last is not None:
                    frames.append({"op": "publish", "topic": topic, "msg": declared.last})
        return frames

    def _subscribe_frames(self) -> list[Json]:
        return [
            {
                "op": "subscribe",
                "topic": topic,
                "type": sub.type,
                "throttle_rate": sub.throttle_rate,
                "queue_length": sub.queue_length,
            }
            for topic, sub in self._subscriptions.items()
        ]

    def _service_frames(self) -> list[Json]:
        return [
            {"op": "advertise_service", "service": service, "type": type_name}
            for service, (type_name, _) in self._services.items()
        ]

    def _lost(self) -> None:
        """Forget the connection and fail the calls that waited on it."""
        self._ws = None
        self._connected.clear()
        for future in self._calls.values():
            if not future.done():
                future.set_exception(NotConnected("the connection was lost"))

    def _congested(self) -> bool:
        ws = self._ws
        return ws is not None and ws.transport.get_write_buffer_size() >= WRITE_LIMIT

    async def _send(self, frame: Json) -> bool:
        """Hand ``frame`` to the connection without waiting long for a slow link; False
        (and dropped) when there is none."""
        ws = self._ws
        if ws is None or not self._connected.is_set():
            return False
        try:
            async with asyncio.timeout(self.keepalive / 10):
                await ws.send(json.dumps(frame))
        except ConnectionClosed:
            return False
        except TimeoutError:
            pass  # written: only the wait for the link to take it was cut short
        return True

    # --- incoming ----------------------------------------------------------------------

    async def _receive(self, ws: ClientConnection) -> None:
        async for data in ws:
            try:
                frame = json.loads(data)
            except ValueError:
                logger.warning("rosbridge: a frame that is not JSON was dropped")
                continue
            if isinstance(frame, dict):
                self._dispatch(frame)

    def _dispatch(self, frame: Json) -> None:
        op = frame.get("op")
        if op == "publish":
            self._deliver(frame.get("topic"), frame.get("msg"))
        elif op == "service_response":
            self._answered(frame)
        elif op == "call_service":
            task = asyncio.create_task(self._serve(frame))
            self._serving.add(task)
            task.add_done_callback(self._serving.discard)
        elif op == "status":
            logger.info("rosbridge status: %s", frame.get("msg"))

    def _deliver(self, topic: Any, msg: Any) -> None:
        subscription = self._subscriptions.get(topic) if isinstance(topic, str) else None
        if subscription is None or not isinstance(msg, dict):
            return
        for callback in subscription.callbacks:
            try:
                callback(msg)
            except Exception:
                logger.exception("rosbridge: the callback of %s failed", topic)

    def _answered(self, frame: Json) -> None:
        future = self._calls.get(str(frame.get("id")))
        if future is None or future.done():
            return
        values = frame.get("values")
        if frame.get("result", True):
            # ROS service responses are messages (objects); anything else has no fields.
            future.set_result(values if isinstance(values, dict) else {})
        else:
            future.set_exception(ServiceError(str(values)))

    async def _serve(self, frame: Json) -> None:
        """Answer a call to one of our services, by id, under the name it was called by."""
        service = frame.get("service")
        declared = self._services.get(service) if isinstance(service, str) else None
        reply: Json = {"op": "service_response", "service": service, "id": frame.get("id")}
        try:
            if declared is None:
                raise ServiceError(f"{service} is not served here")
            values = declared[1](frame.get("args"))
            if inspect.isawaitable(values):
                values = await values
            reply.update(values=values, result=True)
        except Exception as error:  # the caller gets the reason, as rosbridge does
            reply.update(values=str(error), result=False)
        with contextlib.suppress(Exception):
            await self._send(reply)


def endpoints(server: str) -> tuple[str, str]:
    """``(http base, rosbridge URL)`` of a server given either way, e.g.
    ``http://h:8000`` -> ``("http://h:8000", "ws://h:8000/rosbridge")``."""
    parts = urlsplit(server if "//" in server else f"http://{server}")
    secure = parts.scheme in ("https", "wss")
    http = urlunsplit(("https" if secure else "http", parts.netloc, "", "", ""))
    path = parts.path.rstrip("/") if parts.scheme.startswith("ws") and parts.path else "/rosbridge"
    return http, urlunsplit(("wss" if secure else "ws", parts.netloc, path, "", ""))
