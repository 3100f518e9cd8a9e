"""WebRTC by WHEP over real HTTP and real UDP against daphne, with aiortc as the viewer.

A robot publishes JPEG frames at 30 Hz over rosbridge; viewers POST offers to
``/whep?topic=T`` and decode what they receive. Expected: pictures of the asked size in
VP8 and H.264; one encoder for all the viewers of one parameter set, stopped with the
last; DELETE ends a session; a viewer that vanishes is dropped within seconds; the
access rules of ``/stream``; offers beyond a client's share refused.
"""

from __future__ import annotations

import asyncio
import base64
import json
import sys
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Any

import httpx
import pytest
import websockets
from aiortc import RTCPeerConnection

from telemetry.domain.video import Frame
from telemetry.domain.webrtc import new_encoder, parse_whep_request
from tests.conftest import make_building, make_robot
from tests.fixtures_live import until, video_stats
from tests.support.camera_feed import Camera, camera_frames
from tests.support.whep_client import SDP, WhepRefused, WhepViewer

pytestmark = pytest.mark.django_db(transaction=True)

TOPIC = "/r1/camera/image/compressed"
WAIT = 20.0
RATE = 30.0
VIDEO_TYPE = "foxglove_msgs/CompressedVideo"


@dataclass
class Site:
    url: str
    rosbridge: str
    token: str
    units: list[bytes] = field(default_factory=list)  # an H.264 camera's access units

    @property
    def headers(self) -> dict[str, str]:
        return {"Authorization": f"Token {self.token}"}

    def rtc_streams(self) -> list[dict[str, Any]]:
        return [s for s in video_stats(self.url, self.token) if s["type"].startswith("webrtc")]


async def publish(
    site: Site, jpegs: list[bytes], image_format: str = "jpeg", rate: float = RATE
) -> None:
    camera = await Camera.connect(site.rosbridge)
    try:
        i = 0
        while True:
            await camera.send(jpegs[i % len(jpegs)], image_format=image_format)
            i += 1
            await asyncio.sleep(1 / rate)  # the camera's own rate
    finally:
        await camera.close()


@pytest.fixture
def jpegs() -> list[bytes]:
    return camera_frames(320, 240, quality=85, count=30)


@pytest.fixture
def tokens(daphne_servers) -> dict[str, str]:
    """r1 (the camera's robot) and r2, a robot of no building."""
    return {
        "r1": make_robot(name="r1", buildings=[make_building()])[1],
        "r2": make_robot(name="r2", buildings=[])[1],
    }


@pytest.fixture
async def site(daphne_servers, tokens, jpegs) -> AsyncIterator[Site]:
    token = tokens["r1"]
    server = await asyncio.to_thread(daphne_servers.start, {"CLOUDNAV_WHEP_PER_CLIENT": "4"})
    site = Site(server.url, server.rosbridge_url(token), token)
    camera = asyncio.create_task(publish(site, jpegs))
    yield site
    camera.cancel()


@pytest.fixture
async def h264_site(daphne_servers, tokens, jpegs) -> AsyncIterator[Site]:
    """A robot whose camera publishes H.264 (``format: h264``), a keyframe every 30 frames."""
    token = tokens["r1"]
    server = await asyncio.to_thread(daphne_servers.start)
    site = Site(server.url, server.rosbridge_url(token), token)
    params = parse_whep_request({"topic": TOPIC, "type": "h264"}).params
    encoder = new_encoder(params)
    units = [
        b"".join(bytes(p) for p in encoder.packets(Frame(jpeg, "jpeg", None, 0.0), i * 33))
        for i, jpeg in enumerate(jpegs)
    ]
    site.units = units
    camera = asyncio.create_task(publish(site, units, "h264"))
    yield site
    camera.cancel()


async def decoded(viewer: WhepViewer, count: int) -> list[tuple[int, int]]:
    sizes = []
    async with asyncio.timeout(WAIT):
        async for frame in viewer.frames(WAIT):
            sizes.append((frame.width, frame.height))
            if len(sizes) == count:
                return sizes
    raise AssertionError("the stream ended")


@pytest.mark.parametrize("codec", ["vp8", "h264"])
async def test_an_aiortc_viewer_decodes_the_camera_and_delete_ends_it(site, codec):
    viewer = await WhepViewer.open(
        site.url, f"topic={TOPIC}&type={codec}&width=160&height=120", site.headers
    )
    assert f"{codec.upper()}/90000" in viewer.answer.upper()
    assert "typ host" in viewer.answer
    assert await decoded(viewer, 10) == [(160, 120)] * 10
    [stream] = await asyncio.to_thread(site.rtc_streams)
    assert stream["type"] == f"webrtc/{codec}"
    assert stream["viewers"] == 1
    assert await viewer.delete() == 200
    await viewer.peer.close()
    await until(lambda: not site.rtc_streams(), "the encoder to stop", WAIT)
    assert await viewer.delete() == 404


