"""Rosbridge fixtures: in-process clients through the real ASGI application, and live servers.

In-process (``rosbridge``): ``await rosbridge(token=...)`` or ``await rosbridge(user=...)``
opens a ``channels.testing.WebsocketCommunicator`` on the real application and returns a
``RosClient`` speaking rosbridge JSON. Tests using it need ``transactional_db``: the consumer
reads the database from other threads.

Live servers (``daphne_server``, ``daphne_servers.start(env=...)``): real daphne processes
on loopback ports against the test database, for network behaviour and unmodified clients.

Scaled mode (``scaled_servers(2)``): daphne processes sharing a real Redis and a PostgreSQL
database made for the test; mark such tests ``@pytest.mark.scaled``. ``nginx_front(cluster)``
puts a real nginx in front of them, as ``make demo-scaled`` does.
"""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import io
import itertools
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cbor2
import pytest
from channels.testing import WebsocketCommunicator
from django.contrib.auth.models import User
from django.test import Client

TIMEOUT = 3.0


class Refused(Exception):
    """The server refused the WebSocket handshake."""


class RosClient:
    """A rosbridge client over a WebsocketCommunicator (or a ``SocketCommunicator``).

    ``settle``: how long ``quiet`` waits past its round trip for a frame that crosses
    server processes (a sender's ``sync`` on one process does not order delivery on another).
    """

    def __init__(self, communicator: Any, settle: float = 0.0) -> None:
        self.communicator = communicator
        self.settle = settle

    async def send(self, **frame: Any) -> None:
        await self.communicator.send_to(text_data=json.dumps(frame))

    async def send_raw(self, text: str) -> None:
        await self.communicator.send_to(text_data=text)

    async def receive(self, wait: float = TIMEOUT) -> dict[str, Any]:
        """Return the next frame, JSON or CBOR, decoded."""
        message = await self.communicator.receive_output(wait)
        if message["type"] != "websocket.send":
            raise AssertionError(f"expected a frame, got {message}")
        if message.get("text") is not None:
            return json.loads(message["text"])
        return cbor2.loads(message["bytes"])

    async def receive_raw(self, wait: float = TIMEOUT) -> dict[str, Any]:
        return await self.communicator.receive_output(wait)

    async def receive_until(
        self, predicate: Callable[[dict[str, Any]], bool], wait: float = TIMEOUT
    ) -> dict[str, Any]:
        """Return the first frame matching ``predicate``, skipping others, within ``wait``."""
        async with asyncio.timeout(wait):
            while True:
                frame = await self.receive(wait)
                if predicate(frame):
                    return frame

    async def nothing_more(self, wait: float = 0.2) -> bool:
        """True if no frame arrives within ``wait`` (for checks that something is dropped)."""
        return await self.communicator.receive_nothing(wait)

    async def call(self, service: str, args: Any = None, id: str = "call") -> dict[str, Any]:
        """Call a service and return its ``service_response``."""
        await self.send(op="call_service", id=id, service=service, args=args or {})
        return await self.receive_until(
            lambda f: f.get("op") == "service_response" and f.get("id") == id
        )

    async def quiet(self) -> bool:
        """True if nothing was sent to this client before a round trip started now.

        Frames to one client are delivered in order, so once the sender of a frame has
        ``sync``-ed, this tells without waiting whether that frame reached this client.
        """
        await self.send(op="call_service", id="quiet", service="/rosapi/get_time")
        frame = await self.receive()
        if frame.get("op") == "service_response" and frame.get("id") == "quiet":
            return not self.settle or await self.nothing_more(self.settle)
        await self.receive_until(lambda f: f.get("id") == "quiet")
        return False

    async def sync(self) -> None:
        """Return once the server has handled every frame sent so far on this connection."""
        await self.call("/rosapi/get_time", id="sync")

    async def close(self) -> None:
        await self.communicator.disconnect()


