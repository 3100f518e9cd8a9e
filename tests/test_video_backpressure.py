"""A viewer that reads slowly skips frames and never makes the server hold them for it,
and never delays the other viewers (over real sockets against daphne).

The slow viewer is a socket with a tiny receive buffer that stops reading; 60 MB of camera
frames then go through its stream while a healthy viewer reads every one.
"""

from __future__ import annotations

import asyncio

import cv2
import numpy as np
import psutil
import pytest

from telemetry.domain.multipart import PartReader
from tests.fixtures_live import video_stats
from tests.support.camera_feed import Camera
from tests.support.http_stream import Stream, open_stream

pytestmark = pytest.mark.django_db(transaction=True)

TOPIC = "/r1/camera/image/compressed"
FRAMES = 400
WINDOW = 4  # frames the robot keeps in flight to the healthy viewer
STAMP = 1_750_000_000.0


def noise_jpegs(count: int = 4) -> list[bytes]:
    """JPEGs of noise: about 150 kB each, so little goes far."""
    rng = np.random.default_rng(3)
    frames = [rng.integers(0, 256, (360, 480, 3), dtype=np.uint8) for _ in range(count)]
    return [
        bytes(cv2.imencode(".jpg", f, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()) for f in frames
    ]


def rss(pid: int) -> int:
    return int(psutil.Process(pid).memory_info().rss)


def skipped(url: str, token: str) -> int:
    return sum(s["frames_skipped"] for s in video_stats(url, token) if s["type"] == "mjpeg")


async def stamps(stream: Stream, reader: PartReader) -> list[float]:
    """Read once from ``stream``; return the stamps of the parts that completed."""
    return [float(h["x-timestamp"]) for h, _ in reader.feed(await stream.reader.read(2**20))]


async def stream_through(
    camera: Camera, healthy: Stream, reader: PartReader, jpegs: list[bytes]
) -> list[float]:
    """Publish ``FRAMES`` frames, at most ``WINDOW`` ahead of what the healthy viewer read
    (so any delay comes from the server, not from a backlog the test built); return the
    stamps the healthy viewer received."""
    received = list[float]()
    in_flight = asyncio.Semaphore(WINDOW)

    async def publish() -> None:
        for n in range(FRAMES):
            await in_flight.acquire()
            await camera.send(jpegs[n % len(jpegs)], STAMP + n)

    async def read() -> None:
        while len(received) < FRAMES:
            for stamp in await stamps(healthy, reader):
                received.append(stamp)
                in_flight.release()

    async with asyncio.timeout(120):
        await asyncio.gather(read(), publish())
    return received


async def test_a_slow_viewer_skips_frames_without_growing_the_servers_memory(daphne_server, token):
    server, jpegs = daphne_server, noise_jpegs()
    query = f"/stream?topic={TOPIC}&type=mjpeg"
    slow = await open_stream(server.url, query, token=token, receive_buffer=4096)
    healthy = await open_stream(server.url, query, token=token)
    camera = await Camera.connect(server.rosbridge_url(token))
    # one frame first, so the growth measured is not that of the first frame's allocations
    await camera.send(jpegs[0], STAMP - 1)
    reader = PartReader()
    async with asyncio.timeout(10):
        while not await stamps(healthy, reader):
            pass
    before = rss(server.process.pid)
    received = await stream_through(camera, healthy, reader, jpegs)
    grown = rss(server.process.pid) - before

    assert received == [STAMP + n for n in range(FRAMES)]  # the healthy viewer got every one
    assert grown < 30 * 2**20, f"server memory grew by {grown / 2**20:.1f} MiB"

    # Reading again, the slow viewer gets what its socket held, then the newest frame.
    slow_reader, seen = PartReader(), list[float]()
    async with asyncio.timeout(20):
        while not seen or seen[-1] != STAMP + FRAMES - 1:
            seen += await stamps(slow, slow_reader)
    assert len(seen) < FRAMES // 2
    # counted when the slow viewer took the newest frame over the ones it missed
    assert await asyncio.to_thread(skipped, server.url, token) > FRAMES // 2
    for stream in (slow, healthy):
        stream.close()
    await camera.close()
