"""The video relay of one server process: camera feeds and pipelines, counted by viewer.

``watch(topic, params)`` gives a viewer the pipeline of that topic and parameter set,
starting it (and the topic's feed) for the first viewer; leaving stops the pipeline with
its last viewer and unsubscribes the feed with its last pipeline. So a camera nobody
watches costs nothing, and two viewers asking the same thing share one encoder.

An encoder is heavy work: before answering, a view ``reserve``s what a new one would need
from the video budget (``cloudnav_django.heavy``), and is refused with 429 or 503 beyond it;
the pipeline holds that ticket until it stops.

The encoding threads are the process's, shared by the relays of every event loop, and
started with the server (``start_encoders``, from ``cloudnav_web.background``).
"""

from __future__ import annotations

import asyncio
import time
import weakref
from collections.abc import AsyncIterator
from concurrent.futures import Executor
from contextlib import asynccontextmanager
from typing import Any

from cloudnav_core.workers import Pool, Started
from cloudnav_django.heavy import Ticket, video_budget
from telemetry.domain.video import SOURCE, VP8, StreamParams, encoder_memory
from telemetry.domain.webrtc import MIME_TYPES
from telemetry.rosbridge.hub import Hub, get_hub
from telemetry.video.feeds import CameraFeed
from telemetry.video.pipelines import ImagePipeline, Pipeline, RtcPipeline, Vp8Pipeline

# Encoding threads; libvpx and OpenCV release the GIL, and the machines have two cores.
WORKERS = 2


class VideoRelay:
    """Feeds by topic and pipelines by ``(topic, params)`` for this process's viewers."""

    def __init__(self, hub: Hub, executor: Executor) -> None:
        self.hub = hub
        self.executor = executor
        self.feeds: dict[str, CameraFeed] = {}
        self.pipelines: dict[tuple[str, StreamParams], Pipeline] = {}

    def reserve(self, topic: str, params: StreamParams, client: str) -> Ticket | None:
        """Take from the video budget what a new encoder of ``params`` needs; None if a
        pipeline already serves them or they need no encoder. Raises Overloaded."""
        need = encoder_memory(params)
        if need == 0 or (topic, params) in self.pipelines:
            return None
        return video_budget().take(client, need)

    @asynccontextmanager
    async def watch(
        self, topic: str, params: StreamParams, ticket: Ticket | None = None
    ) -> AsyncIterator[Pipeline]:
        """Yield the pipeline serving ``params`` on ``topic`` for as long as it is watched.

        A new pipeline takes over ``ticket`` (from ``reserve``) until it stops; an existing
        one needs none, and the ticket is given back. Raises RosbridgeError (TypeConflict) if
        ``topic`` carries another message type.
        """
        pipeline = self._acquire(topic, params, ticket)
        try:
            yield pipeline
        finally:
            self._release(topic, pipeline)

    def _acquire(self, topic: str, params: StreamParams, ticket: Ticket | None) -> Pipeline:
        pipeline = self.pipelines.get((topic, params))
        if pipeline is None:
            feed = self._feed(topic)
            kind = _pipeline_kind(params)
            pipeline = self.pipelines[(topic, params)] = kind(feed, params, self.executor)
            pipeline.ticket = ticket.handover() if ticket is not None else None
            pipeline.start()
            ticket = None
        if ticket is not None:
            ticket.release()
        pipeline.viewers += 1
        return pipeline

    def _feed(self, topic: str) -> CameraFeed:
        feed = self.feeds.get(topic)
        if feed is None:
            feed = CameraFeed(self.hub.bus, topic)
            feed.start()
            self.feeds[topic] = feed
        return feed

    def _release(self, topic: str, pipeline: Pipeline) -> None:
        pipeline.viewers -= 1
        if pipeline.viewers > 0:
            return
        del self.pipelines[(topic, pipeline.params)]
        pipeline.stop()
        if pipeline.ticket is not None:
            pipeline.ticket.release()
        if not any(key[0] == topic for key in self.pipelines):
            self.feeds.pop(topic).stop()

    def stats(self) -> list[dict[str, Any]]:
        """Return the figures of every stream (busiest first for each topic), then of every
        feed: the camera's frames as published, before any relay."""
        now = time.time()
        streams = [
            _entry(topic, pipeline.params.type, pipeline.params.label(), pipeline.viewers)
            | pipeline.stats.snapshot(now)
            for (topic, _), pipeline in self.pipelines.items()
        ]
        streams.sort(key=lambda s: (s["topic"], -s["viewers"], s["type"]))
        sources = [
            _entry(topic, SOURCE, "as published", 0)
            | feed.stats.snapshot(now)
            | {"frames_bad": feed.bad}
            for topic, feed in self.feeds.items()
        ]
        return streams + sources


def _pipeline_kind(params: StreamParams) -> type[Pipeline]:
    if params.type in MIME_TYPES:
        return RtcPipeline
    return Vp8Pipeline if params.type == VP8 else ImagePipeline


def _entry(topic: str, kind: str, params: str, viewers: int) -> dict[str, Any]:
    return {"topic": topic, "type": kind, "params": params, "viewers": viewers}


_relays: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, VideoRelay] = (
    weakref.WeakKeyDictionary()
)
_encoders: Started[Pool] = Started("video encoding")


def start_encoders() -> Pool:
    """Make the process's encoding threads, once (a registered pool: stopped and joined
    at the end; its threads start with the first frame to encode); return them."""
    return _encoders.start(lambda: Pool("video", WORKERS))


async def get_video_relay() -> VideoRelay:
    """Return this process's relay (one per event loop, on its hub), creating it first.
    Raises NotStarted before ``start_encoders``."""
    loop = asyncio.get_running_loop()
    relay = _relays.get(loop)
    if relay is None:
        encoders = _encoders.get()
        hub = await get_hub()
        relay = _relays.setdefault(loop, VideoRelay(hub, encoders.executor))
    return relay