class SocketCommunicator:
    """What ``RosClient`` uses of a ``WebsocketCommunicator``, over a real WebSocket to a
    live server: one frame may be awaited without being taken (``receive_nothing``)."""

    def __init__(self, socket: Any) -> None:
        self.socket = socket
        self._next: asyncio.Task[str | bytes] | None = None

    async def send_to(self, text_data: str) -> None:
        await self.socket.send(text_data)

    def _next_frame(self) -> asyncio.Task[str | bytes]:
        if self._next is None:
            self._next = asyncio.ensure_future(self.socket.recv())
        return self._next

    async def receive_output(self, timeout: float) -> dict[str, Any]:  # noqa: ASYNC109 (its signature)
        data = await asyncio.wait_for(asyncio.shield(self._next_frame()), timeout)
        self._next = None
        key = "text" if isinstance(data, str) else "bytes"
        return {"type": "websocket.send", key: data}

    async def receive_nothing(self, timeout: float) -> bool:  # noqa: ASYNC109 (its signature)
        done, _ = await asyncio.wait({self._next_frame()}, timeout=timeout)
        return not done

    async def disconnect(self) -> None:
        if self._next is not None:
            self._next.cancel()
        await self.socket.close()


def session_cookie(user: User) -> bytes:
    client = Client()
    client.force_login(user)
    return f"sessionid={client.cookies['sessionid'].value}".encode()


Connect = Callable[..., Awaitable[RosClient]]


@pytest.fixture
async def rosbridge() -> AsyncIterator[Connect]:
    """Open rosbridge connections through the real ASGI application; all closed at the end.

    ``await rosbridge(token=...)`` (query string), ``header_token=...`` (Authorization),
    ``user=...`` (session, with an ``origin`` defaulting to ours), ``path=...``, ``host=...``
    (the ``Host`` header, ``testserver`` unless given).
    Raises Refused when the handshake is refused.
    """
    from channels.db import database_sync_to_async

    from cloudnav_web.asgi import application

    opened: list[RosClient] = []

    async def connect(
        token: str | None = None,
        header_token: str | None = None,
        user: User | None = None,
        origin: str | None = "http://testserver",
        path: str = "/rosbridge",
        host: str = "testserver",
    ) -> RosClient:
        headers: list[tuple[bytes, bytes]] = [(b"host", host.encode())]
        if token is not None:
            path += f"?token={token}"
        if header_token is not None:
            headers.append((b"authorization", f"Token {header_token}".encode()))
        if user is not None:
            headers.append((b"cookie", await database_sync_to_async(session_cookie)(user)))
        if origin is not None:
            headers.append((b"origin", origin.encode()))
        communicator = WebsocketCommunicator(application, path, headers=headers)
        connected, _ = await communicator.connect(timeout=TIMEOUT)
        if not connected:
            await communicator.disconnect(timeout=TIMEOUT)
            raise Refused(path)
        client = RosClient(communicator)
        opened.append(client)
        return client

    yield connect
    for client in opened:
        await client.close()


async def robot_listening(rosbridge: Connect, token: str, *topics: str) -> RosClient:
    """A robot connected with ``token`` and subscribed to its own ``topics`` (``cmd_vel``
    unless given), every subscription in place when this returns."""
    robot = await rosbridge(token=token)
    for topic in topics or ("cmd_vel",):
        await robot.send(op="subscribe", topic=topic)
    await robot.sync()
    return robot


# ---------------------------------------------------------------- live servers
#
# ``daphne_servers`` starts real daphne processes on free loopback ports; ``daphne_server``
# is one such server for the common case. Each server serves ``cloudnav_web.asgi`` with the
# test settings against the test database (or ``database_url``), so data a transactional
# test writes is what the server sees. Extra environment (``env=``) overrides settings the
# server reads from the environment, e.g. ``REDIS_URL`` or ``CLOUDNAV_ROSBRIDGE_...``.

STARTUP_DEADLINE = 90.0
"""Seconds a daphne may take to answer: on a 2-core machine at load 20 it takes 20 s to
import and listen, and its first request several seconds more."""
BASE_DIR = Path(__file__).resolve().parent.parent


@dataclass
class LiveServer:
    """A daphne process serving the project on ``host:port``."""

    host: str
    port: int
    process: subprocess.Popen[bytes]
    log_path: Path

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    @property
    def ws_url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def rosbridge_url(self, token: str | None = None, path: str = "/rosbridge") -> str:
        return f"{self.ws_url}{path}" + (f"?token={token}" if token else "")

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def log_lines(self) -> int:
        return len(self.log().splitlines())

    def told_since(self, since: int) -> list[str]:
        """The log's lines after the first ``since`` (see ``log_lines``), but the access
        log's: what the server said of itself."""
        lines = self.log().splitlines()[since:]
        return [line for line in lines if "cloudnav_web.access" not in line]

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(10)


