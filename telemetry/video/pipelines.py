"""What one topic becomes for one parameter set, computed once for all its viewers.

- ``ImagePipeline`` (``mjpeg``, ``ros_compressed``, snapshots): each frame as a ready
  multipart part. Without ``quality``, ``width``, ``height`` or ``invert`` the robot's own
  JPEG bytes go out untouched; otherwise the frame is re-encoded once, in a worker thread.
- ``Vp8Pipeline`` (``vp8``): one libvpx encoder writing one live WebM stream
  (``telemetry.domain.webm.LiveWebm``) that every viewer reads from its own cursor.
- ``RtcPipeline`` (WebRTC, VP8 or H.264): one encoder whose newest packet every WHEP
  viewer's track sends as it is (``telemetry.video.webrtc``).

A pipeline takes only the newest frame whenever it is free: when encoding is slower than
the camera, frames are skipped, never queued. Encoders run in the relay's thread pool
(OpenCV and libvpx release the GIL), one frame at a time per pipeline, so the event loop
keeps serving rosbridge meanwhile; each pipeline stops when its last viewer leaves.
"""

from __future__ import annotations

import asyncio
import logging
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

import av

from telemetry.domain import jpeg, multipart
from telemetry.domain.newest import Closed, Newest
from telemetry.domain.video import (
    DEFAULT_QUALITY,
    MJPEG,
    BadFrame,
    Frame,
    StreamParams,
    Vp8Params,
)
from telemetry.domain.video_stats import StreamStats
from telemetry.domain.vp8 import MILLISECONDS, Vp8Encoder
from telemetry.domain.webm import EncodedFrame, FrameClock, LiveWebm
from telemetry.domain.webrtc import WEBRTC_H264, h264_keyframe, new_encoder
from telemetry.video.feeds import CameraFeed

if TYPE_CHECKING:
    from cloudnav_django.heavy import Ticket

logger = logging.getLogger(__name__)

T = TypeVar("T")
# A keyframe interval past this many bytes ends early: late joiners get at most this much.
MAX_INTERVAL_BYTES = 2 * 2**20
# A new pipeline starts from the feed's current frame if it is at most this old.
FRESH_FOR = 1.0
# At most one keyframe asked by a WebRTC pipeline's lagging viewers per second.
KEYFRAME_EVERY = 1.0


@dataclass(frozen=True, slots=True)
class Part:
    """One image ready to send: as a multipart part (``data``) and as it is (``payload``)."""

    frame: Frame
    payload: bytes
    content_type: str
    data: bytes


class Pipeline(ABC):
    """Base of both kinds: a task turning the feed's frames into output, and statistics."""

    def __init__(self, feed: CameraFeed, params: StreamParams, executor: Executor) -> None:
        self.feed = feed
        self.params = params
        self.executor = executor
        self.viewers = 0
        self.ticket: Ticket | None = None  # the encoder's share of the video budget
        self.stats = StreamStats(started=time.time())
        self._task: asyncio.Task[None] | None = None

    def start(self) -> None:
        self._task = asyncio.get_running_loop().create_task(self._run())

    def stop(self) -> None:
        """Stop the task; readers waiting on the output are told it is over."""
        if self._task is not None:
            self._task.cancel()

    async def _run(self) -> None:
        version = self._first_version()
        try:
            while True:
                version, frame = await self.feed.frames.newer(version)
                await self._take_safely(frame)
        except Closed:
            pass
        finally:
            self._closed()

    async def _take_safely(self, frame: Frame) -> None:
        """Take one frame; a failure loses that frame only, never the viewers' stream."""
        try:
            await self._take(frame)
        except Exception:
            logger.exception("video: %s (%s) dropped a frame", self.feed.topic, self.params.label())

    def _first_version(self) -> int:
        """Start from the feed's current frame if it is fresh, else from the next one."""
        frames = self.feed.frames
        fresh = frames.value is not None and time.time() - frames.value.received < FRESH_FOR
        return frames.version - 1 if fresh else frames.version

    @abstractmethod
    async def _take(self, frame: Frame) -> None:
        """Turn one frame into output; bad frames are logged and skipped."""

    @abstractmethod
    def _closed(self) -> None:
        """Tell the readers of the output that there will be no more."""

    async def _in_worker(self, work: Callable[[], T]) -> T | None:
        """Run ``work`` in the thread pool and account its CPU; None if the frame was bad."""

        def timed() -> tuple[T, float]:
            started = time.thread_time()
            return work(), time.thread_time() - started

        loop = asyncio.get_running_loop()
        try:
            result, cpu = await loop.run_in_executor(self.executor, timed)
        except BadFrame as error:
            logger.warning("video: %s: %s", self.feed.topic, error)
            return None
        self.stats.encoded(time.time(), cpu)
        return result


