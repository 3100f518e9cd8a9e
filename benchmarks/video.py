"""Video relays: one robot camera (480x320, 30 Hz) to 20 MJPEG, then 20 VP8 viewers.

The server runs as its own daphne process (embedded mode, on a scratch SQLite database
seeded with one robot and a viewer), or ``--url`` points at a running one together with
``--token`` and ``--cookie``. This process is the load: the robot, publishing JPEG
``sensor_msgs/CompressedImage`` over rosbridge with its send time in ``header.stamp``, and
the viewers, reading ``/stream`` over plain sockets (HTTP/1.0, as web_video_server speaks).

For each stream type it prints what one viewer receives (KB/s), frames delivered per
viewer against frames published, the delay from a frame's stamp to its arrival at the
viewer (p50, p99), the encoder's share of a core (from the relay's statistics) and the
server's CPU. The second paper's Table I measured web_video_server at 687 KB/s for MJPEG
at quality 90 and 291 KB/s for VP8 at its default bitrate.

The robot's camera and the viewers' stream client live in ``tests/support/``
(``tests.support.camera_feed``, ``tests.support.http_stream``), shared with the tests.
``--seed N`` draws the camera's texture and noise (7, the default, is the scene the
figures in the README were measured on); ``--json`` prints one JSON object instead of
the table.
"""

from __future__ import annotations

import argparse
import asyncio
import bisect
import json
import time
import urllib.parse
import urllib.request
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import psutil

from benchmarks.rosbridge import Server, start_server
from telemetry.domain.multipart import PartReader
from telemetry.domain.video_stats import percentile
from tests.support.camera_feed import Camera, camera_frames
from tests.support.http_stream import open_stream
from tests.support.webm_reader import WebmReader

ROBOT = "b0"
TOPIC = f"/{ROBOT}/camera/image/compressed"
PAPER_KB_PER_S = {"mjpeg": 687, "vp8": 291}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--width", type=int, default=480)
    parser.add_argument("--height", type=int, default=320)
    parser.add_argument("--rate", type=float, default=30.0, help="camera frames per second")
    parser.add_argument("--duration", type=float, default=30.0, help="seconds measured per type")
    parser.add_argument("--warmup", type=float, default=2.0, help="seconds before measuring")
    parser.add_argument("--viewers", type=int, default=20, help="viewers of each stream type")
    parser.add_argument(
        "--quality", type=int, help="MJPEG quality viewers ask (re-encoded; default: as sent)"
    )
    parser.add_argument("--camera-quality", type=int, default=90, help="the robot's JPEG quality")
    parser.add_argument("--types", default="mjpeg,vp8", help="stream types, in order")
    parser.add_argument("--url", help="a running server's http:// URL instead of starting one")
    parser.add_argument("--token", help="with --url: the token of robot b0")
    parser.add_argument("--cookie", help="with --url: a viewer's session Cookie header")
    parser.add_argument("--server-pid", type=int, help="with --url: the server's pid, for CPU")
    parser.add_argument("--seed", type=int, default=7, help="the camera's texture and noise")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(options: dict[str, Any]) -> None:
    seed, as_json = options.get("seed", 7), options.get("json", False)
    with _server(options) as server:
        frames = camera_frames(
            options["width"], options["height"], options["camera_quality"], seed=seed
        )
        source = sum(map(len, frames)) / len(frames) * options["rate"] / 1000
        if not as_json:
            print(
                f"camera: {options['width']}x{options['height']} at {options['rate']:g} Hz, "
                f"JPEG quality {options['camera_quality']} ({source:.0f} KB/s as published); "
                f"{options['viewers']} viewers per type, {options['duration']:g} s each",
                flush=True,
            )
            print(HEADER, flush=True)
        streams = []
        for kind in options["types"].split(","):
            result = asyncio.run(measure(server, options, frames, kind))
            if as_json:
                streams.append(figures(result))
            else:
                print(line(result), flush=True)
        if as_json:
            camera = {"width": options["width"], "height": options["height"]}
            camera |= {"rate_hz": options["rate"], "kb_per_s": round(source, 1)}
            print(json.dumps({"seed": seed, "camera": camera, "streams": streams}))


