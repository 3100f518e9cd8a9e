"""MJPEG and ros_compressed streams and snapshots, over real sockets against daphne.

A robot publishes JPEG frames over rosbridge (JSON with base64, or CBOR with the bytes);
viewers read ``/stream`` as web_video_server's clients do and the body is parsed part by
part: its framing, each part's headers, and the robot's own bytes inside.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from typing import Any

import pytest

from telemetry.domain.jpeg import decode
from telemetry.domain.multipart import PartReader
from tests.conftest import make_building, make_robot
from tests.fixtures_live import until, video_stats
from tests.support.camera_feed import Camera, camera_frames
from tests.support.http_stream import Stream, open_stream

pytestmark = pytest.mark.django_db(transaction=True)

TOPIC = "/r1/camera/image/compressed"
STAMP = 1_750_000_000.0  # stamps a binary fraction apart print exactly with six decimals
WAIT = 10.0


@dataclass
class Site:
    """The live server, and the token of robot r1, which may watch its own camera."""

    url: str
    rosbridge: str
    token: str

    async def stream(self, query: str, path: str = "/stream") -> Stream:
        return await open_stream(self.url, f"{path}?{query}", token=self.token)

    def stats(self) -> list[dict[str, Any]]:
        return video_stats(self.url, self.token, WAIT)


@pytest.fixture
def site(daphne_server) -> Site:
    _, token = make_robot(name="r1", buildings=[make_building()])
    return Site(daphne_server.url, daphne_server.rosbridge_url(token), token)


@pytest.fixture(scope="module")
def jpegs() -> list[bytes]:
    return camera_frames(320, 240, quality=90, count=6)


async def read_parts(
    stream: Stream, reader: PartReader, count: int
) -> list[tuple[dict[str, str], bytes]]:
    """Read until ``count`` more parts are complete; fail after ``WAIT`` seconds."""
    parts: list[tuple[dict[str, str], bytes]] = []
    async with asyncio.timeout(WAIT):
        while len(parts) < count:
            data = await stream.reader.read(2**16)
            assert data, "the stream ended"
            parts += reader.feed(data)
    return parts


async def test_it_relays_the_robots_own_jpeg_bytes_part_by_part(site, jpegs):
    viewer = await site.stream(f"topic={TOPIC}&type=mjpeg")
    assert viewer.status == 200
    assert viewer.headers["content-type"] == "multipart/x-mixed-replace;boundary=boundarydonotcross"
    assert viewer.headers["cache-control"] == (
        "no-cache, no-store, must-revalidate, pre-check=0, post-check=0, max-age=0"
    )
    assert viewer.headers["pragma"] == "no-cache"
    assert await viewer.reader.readexactly(22) == b"--boundarydonotcross\r\n"
    camera = await Camera.connect(site.rosbridge)
    for i, jpeg in enumerate(jpegs):
        await camera.send(jpeg, STAMP + i / 4)
        head = await asyncio.wait_for(viewer.reader.readuntil(b"\r\n\r\n"), WAIT)
        assert head == (
            b"Content-type: image/jpeg\r\n"
            + f"X-Timestamp: {STAMP + i / 4:.6f}\r\n".encode()
            + f"Content-Length: {len(jpeg)}\r\n\r\n".encode()
        )
        assert await viewer.reader.readexactly(len(jpeg)) == jpeg  # not decoded, not changed
        assert await viewer.reader.readexactly(24) == b"\r\n--boundarydonotcross\r\n"
    viewer.close()
    await camera.close()


async def test_cbor_frames_carry_the_same_bytes(site, jpegs):
    viewer = await site.stream(f"topic={TOPIC}")
    reader = PartReader()
    camera = await Camera.connect(site.rosbridge, cbor=True)
    await read_parts(viewer, reader, 0)
    await camera.send(jpegs[0], STAMP)
    [(headers, payload)] = await read_parts(viewer, reader, 1)
    assert payload == jpegs[0]
    assert headers["x-timestamp"] == f"{STAMP:.6f}"
    viewer.close()
    await camera.close()


async def test_viewers_asking_the_same_size_and_quality_share_one_reencode(site, jpegs):
    query = f"topic={TOPIC}&quality=40&width=160&height=120"
    viewers = [await site.stream(query) for _ in range(2)]
    readers = [PartReader() for _ in viewers]
    camera = await Camera.connect(site.rosbridge)
    for i in range(3):
        await camera.send(jpegs[i], STAMP + i)
        got = [await read_parts(v, r, 1) for v, r in zip(viewers, readers, strict=True)]
        (headers, first), (_, second) = got[0][0], got[1][0]
        assert first == second  # encoded once, for both
        assert int(headers["content-length"]) == len(first) < len(jpegs[i])
        image = decode(first)
        assert image.shape == (120, 160, 3)
    streams = [s for s in await asyncio.to_thread(site.stats) if s["type"] == "mjpeg"]
    assert [(s["viewers"], s["params"]) for s in streams] == [(2, "mjpeg q=40 160x120")]
    assert streams[0]["encoder_cpu"] > 0
    for viewer in viewers:
        viewer.close()
    await camera.close()

    async def stopped() -> bool:
        return all(s["type"] == "source" for s in await asyncio.to_thread(site.stats))

    await until(stopped, "the re-encode to stop", WAIT)  # it stops with its last viewer


async def test_ros_compressed_takes_the_base_topic_as_web_video_server_does(site, jpegs):
    viewer = await site.stream("topic=/r1/camera/image&type=ros_compressed")
    reader = PartReader()
    camera = await Camera.connect(site.rosbridge)
    await read_parts(viewer, reader, 0)
    await camera.send(jpegs[1], STAMP)
    [(headers, payload)] = await read_parts(viewer, reader, 1)
    assert headers["content-type"] == "image/jpeg"
    assert payload == jpegs[1]
    viewer.close()
    await camera.close()


async def test_a_snapshot_is_the_next_frame_as_one_jpeg(site, jpegs):
    camera = await Camera.connect(site.rosbridge)

    async def keep_publishing() -> None:
        for i in range(100):
            await camera.send(jpegs[i % len(jpegs)], STAMP + i)
            await asyncio.sleep(0.05)

    publishing = asyncio.create_task(keep_publishing())
    snapshot = await site.stream(f"topic={TOPIC}&width=100&height=50", path="/snapshot")
    body = await asyncio.wait_for(snapshot.reader.read(), WAIT)
    publishing.cancel()
    assert snapshot.status == 200
    assert snapshot.headers["content-type"] == "image/jpeg"
    assert int(snapshot.headers["content-length"]) == len(body)
    assert float(snapshot.headers["x-timestamp"]) >= STAMP
    assert decode(body).shape == (50, 100, 3)
    await camera.close()