class ImagePipeline(Pipeline):
    """Each frame as a multipart part, untouched or re-encoded as JPEG."""

    def __init__(self, feed: CameraFeed, params: StreamParams, executor: Executor) -> None:
        super().__init__(feed, params, executor)
        self.output: Newest[Part] = Newest()

    async def _take(self, frame: Frame) -> None:
        if frame.content_type is None:  # H.264, which only the WebRTC relay passes on
            raise BadFrame(f"{frame.format} frames are relayed by WebRTC (/whep) only")
        payload = await self._payload(frame)
        if payload is None:
            return
        content_type = frame.content_type if self._untouched(frame) else "image/jpeg"
        assert content_type is not None  # feeds only take frames of image formats
        data = multipart.part(payload, content_type, frame.origin_time)
        self.output.put(Part(frame, payload, content_type, data))
        self.stats.produced(time.time(), len(data))

    def _untouched(self, frame: Frame) -> bool:
        """True if the robot's bytes go out as they are: always for ``ros_compressed``, and
        for ``mjpeg`` when nothing is asked of a JPEG."""
        if self.params.type != MJPEG:
            return True
        return self.params.image.untouched and frame.is_jpeg

    async def _payload(self, frame: Frame) -> bytes | None:
        if self._untouched(frame):
            return frame.data
        image = self.params.image
        return await self._in_worker(lambda: jpeg.reencode(frame.data, image, DEFAULT_QUALITY))

    def _closed(self) -> None:
        self.output.close()


class Vp8Pipeline(Pipeline):
    """One VP8 encoder and the live WebM stream it writes.

    ``appended`` changes each time frames were added to ``stream``; viewers wait on it and
    then read ``stream`` from their cursors.
    """

    def __init__(self, feed: CameraFeed, params: StreamParams, executor: Executor) -> None:
        super().__init__(feed, params, executor)
        assert params.vp8 is not None  # a vp8 stream always has its encoder settings
        self.encoder = Vp8Encoder(params.vp8, params.image)
        self.stream: LiveWebm | None = None
        self.appended: Newest[int] = Newest()
        self.clock = FrameClock()

    @property
    def vp8(self) -> Vp8Params:
        assert self.params.vp8 is not None
        return self.params.vp8

    async def _take(self, frame: Frame) -> None:
        timestamp, duration = self.clock.time_of(frame.received)
        if self.stream is not None and not self.stream.continues(timestamp):
            self.encoder.force_keyframe()  # players would drop it otherwise (see webm.py)
        encoded = await self._in_worker(lambda: self.encoder.encode(frame, timestamp, duration))
        if encoded:
            self._append(encoded)

    def _append(self, encoded: list[EncodedFrame]) -> None:
        if self.stream is None:
            assert self.encoder.size is not None  # set by the first encode
            self.stream = LiveWebm(*self.encoder.size, self.feed.topic, self.clock.epoch)
        for frame in encoded:
            cluster = self.stream.append(frame)
            self.stats.produced(time.time(), len(cluster))
        if self.stream.nbytes > MAX_INTERVAL_BYTES:
            self.encoder.force_keyframe()
        self.appended.put(self.stream.next)

    def _closed(self) -> None:
        self.appended.close()
        self.encoder.close()


class RtcPipeline(Pipeline):
    """One encoder whose packets every viewer's track sends; ``output`` holds the newest."""

    def __init__(self, feed: CameraFeed, params: StreamParams, executor: Executor) -> None:
        super().__init__(feed, params, executor)
        self.encoder = new_encoder(params)
        self.output: Newest[av.Packet[Any]] = Newest()
        self.epoch: float | None = None
        self._last_sent = 0.0
        self._last_key_asked = 0.0

    def ask_keyframe(self) -> None:
        """Make the next packet a keyframe, unless one was asked less than a second ago."""
        now = time.monotonic()
        if now - self._last_key_asked >= KEYFRAME_EVERY:
            self._last_key_asked = now
            self.encoder.force_keyframe()

    async def _take(self, frame: Frame) -> None:
        if (
            self.params.fps is not None
            and frame.received - self._last_sent < 0.95 / self.params.fps
        ):
            return
        self._last_sent = frame.received
        if self.epoch is None:
            self.epoch = frame.received
        stamp = int((frame.received - self.epoch) * 1000)
        if frame.is_h264:
            packets: list[av.Packet[Any]] | None = [self._passed_through(frame, stamp)]
        else:
            packets = await self._in_worker(lambda: self.encoder.packets(frame, stamp))
        for packet in packets or []:
            self.output.put(packet)
            self.stats.produced(time.time(), packet.size)

    def _passed_through(self, frame: Frame, stamp: int) -> av.Packet[Any]:
        """The robot's own H.264 access unit as a packet, never decoded. Raises BadFrame
        unless the stream asks for H.264 as the robot sends it."""
        if self.params.type != WEBRTC_H264 or not self.params.image.untouched:
            raise BadFrame("an H.264 camera is relayed as it is: ask type=h264, no width/height")
        packet = av.Packet(frame.data)
        packet.pts = stamp
        packet.time_base = MILLISECONDS
        packet.is_keyframe = h264_keyframe(frame.data)
        return packet

    def _closed(self) -> None:
        self.output.close()
        self.encoder.close()