async def test_a_session_that_ended_on_its_own_is_deleted_without_a_404(site):
    # A page changing its camera's mode DELETEs a session the server may have ended already
    # (the peer failed or left): that DELETE is done, not 404.
    viewer = await WhepViewer.open(site.url, f"topic={TOPIC}&type=vp8", site.headers)
    assert await decoded(viewer, 3) == [(320, 240)] * 3
    await viewer.peer.close()  # the viewer's peer leaves first, with no DELETE
    await until(lambda: not site.rtc_streams(), "the server to end the session", WAIT)
    assert await viewer.delete() == 200
    assert await viewer.delete() == 404  # once: it is gone now


async def test_an_h264_camera_is_relayed_without_decoding(h264_site):
    site = h264_site
    viewer = await WhepViewer.open(site.url, f"topic={TOPIC}&type=h264", site.headers)
    assert await decoded(viewer, 10) == [(320, 240)] * 10
    [stream] = await asyncio.to_thread(site.rtc_streams)
    assert stream["encoder_cpu"] == 0
    await viewer.close()


async def publish_compressed_video(site: Site, units: list[bytes]) -> None:
    """A camera that encodes H.264 itself, as Foxglove's ``CompressedVideo`` on a topic of
    its own choosing (``camera/video``, not the contract's image topic)."""
    async with websockets.connect(site.rosbridge, max_size=None) as ws:
        topic = {"topic": "camera/video"}
        await ws.send(json.dumps({"op": "advertise", **topic, "type": VIDEO_TYPE}))
        for i in range(10**6):
            now = time.time()
            msg = {
                "timestamp": {"sec": int(now), "nanosec": int(now % 1 * 1e9)},
                "frame_id": "camera",
                "data": base64.b64encode(units[i % len(units)]).decode(),
                "format": "h264",
            }
            await ws.send(json.dumps({"op": "publish", **topic, "msg": msg}))
            await asyncio.sleep(1 / RATE)


async def test_a_foxglove_compressed_video_camera_is_relayed_without_decoding(h264_site):
    site = h264_site
    units = h264_site.units
    camera = asyncio.create_task(publish_compressed_video(site, units))
    viewer = None
    async with asyncio.timeout(WAIT):  # the topic is a camera once it is advertised
        while viewer is None:
            try:
                query = "topic=/r1/camera/video&type=h264"
                viewer = await WhepViewer.open(site.url, query, site.headers)
            except WhepRefused as refused:
                if refused.status != 404:
                    raise
                await asyncio.sleep(0.1)
    assert await decoded(viewer, 10) == [(320, 240)] * 10
    stream = next(s for s in await asyncio.to_thread(site.rtc_streams) if "video" in s["topic"])
    assert stream["encoder_cpu"] == 0
    await viewer.close()
    camera.cancel()


async def test_viewers_of_one_parameter_set_share_one_encoder(site):
    query = f"topic={TOPIC}&type=vp8&bitrate=300000"
    viewers = [await WhepViewer.open(site.url, query, site.headers) for _ in range(3)]
    results = await asyncio.gather(*(decoded(v, 10) for v in viewers))
    assert all(len(sizes) == 10 for sizes in results)
    [stream] = await asyncio.to_thread(site.rtc_streams)
    assert stream["viewers"] == 3
    assert stream["params"].startswith("webrtc/vp8 300kbit/s")
    for viewer in viewers[:2]:
        await viewer.close()
    [stream] = await asyncio.to_thread(site.rtc_streams)
    assert stream["viewers"] == 1
    await viewers[2].close()
    await until(lambda: not site.rtc_streams(), "the encoder to stop", WAIT)


async def test_a_viewer_of_a_slow_camera_sees_a_picture_within_seconds(
    daphne_servers, tokens, jpegs
):
    # 4 frames/s: the encoder's own keyframe comes every 60 frames, 15 s apart; a viewer
    # joining a running encoder must not wait for it (the browser's panel gives up at 8 s).
    server = await asyncio.to_thread(daphne_servers.start)
    site = Site(server.url, server.rosbridge_url(tokens["r1"]), tokens["r1"])
    camera = asyncio.create_task(publish(site, jpegs, rate=4.0))
    query = f"topic={TOPIC}&type=vp8"
    first = await WhepViewer.open(site.url, query, site.headers)
    assert len(await decoded(first, 2)) == 2
    for _ in range(3):  # each joins an encoder already running, between its keyframes
        late = await WhepViewer.open(site.url, query, site.headers)
        async with asyncio.timeout(4.0):
            assert len(await decoded(late, 1)) == 1
        await late.close()
    await first.close()
    camera.cancel()