def _server(options: dict[str, Any]) -> Server:
    if options["url"]:
        ws = options["url"].replace("http://", "ws://") + "/rosbridge"
        tokens = {ROBOT: options["token"]}
        return Server(ws, options["url"], tokens, options["cookie"], options["server_pid"])
    return start_server(1, ["LOG_LEVEL=WARNING"])


# ---------------------------------------------------------------- the camera


async def publish(
    server: Server, frames: list[bytes], rate: float, until: float, stamps: list[float]
) -> None:
    """Publish ``frames`` in a loop at ``rate`` Hz until ``until``, adding each frame's
    stamp to ``stamps`` as it goes."""
    camera = await Camera.connect(f"{server.url}?token={server.tokens[ROBOT]}")
    try:
        due = time.time()
        while due < until:
            await asyncio.sleep(max(0.0, due - time.time()))
            stamps.append(await camera.send(frames[len(stamps) % len(frames)]))
            due += 1.0 / rate
    finally:
        await camera.close()


# ---------------------------------------------------------------- the viewers


@dataclass
class Viewer:
    """What one viewer received: bytes, and each frame's time and arrival."""

    kind: str
    received: list[tuple[float, float, int]] = field(default_factory=list)  # (stamp, at, bytes)
    joined: asyncio.Event = field(default_factory=asyncio.Event)


async def watch(server: Server, kind: str, query: str, viewer: Viewer, stamps: list[float]) -> None:
    """Read one stream until cancelled, noting each frame (see ``Viewer``)."""
    stream = await open_stream(
        server.origin, f"/stream?topic={TOPIC}&type={kind}{query}", server.cookie
    )
    if stream.status != 200:
        raise RuntimeError(f"/stream answered {stream.status}")
    viewer.joined.set()
    try:
        reader = WebmReader() if kind == "vp8" else PartReader()
        first_chunk = True
        while data := await stream.reader.read(2**20):
            at = time.time()
            if isinstance(reader, PartReader):
                for headers, payload in reader.feed(data):
                    viewer.received.append((float(headers["x-timestamp"]), at, len(payload)))
            else:
                blocks = reader.feed(data)
                if blocks and not first_chunk:  # the join chunk is re-timed: not live frames
                    epoch = reader.epoch or 0.0
                    for block in blocks:
                        stamp = _published(stamps, epoch + block.timestamp / 1000)
                        viewer.received.append((stamp, at, len(block.data)))
                first_chunk = first_chunk and not blocks
    finally:
        stream.close()


def _published(stamps: list[float], arrived: float) -> float:
    """Return the stamp of the frame the server received at ``arrived`` (the latest stamp
    before it: frames leave the robot 33 ms apart and cross loopback in about 1 ms)."""
    index = bisect.bisect_right(stamps, arrived + 0.002) - 1
    return stamps[max(index, 0)]


# ---------------------------------------------------------------- one measurement


@dataclass
class Result:
    kind: str
    viewers: int
    seconds: float
    published: int = 0
    frames: list[int] = field(default_factory=list)
    kb_per_s: float = 0.0
    delays: list[float] = field(default_factory=list)
    encoder_cpu: float | None = None
    server_cpu: float | None = None


async def measure(
    server: Server, options: dict[str, Any], frames: list[bytes], kind: str
) -> Result:
    """Stream ``kind`` to the viewers while the robot publishes; return the figures."""
    query = f"&quality={options['quality']}" if kind == "mjpeg" and options["quality"] else ""
    start = time.time() + options["warmup"]
    end = start + options["duration"]
    stamps: list[float] = []
    robot = asyncio.create_task(publish(server, frames, options["rate"], end, stamps))
    viewers = [Viewer(kind) for _ in range(options["viewers"])]
    tasks = [asyncio.create_task(watch(server, kind, query, v, stamps)) for v in viewers]
    await asyncio.wait_for(asyncio.gather(*(v.joined.wait() for v in viewers)), 30)
    await asyncio.sleep(max(0.0, start - time.time()))
    cpu_before = _cpu(server.pid)
    await robot
    server_cpu = _cpu_share(server.pid, cpu_before, time.time() - start)
    await asyncio.sleep(0.5)  # frames in flight arrive
    stats = await asyncio.to_thread(_stream_stats, server, kind)
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    return _result(kind, viewers, stamps, start, end, stats, server_cpu)


