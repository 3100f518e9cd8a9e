"""A robot camera over rosbridge: camera-like JPEG frames and a publisher of them.

The client side, for tests and benchmarks: ``Camera`` publishes
``sensor_msgs/CompressedImage`` as a robot does, stamped with its send time, so a viewer
of ``/stream`` can measure each frame's delay.
"""

from __future__ import annotations

import base64
import json
import time
from typing import Any

import cbor2
import cv2
import numpy as np
import websockets


def camera_frames(
    width: int, height: int, quality: int, count: int = 150, seed: int = 7
) -> list[bytes]:
    """Return ``count`` JPEGs of a camera-like scene: a textured room with a moving object
    and sensor noise (drawn from ``seed``), so both codecs work as hard as on a real
    camera."""
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:height, 0:width]
    room = (110 + 60 * np.sin(xs / 37.0) * np.cos(ys / 23.0)).astype(np.float32)
    texture = rng.normal(0, 5, (height, width)).astype(np.float32)
    base = np.clip(np.dstack([room + texture, room * 0.9, room * 0.8 + texture]), 0, 255)
    base = base.astype(np.uint8)
    frames = []
    for i in range(count):
        image = base.copy()
        x = int(width / 2 + width / 3 * np.sin(2 * np.pi * i / count))
        cv2.circle(image, (x, height // 2), height // 6, (40, 60, 200), -1)
        cv2.putText(image, f"{i:03d}", (10, 30), cv2.FONT_HERSHEY_SIMPLEX, 1, (250, 250, 250), 2)
        noise = rng.normal(0, 1.5, image.shape)
        noisy = np.clip(image.astype(np.float32) + noise, 0, 255).astype(np.uint8)
        frames.append(cv2.imencode(".jpg", noisy, [cv2.IMWRITE_JPEG_QUALITY, quality])[1].tobytes())
    return frames


def image_message(jpeg: bytes, stamp: float, image_format: str = "jpeg") -> dict[str, Any]:
    """Return a ``sensor_msgs/CompressedImage`` (JPEG unless ``image_format`` says
    otherwise) stamped ``stamp`` (Unix seconds)."""
    sec = int(stamp)
    return {
        "header": {
            "frame_id": "camera",
            "stamp": {"sec": sec, "nanosec": int((stamp - sec) * 1e9)},
        },
        "format": image_format,
        "data": jpeg,
    }


class Camera:
    """A robot's camera publishing over rosbridge: JSON with base64 data, or CBOR frames
    with the bytes as they are (both are rosbridge's)."""

    def __init__(self, ws: websockets.ClientConnection, cbor: bool = False) -> None:
        self.ws = ws
        self.cbor = cbor

    @classmethod
    async def connect(cls, rosbridge_url: str, cbor: bool = False) -> Camera:
        """Connect (the URL carries the robot's token) and advertise the camera topic."""
        ws = await websockets.connect(rosbridge_url, compression=None, max_size=None)
        advertise = {"op": "advertise", "topic": "camera/image/compressed"}
        await ws.send(json.dumps({**advertise, "type": "sensor_msgs/CompressedImage"}))
        return cls(ws, cbor)

    async def send(
        self, jpeg: bytes, stamp: float | None = None, image_format: str = "jpeg"
    ) -> float:
        """Publish one frame; return its stamp (now, unless given)."""
        stamp = time.time() if stamp is None else stamp
        msg = image_message(jpeg, stamp, image_format)
        frame = {"op": "publish", "topic": "camera/image/compressed", "msg": msg}
        if self.cbor:
            await self.ws.send(cbor2.dumps(frame))
        else:
            msg["data"] = base64.b64encode(jpeg).decode("ascii")
            await self.ws.send(json.dumps(frame))
        return stamp

    async def close(self) -> None:
        await self.ws.close()