def agent_process(
    server_url: str, token: str, log: Path, *options: str
) -> contextlib.AbstractContextManager[Path]:
    """Run ``python -m robots.agent`` for one robot in its own process, logging to ``log``."""
    return _agent(server_url, log, "--token", token, *options)


def fleet_process(
    server_url: str, tokens: Path, count: int, log: Path, *options: str
) -> contextlib.AbstractContextManager[Path]:
    """Run the demo's robots as ``make demo`` does: one agent process for ``count`` robots
    of a ``seed_demo`` tokens file, at their default start and real time unless
    ``options`` (the agent's) say otherwise."""
    return _agent(server_url, log, "--tokens-file", str(tokens), "--count", str(count), *options)


@contextlib.contextmanager
def _agent(server_url: str, log: Path, *arguments: str) -> Iterator[Path]:
    command = [sys.executable, "-m", "robots.agent", "--server", server_url, *arguments]
    with log.open("wb") as out:
        process = subprocess.Popen(command, cwd=BASE_DIR, stdout=out, stderr=subprocess.STDOUT)
    try:
        yield log
    finally:
        process.terminate()
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(10)


def client_scenarios(
    command: list[str], server: LiveServer, building: Any, operator: User
) -> Callable[[str], dict[str, Any]]:
    """Return a runner of ``command NAME ARGS``: a client-library scenario in its own process.

    ARGS (JSON) holds the rosbridge URL, a robot token, the operator's session cookie and the
    origin; the scenario prints its findings as JSON on its last line.
    """
    from tests.conftest import make_robot

    args = {
        "url": server.rosbridge_url(),
        "token": make_robot(name="r1", buildings=[building])[1],
        "cookie": session_cookie(operator).decode(),
        "origin": server.url,
    }

    def run_scenario(name: str) -> dict[str, Any]:
        done = subprocess.run(
            [*command, name, json.dumps(args)],
            cwd=BASE_DIR,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert done.returncode == 0, done.stderr + "\n--- server log ---\n" + server.log()
        result: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
        return result

    return run_scenario


def seed_demo_token(tokens: Path, robot: str) -> str:
    """Seed the demo building with one robot and return ``robot``'s token."""
    from django.core.management import call_command

    call_command("seed_demo", "--robots", "1", "--tokens-file", str(tokens), stdout=io.StringIO())
    return str(json.loads(tokens.read_text())[robot])


async def until(
    check: Callable[[], bool | Awaitable[bool]], what: str = "the condition", wait: float = 5.0
) -> None:
    """Poll ``check`` (a function or a coroutine function) until it holds; fail naming
    ``what`` after ``wait`` seconds."""
    give_up = time.monotonic() + wait
    while True:
        held = check()
        if inspect.isawaitable(held):
            held = await held
        if held:
            return
        assert time.monotonic() < give_up, f"timed out waiting for {what}"
        await asyncio.sleep(0.02)


def wait_for(done: Callable[[], Any], seconds: float, what: str) -> Any:
    """Poll ``done`` until it returns something true, and return that; fail naming
    ``what`` after ``seconds``."""
    give_up = time.monotonic() + seconds
    while not (value := done()):
        assert time.monotonic() < give_up, f"timed out waiting for {what}"
        time.sleep(0.05)
    return value


def video_stats(url: str, token: str, timeout: float = 10.0) -> list[dict[str, Any]]:
    """The live server's video relays, as ``/api/video/stats`` lists them to robot ``token``."""
    request = urllib.request.Request(
        url + "/api/video/stats", headers={"Authorization": f"Token {token}"}
    )
    with urllib.request.urlopen(request, timeout=timeout) as response:
        return list(json.load(response)["streams"])


@pytest.fixture
def demo_token(transactional_db: None, tmp_path: Path) -> str:
    """The demo building, seeded with one robot (``robot_0``): that robot's token."""
    return seed_demo_token(tmp_path / "tokens.json", "robot_0")


@pytest.fixture
def operator_headers(daphne_server: LiveServer, demo_token: str) -> dict[str, str]:
    """Handshake headers of the demo operator's browser session, on the seeded demo."""
    return operator_handshake(daphne_server)


def operator_handshake(server: LiveServer) -> dict[str, str]:
    """Handshake headers of the demo operator's browser session."""
    cookie = session_cookie(User.objects.get(username="operator")).decode()
    return {"Cookie": cookie, "Origin": server.url}


def free_port(host: str = "127.0.0.1") -> int:
    with socket.socket() as probe:
        probe.bind((host, 0))
        return int(probe.getsockname()[1])


def tests_database_url() -> str:
    """Return a URL of the database the tests use, for a server process to open."""
    from django.db import connection

    settings_dict = connection.settings_dict
    if settings_dict["ENGINE"] == "django.db.backends.sqlite3":
        return f"sqlite:///{settings_dict['NAME']}"
    user, password = settings_dict.get("USER", ""), settings_dict.get("PASSWORD", "")
    credentials = f"{user}:{password}@" if password else (f"{user}@" if user else "")
    port = f":{settings_dict['PORT']}" if settings_dict.get("PORT") else ""
    return f"postgres://{credentials}{settings_dict['HOST']}{port}/{settings_dict['NAME']}"


def start_daphne(
    log_dir: Path,
    database_url: str,
    env: dict[str, str] | None = None,
    host: str = "127.0.0.1",
    attempts: int = 3,
) -> LiveServer:
    """Start daphne on a free port and return once it answers HTTP.

    Retries on a new port if the chosen one was taken meanwhile. Raises RuntimeError with
    the server's log if it does not come up within ``STARTUP_DEADLINE`` seconds.
    """
    return start_daphnes(1, log_dir, database_url, env, host, attempts)[0]


def start_daphnes(
    count: int,
    log_dir: Path,
    database_url: str,
    env: dict[str, str] | None = None,
    host: str = "127.0.0.1",
    attempts: int = 3,
) -> list[LiveServer]:
    """Start ``count`` daphne processes at once (see ``start_daphne``)."""
    environment = {
        **os.environ,
        "DJANGO_SETTINGS_MODULE": "cloudnav_web.settings_test",
        "DATABASE_URL": database_url,
        "REDIS_URL": "",
        "CLOUDNAV_LIVE_SERVER": "1",
        "PYTHONUNBUFFERED": "1",
        **(env or {}),
    }
    ready: list[LiveServer] = []
    for attempt in range(attempts):
        spawned = [spawn_daphne(log_dir, environment, host) for _ in range(count - len(ready))]
        for server in spawned:
            if wait_until_serving(server):
                ready.append(server)
                continue
            server.stop()
            if attempt == attempts - 1 or "Address already in use" not in server.log():
                for other in ready + spawned:
                    other.stop()
                raise RuntimeError(f"daphne did not start on port {server.port}:\n{server.log()}")
        if len(ready) == count:
            return ready
    raise AssertionError("unreachable")


def spawn_daphne(log_dir: Path, environment: dict[str, str], host: str) -> LiveServer:
    port = free_port(host)
    log_path = log_dir / f"daphne-{port}.log"
    with log_path.open("wb") as log:
        process = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "daphne",
                "-b",
                host,
                "-p",
                str(port),
                "--websocket_timeout",
                "-1",
                "cloudnav_web.asgi:application",
            ],
            cwd=BASE_DIR,
            env=environment,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    return LiveServer(host, port, process, log_path)


