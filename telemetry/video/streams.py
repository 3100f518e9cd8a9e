"""The bodies of the stream responses, one generator per viewer, and snapshots.

Each body holds its pipeline for as long as the response lasts (the relay stops encoders
that nobody reads) and writes only when the viewer's socket took the previous write
(``readiness``):

- MJPEG and ``ros_compressed``: the newest part each time, so a slow viewer skips frames;
- VP8: the init segment and the current keyframe interval first, then every new Cluster;
  a viewer too slow to keep the interval skips to the next keyframe (``LiveWebm.read``),
  because a VP8 frame without the ones before it cannot be decoded.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator, Mapping
from typing import Any, TypeVar

from cloudnav_django.heavy import Ticket
from cloudnav_django.readiness import Readiness, readiness_for
from telemetry.access.rules import Principal
from telemetry.domain import multipart
from telemetry.domain.newest import Closed, Newest
from telemetry.domain.video import MJPEG, NoFrame, StreamParams
from telemetry.video.cameras import Camera
from telemetry.video.pipelines import FRESH_FOR, ImagePipeline, Part, Vp8Pipeline
from telemetry.video.relay import VideoRelay

SNAPSHOT_TIMEOUT = 5.0


class Ended(Exception):
    """The stream's access was revoked (``Hub.watching``)."""


async def _until(work: Any, ended: asyncio.Event) -> Any:
    """Return what ``work`` (an awaitable) returns, unless ``ended`` is set first: then
    cancel it and raise Ended."""
    if ended.is_set():
        raise Ended
    task = asyncio.ensure_future(work)
    stop = asyncio.ensure_future(ended.wait())
    try:
        await asyncio.wait({task, stop}, return_when=asyncio.FIRST_COMPLETED)
    finally:
        stop.cancel()
        if not task.done():
            task.cancel()
    if not task.done() or task.cancelled():
        raise Ended
    return task.result()


T = TypeVar("T")


async def _newer(value: Newest[T], version: int, ended: asyncio.Event) -> tuple[int, T]:
    """``value.newer(version)`` unless ``ended`` is set first. When a newer version is
    there already it returns without a turn of the event loop, so a viewer that keeps up
    is never made to skip a frame by the wait itself."""
    if ended.is_set():
        raise Ended
    if value.version > version or value.closed:
        return await value.newer(version)
    result: tuple[int, T] = await _until(value.newer(version), ended)
    return result


async def _writable(readiness: Readiness, ended: asyncio.Event) -> None:
    """Return once the viewer's socket is ready (at once if it is), or raise Ended."""
    if ended.is_set():
        raise Ended
    if not readiness.ready():
        await _until(readiness.wait(), ended)


async def image_body(
    relay: VideoRelay,
    camera: Camera,
    params: StreamParams,
    scope: Mapping[str, Any],
    ticket: Ticket | None = None,
    principal: Principal | None = None,
) -> AsyncIterator[bytes]:
    """Yield a multipart body: the preamble, then the newest part whenever it can go.

    ``ticket`` is what ``relay.reserve`` took for a new encoder. The body ends when the
    access of ``principal`` to the camera is revoked."""
    readiness = readiness_for(scope)
    watcher = principal or Principal(label="", robot=None, buildings=frozenset())
    try:
        with relay.hub.review.watching(watcher, camera.robot, camera.robot_pk) as ended:
            async with relay.watch(camera.topic, params, ticket) as pipeline:
                assert isinstance(pipeline, ImagePipeline)
                yield multipart.preamble()
                async for part in _newest_parts(pipeline, readiness, ended):
                    yield part.data
    finally:
        readiness.close()


async def _newest_parts(
    pipeline: ImagePipeline, readiness: Readiness, ended: asyncio.Event
) -> AsyncIterator[Part]:
    output = pipeline.output
    version = 0
    while True:
        try:
            await _newer(output, version, ended)
            await _writable(readiness, ended)
        except (Closed, Ended):
            return
        # Frames that arrived while the socket was busy are skipped: take the newest.
        newest, part = output.version, output.value
        assert part is not None  # a version was put
        if version:
            pipeline.stats.skipped(newest - version - 1)
        version = newest
        times = [(part.frame.origin_time, part.frame.received)]
        pipeline.stats.sent(time.time(), times, len(part.data))
        yield part


async def webm_body(
    relay: VideoRelay,
    camera: Camera,
    params: StreamParams,
    scope: Mapping[str, Any],
    ticket: Ticket | None = None,
    principal: Principal | None = None,
) -> AsyncIterator[bytes]:
    """Yield a live WebM body: a start the viewer can decode at once, then new Clusters.

    ``ticket`` is what ``relay.reserve`` took for a new encoder. The body ends when the
    access of ``principal`` to the camera is revoked."""
    readiness = readiness_for(scope)
    watcher = principal or Principal(label="", robot=None, buildings=frozenset())
    try:
        with relay.hub.review.watching(watcher, camera.robot, camera.robot_pk) as ended:
            async with relay.watch(camera.topic, params, ticket) as pipeline:
                assert isinstance(pipeline, Vp8Pipeline)
                # An empty write sends the response headers now (daphne sends them with
                # the first body bytes), so the viewer's player sets up before the first
                # frame.
                yield b""
                async for data in _clusters(pipeline, readiness, ended):
                    yield data
    finally:
        readiness.close()


async def _clusters(
    pipeline: Vp8Pipeline, readiness: Readiness, ended: asyncio.Event
) -> AsyncIterator[bytes]:
    version = 0
    cursor: int | None = None
    while True:
        try:
            version, _ = await _newer(pipeline.appended, version, ended)
            await _writable(readiness, ended)
        except (Closed, Ended):
            return
        stream = pipeline.stream
        assert stream is not None  # frames were appended
        chunk = stream.join() if cursor is None else stream.read(cursor)
        cursor = chunk.cursor
        if chunk.data:
            pipeline.stats.skipped(chunk.skipped)
            times = [(f.origin, f.received) for f in chunk.frames]
            pipeline.stats.sent(time.time(), times, len(chunk.data))
            yield chunk.data


async def snapshot(relay: VideoRelay, camera: Camera, params: StreamParams) -> Part:
    """Return the camera's newest image if it is fresh, else the next one.

    Shares the MJPEG pipeline of the same parameters with any viewer. Raises NoFrame when
    no frame arrives within ``SNAPSHOT_TIMEOUT`` seconds.
    """
    image_params = StreamParams(MJPEG, params.image)
    async with relay.watch(camera.topic, image_params) as pipeline:
        assert isinstance(pipeline, ImagePipeline)
        output = pipeline.output
        current = output.value
        if current is not None and time.time() - current.frame.received < FRESH_FOR:
            return current
        try:
            async with asyncio.timeout(SNAPSHOT_TIMEOUT):
                return (await output.newer(output.version))[1]
        except (TimeoutError, Closed):
            raise NoFrame(f"no frame arrived on {camera.topic}") from None
