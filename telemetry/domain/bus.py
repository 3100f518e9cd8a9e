"""The topic bus of one server process: topics, publishers, subscriptions and fan-out.

Semantics follow rosbridge_suite: a connection's subscriptions to one topic are merged
(lowest ``throttle_rate``, lowest ``queue_length``, smallest ``fragment_size``, CBOR if any
asked for it) and each ``id`` can be unsubscribed alone; publishing registers the publisher
(implicit advertise) when the topic's type is known; a latched topic's last message goes to
every new subscriber; a publisher subscribed to its own topic receives its own messages.

Each peer holds at most ``limits.subscriptions`` subscription requests and
``limits.advertisements`` advertisements (publishing on a topic counts as one), counted
when a request arrives, and the messages it latched, at most ``limits.latched_bytes``.

Fan-out encodes each message once per variant (see ``encoding``) and hands the result to
each peer's ``deliver``, which must not block: peers queue or drop, the bus never waits.

Taps are the one way for the server's own features (recording, mapping, map upkeep) to
read messages off the bus without being a connection. ``tap(topic, on_message)`` calls
``on_message(topic, msg)`` with every message of ``topic`` (an absolute name, or
``EVERY_TOPIC``) that the bus fans out here: published in this process (by a connection
or by the server), or received from another process for local subscribers. It returns a
``TopicTap``; ``close()`` ends it. ``msg`` is shared with every subscriber: read it, never
change it. ``on_message`` runs on the event loop for every message and must return at
once (copy what it needs, hand heavy work to a bounded queue); an exception it raises is
logged and the message still reaches everyone else. A tap is no subscription: it does not
make this process join a topic's group in scaled mode (a feature that needs another
process's messages, such as the video relay's camera feeds, subscribes as a peer).
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol

from telemetry.exceptions import LimitReached, TypeConflict, UnknownTopic

from .encoding import Outgoing, Variant, Wire
from .limits import ConnectionLimits, Holdings, check_room
from .names import canonical_type
from .protocol import Json, PublishFrame
from .timers import Cancellable, Scheduler

logger = logging.getLogger(__name__)


class Peer(Protocol):
    """A connection as the bus sees it."""

    @property
    def key(self) -> str: ...

    def deliver(self, wire: Wire) -> None:
        """Send or queue one encoded message; never blocks, never raises."""


class BusListener(Protocol):
    """What the bus tells the layer above (the scaled-mode relay) about local activity."""

    def published(self, topic: Topic, msg: dict[str, Json]) -> None: ...

    def interest(self, topic: str, interested: bool) -> None: ...

    def publishers_changed(self, topic: Topic) -> None:
        """The topic gained its first publisher here, or lost its last one."""


EVERY_TOPIC = None
"""``tap(EVERY_TOPIC, on_message)`` sees the messages of every topic (the recorder)."""

# on_message(topic, msg): one message of a tapped topic (see the module's docstring)
OnMessage = Callable[["Topic", dict[str, Json]], None]


class TopicTap:
    """One tap of the bus (``TopicBus.tap``): ``close`` ends it; closing again does nothing."""

    __slots__ = ("_taps", "on_message", "topic")

    def __init__(
        self, taps: dict[str | None, list[TopicTap]], topic: str | None, on_message: OnMessage
    ) -> None:
        self._taps = taps
        self.topic = topic
        self.on_message = on_message

    def close(self) -> None:
        listed = self._taps.get(self.topic)
        if listed is None or self not in listed:
            return
        listed.remove(self)
        if not listed:
            del self._taps[self.topic]


@dataclass(slots=True, frozen=True)
class SubscribeParams:
    throttle_rate: int = 0
    queue_length: int = 0
    fragment_size: int | None = None
    compression: str = "none"


class Subscription:
    """One peer's merged subscriptions to one topic, with rosbridge's throttle and queue.

    ``throttle_rate`` (ms) is the least time between two messages; with ``queue_length`` 0
    the messages in between are dropped, otherwise the newest ``queue_length`` wait and are
    released one per interval.
    """

    __slots__ = (
        "_queue",
        "_timer",
        "bus",
        "compression",
        "fragment_size",
        "last_sent",
        "peer",
        "queue_length",
        "requests",
        "spelling",
        "throttle",
        "variant",
    )

    def __init__(self, bus: TopicBus, peer: Peer, spelling: str) -> None:
        self.bus = bus
        self.peer = peer
        self.spelling = spelling
        self.requests: dict[Json, SubscribeParams] = {}
        self.throttle = 0.0
        self.queue_length = 0
        self.fragment_size: int | None = None
        self.compression = "none"
        self.variant: Variant = ("none", None, spelling)
        self.last_sent = float("-inf")
        self._queue: deque[Outgoing] = deque()
        self._timer: Cancellable | None = None

    def add(self, sid: Json, params: SubscribeParams) -> None:
        self.requests[sid] = params
        self._merge()

    def remove(self, sid: Json) -> bool:
        """Remove one request (all of them when ``sid`` is None); True if none is left."""
        if sid is None:
            self.requests.clear()
        else:
            self.requests.pop(sid, None)
        if self.requests:
            self._merge()
        else:
            self.close()
        return not self.requests

    def _merge(self) -> None:
        params = self.requests.values()
        self.throttle = min(p.throttle_rate for p in params) / 1000.0
        self.queue_length = min(p.queue_length for p in params)
        sizes = [p.fragment_size for p in params if p.fragment_size is not None]
        self.fragment_size = min(sizes) if sizes else None
        self.compression = "cbor" if any(p.compression == "cbor" for p in params) else "none"
        self.variant = (self.compression, self.fragment_size, self.spelling)
        self._queue = deque(self._queue, maxlen=self.queue_length or None)
        if self.throttle == 0:
            self._flush()

    def offer(self, out: Outgoing, now: float) -> None:
        """Send ``out`` now, drop it, or queue it, as the throttle and queue say."""
        if self.throttle == 0 or (now - self.last_sent >= self.throttle and not self._queue):
            # ``_send`` written out: this line runs once per subscriber per message
            self.last_sent = now
            self.peer.deliver(out.wire_of(self.variant))
        elif self.queue_length:
            self._queue.append(out)
            self._arm(now)

    def _send(self, out: Outgoing, now: float) -> None:
        self.last_sent = now
        self.peer.deliver(out.wire_of(self.variant))

    def _arm(self, now: float) -> None:
        if self._timer is None:
            delay = max(0.0, self.last_sent + self.throttle - now)
            self._timer = self.bus.scheduler(delay, self._release)

    def _release(self) -> None:
        self._timer = None
        if self._queue:
            self._send(self._queue.popleft(), self.bus.clock())
        if self._queue:
            self._arm(self.bus.clock())

    def _flush(self) -> None:
        now = self.bus.clock()
        while self._queue:
            self._send(self._queue.popleft(), now)

    def close(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self._queue.clear()


SubscriptionKey = tuple[str, str]  # (peer key, the topic as that peer spelled it)


class Topic:
    """A topic: its type, who publishes it, who subscribes, and its latched message."""

    __slots__ = ("last", "latched", "name", "publishers", "subscriptions", "type")

    def __init__(self, name: str, type_name: str | None) -> None:
        self.name = name
        self.type = type_name
        self.latched = False
        self.last: Outgoing | None = None
        self.publishers: dict[str, set[Json]] = {}
        self.subscriptions: dict[SubscriptionKey, Subscription] = {}

    def check_type(self, type_name: str | None) -> None:
        """Adopt ``type_name`` if the topic has none; raise TypeConflict if it differs."""
        if not type_name:
            return
        if self.type is None:
            self.type = type_name
        elif canonical_type(self.type) != canonical_type(type_name):
            raise TypeConflict(
                f"{self.name} is of type {self.type}, not {type_name}", op=None, id=None
            )

    @property
    def idle(self) -> bool:
        return not self.publishers and not self.subscriptions


class TopicBus:
    """All topics of this process.

    ``type_hint(name)`` gives the type of topics the server knows in advance (the fleet's),
    ``latch_hint(name)`` says which topics are latched whatever their publisher asks.
    """

    def __init__(
        self,
        scheduler: Scheduler,
        clock: Callable[[], float] = time.monotonic,
        type_hint: Callable[[str], str | None] = lambda _name: None,
        latch_hint: Callable[[str], bool] = lambda _name: False,
        limits: ConnectionLimits | None = None,
    ) -> None:
        self.scheduler = scheduler
        self.limits = limits or ConnectionLimits()
        self.clock = clock
        self.type_hint = type_hint
        self.latch_hint = latch_hint
        self.listener: BusListener | None = None
        self._taps: dict[str | None, list[TopicTap]] = {}  # by topic; None: every topic
        self._topics: dict[str, Topic] = {}
        self._peer_topics: dict[str, set[str]] = {}
        # per peer key: subscription requests and advertisements it holds
        self._subscriptions: dict[str, int] = {}
        self._advertisements: dict[str, int] = {}
        self._latched = Holdings(
            "latched messages", self.limits.advertisements, self.limits.latched_bytes
        )

    def get(self, name: str) -> Topic | None:
        return self._topics.get(name)

    def _topic(self, name: str, type_name: str | None, need_type: bool) -> Topic:
        topic = self._topics.get(name)
        if topic is None:
            known = type_name or self.type_hint(name)
            if known is None and need_type:
                raise UnknownTopic(f"{name} does not exist and no type was given")
            topic = self._topics[name] = Topic(name, self.type_hint(name) or known)
            topic.latched = self.latch_hint(name)
        topic.check_type(type_name)
        return topic

    def _claim(self, held: dict[str, int], peer: Peer, topic: Topic, what: str) -> None:
        """Count one more subscription request or advertisement of ``peer``.

        Raises LimitReached (and forgets ``topic`` if it was made for this) when the peer
        already holds as many as it may.
        """
        count = held.get(peer.key, 0)
        try:
            check_room(what, count, getattr(self.limits, what))
        except LimitReached:
            self._forget_if_idle(topic)
            raise
        held[peer.key] = count + 1

    def _remember(self, peer: Peer, name: str) -> None:
        self._peer_topics.setdefault(peer.key, set()).add(name)

    def advertise(
        self, peer: Peer, name: str, type_name: str, latch: bool = False, aid: Json = None
    ) -> Topic:
        """Register ``peer`` as a publisher of ``name``. Raises TypeConflict."""
        topic = self._topic(name, type_name, need_type=True)
        self._add_publisher(topic, peer, aid)
        topic.latched = topic.latched or latch
        return topic

    def _add_publisher(self, topic: Topic, peer: Peer, aid: Json) -> None:
        first = not topic.publishers
        ids = topic.publishers.get(peer.key)
        if ids is None or aid not in ids:
            self._claim(self._advertisements, peer, topic, "advertisements")
        topic.publishers.setdefault(peer.key, set()).add(aid)
        self._remember(peer, topic.name)
        if first and self.listener is not None:
            self.listener.publishers_changed(topic)

    def unadvertise(self, peer: Peer, name: str, aid: Json = None) -> None:
        """Withdraw one advertisement (all of the peer's when ``aid`` is None)."""
        topic = self._topics.get(name)
        if topic is None or peer.key not in topic.publishers:
            return
        ids = topic.publishers[peer.key]
        before = len(ids)
        if aid is None:
            ids.clear()
        else:
            ids.discard(aid)
        self._advertisements[peer.key] -= before - len(ids)
        if not ids:
            self._latched.release(peer.key, name)
            del topic.publishers[peer.key]
            self._after_publisher_left(topic)

    def publish(
        self,
        peer: Peer | None,
        name: str,
        msg: dict[str, Json],
        latch: bool = False,
        size: int = 0,
    ) -> Outgoing:
        """Publish ``msg`` from ``peer`` (None: the server itself) and fan it out.

        Registers the publisher if needed. ``size`` is the bytes of the frame that carried
        ``msg``: on a latched topic the message is kept, and counts against the peer's
        ``limits.latched_bytes``. Raises UnknownTopic if no one established the topic's
        type and the server does not know it, LimitReached past the peer's limits.
        """
        topic = self._topic(name, None, need_type=True)
        if peer is not None and peer.key not in topic.publishers:
            self._add_publisher(topic, peer, None)
        topic.latched = topic.latched or latch
        if topic.latched and peer is not None:
            self._latched.take(peer.key, name, size)
        out = Outgoing(PublishFrame(op="publish", topic=name, msg=msg))
        self.fan_out(topic, out)
        if self._taps:
            self._offer_taps(topic, msg)
        if self.listener is not None:
            self.listener.published(topic, msg)
        return out

    def fan_out(self, topic: Topic, out: Outgoing) -> None:
        """Hand ``out`` to every subscriber of ``topic``; remember it if the topic is latched."""
        if topic.latched:
            topic.last = out
        now = self.clock()
        for subscription in tuple(topic.subscriptions.values()):
            subscription.offer(out, now)

    def receive_remote(
        self, name: str, _type_name: str | None, msg: dict[str, Json], latched: bool
    ) -> None:
        """Fan out a message published on another server process to local subscribers."""
        topic = self._topics.get(name)
        if topic is None or not topic.subscriptions:
            return
        topic.latched = topic.latched or latched
        self.fan_out(topic, Outgoing(PublishFrame(op="publish", topic=name, msg=msg)))
        if self._taps:
            self._offer_taps(topic, msg)

    def tap(self, topic: str | None, on_message: OnMessage) -> TopicTap:
        """Call ``on_message(topic, msg)`` with every message of ``topic`` (``EVERY_TOPIC``:
        of all) fanned out here, until the tap returned is closed (see the module's
        docstring)."""
        tap = TopicTap(self._taps, topic, on_message)
        self._taps.setdefault(topic, []).append(tap)
        return tap

    def _offer_taps(self, topic: Topic, msg: dict[str, Json]) -> None:
        for key in (EVERY_TOPIC, topic.name):
            for tap in tuple(self._taps.get(key, ())):  # a tap may close itself meanwhile
                try:
                    tap.on_message(topic, msg)
                except Exception:
                    logger.exception("a tap of %s failed", topic.name)

    def subscribe(
        self,
        peer: Peer,
        name: str,
        type_name: str | None,
        params: SubscribeParams,
        sid: Json = None,
        spelling: str | None = None,
    ) -> bool:
        """Add a subscription request; return True if a latched message was replayed to it.

        ``spelling`` is the topic as the peer wrote it (default: ``name``); messages go to
        it under that name, and requests under different spellings are separate, as in
        rosbridge. Raises TypeConflict, or UnknownTopic when neither the topic nor its type
        is known.
        """
        topic = self._topic(name, type_name, need_type=True)
        key = (peer.key, spelling or name)
        subscription = topic.subscriptions.get(key)
        first = subscription is None
        if subscription is None or sid not in subscription.requests:
            self._claim(self._subscriptions, peer, topic, "subscriptions")
        if subscription is None:
            subscription = topic.subscriptions[key] = Subscription(self, peer, key[1])
            self._remember(peer, name)
        subscription.add(sid, params)
        if first and len(topic.subscriptions) == 1 and self.listener is not None:
            self.listener.interest(name, True)
        if topic.last is not None and first:
            subscription.offer(topic.last, self.clock())
            return True
        return False

    def unsubscribe(
        self, peer: Peer, name: str, sid: Json = None, spelling: str | None = None
    ) -> None:
        topic = self._topics.get(name)
        key = (peer.key, spelling or name)
        subscription = topic.subscriptions.get(key) if topic else None
        if topic is None or subscription is None:
            return
        before = len(subscription.requests)
        emptied = subscription.remove(sid)
        self._subscriptions[peer.key] -= before - len(subscription.requests)
        if emptied:
            del topic.subscriptions[key]
            self._after_subscriber_left(topic)

    def holdings(self, peer: Peer) -> list[tuple[str, str | None]]:
        """Return what ``peer`` holds: ``(topic, spelling)`` of each subscription, and
        ``(topic, None)`` of each topic it publishes."""
        held: list[tuple[str, str | None]] = []
        for name in self._peer_topics.get(peer.key, ()):
            topic = self._topics.get(name)
            if topic is None:
                continue
            held += [(name, key[1]) for key in topic.subscriptions if key[0] == peer.key]
            if peer.key in topic.publishers:
                held.append((name, None))
        return held

    def withdraw(self, peer: Peer, name: str, spelling: str | None) -> None:
        """End what ``peer`` holds on ``name``: the subscription of ``spelling``, or its
        publication when ``spelling`` is None (access to it was revoked)."""
        topic = self._topics.get(name)
        if topic is None:
            return
        if spelling is None:
            self.unadvertise(peer, name)
            return
        subscription = topic.subscriptions.pop((peer.key, spelling), None)
        if subscription is not None:
            self._subscriptions[peer.key] -= len(subscription.requests)
            subscription.close()
            self._after_subscriber_left(topic)

    def drop(self, peer: Peer) -> None:
        """Forget everything ``peer`` published or subscribed (it disconnected)."""
        self._subscriptions.pop(peer.key, None)
        self._advertisements.pop(peer.key, None)
        self._latched.drop(peer.key)
        for name in self._peer_topics.pop(peer.key, ()):
            topic = self._topics.get(name)
            if topic is None:
                continue
            mine = [key for key in topic.subscriptions if key[0] == peer.key]
            for key in mine:
                topic.subscriptions.pop(key).close()
            if mine:
                self._after_subscriber_left(topic)
            if topic.publishers.pop(peer.key, None) is not None:
                self._after_publisher_left(topic)

    def _after_subscriber_left(self, topic: Topic) -> None:
        if not topic.subscriptions and self.listener is not None:
            self.listener.interest(topic.name, False)
        self._forget_if_idle(topic)

    def _after_publisher_left(self, topic: Topic) -> None:
        if not topic.publishers:
            topic.last = None
            if self.listener is not None:
                self.listener.publishers_changed(topic)
        self._forget_if_idle(topic)

    def _forget_if_idle(self, topic: Topic) -> None:
        if topic.idle and self._topics.get(topic.name) is topic:
            del self._topics[topic.name]

    def published_topics(self) -> Iterator[tuple[str, str]]:
        """Yield ``(name, type)`` of every topic someone advertised or published here."""
        for topic in self._topics.values():
            if topic.publishers and topic.type:
                yield topic.name, topic.type
