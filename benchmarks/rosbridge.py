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

``--processes N`` (N >= 2) starts N daphne processes in scaled mode on one Redis
(``--redis-url``, flushed first) and a scratch PostgreSQL database (made on the server of
``--postgres-url``, dropped after), and measures the same load twice in one run: ``cross``,
the robots on the first half of the processes and the subscribers on the others, and
``single``, everything on the first process. Each holds ``delivered_per_s``, ``loss``,
``p50_ms``, ``p99_ms``, ``server_cpu`` (every server process and Redis, in cores) and
``cpu_s_per_1000`` (CPU seconds per 1,000 delivered messages). With ``--saturate`` it adds
``saturation_1`` and ``saturation_2``: the highest delivered msg/s meeting ``--p99-limit``
without loss on one process, and with robots and subscribers spread over two, each with
``saturation_N_failed_step``: the figures of the first rate that failed (its
``load_cpu_percent`` and ``load_lagging`` say whether the load, not the servers, was the
limit).
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
CONNECT_WITHIN = 120.0  # seconds for every client to connect, on a loaded machine
HANDSHAKES_AT_ONCE = 8


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
    parser.add_argument("--processes", type=int, default=1, help="server processes (scaled)")
    parser.add_argument(
        "--redis-url",
        default=os.environ.get("REDIS_URL") or "redis://127.0.0.1:6379/0",
        help="with --processes: the Redis they share (its database is flushed)",
    )
    parser.add_argument(
        "--postgres-url",
        default="postgres://postgres@127.0.0.1:5432/postgres",
        help="with --processes: a maintenance database to create the scratch one from",
    )


def run(options: dict[str, Any]) -> None:
    random.seed(options.get("seed", 0))
    with Server.for_options(options) as server:
        if options.get("processes", 1) > 1:
            print(json.dumps(scaled(server, options)), flush=True)
        elif options["saturate"]:
            saturate(server, options)
        else:
            report(asyncio.run(measure(server, options, options["rate"])), options)


# ---------------------------------------------------------------- the server under test


@dataclass(frozen=True)
class Endpoint:
    """One server process: its rosbridge URL, its origin and its pid (for CPU)."""

    url: str
    origin: str
    pid: int | None


@dataclass
class Server:
    """The server under test: its first process (``url``, ``origin``, ``pid``), any others
    (``more``, in scaled mode) and the Redis process they share, whose CPU counts as theirs."""

    url: str
    origin: str
    tokens: dict[str, str]
    cookie: str
    pid: int | None
    process: subprocess.Popen[bytes] | None = None
    scratch: tempfile.TemporaryDirectory[str] | None = None
    more: list[Endpoint] = field(default_factory=list)
    redis_pid: int | None = None
    cleanups: list[Any] = field(default_factory=list)

    @property
    def endpoints(self) -> list[Endpoint]:
        return [Endpoint(self.url, self.origin, self.pid), *self.more]

    def server_pids(self) -> list[int]:
        """The processes whose CPU is the server's: every daphne, and Redis if here."""
        pids = (*(e.pid for e in self.endpoints), self.redis_pid)
        return [pid for pid in pids if pid is not None]

    @classmethod
    def for_options(cls, options: dict[str, Any]) -> Server:
        if options["url"]:
            tokens = json.loads(Path(options["tokens"]).read_text())
            origin = options["url"].replace("ws://", "http://").split("/rosbridge")[0]
            return cls(options["url"], origin, tokens, options["cookie"], options["server_pid"])
        scaled = options.get("processes", 1) > 1
        return start_server(
            options["robots"],
            options["server_env"],
            options.get("processes", 1),
            options["redis_url"] if scaled else "",
            options["postgres_url"] if scaled else "",
        )

    def __enter__(self) -> Server:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.process is not None:
            _stop(self.process)
        for cleanup in reversed(self.cleanups):
            cleanup()  # the other processes, then the scratch database
        if self.scratch is not None:
            self.scratch.cleanup()


def start_server(
    robots: int,
    extra_env: list[str],
    processes: int = 1,
    redis_url: str = "",
    postgres_url: str = "",
) -> Server:
    """Migrate and seed a scratch database, then start ``processes`` daphnes on it on free
    ports: on SQLite in embedded mode; with ``redis_url``, in scaled mode on it and on a
    scratch database made on the PostgreSQL server of ``postgres_url``."""
    scratch = tempfile.TemporaryDirectory(prefix="cloudnav-bench-")
    env = {
        **os.environ,
        "DJANGO_SETTINGS_MODULE": "cloudnav_web.settings",
        "CLOUDNAV_DEMO": "1",  # a scratch server of the demo building
        "DATABASE_URL": f"sqlite:///{scratch.name}/bench.sqlite3",
        "REDIS_URL": "",
        "CLOUDNAV_RECORDING_DIR": f"{scratch.name}/recordings",  # recorded, then thrown away
        "LOG_LEVEL": "WARNING",
        **dict(item.split("=", 1) for item in extra_env),
    }
    cleanups: list[Any] = []
    redis_pid = None
    if redis_url:
        env["DATABASE_URL"] = scratch_postgres(postgres_url, cleanups)
        env["REDIS_URL"] = redis_url
        redis_pid = flushed_redis(redis_url)
    credentials = seeded_database(robots, env)
    started = [started_daphne(env) for _ in range(processes)]
    first, process = started[0]
    return Server(
        first.url,
        first.origin,
        credentials["tokens"],
        credentials["cookie"],
        first.pid,
        process,
        scratch,
        more=[endpoint for endpoint, _ in started[1:]],
        redis_pid=redis_pid,
        cleanups=[*cleanups, *(lambda p=p: _stop(p) for _, p in started[1:])],
    )