def wait_until_serving(server: LiveServer, deadline: float = STARTUP_DEADLINE) -> bool:
    """Poll the server with HTTP requests until it answers; False if it died or timed out."""
    give_up = time.monotonic() + deadline
    while (left := give_up - time.monotonic()) > 0 and server.process.poll() is None:
        try:
            # A short timeout aborts a first request that a busy machine serves slowly.
            with urllib.request.urlopen(f"{server.url}/api/", timeout=min(10.0, left)):
                return True
        except urllib.error.HTTPError:
            return True  # any HTTP answer means the application is up
        except OSError:
            time.sleep(0.05)
    return False


class LiveServers:
    """Starts daphne processes on demand and stops them all at the end of a test."""

    def __init__(self, log_dir: Path, database_url: str) -> None:
        self.log_dir = log_dir
        self.database_url = database_url
        self.started: list[LiveServer] = []

    def start(
        self, env: dict[str, str] | None = None, database_url: str | None = None
    ) -> LiveServer:
        server = start_daphne(self.log_dir, database_url or self.database_url, env)
        self.started.append(server)
        return server

    def start_many(self, count: int, env: dict[str, str] | None = None) -> list[LiveServer]:
        servers = start_daphnes(count, self.log_dir, self.database_url, env)
        self.started += servers
        return servers

    def stop_all(self) -> None:
        for server in self.started:
            server.stop()