VANISHING_VIEWER = """
import asyncio, json, os, sys
from tests.support.whep_client import WhepViewer
async def main():
    viewer = await WhepViewer.open(sys.argv[1], sys.argv[2], json.loads(sys.argv[3]))
    async for _ in viewer.frames(20):
        print("playing", flush=True)
        await asyncio.sleep(3600)
asyncio.run(main())
"""


async def test_a_viewer_that_vanishes_without_delete_is_dropped_within_seconds(site):
    query = f"topic={TOPIC}&type=vp8"
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-c",
        VANISHING_VIEWER,
        site.url,
        query,
        json.dumps(site.headers),
        stdout=asyncio.subprocess.PIPE,
    )
    assert process.stdout is not None
    try:
        line = await asyncio.wait_for(process.stdout.readline(), WAIT)
        assert line.strip() == b"playing"
        assert [s["viewers"] for s in await asyncio.to_thread(site.rtc_streams)] == [1]
    finally:
        process.kill()  # no DELETE, no DTLS goodbye: the peer is simply gone
        await process.wait()
    await until(lambda: not site.rtc_streams(), "the vanished viewer to be dropped", 10)


async def unanswered_offer(site: Site, query: str) -> int:
    """POST an offer whose peer then goes away before any ICE check: it never connects."""
    peer = RTCPeerConnection()
    peer.addTransceiver("video", direction="recvonly")
    await peer.setLocalDescription(await peer.createOffer())
    await peer.close()
    headers = {**site.headers, "Content-Type": SDP}
    return await post(site, query, headers, peer.localDescription.sdp)


async def test_an_offer_that_never_connects_releases_its_encoder(daphne_servers, tokens, jpegs):
    # one encoder per client, and a short wait for a peer to connect
    env = {"CLOUDNAV_VIDEO_ENCODER_PER_CLIENT": "1", "CLOUDNAV_WHEP_CONNECT_TIMEOUT": "2"}
    server = await asyncio.to_thread(daphne_servers.start, env)
    site = Site(server.url, server.rosbridge_url(tokens["r1"]), tokens["r1"])
    camera = asyncio.create_task(publish(site, jpegs))
    try:
        assert await unanswered_offer(site, f"topic={TOPIC}&type=vp8") == 201
        [ghost] = await asyncio.to_thread(site.rtc_streams)
        assert ghost["viewers"] == 1
        # its encoder holds the client's whole share meanwhile
        other = f"topic={TOPIC}&type=vp8&bitrate=300000"
        with pytest.raises(WhepRefused) as refused:
            await WhepViewer.open(site.url, other, site.headers)
        assert refused.value.status == 429
        await until(lambda: not site.rtc_streams(), "the unconnected session to be dropped", WAIT)
        viewer = await WhepViewer.open(site.url, other, site.headers)
        assert len(await decoded(viewer, 2)) == 2
        await viewer.close()
    finally:
        camera.cancel()


async def test_offers_beyond_the_clients_share_are_refused(site):
    viewers = [await WhepViewer.open(site.url, f"topic={TOPIC}", site.headers) for _ in range(4)]
    with pytest.raises(WhepRefused) as refused:
        await WhepViewer.open(site.url, f"topic={TOPIC}", site.headers)
    assert refused.value.status == 429
    for viewer in viewers:
        await viewer.close()


async def post(site: Site, query: str, headers: dict[str, str], body: str = "v=0\r\n") -> int:
    async with httpx.AsyncClient(base_url=site.url, timeout=WAIT) as http:
        answer = await http.post(f"/whep?{query}", content=body, headers=headers)
    return answer.status_code


async def test_it_answers_as_stream_does_to_bad_requests_and_strangers(site, tokens):
    sdp = {"Content-Type": SDP}
    other = tokens["r2"]
    assert await post(site, f"topic={TOPIC}", sdp) == 401
    assert await post(site, f"topic={TOPIC}", sdp | {"Authorization": "Token nope"}) == 401
    assert await post(site, f"topic={TOPIC}", sdp | {"Authorization": f"Token {other}"}) == 403
    assert await post(site, "topic=/r1/nothing", sdp | site.headers) == 404
    assert await post(site, f"topic={TOPIC}&type=av1", sdp | site.headers) == 404
    assert await post(site, f"topic={TOPIC}&bitrate=abc", sdp | site.headers) == 400
    assert await post(site, f"topic={TOPIC}", site.headers | {"Content-Type": "text/plain"}) == 415
    assert await post(site, f"topic={TOPIC}", sdp | site.headers, "not sdp") == 400
    assert not await asyncio.to_thread(site.rtc_streams)  # nothing left behind
