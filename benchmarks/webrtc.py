"""Glass-to-glass delay of WebRTC, MJPEG and VP8 over MSE, read back in Chromium.

A scratch server is started (seeded with robot ``b0``); the robot publishes 640x480 JPEG
frames at 30 Hz (quality 80), each stamped with the wall-clock time code of
``cloudnav_core.timecode`` just before it is encoded. For each stream type in turn
(``--types``), Chromium (Debian's, through Playwright) opens ``/stream_viewer`` of that
type and ``static/js/timecode.js`` reads the code from every picture the page shows (the
``<video>`` at each frame's expected display time, the MJPEG ``<img>`` once per animation
frame) and compares it with the clock. WebRTC and VP8 are both asked for 800 kbit/s
(the WHEP default), MJPEG passes the camera's own JPEG on. ``--viewers N`` adds N-1
viewers that only receive (aiortc for WebRTC, HTTP readers for the others), to load the
encoder as N people would; one browser measures. With ``--client aiortc`` an aiortc
viewer reads the code instead of Chromium (WebRTC only: a client with no jitter buffer).

Prints per type: delay p50/p95 (camera clock to the picture shown), pictures shown per
second, and from the relay's statistics the bytes per second each viewer is sent and the
encoder's share of a core (``--json``: one JSON object with a row per type).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import time
import urllib.request
from collections.abc import AsyncIterator
from typing import Any

import cv2
from playwright.async_api import Page, async_playwright

from benchmarks.rosbridge import Server, start_server
from benchmarks.video import ROBOT, TOPIC
from cloudnav_core import timecode
from telemetry.domain.jpeg import decode
from telemetry.domain.video_stats import percentile
from tests.support.camera_feed import Camera, camera_frames
from tests.support.http_stream import open_stream
from tests.support.whep_client import WhepViewer

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
BITRATE = 800_000  # bit/s, WebRTC's default, asked of the VP8 relay too
# The viewer page's query per type, and what the relay's statistics call that stream.
PAGES = {
    "webrtc": (f"type=webrtc&bitrate={BITRATE}", "webrtc/vp8"),
    "mjpeg": ("type=mjpeg", "mjpeg"),
    "vp8": (f"type=vp8&bitrate={BITRATE}", "vp8"),
    "webrtc-h264": (f"type=webrtc&codec=h264&bitrate={BITRATE}", "webrtc/h264"),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=0, help="accepted for the common interface")
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    parser.add_argument(
        "--types", default="webrtc,mjpeg,vp8", help="of webrtc, mjpeg, vp8, webrtc-h264"
    )
    parser.add_argument("--client", default="chromium", choices=["chromium", "aiortc"])
    parser.add_argument("--viewers", type=int, default=1, help="one measures, the rest receive")
    parser.add_argument("--duration", type=float, default=20.0, help="s measured per type")
    parser.add_argument("--warmup", type=float, default=3.0, help="s shown before measuring")
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--rate", type=float, default=30.0)


def run(options: dict[str, Any]) -> None:
    types = [t for t in options["types"].split(",") if t]
    unknown = set(types) - set(PAGES)
    if unknown or (options["client"] == "aiortc" and types != ["webrtc"]):
        raise SystemExit(f"--types: {sorted(unknown) or types} (aiortc measures webrtc only)")
    with start_server(1, ["LOG_LEVEL=WARNING", "CLOUDNAV_WHEP_PER_CLIENT=64"]) as server:
        result = asyncio.run(measure(server, options, types))
    print(json.dumps(result) if options["json"] else table(result))


def table(result: dict[str, Any]) -> str:
    """The rows as a table a person reads."""
    head = (
        f"{result['client']}, {result['size']} at {result['camera_hz']:g} Hz, "
        f"{result['viewers']} viewer(s)\n"
        "type         delay p50  delay p95  shown/s  kB/s/viewer  encoder core"
    )
    lines = [head]
    for row in result["rows"]:
        kbps = row["bytes_per_s_per_viewer"]
        cpu = row["encoder_cpu_core"]
        lines.append(
            f"{row['type']:<12} {row['delay_p50_ms']:>6} ms  {row['delay_p95_ms']:>6} ms  "
            f"{row['frames_per_s']:>7.1f}  {kbps / 1000 if kbps else 0:>11.1f}  "
            f"{cpu if cpu is not None else 0:>12.3f}"
        )
    return "\n".join(lines)


async def measure(server: Server, options: dict[str, Any], types: list[str]) -> dict[str, Any]:
    camera = asyncio.create_task(publish(server, options))
    try:
        if options["client"] == "aiortc":
            rows = [await _measure_aiortc(server, options)]
        else:
            rows = await _measure_chromium(server, options, types)
    finally:
        camera.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await camera
    return {
        "benchmark": "webrtc",
        "client": options["client"],
        "size": f"{options['width']}x{options['height']}",
        "camera_hz": options["rate"],
        "viewers": options["viewers"],
        "rows": rows,
    }


async def publish(server: Server, options: dict[str, Any]) -> None:
    """The robot's camera: stamped JPEG pictures at ``rate``, on the wall clock."""
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