@pytest.fixture
def daphne_servers(transactional_db: None, tmp_path: Path) -> Iterator[LiveServers]:
    """A factory of live daphne servers on the test database; ``.start(env=...)``."""
    servers = LiveServers(tmp_path, tests_database_url())
    yield servers
    servers.stop_all()


@pytest.fixture
def daphne_server(daphne_servers: LiveServers) -> LiveServer:
    """One live daphne server (embedded mode) on the test database."""
    return daphne_servers.start()


# The access-log level at which the unchanged checks (304) are written too.
ACCESS_LOG_ALL = {"CLOUDNAV_ACCESS_LOG_LEVEL": "DEBUG"}


# ---------------------------------------------------------------- scaled mode
#
# ``scaled_servers`` gives several daphne processes sharing a real Redis (channel layer and
# rosbridge state) and a real PostgreSQL database created for the test and dropped after.
# Defaults are the services this machine runs; the environment can point elsewhere:
# ``CLOUDNAV_TEST_REDIS_URL`` (else ``REDIS_URL``) and ``CLOUDNAV_TEST_POSTGRES_URL``, a
# URL of the server's maintenance database, used to create and drop the test's own.

DEFAULT_REDIS_URL = "redis://127.0.0.1:6379/13"
DEFAULT_POSTGRES_URL = "postgres://postgres@127.0.0.1:5432/postgres"


def worker_index() -> int:
    """This pytest process's number among pytest-xdist's workers (``gw0`` is 0), 0 alone."""
    return int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw") or 0)


def scaled_redis_url() -> str:
    """The Redis database of this pytest process: the configured one, plus the worker's
    number, so that workers running at once never flush each other's."""
    configured = os.environ.get("CLOUDNAV_TEST_REDIS_URL") or os.environ.get("REDIS_URL")
    url = configured or DEFAULT_REDIS_URL
    parts = urllib.parse.urlsplit(url)
    database = int(parts.path.strip("/") or 0) + worker_index()
    return urllib.parse.urlunsplit(parts._replace(path=f"/{database}"))


def scaled_postgres_url() -> str:
    return os.environ.get("CLOUDNAV_TEST_POSTGRES_URL") or DEFAULT_POSTGRES_URL


@dataclass
class ScaledCluster:
    """Server processes sharing Redis and PostgreSQL, and the people and robots seeded there.

    ``tokens``: robot name -> token; ``cookies``: username -> session cookie header value;
    ``database_url``: the database they share.
    """

    servers: list[LiveServer]
    tokens: dict[str, str]
    cookies: dict[str, str]
    database_url: str = ""
    spawn: Callable[[], LiveServer] | None = None

    def kill(self, index: int) -> None:
        """Kill server ``index`` at once (SIGKILL, as a crash)."""
        self.servers[index].process.kill()
        self.servers[index].process.wait(10)

    def replace(self, index: int) -> LiveServer:
        """Kill server ``index`` (see ``kill``) and start a new process in its place, on the
        same Redis and database; return the new one."""
        assert self.spawn is not None
        self.kill(index)
        self.servers[index] = self.spawn()
        return self.servers[index]


def run_manage(database_url: str, *args: str) -> str:
    env = {
        **os.environ,
        "DJANGO_SETTINGS_MODULE": "cloudnav_web.settings_test",
        "DATABASE_URL": database_url,
        "CLOUDNAV_LIVE_SERVER": "1",
        "REDIS_URL": "",
    }
    done = subprocess.run(
        [sys.executable, *args], cwd=BASE_DIR, env=env, capture_output=True, text=True, timeout=300
    )
    if done.returncode != 0:
        raise RuntimeError(f"{args} failed:\n{done.stdout}\n{done.stderr}")
    return done.stdout


