"""Scaled mode: a robot publishing on one server process is watched through another, by
MJPEG, VP8 and WebRTC (WHEP).

The relay on the viewer's process subscribes to the camera on its own topic bus, which
joins the topic's channel-layer group, so frames cross processes once per process; the
WebRTC encoder runs on the viewer's process.
"""

from __future__ import annotations

import asyncio

import pytest

from telemetry.domain.multipart import PartReader
from tests.fixtures_live import video_stats
from tests.support.camera_feed import Camera, camera_frames
from tests.support.http_stream import open_stream
from tests.support.webm_reader import WebmReader
from tests.support.whep_client import WhepRefused, WhepViewer

pytestmark = pytest.mark.scaled

TOPIC = "/r1/camera/image/compressed"
STAMP = 1_750_000_000.0


async def test_a_camera_on_one_process_streams_from_another(scaled_servers):
    cluster = scaled_servers(2)
    robot_side, viewer_side = cluster.servers
    cookie = cluster.cookies["viewer"]
    mjpeg = await open_stream(viewer_side.url, f"/stream?topic={TOPIC}", cookie)
    vp8 = await open_stream(viewer_side.url, f"/stream?topic={TOPIC}&type=vp8", cookie)
    assert (mjpeg.status, vp8.status) == (200, 200)
    camera = await Camera.connect(robot_side.rosbridge_url(cluster.tokens["r1"]))
    jpegs = camera_frames(160, 120, quality=90, count=5)
    parts, blocks = PartReader(), WebmReader()
    got_parts: list[bytes] = []
    got_blocks: list[object] = []

    async def read_mjpeg() -> None:
        while len(got_parts) < 3:
            got_parts.extend(p for _, p in parts.feed(await mjpeg.reader.read(2**16)))

    async def read_vp8() -> None:
        while len(got_blocks) < 3:
            got_blocks.extend(blocks.feed(await vp8.reader.read(2**16)))

    async def publish() -> None:
        # the viewer's process joins the group asynchronously: publish until frames arrive
        for i in range(200):
            await camera.send(jpegs[i % len(jpegs)], STAMP + i)
            await asyncio.sleep(0.05)

    publishing = asyncio.create_task(publish())
    try:
        async with asyncio.timeout(20):
            await asyncio.gather(read_mjpeg(), read_vp8())
    finally:
        publishing.cancel()
    assert set(got_parts) <= set(jpegs)  # the robot's own bytes, across processes
    for stream in (mjpeg, vp8):
        stream.close()
    await camera.close()


async def test_a_webrtc_viewer_on_one_process_watches_a_robot_on_another(scaled_servers):
    cluster = scaled_servers(2)
    robot_side, viewer_side = cluster.servers
    csrf = "c" * 32  # a session's POST carries Django's CSRF cookie and the same token
    headers = {"Cookie": f"{cluster.cookies['viewer']}; csrftoken={csrf}", "X-CSRFToken": csrf}
    camera = await Camera.connect(robot_side.rosbridge_url(cluster.tokens["r1"]))
    jpegs = camera_frames(320, 240, quality=85, count=30)

    async def publish() -> None:
        for i in range(10**6):
            await camera.send(jpegs[i % len(jpegs)])
            await asyncio.sleep(1 / 15)

    publishing = asyncio.create_task(publish())
    try:
        # The viewer's process learns of the camera from the channel layer: offer until
        # it knows the topic (404 before).
        viewer = None
        async with asyncio.timeout(20):
            while viewer is None:
                try:
                    viewer = await WhepViewer.open(viewer_side.url, f"topic={TOPIC}", headers)
                except WhepRefused as refused:
                    if refused.status != 404:
                        raise
                    await asyncio.sleep(0.2)
        sizes = []
        async with asyncio.timeout(20):
            async for frame in viewer.frames(20):
                sizes.append((frame.width, frame.height))
                if len(sizes) == 10:
                    break
        assert sizes == [(320, 240)] * 10
        # The encoder runs where the viewer is; the robot's process encodes nothing.
        assert await rtc_viewers(viewer_side.url, cluster.tokens["r1"]) == [1]
        assert await rtc_viewers(robot_side.url, cluster.tokens["r1"]) == []
        await viewer.close()
    finally:
        publishing.cancel()
        await camera.close()


async def rtc_viewers(url: str, token: str) -> list[int]:
    """The viewer counts of the WebRTC streams the server at ``url`` encodes."""
    stats = await asyncio.to_thread(video_stats, url, token)
    return [s["viewers"] for s in stats if s["type"].startswith("webrtc")]