# ---------------------------------------------------------------- Chromium


async def _measure_chromium(
    server: Server, options: dict[str, Any], types: list[str]
) -> list[dict[str, Any]]:
    name, value = server.cookie.split("=", 1)
    async with async_playwright() as playwright:
        browser = await playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        context = await browser.new_context()
        await context.add_cookies([{"name": name, "value": value, "url": server.origin}])
        rows = []
        for kind in types:
            async with _receivers(server, kind, options["viewers"] - 1):
                page = await context.new_page()
                rows.append(await _measure_page(server, page, kind, options))
                await page.close()
        await browser.close()
    return rows


async def _measure_page(
    server: Server, page: Page, kind: str, options: dict[str, Any]
) -> dict[str, Any]:
    query, stats_type = PAGES[kind]
    await page.goto(f"{server.origin}/stream_viewer?topic={TOPIC}&{query}")
    await page.wait_for_function("() => window.delayMeter?.count > 0", timeout=30_000)
    await asyncio.sleep(options["warmup"])
    first = await page.evaluate(
        "() => { window.delayMeter.record(); return window.delayMeter.count }"
    )
    await asyncio.sleep(options["duration"])
    delays, last = await page.evaluate(
        "() => [window.delayMeter.recording, window.delayMeter.count]"
    )
    if await page.evaluate("() => document.getElementById('stream').tagName") != "VIDEO" and (
        kind != "mjpeg"
    ):
        raise SystemExit(f"{kind}: the viewer page fell back to MJPEG")
    return _row(
        kind, [float(d) for d in delays], (last - first) / options["duration"], server, stats_type
    )


@contextlib.asynccontextmanager
async def _receivers(server: Server, kind: str, count: int) -> AsyncIterator[None]:
    """``count`` viewers of ``kind`` that only receive, for as long as the block runs."""
    query, stats_type = PAGES[kind]
    token = server.tokens[ROBOT]
    tasks = []
    for _ in range(count):
        if kind.startswith("webrtc"):
            headers = {"Authorization": f"Token {token}"}
            whep = f"topic={TOPIC}&type={stats_type.split('/')[1]}&bitrate={BITRATE}"
            viewer = await WhepViewer.open(server.origin, whep, headers)
            tasks.append(asyncio.create_task(_drain_whep(viewer)))
        else:
            stream = await open_stream(server.origin, f"/stream?topic={TOPIC}&{query}", token=token)
            tasks.append(asyncio.create_task(_drain_http(stream.reader)))
    try:
        yield
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)


async def _drain_whep(viewer: WhepViewer) -> None:
    try:
        async for _ in viewer.frames(60):
            pass
    finally:
        await viewer.close()


async def _drain_http(reader: asyncio.StreamReader) -> None:
    while await reader.read(2**16):
        pass


# ---------------------------------------------------------------- aiortc


async def _measure_aiortc(server: Server, options: dict[str, Any]) -> dict[str, Any]:
    headers = {"Authorization": f"Token {server.tokens[ROBOT]}"}
    async with _receivers(server, "webrtc", options["viewers"] - 1):
        viewer = await WhepViewer.open(server.origin, f"topic={TOPIC}&bitrate={BITRATE}", headers)
        try:
            delays, shown = await _read_aiortc(viewer, options)
        finally:
            await viewer.close()
        return _row("webrtc", delays, shown / options["duration"], server, "webrtc/vp8")


async def _read_aiortc(viewer: WhepViewer, options: dict[str, Any]) -> tuple[list[float], int]:
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


# ---------------------------------------------------------------- rows


def _row(
    kind: str, delays: list[float], shown_per_s: float, server: Server, stats_type: str
) -> dict[str, Any]:
    stats = _stats(server, stats_type)
    return {
        "type": stats_type if kind != "vp8" else "vp8/mse",
        "delay_p50_ms": _rounded(percentile(delays, 50)),
        "delay_p95_ms": _rounded(percentile(delays, 95)),
        "pictures_read": len(delays),
        "frames_per_s": round(shown_per_s, 2),
        "bytes_per_s_per_viewer": round(stats["kB_per_s"] * 1000) if stats else None,
        "encoder_cpu_core": stats["encoder_cpu"] if stats else None,
    }


def _rounded(value: float | None) -> float | None:
    return None if value is None else round(value, 1)


def _stats(server: Server, stats_type: str) -> dict[str, Any] | None:
    """The relay's figures of the stream of ``stats_type`` its viewers are watching now."""
    request = urllib.request.Request(
        f"{server.origin}/api/video/stats",
        headers={"Authorization": f"Token {server.tokens[ROBOT]}"},
    )
    with urllib.request.urlopen(request, timeout=10) as response:
        streams = json.load(response)["streams"]
    mine = (s for s in streams if s["topic"] == TOPIC and s["type"] == stats_type)
    return next((s for s in mine if s.get("viewers")), None)
