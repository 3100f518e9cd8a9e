"""WebRTC (WHEP) glass-to-glass: a camera stamping a time code, aiortc viewers reading it.

A scratch server is started (seeded with robot ``b0``); the robot publishes 640x480 JPEG
frames at 30 Hz, each stamped with the wall-clock time code of ``telemetry.domain.timecode``
just before it is encoded; ``--viewers`` aiortc viewers open ``/whep`` and one of them
reads the code from every decoded picture. Prints one JSON object: delay p50/p95 (camera
clock to decoded picture), frames decoded per second, and from the relay's statistics
the bytes per second each viewer is sent and the encoder's share of a core.

Not yet measured here: MJPEG and VP8 over MSE read back in Chromium (the browser reader).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import time
import urllib.request
from typing import Any

import cv2

from benchmarks.rosbridge import Server, start_server
from benchmarks.video import ROBOT, TOPIC
from telemetry.domain import timecode
from telemetry.domain.camera_feed import Camera, camera_frames
from telemetry.domain.jpeg import decode
from telemetry.domain.video_stats import percentile
from telemetry.domain.whep_client import WhepViewer


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=0, help="accepted for the common interface")
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    parser.add_argument("--viewers", type=int, default=1)
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--warmup", type=float, default=3.0)
    parser.add_argument("--codec", default="vp8", choices=["vp8", "h264"])
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--rate", type=float, default=30.0)


def run(options: dict[str, Any]) -> None:
    with start_server(1, ["LOG_LEVEL=WARNING", "CLOUDNAV_WHEP_PER_CLIENT=64"]) as server:
        result = asyncio.run(measure(server, options))
    print(json.dumps(result))


async def publish(server: Server, options: dict[str, Any]) -> None:
    images = [decode(j) for j in camera_frames(options["width"], options["height"], 80, 60)]
    camera = await Camera.connect(f"{server.url}?token={server.tokens[ROBOT]}")
    try:
        due = time.time()
        for i in range(10**9):
            await asyncio.sleep(max(0.0, due - time.time()))
            image = images[i % len(images)].copy()
            now = time.time()
            timecode.stamp(image, int(now * 1000))
            jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])[1].tobytes()
            await camera.send(jpeg, now)
            due += 1.0 / options["rate"]
    finally:
        await camera.close()


async def measure(server: Server, options: dict[str, Any]) -> dict[str, Any]:
    camera = asyncio.create_task(publish(server, options))
    headers = {"Authorization": f"Token {server.tokens[ROBOT]}"}
    query = f"topic={TOPIC}&type={options['codec']}"
    viewers = [
        await WhepViewer.open(server.origin, query, headers) for _ in range(options["viewers"])
    ]
    others = [asyncio.create_task(_drain(v)) for v in viewers[1:]]
    delays, shown = await _read(viewers[0], options)
    stats = _stats(server, headers)
    for task in [camera, *others]:
        task.cancel()
    for viewer in viewers:
        await viewer.close()
    return {
        "benchmark": "webrtc",
        "codec": options["codec"],
        "size": f"{options['width']}x{options['height']}",
        "camera_hz": options["rate"],
        "viewers": options["viewers"],
        "delay_p50_ms": percentile(delays, 50),
        "delay_p95_ms": percentile(delays, 95),
        "frames_per_s": shown / options["duration"],
        "bytes_per_s_per_viewer": stats["kB_per_s"] * 1000 if stats else None,
        "encoder_cpu_core": stats["encoder_cpu"] if stats else None,
    }


async def _read(viewer: WhepViewer, options: dict[str, Any]) -> tuple[list[float], int]:
    delays: list[float] = []
    shown = 0
    started = time.monotonic()
    async for frame in viewer.frames(20):
        elapsed = time.monotonic() - started
        if elapsed > options["warmup"] + options["duration"]:
            break
        if elapsed < options["warmup"]:
            continue
        shown += 1
        try:
            stamped = timecode.read(frame.to_ndarray(format="bgr24"))
        except timecode.NoTimecode:
            continue
        delays.append(float(timecode.delay_ms(stamped, int(time.time() * 1000))))
    return delays, shown


async def _drain(viewer: WhepViewer) -> None:
    async for _ in viewer.frames(60):
        pass


def _stats(server: Server, headers: dict[str, str]) -> dict[str, Any] | None:
    request = urllib.request.Request(server.origin + "/api/video/stats", headers=headers)
    with urllib.request.urlopen(request, timeout=10) as response:
        streams = json.load(response)["streams"]
    return next((s for s in streams if s["type"].startswith("webrtc")), None)