PEOPLE = [("operator", "operator"), ("operator2", "operator"), ("viewer", "viewer")]
SEED = """
import json, django
django.setup()
from tests.fixtures_live import seed_fleet
print(json.dumps(seed_fleet()))
"""


def seed_fleet() -> dict[str, dict[str, str]]:
    """Create a building with ``PEOPLE`` as members and robots r1, r2; return their
    credentials. Runs in a process of its own against the scaled database."""
    from tests.conftest import make_building, make_robot, make_submap, make_user

    people = [make_user(name, role) for name, role in PEOPLE]
    building = make_building(members=people)
    make_submap(building, code="Hall")  # goals are checked against their sub-map
    tokens = {name: make_robot(name=name, buildings=[building])[1] for name in ("r1", "r2")}
    cookies = {user.username: session_cookie(user).decode() for user in people}
    return {"tokens": tokens, "cookies": cookies}


@contextlib.contextmanager
def postgres_database(admin_url: str, template: str | None = None) -> Iterator[str]:
    """Create a fresh database (a copy of ``template`` if given) on the server of
    ``admin_url``; yield its URL; drop it."""
    import psycopg

    name = f"cloudnav_scaled_{os.getpid()}_{next(_database_numbers)}"
    copy = f' TEMPLATE "{template}"' if template else ""
    with psycopg.connect(admin_url, autocommit=True) as admin:
        admin.execute(f'CREATE DATABASE "{name}"{copy}')
    try:
        parts = urllib.parse.urlsplit(admin_url)
        yield urllib.parse.urlunsplit(parts._replace(path=f"/{name}"))
    finally:
        with psycopg.connect(admin_url, autocommit=True) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


_database_numbers = itertools.count(1)


def flush_redis(url: str) -> None:
    import redis

    client = redis.Redis.from_url(url)
    client.flushdb()
    client.close()