def started_daphne(env: dict[str, str]) -> tuple[Endpoint, subprocess.Popen[bytes]]:
    port = free_port()
    process = daphne(port, env)
    wait_for_http(f"http://127.0.0.1:{port}/", process)
    endpoint = Endpoint(f"ws://127.0.0.1:{port}/rosbridge", f"http://127.0.0.1:{port}", process.pid)
    return endpoint, process


def _stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is None:
        process.terminate()
        process.wait(10)


def daphne(port: int, env: dict[str, str]) -> subprocess.Popen[bytes]:
    command = [sys.executable, "-m", "daphne", "-b", "127.0.0.1", "-p", str(port)]
    return subprocess.Popen(
        [*command, "--websocket_timeout", "-1", "cloudnav_web.asgi:application"],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def scratch_postgres(admin_url: str, cleanups: list[Any]) -> str:
    """Create a scratch database on the PostgreSQL server of ``admin_url``, dropped by a
    function added to ``cleanups``; return its URL."""
    import urllib.parse

    import psycopg

    name = f"cloudnav_bench_{os.getpid()}"
    with psycopg.connect(admin_url, autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.execute(f'CREATE DATABASE "{name}"')

    def drop() -> None:
        with psycopg.connect(admin_url, autocommit=True) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')

    cleanups.append(drop)
    return urllib.parse.urlunsplit(urllib.parse.urlsplit(admin_url)._replace(path=f"/{name}"))


def flushed_redis(url: str) -> int | None:
    """Flush the database of ``url``; return the Redis server's pid if it runs here."""
    import redis

    client = redis.Redis.from_url(url)
    client.flushdb()
    pid = int(client.info("server")["process_id"])
    client.close()
    return pid if psutil.pid_exists(pid) else None


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


@dataclass
class Start:
    """Publishers connect, say they are ``ready``, and publish once told to ``go``: a
    server slow to take a hundred handshakes at once (a loaded machine, PostgreSQL) is
    not mistaken for a slow relay."""

    ready: asyncio.Event = field(default_factory=asyncio.Event)
    go: asyncio.Event = field(default_factory=asyncio.Event)


async def connected(handshakes: asyncio.Semaphore, url: str, **options: Any) -> Any:
    """Open a WebSocket once one of ``handshakes`` is free: a fleet's robots do not all
    connect in the same millisecond, and daphne drops a handshake not accepted in 5 s."""
    async with handshakes:
        return await websockets.connect(url, open_timeout=CONNECT_WITHIN, **options)


async def publisher(
    server: Server,
    place: int,
    name: str,
    rate: float,
    window: Window,
    result: Result,
    start: Start,
    handshakes: asyncio.Semaphore,
) -> None:
    url = f"{server.endpoints[place].url}?token={server.tokens[name]}"
    async with await connected(handshakes, url, compression=None) as ws:
        start.ready.set()
        await start.go.wait()
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
    server: Server,
    place: int,
    robots: list[str],
    window: Window,
    result: Result,
    ready: asyncio.Event,
    handshakes: asyncio.Semaphore,
) -> None:
    endpoint = server.endpoints[place]
    headers = {"Cookie": server.cookie, "Origin": endpoint.origin}
    options = {"additional_headers": headers, "compression": None, "max_queue": None}
    async with await connected(handshakes, endpoint.url, **options) as ws:
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


async def measure(
    server: Server,
    options: dict[str, Any],
    rate: float,
    robots_on: tuple[int, ...] = (0,),
    subscribers_on: tuple[int, ...] = (0,),
) -> Result:
    """Run the load once at ``rate`` Hz per robot and return what was measured; robots and
    subscribers are dealt in turn to the server processes ``robots_on`` and
    ``subscribers_on``."""
    robots = sorted(server.tokens)[: options["robots"]]
    result = Result(len(robots), rate, options["subscribers"], options["duration"])
    window = Window(time.time() + 3600, options["duration"])  # placed once all are connected
    handshakes = asyncio.Semaphore(HANDSHAKES_AT_ONCE)
    readies = [asyncio.Event() for _ in range(options["subscribers"])]
    subscribers = [
        asyncio.create_task(
            subscriber(
                server,
                subscribers_on[n % len(subscribers_on)],
                robots,
                window,
                result,
                ready,
                handshakes,
            )
        )
        for n, ready in enumerate(readies)
    ]
    await asyncio.wait_for(asyncio.gather(*(r.wait() for r in readies)), CONNECT_WITHIN)
    starts = [Start() for _ in robots]
    publishers = [
        asyncio.create_task(
            publisher(
                server, robots_on[n % len(robots_on)], name, rate, window, result, start, handshakes
            )
        )
        for n, (name, start) in enumerate(zip(robots, starts, strict=True))
    ]
    await asyncio.wait_for(asyncio.gather(*(s.ready.wait() for s in starts)), CONNECT_WITHIN)
    window.start = time.time() + options["warmup"] + 1.0
    window.end = window.start + options["duration"]
    for start in starts:
        start.go.set()
    await asyncio.sleep(max(0.0, window.start - time.time()))
    result.server_cpu, result.load_cpu = await cpu_during(window, server.server_pids())
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


async def cpu_during(window: Window, server_pids: list[int]) -> tuple[float | None, float]:
    """Return the CPU (percent of one core) the server's processes together, and this
    process, use in ``window`` (None for the server when none of its pids is known)."""
    servers = [psutil.Process(pid) for pid in server_pids]
    load = psutil.Process()
    before = [_cpu_seconds(p) for p in servers], _cpu_seconds(load)
    await asyncio.sleep(max(0.0, window.end - time.time()))
    seconds = window.end - window.start
    server = sum(_cpu_seconds(p) for p in servers) - sum(before[0])
    own = _cpu_seconds(load) - before[1]
    return (100.0 * server / seconds if servers else None), 100.0 * own / seconds


def _cpu_seconds(process: psutil.Process) -> float:
    times = process.cpu_times()
    return float(times.user + times.system)


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


def attempt(
    server: Server, options: dict[str, Any], rate: float, *placement: tuple[int, ...]
) -> Result:
    """Measure at ``rate``; a failed run is tried once more, since a machine shared with
    other work can stall either process for a moment."""
    for _ in range(2):
        result = asyncio.run(measure(server, options, rate, *placement))
        if not options.get("json"):
            print(line(result), flush=True)
        if good(result, options["p99_limit"]):
            break
    return result


def highest_good_rate(
    server: Server, options: dict[str, Any], *placement: tuple[int, ...]
) -> tuple[Result | None, list[dict[str, Any]]]:
    """Raise the rate by ``--step`` until p99 or loss fails twice; return the best run (None
    if none was good) and every step's figures."""
    rate, best, steps = options["rate"], None, []
    while True:
        result = attempt(server, options, rate, *placement)
        steps.append(result.figures())
        if not good(result, options["p99_limit"]):
            return best, steps
        best = result
        rate *= options["step"]


def saturate(server: Server, options: dict[str, Any]) -> None:
    """Find the highest good rate (``highest_good_rate``) and print the best run."""
    if not options.get("json"):
        print(HEADER, flush=True)
    best, steps = highest_good_rate(server, options)
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


# ---------------------------------------------------------------- scaled mode


def scaled(server: Server, options: dict[str, Any]) -> dict[str, Any]:
    """Measure the same load across processes and on one, in this run (and with
    ``--saturate``, the highest good rate on one process and spread over two)."""
    count = len(server.endpoints)
    half = max(1, count // 2)
    robots_on, subscribers_on = tuple(range(half)), tuple(range(half, count))
    cross = asyncio.run(measure(server, options, options["rate"], robots_on, subscribers_on))
    single = asyncio.run(measure(server, options, options["rate"]))
    found: dict[str, Any] = {
        "seed": options.get("seed", 0),
        "processes": count,
        "robots": cross.robots,
        "rate_hz": cross.rate,
        "subscribers": cross.subscribers,
        "cross": scaled_figures(cross),
        "single": scaled_figures(single),
    }
    if options["saturate"]:
        both = (0, 1)
        for name, placement in (("saturation_1", ((0,), (0,))), ("saturation_2", (both, both))):
            best, steps = highest_good_rate(server, {**options, "json": True}, *placement)
            found[name] = round(best.delivered, 1) if best is not None else None
            found[name + "_cpu_s_per_1000"] = (
                scaled_figures(best)["cpu_s_per_1000"] if best else None
            )
            # the step that failed, and whether the load (not the servers) was its limit
            found[name + "_failed_step"] = steps[-1]
    return found


def scaled_figures(result: Result) -> dict[str, Any]:
    """One case of the scaled report: server CPU in cores (daphnes and Redis together)."""
    cores = None if result.server_cpu is None else result.server_cpu / 100.0
    per_1000 = None
    if cores is not None and result.delivered:
        per_1000 = round(1000.0 * cores / result.delivered, 4)
    return {
        "delivered_per_s": round(result.delivered, 1),
        "loss": round(result.loss, 6),
        "p50_ms": _ms_or_none(result.percentile(50)),
        "p99_ms": _ms_or_none(result.percentile(99)),
        "server_cpu": None if cores is None else round(cores, 3),
        "cpu_s_per_1000": per_1000,
        "load_lagging": result.lagging,
    }
