"""A camera topic as the video relay takes it off the topic bus: its newest frame only.

The feed subscribes to the topic on this process's bus like any rosbridge connection, so
scaled mode needs nothing more: the subscription makes this process join the topic's
channel-layer group, and a robot publishing on another process reaches it. The bus hands
the feed each message encoded as CBOR (a few microseconds for a camera frame, and shared
with any other CBOR subscriber); the feed decodes it and keeps the newest frame. Nothing
queues: a frame nobody took before the next one arrived is simply replaced.
"""

from __future__ import annotations

import logging
import time
from typing import Any

import cbor2

from telemetry.domain.bus import SubscribeParams, TopicBus
from telemetry.domain.encoding import Wire
from telemetry.domain.newest import Newest
from telemetry.domain.video import (
    COMPRESSED_IMAGE,
    COMPRESSED_VIDEO,
    BadFrame,
    Frame,
    frame_from_message,
)
from telemetry.domain.video_stats import StreamStats
from telemetry.exceptions import TypeConflict

logger = logging.getLogger(__name__)

_AS_CBOR = SubscribeParams(compression="cbor")


class CameraFeed:
    """The newest frame of one camera topic, while someone watches it.

    A peer of the topic bus (``key`` and ``deliver``); ``frames.version`` counts the frames
    taken, ``bad`` those that were not images.
    """

    def __init__(self, bus: TopicBus, topic: str) -> None:
        self.bus = bus
        self.topic = topic
        self.key = f"video:{topic}"
        self.frames: Newest[Frame] = Newest()
        self.stats = StreamStats(started=time.time())
        self.bad = 0

    def start(self) -> None:
        """Subscribe to the topic. Raises RosbridgeError (TypeConflict) if the topic is
        neither a compressed image topic nor a Foxglove compressed video topic."""
        try:
            self.bus.subscribe(self, self.topic, COMPRESSED_IMAGE, _AS_CBOR)
        except TypeConflict:
            self.bus.subscribe(self, self.topic, COMPRESSED_VIDEO, _AS_CBOR)

    def stop(self) -> None:
        """Unsubscribe; readers waiting for a frame are told it is over."""
        self.bus.drop(self)  # as a connection that closes: the bus forgets the peer too
        self.frames.close()

    def deliver(self, wire: Wire) -> None:
        """Take one published message (the bus calls this; it never raises)."""
        try:
            frame = frame_from_message(_message(wire))
        except (BadFrame, ValueError, KeyError, TypeError) as error:  # CBOR errors are ValueErrors
            self.bad += 1
            if self.bad == 1:
                logger.warning(
                    "video: %s carries something that is not an image: %s", self.topic, error
                )
            return
        self.frames.put(frame)
        self.stats.produced(frame.received, len(frame.data))


def _message(wire: Wire) -> dict[str, Any]:
    frame = cbor2.loads(wire.payloads[0])
    msg = frame["msg"]
    if not isinstance(msg, dict):
        raise BadFrame("a publish frame without a message")
    return msg
