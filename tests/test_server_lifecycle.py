"""The server's life: a viewer leaving a stream, and SIGTERM with streams open, leave no
traceback (over real sockets against daphne)."""

from __future__ import annotations

import asyncio
import signal

import cv2
import numpy as np
import pytest

from tests.conftest import make_building, make_robot
from tests.support.camera_feed import Camera
from tests.support.http_stream import open_stream

pytestmark = pytest.mark.django_db(transaction=True)

TOPIC = "/r1/camera/image/compressed"


def jpeg() -> bytes:
    image = np.random.default_rng(1).integers(0, 256, (240, 320, 3), dtype=np.uint8)
    return bytes(cv2.imencode(".jpg", image)[1].tobytes())


@pytest.fixture
def token() -> str:
    return make_robot(name="r1", buildings=[make_building()])[1]


async def watch(server, token: str, kind: str):
    """Open a ``kind`` stream of the camera, with the camera sending, until a byte came."""
    camera = await Camera.connect(server.rosbridge_url(token))
    stream = await open_stream(server.url, f"/stream?topic={TOPIC}&type={kind}", token=token)
    async with asyncio.timeout(15):
        while not await asyncio.wait_for(_sent_and_read(camera, stream), 1.0):
            pass
    return camera, stream


async def _sent_and_read(camera, stream) -> bool:
    await camera.send(jpeg())
    try:
        return bool(await asyncio.wait_for(stream.reader.read(4096), 0.3))
    except TimeoutError:
        return False


@pytest.mark.parametrize("kind", ["mjpeg", "vp8"])
async def test_a_viewer_leaving_a_stream_logs_no_traceback(daphne_server, token, kind):
    camera, stream = await watch(daphne_server, token, kind)
    stream.close()
    for _ in range(10):  # frames after the viewer left: the stream notices and ends
        await camera.send(jpeg())
        await asyncio.sleep(0.05)
    await camera.close()
    await asyncio.sleep(0.5)
    assert "Traceback" not in daphne_server.log()


@pytest.mark.parametrize("kind", ["mjpeg", "vp8"])
async def test_sigterm_with_a_stream_open_exits_cleanly(daphne_server, token, kind):
    camera, stream = await watch(daphne_server, token, kind)
    daphne_server.process.send_signal(signal.SIGTERM)
    code = await asyncio.to_thread(daphne_server.process.wait, 15)
    stream.close()
    await camera.close()
    log = daphne_server.log()
    assert code == 0, log
    assert "Traceback" not in log
    assert "Segmentation fault" not in log