def _result(
    kind: str,
    viewers: list[Viewer],
    stamps: list[float],
    start: float,
    end: float,
    stats: dict[str, Any] | None,
    server_cpu: float | None,
) -> Result:
    seconds = end - start
    result = Result(kind, len(viewers), seconds, server_cpu=server_cpu)
    result.published = sum(1 for s in stamps if start <= s < end)
    in_window = [[r for r in v.received if start <= r[0] < end] for v in viewers]
    result.frames = [len({r[0] for r in got}) for got in in_window]
    result.kb_per_s = (
        sum(sum(r[2] for r in got) for got in in_window) / len(viewers) / seconds / 1000
    )
    result.delays = [at - stamp for got in in_window for stamp, at, _ in got]
    result.encoder_cpu = stats.get("encoder_cpu") if stats else None
    return result


def _stream_stats(server: Server, kind: str) -> dict[str, Any] | None:
    request = urllib.request.Request(
        server.origin + "/api/video/stats", headers={"Cookie": server.cookie}
    )
    with urllib.request.urlopen(request, timeout=10) as response:
        streams = json.load(response)["streams"]
    return next((s for s in streams if s["topic"] == TOPIC and s["type"] == kind), None)


def _cpu(pid: int | None) -> float | None:
    if pid is None:
        return None
    times = psutil.Process(pid).cpu_times()
    return float(times.user + times.system)


def _cpu_share(pid: int | None, before: float | None, seconds: float) -> float | None:
    after = _cpu(pid)
    return None if after is None or before is None else (after - before) / seconds


# ---------------------------------------------------------------- reporting

HEADER = (
    f"{'type':<6} {'viewers':>7} {'KB/s':>7} {'paper':>6} {'frames/viewer':>17} "
    f"{'p50 ms':>7} {'p99 ms':>7} {'encoder':>8} {'server':>7}"
)


def line(result: Result) -> str:
    low, mean = min(result.frames, default=0), np.mean(result.frames) if result.frames else 0
    delivered = f"{low}..{max(result.frames, default=0)}/{result.published}"
    p50, p99 = (percentile(result.delays, p) for p in (50, 99))
    return (
        f"{result.kind:<6} {result.viewers:>7} {result.kb_per_s:>7.1f} "
        f"{PAPER_KB_PER_S.get(result.kind, 0):>6} {delivered:>17} "
        f"{_ms(p50):>7} {_ms(p99):>7} {_core(result.encoder_cpu):>8} {_core(result.server_cpu):>7}"
        f"   (mean {mean:.1f} frames)"
    )


def figures(result: Result) -> dict[str, Any]:
    """One stream type's row as a JSON object (delays in ms, CPU as a share of a core)."""
    p50, p99 = (percentile(result.delays, p) for p in (50, 99))
    return {
        "type": result.kind,
        "viewers": result.viewers,
        "kb_per_s": round(result.kb_per_s, 1),
        "published": result.published,
        "frames_per_viewer_min": min(result.frames, default=0),
        "frames_per_viewer_max": max(result.frames, default=0),
        "frames_per_viewer_mean": round(float(np.mean(result.frames)), 1) if result.frames else 0,
        "p50_ms": None if p50 is None else round(p50 * 1000, 1),
        "p99_ms": None if p99 is None else round(p99 * 1000, 1),
        "encoder_cpu": result.encoder_cpu,
        "server_cpu": None if result.server_cpu is None else round(result.server_cpu, 3),
    }


def _ms(seconds: float | None) -> str:
    return "-" if seconds is None else f"{seconds * 1000:.1f}"


def _core(share: float | None) -> str:
    return "-" if share is None else f"{share:.3f}"
