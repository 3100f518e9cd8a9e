"""VP8 streams over real sockets against daphne: a live WebM that PyAV decodes, a viewer
who joins late and plays at once, one encoder shared by every viewer and stopped with the
last one."""

from __future__ import annotations

import asyncio
import io
import time
from typing import Any

import av
import pytest

from tests.fixtures_live import video_stats
from tests.support.camera_feed import Camera, camera_frames
from tests.support.http_stream import Stream, open_stream
from tests.support.webm_reader import WebmReader

pytestmark = pytest.mark.django_db(transaction=True)

TOPIC = "/r1/camera/image/compressed"
QUERY = f"/stream?topic={TOPIC}&type=vp8&gop=10"
WAIT = 10.0


@pytest.fixture(scope="module")
def jpegs() -> list[bytes]:
    return camera_frames(320, 240, quality=90, count=30)


def stats(url: str, token: str) -> list[dict[str, Any]]:
    return [s for s in video_stats(url, token, WAIT) if s["type"] == "vp8"]


class Recording:
    """Everything one viewer received, and the blocks in it as they arrived."""

    def __init__(self, stream: Stream) -> None:
        self.stream = stream
        self.data = bytearray()
        self.reader = WebmReader()
        self.blocks: list[Any] = []

    async def read_blocks(self, count: int) -> None:
        """Read until ``count`` more blocks arrived; fail after ``WAIT`` seconds."""
        wanted = len(self.blocks) + count
        async with asyncio.timeout(WAIT):
            while len(self.blocks) < wanted:
                data = await self.stream.reader.read(2**16)
                assert data, "the stream ended"
                self.data += data
                self.blocks += self.reader.feed(data)

    def decoded(self) -> list[av.VideoFrame]:
        with av.open(io.BytesIO(bytes(self.data)), mode="r") as container:
            return list(container.decode(video=0))


async def test_the_stream_is_a_live_webm_that_pyav_decodes(daphne_server, token, jpegs):
    stream = await open_stream(daphne_server.url, QUERY, token=token)
    assert stream.status == 200
    assert stream.headers["content-type"] == "video/webm"
    viewer = Recording(stream)
    camera = await Camera.connect(daphne_server.rosbridge_url(token))
    for jpeg in jpegs[:12]:
        await camera.send(jpeg)
        await viewer.read_blocks(1)  # each frame leaves as soon as it is encoded
    frames = viewer.decoded()
    assert len(frames) == 12
    assert (frames[0].width, frames[0].height) == (320, 240)
    assert viewer.blocks[0].keyframe
    assert viewer.reader.epoch == pytest.approx(time.time(), abs=30)
    stream.close()
    await camera.close()


async def test_a_late_joiner_plays_at_once_from_the_last_keyframe(daphne_server, token, jpegs):
    first = Recording(await open_stream(daphne_server.url, QUERY, token=token))
    camera = await Camera.connect(daphne_server.rosbridge_url(token))
    for jpeg in jpegs[:15]:  # keyframes at frames 0 and 10 (and at a gap a loaded machine
        await camera.send(jpeg)  # makes: a frame late by twice its interval is one)
        await first.read_blocks(1)
    last_keyframe = max(i for i, block in enumerate(first.blocks) if block.keyframe)
    interval = first.blocks[last_keyframe:]
    assert len(first.blocks) == 15
    assert 1 <= len(interval) <= 5

    # No frame is published while the late viewer joins: what it gets, it gets at once.
    late = Recording(await open_stream(daphne_server.url, QUERY, token=token))
    await late.read_blocks(len(interval))
    assert late.blocks[0].keyframe
    # The init segment and the last keyframe's interval: decodable from the start.
    assert len(late.decoded()) == len(interval)
    newest, count = first.blocks[-1].timestamp, len(interval)
    assert [b.timestamp for b in late.blocks] == [newest - count + 1 + i for i in range(count)]

    # Both viewers read one encoder, which encodes each frame once.
    [shared] = await asyncio.to_thread(stats, daphne_server.url, token)
    assert shared["viewers"] == 2
    await camera.send(jpegs[15])
    await asyncio.gather(first.read_blocks(1), late.read_blocks(1))
    assert first.blocks[-1] == late.blocks[-1]
    assert len(late.decoded()) == len(interval) + 1

    first.stream.close()
    late.stream.close()
    await camera.close()
    async with asyncio.timeout(WAIT):
        while await asyncio.to_thread(stats, daphne_server.url, token):  # noqa: ASYNC110
            await asyncio.sleep(0.05)  # the encoder stops with its last viewer


async def test_viewers_asking_other_settings_get_their_own_encoder(daphne_server, token, jpegs):
    low = Recording(await open_stream(daphne_server.url, QUERY + "&bitrate=50000", token=token))
    small = Recording(
        await open_stream(daphne_server.url, QUERY + "&width=160&height=120", token=token)
    )
    camera = await Camera.connect(daphne_server.rosbridge_url(token))
    await camera.send(jpegs[0])
    await asyncio.gather(low.read_blocks(1), small.read_blocks(1))
    assert (low.decoded()[0].width, small.decoded()[0].width) == (320, 160)
    encoders = await asyncio.to_thread(stats, daphne_server.url, token)
    assert sorted(s["params"] for s in encoders) == [
        "vp8 160x120 100kbit/s q10-42 gop=10",
        "vp8 50kbit/s q10-42 gop=10",
    ]
    for viewer in (low, small):
        viewer.stream.close()
    await camera.close()
