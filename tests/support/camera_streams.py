"""A camera stream opened against a live server with the robot's camera sending: ``watch``
waits until the first bytes of the stream came."""

from __future__ import annotations

import asyncio

import cv2
import numpy as np

from tests.support.camera_feed import Camera
from tests.support.http_stream import open_stream

TOPIC = "/r1/camera/image/compressed"


def jpeg() -> bytes:
    image = np.random.default_rng(1).integers(0, 256, (240, 320, 3), dtype=np.uint8)
    return bytes(cv2.imencode(".jpg", image)[1].tobytes())


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
