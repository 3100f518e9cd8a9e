"""rosbridge fan-out: N robots publish PoseStamped at R Hz to M subscribers of every robot.

The server runs as its own daphne process (embedded mode, on a scratch SQLite database
seeded with the robots and a viewer), or ``--url`` points at a running one together with
``--tokens``/``--cookie``. This process is the load: ``websockets`` clients, robots
publishing with their send time in ``header.stamp`` and subscribers (browser-like viewer
sessions) measuring each message's delay on arrival.

It prints, per run: offered and delivered messages/s, loss, delay p50/p95/p99, and the
CPU of the server and of the load. ``--saturate`` raises the rate step by step and reports
the highest delivered rate whose p99 stays under ``--p99-limit`` (100 ms) without loss.
``--seed N`` fixes the one random thing, each publisher's phase within its period;
``--json`` prints one JSON object instead of the table (with ``--saturate``: every step
and the best).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import random
import re
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import psutil
import websockets

ROOT = Path(__file__).resolve().parent.parent
BUILDING = "bench"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robots", type=int, default=100, help="publishing robots (N)")
    parser.add_argument("--rate", type=float, default=10.0, help="Hz per robot (R)")
    parser.add_argument("--subscribers", type=int, default=10, help="subscribers of all (M)")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds measured")
    parser.add_argument("--warmup", type=float, default=2.0, help="seconds before measuring")
    parser.add_argument("--saturate", action="store_true", help="find the highest good rate")
    parser.add_argument("--p99-limit", type=float, default=100.0, help="ms, for --saturate")
    parser.add_argument("--step", type=float, default=1.25, help="rate factor per step")
    parser.add_argument("--url", help="a running server's ws:// base URL instead of starting one")
    parser.add_argument("--tokens", help="with --url: JSON file {robot: token}")
    parser.add_argument("--cookie", help="with --url: a viewer's session Cookie header")
    parser.add_argument("--server-pid", type=int, help="with --url: the server's pid, for CPU")
    parser.add_argument("--server-env", action="append", default=[], metavar="NAME=VALUE")
    parser.add_argument("--seed", type=int, default=0, help="the publishers' phases")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(options: dict[str, Any]) -> None:
    random.seed(options.get("seed", 0))
    with Server.for_options(options) as server:
        if options["saturate"]:
            saturate(server, options)
        else:
            report(asyncio.run(measure(server, options, options["rate"])), options)


# ---------------------------------------------------------------- the server under test


@dataclass
class Server:
    url: str
    origin: str
    tokens: dict[str, str]
    cookie: str
    pid: int | None
    process: subprocess.Popen[bytes] | None = None
    scratch: tempfile.TemporaryDirectory[str] | None = None

    @classmethod
    def for_options(cls, options: dict[str, Any]) -> Server:
        if options["url"]:
            tokens = json.loads(Path(options["tokens"]).read_text())
            origin = options["url"].replace("ws://", "http://").split("/rosbridge")[0]
            return cls(options["url"], origin, tokens, options["cookie"], options["server_pid"])
        return start_server(options["robots"], options["server_env"])

    def __enter__(self) -> Server:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            self.process.wait(10)
        if self.scratch is not None:
            self.scratch.cleanup()


def start_server(robots: int, extra_env: list[str]) -> Server:
    """Migrate and seed a scratch database, then start daphne on it on a free port."""
    scratch = tempfile.TemporaryDirectory(prefix="cloudnav-bench-")
    env = {
        **os.environ,
        "DJANGO_SETTINGS_MODULE": "cloudnav_web.settings",
        "CLOUDNAV_DEMO": "1",  # a scratch server of the demo building
        "DATABASE_URL": f"sqlite:///{scratch.name}/bench.sqlite3",
        "REDIS_URL": "",
        "LOG_LEVEL": "WARNING",
        **dict(item.split("=", 1) for item in extra_env),
    }
    credentials = seeded_database(robots, env)
    port = free_port()
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "daphne",
            "-b",
            "127.0.0.1",
            "-p",
            str(port),
            "--websocket_timeout",
            "-1",
            "cloudnav_web.asgi:application",
        ],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    wait_for_http(f"http://127.0.0.1:{port}/", process)
    return Server(
        f"ws://127.0.0.1:{port}/rosbridge",
        f"http://127.0.0.1:{port}",
        credentials["tokens"],
        credentials["cookie"],
        process.pid,
        process,
        scratch,
    )


def seeded_database(robots: int, env: dict[str, str]) -> dict[str, Any]:
    """Migrate the database ``env`` names and run ``seed`` on it; return the credentials."""
    subprocess.run([sys.executable, "manage.py", "migrate", "-v0"], cwd=ROOT, env=env, check=True)
    seeded = subprocess.run(
        [sys.executable, "-c", f"from benchmarks.rosbridge import seed; seed({robots})"],
        cwd=ROOT,
        env=env,
        check=True,
        capture_output=True,
        text=True,
    )
    return dict(json.loads(seeded.stdout.strip().splitlines()[-1]))


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def wait_for_http(url: str, process: subprocess.Popen[bytes], deadline: float = 30.0) -> None:
    give_up = time.monotonic() + deadline
    while time.monotonic() < give_up and process.poll() is None:
        try:
            urllib.request.urlopen(url, timeout=1).close()
            return
        except urllib.error.HTTPError:
            return
        except OSError:
            time.sleep(0.05)
    raise RuntimeError("the server did not start")


def seed(robots: int) -> None:
    """Create the building, ``robots`` robots and a viewer; print their credentials as JSON.

    Runs in a process of its own, against the scratch database.
    """
    import django

    django.setup()
    from django.contrib.auth.models import Group, User
    from django.test import Client

    from maps.models import Building
    from robots.services import register_robot

    building = Building.objects.create(code=BUILDING, name="Benchmark building")
    viewer = User.objects.create_user("bench-viewer", password="unused-password-1")
    viewer.groups.add(Group.objects.get_or_create(name="viewer")[0])
    building.members.add(viewer)
    tokens = {f"b{n}": register_robot(f"b{n}", [building])[1] for n in range(robots)}
    client = Client()
    client.force_login(viewer)
    cookie = f"sessionid={client.cookies['sessionid'].value}"
    print(json.dumps({"tokens": tokens, "cookie": cookie}))


# ---------------------------------------------------------------- the load


@dataclass
class Result:
    robots: int
    rate: float
    subscribers: int
    seconds: float
    sent: int = 0
    received: int = 0
    delays: list[float] = field(default_factory=list)
    server_cpu: float | None = None
    load_cpu: float = 0.0

    @property
    def lagging(self) -> bool:
        """True if the load could not publish at the asked rate: it, not the server, was
        the limit."""
        return self.sent < 0.98 * self.robots * self.rate * self.seconds or (
            self.sent > 1.02 * self.robots * self.rate * self.seconds
        )

    @property
    def offered(self) -> float:
        return self.sent * self.subscribers / self.seconds

    @property
    def delivered(self) -> float:
        return self.received / self.seconds

    @property
    def loss(self) -> float:
        expected = self.sent * self.subscribers
        return 1.0 - self.received / expected if expected else 0.0

    def percentile(self, p: float) -> float:
        if not self.delays:
            return float("nan")
        ordered = sorted(self.delays)
        return 1000.0 * ordered[min(len(ordered) - 1, int(p / 100 * len(ordered)))]

    def figures(self) -> dict[str, Any]:
        """The row of the table as a JSON object (delays in ms, CPU in percent of a core)."""
        return {
            "robots": self.robots,
            "rate_hz": self.rate,
            "subscribers": self.subscribers,
            "seconds": self.seconds,
            "offered_per_s": round(self.offered, 1),
            "delivered_per_s": round(self.delivered, 1),
            "loss": round(self.loss, 6),
            "p50_ms": _ms_or_none(self.percentile(50)),
            "p95_ms": _ms_or_none(self.percentile(95)),
            "p99_ms": _ms_or_none(self.percentile(99)),
            "server_cpu_percent": _round_or_none(self.server_cpu),
            "load_cpu_percent": round(self.load_cpu, 1),
            "load_lagging": self.lagging,
        }


def _ms_or_none(ms: float) -> float | None:
    return None if ms != ms else round(ms, 2)  # NaN (no delays) is not JSON


def _round_or_none(value: float | None) -> float | None:
    return None if value is None else round(value, 1)


class Window:
    """The measured interval, in wall-clock time shared by every process on the machine."""

    def __init__(self, start: float, seconds: float) -> None:
        self.start, self.end = start, start + seconds

    def holds(self, stamp: float) -> bool:
        return self.start <= stamp < self.end


def pose(seq: int, now: float) -> str:
    sec = int(now)
    msg = {
        "header": {
            "frame_id": f"{BUILDING}/Floor",
            "stamp": {"sec": sec, "nanosec": int((now - sec) * 1e9)},
        },
        "pose": {
            "position": {"x": seq * 0.01, "y": 1.0, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
        },
    }
    return json.dumps({"op": "publish", "topic": "pose", "msg": msg})


async def publisher(server: Server, name: str, rate: float, window: Window, result: Result) -> None:
    async with websockets.connect(
        f"{server.url}?token={server.tokens[name]}", compression=None
    ) as ws:
        period = 1.0 / rate
        due = time.time() + random.random() * period
        seq = 0
        while due < window.end:
            await asyncio.sleep(max(0.0, due - time.time()))
            now = time.time()
            await ws.send(pose(seq, now))
            seq += 1
            if window.holds(now):
                result.sent += 1
            due += period


async def subscriber(
    server: Server, robots: list[str], window: Window, result: Result, ready: asyncio.Event
) -> None:
    headers = {"Cookie": server.cookie, "Origin": server.origin}
    async with websockets.connect(
        server.url, additional_headers=headers, compression=None, max_queue=None
    ) as ws:
        for name in robots:
            await ws.send(json.dumps({"op": "subscribe", "topic": f"/{name}/pose"}))
        await ws.send(
            json.dumps({"op": "call_service", "id": "ready", "service": "/rosapi/get_time"})
        )
        async for frame in ws:
            if '"ready"' in frame:
                ready.set()
                continue
            now = time.time()
            sent = send_time(frame)
            if window.holds(sent):
                result.received += 1
                result.delays.append(now - sent)


_STAMP = re.compile(r'"stamp":\{"sec":(\d+),"nanosec":(\d+)')


def send_time(frame: str | bytes) -> float:
    """Return the publisher's send time from a delivered pose.

    The server's compact JSON keeps the stamp's spelling, so a regular expression finds it
    at a fraction of a full parse: the load process must stay cheaper than the server.
    """
    text = frame if isinstance(frame, str) else frame.decode()
    found = _STAMP.search(text)
    if found is None:
        stamp = json.loads(text)["msg"]["header"]["stamp"]
        return float(stamp["sec"] + stamp["nanosec"] * 1e-9)
    return int(found.group(1)) + int(found.group(2)) * 1e-9


async def measure(server: Server, options: dict[str, Any], rate: float) -> Result:
    """Run the load once at ``rate`` Hz per robot and return what was measured."""
    robots = sorted(server.tokens)[: options["robots"]]
    result = Result(len(robots), rate, options["subscribers"], options["duration"])
    window = Window(time.time() + 3600, options["duration"])  # placed once all are connected
    readies = [asyncio.Event() for _ in range(options["subscribers"])]
    subscribers = [
        asyncio.create_task(subscriber(server, robots, window, result, ready)) for ready in readies
    ]
    await asyncio.wait_for(asyncio.gather(*(r.wait() for r in readies)), 60)
    window.start = time.time() + options["warmup"] + 1.0
    window.end = window.start + options["duration"]
    publishers = [
        asyncio.create_task(publisher(server, name, rate, window, result)) for name in robots
    ]
    await asyncio.sleep(max(0.0, window.start - time.time()))
    result.server_cpu, result.load_cpu = await cpu_during(window, server.pid)
    await asyncio.gather(*publishers)
    await drained(result)
    for task in subscribers:
        task.cancel()
    await asyncio.gather(*subscribers, return_exceptions=True)
    return result


async def drained(result: Result, quiet: float = 0.5, longest: float = 10.0) -> None:
    """Wait until messages stop arriving (or ``longest`` seconds): late ones count as late,
    not lost."""
    give_up = time.monotonic() + longest
    seen = -1
    while seen != result.received and time.monotonic() < give_up:
        seen = result.received
        await asyncio.sleep(quiet)


async def cpu_during(window: Window, server_pid: int | None) -> tuple[float | None, float]:
    """Return the CPU (percent of one core) the server and this process use in ``window``."""
    processes = [psutil.Process(server_pid) if server_pid else None, psutil.Process()]
    before = [p.cpu_times() if p else None for p in processes]
    await asyncio.sleep(max(0.0, window.end - time.time()))
    seconds = window.end - window.start
    used: list[float | None] = []
    for process, start in zip(processes, before, strict=True):
        if process is None or start is None:
            used.append(None)
            continue
        end = process.cpu_times()
        used.append(100.0 * (end.user - start.user + end.system - start.system) / seconds)
    return used[0], used[1] or 0.0


# ---------------------------------------------------------------- reporting


HEADER = (
    f"{'robots':>6} {'Hz':>6} {'subs':>4} {'offered/s':>10} {'delivered/s':>11} "
    f"{'loss':>7} {'p50 ms':>7} {'p95 ms':>7} {'p99 ms':>7} {'server CPU':>10} {'load CPU':>8}"
)


def line(result: Result) -> str:
    server_cpu = f"{result.server_cpu:.0f}%" if result.server_cpu is not None else "-"
    return (
        f"{result.robots:>6} {result.rate:>6.1f} {result.subscribers:>4} "
        f"{result.offered:>10.0f} {result.delivered:>11.0f} {100 * result.loss:>6.2f}% "
        f"{result.percentile(50):>7.1f} {result.percentile(95):>7.1f} "
        f"{result.percentile(99):>7.1f} {server_cpu:>10} {result.load_cpu:>7.0f}%"
        + ("  (load lagging: the load, not the server, was the limit)" if result.lagging else "")
    )


def report(result: Result, options: dict[str, Any]) -> None:
    if options.get("json"):
        print(json.dumps({"seed": options.get("seed", 0), **result.figures()}), flush=True)
        return
    print(HEADER)
    print(line(result), flush=True)


def good(result: Result, limit_ms: float) -> bool:
    return result.loss <= 0.0 and result.percentile(99) < limit_ms


def attempt(server: Server, options: dict[str, Any], rate: float) -> Result:
    """Measure at ``rate``; a failed run is tried once more, since a machine shared with
    other work can stall either process for a moment."""
    for _ in range(2):
        result = asyncio.run(measure(server, options, rate))
        if not options.get("json"):
            print(line(result), flush=True)
        if good(result, options["p99_limit"]):
            break
    return result


def saturate(server: Server, options: dict[str, Any]) -> None:
    """Raise the rate by ``--step`` until p99 or loss fails twice, then print the best run."""
    if not options.get("json"):
        print(HEADER, flush=True)
    rate, best, steps = options["rate"], None, []
    while True:
        result = attempt(server, options, rate)
        steps.append(result.figures())
        if not good(result, options["p99_limit"]):
            break
        best = result
        rate *= options["step"]
    if options.get("json"):
        saturation = best.figures() if best is not None else None
        print(json.dumps({"seed": options.get("seed", 0), "steps": steps, "best": saturation}))
    elif best is None:
        print(f"no rate met p99 < {options['p99_limit']:.0f} ms without loss")
    else:
        print(
            f"saturation: {best.delivered:.0f} delivered msg/s at {best.rate:.1f} Hz "
            f"(p99 {best.percentile(99):.1f} ms, server CPU {best.server_cpu or 0:.0f}%)"
        )