class PrivateRedis:
    """A redis-server of this test's own on a free port (never the shared one), to stop and
    start again: ``url``, ``restart(down=seconds)``."""

    def __init__(self, directory: Path) -> None:
        self.port = free_port()
        self.url = f"redis://127.0.0.1:{self.port}/0"
        self.directory = directory
        self.process: subprocess.Popen[bytes] | None = None
        self.start()

    def start(self) -> None:
        command = ["redis-server", "--port", str(self.port), "--bind", "127.0.0.1"]
        options = ["--save", "", "--appendonly", "no", "--dir", str(self.directory)]
        self.process = subprocess.Popen(
            [*command, *options], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        give_up = time.monotonic() + STARTUP_DEADLINE
        while not self._answers():
            assert time.monotonic() < give_up, "redis-server did not start"
            time.sleep(0.05)

    def _answers(self) -> bool:
        import redis

        try:
            return bool(redis.Redis.from_url(self.url, socket_timeout=1).ping())
        except redis.RedisError:
            return False

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.kill()  # empty when it starts again, as a restarted cache would be
            self.process.wait(10)

    def restart(self, down: float = 0.0) -> None:
        self.stop()
        time.sleep(down)  # the outage itself is what is tested
        self.start()


@pytest.fixture
def private_redis(tmp_path: Path) -> Iterator[PrivateRedis]:
    server = PrivateRedis(tmp_path)
    yield server
    server.stop()


class PrivatePostgres:
    """A PostgreSQL cluster of this test's own (``initdb`` on a free port, never the shared
    server), holding a copy of a database, to stop and start again: ``url`` (of the copy),
    ``restart(down=seconds)``."""

    def __init__(self, source_url: str) -> None:
        binaries = sorted(Path("/usr/lib/postgresql").glob("*/bin/pg_ctl"), key=_version)
        if not binaries:
            pytest.skip("PostgreSQL's server binaries are absent: make setup installs them")
        self.bin = binaries[-1].parent
        # Outside the test's directory: initdb refuses root, and its user must reach this.
        self.directory = Path(tempfile.mkdtemp(prefix="cloudnav-pg-"))
        if os.geteuid() == 0:
            shutil.chown(self.directory, "postgres")
        self.port = free_port()
        self._as_owner("initdb", "-D", "data", "-U", "postgres", "--auth=trust", "-N")
        self.start()
        self.url = f"postgres://postgres@127.0.0.1:{self.port}/cloudnav"
        self._copy(source_url)

    def _as_owner(self, program: str, *arguments: str) -> None:
        owner = ["runuser", "-u", "postgres", "--"] if os.geteuid() == 0 else []
        command = [*owner, str(self.bin / program), *arguments]
        subprocess.run(command, cwd=self.directory, check=True, capture_output=True, timeout=120)

    def _copy(self, source_url: str) -> None:
        import psycopg

        admin_url = f"postgres://postgres@127.0.0.1:{self.port}/postgres"
        with psycopg.connect(admin_url, autocommit=True) as admin:
            admin.execute("CREATE DATABASE cloudnav")
        dump = subprocess.run(
            [self.bin / "pg_dump", "--no-owner", "--no-privileges", "-d", source_url],
            check=True,
            capture_output=True,
            timeout=120,
        )
        subprocess.run(
            [self.bin / "psql", "-q", "-v", "ON_ERROR_STOP=1", "-d", self.url],
            input=dump.stdout,
            check=True,
            capture_output=True,
            timeout=120,
        )

    def start(self) -> None:
        options = f"-h 127.0.0.1 -p {self.port} -k {self.directory} -F"
        self._as_owner("pg_ctl", "-D", "data", "-l", "server.log", "-o", options, "-w", "start")

    def stop(self) -> None:
        """Stop at once (``immediate``: no checkpoint, connections cut, as a crash)."""
        self._as_owner("pg_ctl", "-D", "data", "-m", "immediate", "-w", "stop")

    def restart(self, down: float = 0.0) -> None:
        self.stop()
        time.sleep(down)  # the outage itself is what is tested
        self.start()

    def remove(self) -> None:
        with contextlib.suppress(subprocess.CalledProcessError):
            self.stop()
        shutil.rmtree(self.directory, ignore_errors=True)


def _version(pg_ctl: Path) -> tuple[int, ...]:
    return tuple(int(part) for part in pg_ctl.parent.parent.name.split("."))


@pytest.fixture
def private_postgres(scaled_template: tuple[str, dict[str, Any]]) -> Iterator[PrivatePostgres]:
    """A ``PrivatePostgres`` holding a copy of the seeded scaled database."""
    parts = urllib.parse.urlsplit(scaled_postgres_url())
    source = urllib.parse.urlunsplit(parts._replace(path=f"/{scaled_template[0]}"))
    server = PrivatePostgres(source)
    yield server
    server.remove()


@pytest.fixture(scope="session")
def scaled_template() -> Iterator[tuple[str, dict[str, Any]]]:
    """A PostgreSQL database migrated and seeded once per run, copied by each scaled test;
    yields its name and the seeded credentials."""
    with postgres_database(scaled_postgres_url()) as url:
        run_manage(url, "manage.py", "migrate", "--noinput")
        seeded = json.loads(run_manage(url, "-c", SEED).strip().splitlines()[-1])
        yield urllib.parse.urlsplit(url).path.lstrip("/"), seeded


@pytest.fixture
def scaled_servers(
    tmp_path: Path, scaled_template: tuple[str, dict[str, Any]]
) -> Iterator[Callable[..., ScaledCluster]]:
    """``scaled_servers(2, env=...)``: that many daphne processes in scaled mode on a fresh copy of
    the seeded database and an emptied Redis; all stopped and dropped after the test."""
    template, seeded = scaled_template
    redis_url = scaled_redis_url()
    with contextlib.ExitStack() as stack:

        def start(count: int = 2, env: dict[str, str] | None = None) -> ScaledCluster:
            database_url = stack.enter_context(postgres_database(scaled_postgres_url(), template))
            flush_redis(redis_url)
            environment = {"REDIS_URL": redis_url, **(env or {})}

            def spawn(count: int = 1) -> list[LiveServer]:
                servers = start_daphnes(count, tmp_path, database_url, environment)
                for server in servers:
                    stack.callback(server.stop)  # before the drop
                return servers

            return ScaledCluster(
                spawn(count),
                seeded["tokens"],
                seeded["cookies"],
                database_url,
                spawn=lambda: spawn()[0],
            )

        yield start


# ``nginx_front``: a real nginx (Debian's package, installed by scripts/setup.sh) in front
# of a scaled cluster, configured as ``make demo-scaled`` configures it (cloudnav_web/front.py)
# and run as this user from the test's directory.


def nginx_binary() -> str | None:
    return shutil.which("nginx") or next(
        (path for path in ("/usr/sbin/nginx",) if os.access(path, os.X_OK)), None
    )


@dataclass
class Front:
    """nginx on ``server`` (a ``LiveServer``: ``url``, ``rosbridge_url``, ...) spreading
    connections over ``cluster``'s processes; it names the process that answered each
    handshake in ``UPSTREAM_HEADER``."""

    server: LiveServer
    cluster: ScaledCluster

    def process_of(self, headers: Any) -> int:
        """The index in ``cluster.servers`` of the process behind a response's ``headers``."""
        from cloudnav_web.front import UPSTREAM_HEADER

        upstream = headers[UPSTREAM_HEADER].split(",")[-1].strip()  # the last one tried
        return next(
            index
            for index, live in enumerate(self.cluster.servers)
            if f"{live.host}:{live.port}" == upstream
        )


@pytest.fixture
def nginx_front(tmp_path: Path) -> Iterator[Callable[[ScaledCluster], Front]]:
    """``nginx_front(cluster)``: a ``Front`` over ``cluster``'s processes, on a free port;
    stopped after the test. Skips when nginx is absent (``make setup`` installs it)."""
    from cloudnav_web.front import write_config

    nginx = nginx_binary()
    if nginx is None:
        pytest.skip("nginx is not installed: make setup (scripts/setup.sh) installs Debian's")
    started: list[LiveServer] = []

    def start(cluster: ScaledCluster) -> Front:
        directory = tmp_path / f"nginx-{len(started)}"
        port = free_port()
        upstreams = [f"{live.host}:{live.port}" for live in cluster.servers]
        config = write_config(upstreams, f"127.0.0.1:{port}", directory, show_upstream=True)
        log_path = directory / "error.log"
        with (directory / "stdout.log").open("wb") as out:
            process = subprocess.Popen(
                [nginx, "-p", str(directory), "-c", str(config)], stdout=out, stderr=out
            )
        server = LiveServer("127.0.0.1", port, process, log_path)
        started.append(server)
        if not wait_until_serving(server):
            raise RuntimeError(f"nginx did not start:\n{(directory / 'stdout.log').read_text()}")
        return Front(server, cluster)

    yield start
    for server in started:
        server.stop()


# ``rosbridge_across_processes``: the rosbridge fixture's clients, on two live server
# processes in scaled mode over the test database, for tests parametrised to run in both
# modes (the same rules and behaviour, whichever process each party is on).

CROSS_PROCESS_SETTLE = 2.0  # how long "nothing arrived" is waited for across processes


@pytest.fixture
async def rosbridge_across_processes(
    daphne_servers: LiveServers,
) -> AsyncIterator[Callable[..., Awaitable[RosClient]]]:
    """``await connect(process, token=...)`` or ``connect(process, user=...)``: a
    ``RosClient`` on server process 0 or 1 of two sharing Redis and the test database.
    Raises Refused when the handshake is refused. All closed at the end."""
    import websockets

    redis_url = scaled_redis_url()
    flush_redis(redis_url)
    servers = daphne_servers.start_many(2, env={"REDIS_URL": redis_url})
    opened: list[RosClient] = []

    async def connect(
        process: int, token: str | None = None, user: User | None = None
    ) -> RosClient:
        from channels.db import database_sync_to_async

        server = servers[process]
        headers = {}
        if user is not None:
            cookie = await database_sync_to_async(session_cookie)(user)
            headers = {"Cookie": cookie.decode(), "Origin": server.url}
        try:
            socket = await websockets.connect(
                server.rosbridge_url(token), additional_headers=headers, open_timeout=TIMEOUT * 3
            )
        except websockets.InvalidStatus as refused:
            raise Refused(server.rosbridge_url()) from refused
        client = RosClient(SocketCommunicator(socket), settle=CROSS_PROCESS_SETTLE)
        opened.append(client)
        return client

    yield connect
    for client in opened:
        await client.close()
