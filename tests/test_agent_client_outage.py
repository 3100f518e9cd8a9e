"""The robot's rosbridge client through a cloud outage, over real sockets to a real daphne:
it retries with backoff and jitter, and on return it restores what it declared and sends
only fresh messages at its rates, never what piled up while the cloud was away.

The robot reaches the server through ``Link``, a TCP relay the test cuts and restores; an
operator watches the robot's topics on a connection of its own, straight to the server.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import math
import random
import socket
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import pytest
import websockets

from cloudnav_core.messages import (
    laser_scan,
    odometry,
    pose_stamped,
    string_message,
    twist_2d,
)
from cloudnav_core.topics import CANCEL_GOAL, ROBOT_SERVICE_TYPES, ROBOT_TOPIC_TYPES
from robots.agent.client import Backoff, RosbridgeClient
from robots.agent.hardware import compressed_image_message
from robots.agent.whereabouts import Localisation, Whereabouts
from telemetry.rosbridge.cloud import TELEOP_LOCK
from tests.conftest import make_robot
from tests.fixtures_live import LiveServer, operator_handshake, until

BACKOFF = Backoff(initial=0.2, factor=2.0, maximum=1.6)
SEED = 7
ATTEMPTS_WHILE_DOWN = 6
# How late a reconnection attempt or a frame may come on a loaded 2-core machine.
SLACK = 0.5
DEADLINE = 30.0
RATES = {"pose": 10.0, "odom": 10.0, "scan": 5.0}  # the robot's defaults (RobotConfig)
MAP_ID = "boccioni_1/CorridorA@v1"
# A camera frame as incompressible as a JPEG, for a stream that fills a stalled link.
FRAME = random.Random(1).randbytes(50_000)
KEEPALIVE = 1.0
SCAN = {
    "angle_min": -math.pi, "angle_max": math.pi, "angle_increment": math.tau / 360,
    "time_increment": 0.0, "scan_time": 0.2, "range_min": 0.1, "range_max": 10.0,
}  # fmt: skip


class Link:
    """A TCP relay between the robot and the server that the test can cut.

    While cut, the relayed connections are dropped and every new connection is accepted
    only to note when it came (``attempts``, loop time) and be closed at once.
    """

    def __init__(self, server: LiveServer) -> None:
        self.server = server
        self.cut = False
        self.attempts: list[float] = []
        self._relayed: set[asyncio.StreamWriter] = set()
        self._listener: asyncio.Server | None = None

    async def open(self) -> str:
        """Start relaying; return the rosbridge URL through the link."""
        listening = socket.socket()
        # Little room in flight, as on a radio link (loopback would hold megabytes).
        listening.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 2**14)
        listening.bind(("127.0.0.1", 0))
        self._listener = await asyncio.start_server(self._accept, sock=listening)
        port = listening.getsockname()[1]
        return f"ws://127.0.0.1:{port}/rosbridge"

    def go_down(self, *, silently: bool = False) -> None:
        """Cut the link: the relayed connections are reset, or with ``silently`` left
        open but carrying nothing, as when a radio link goes (reset on return: by then
        both ends have given them up)."""
        self.cut = True
        for writer in self._relayed:
            if silently:
                cast(asyncio.Transport, writer.transport).pause_reading()
            else:
                writer.transport.abort()

    def come_back(self) -> None:
        for writer in self._relayed:
            writer.transport.abort()
        self.cut = False

    async def close(self) -> None:
        self.go_down()
        if self._listener is not None:
            self._listener.close()

    async def _accept(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if self.cut:
            self.attempts.append(asyncio.get_running_loop().time())
            writer.transport.abort()
            return
        upstream_reader, upstream = await asyncio.open_connection(
            self.server.host, self.server.port
        )
        self._relayed |= {writer, upstream}
        try:
            await asyncio.gather(relay(reader, upstream), relay(upstream_reader, writer))
        finally:
            self._relayed -= {writer, upstream}


async def relay(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    try:
        while data := await reader.read(65536):
            writer.write(data)
            await writer.drain()
    except OSError:
        pass
    finally:
        writer.transport.abort()


@dataclass
class Heard:
    topic: str
    msg: dict[str, Any]
    at: float  # wall clock


@dataclass
class Operator:
    """An operator's connection, keeping every frame it hears."""

    ws: Any
    heard: list[Heard] = field(default_factory=list)
    replies: dict[str, dict[str, Any]] = field(default_factory=dict)

    async def listen(self) -> None:
        async for data in self.ws:
            frame = json.loads(data)
            if frame.get("op") == "publish":
                self.heard.append(Heard(frame["topic"], frame["msg"], time.time()))
            elif frame.get("op") == "service_response":
                self.replies[frame["id"]] = frame

    def on(self, topic: str, since: float = 0.0) -> list[Heard]:
        return [h for h in self.heard if h.topic == topic and h.at >= since]

    async def send(self, **frame: Any) -> None:
        await self.ws.send(json.dumps(frame))


@dataclass
class Robot:
    """A robot publishing its pose, odometry and scan at its rates, wall-clock stamped,
    whether or not the cloud is there."""

    client: RosbridgeClient
    rates: dict[str, float] = field(default_factory=lambda: dict(RATES))
    dropped: int = 0
    slowest: float = 0.0  # seconds, the longest a publication kept the robot waiting
    commands: list[dict[str, Any]] = field(default_factory=list)

    def declare(self) -> None:
        for topic in self.rates:
            self.client.advertise(topic, ROBOT_TOPIC_TYPES[topic])
        for latched in ("map_id", "localisation"):
            self.client.advertise(latched, ROBOT_TOPIC_TYPES[latched], latch=True)
        self.client.subscribe("cmd_vel", ROBOT_TOPIC_TYPES["cmd_vel"], self.commands.append)
        service_type = ROBOT_SERVICE_TYPES[CANCEL_GOAL]
        self.client.advertise_service(CANCEL_GOAL, service_type, lambda _: {"success": True})

    async def run(self) -> None:
        loop = asyncio.get_running_loop()
        next_at = {topic: loop.time() for topic in self.rates}
        while True:
            topic = min(next_at, key=next_at.__getitem__)
            await asyncio.sleep(max(0.0, next_at[topic] - loop.time()))
            next_at[topic] += 1 / self.rates[topic]
            started = loop.time()
            sent = await self.client.publish(topic, message(topic, time.time()))
            self.slowest = max(self.slowest, loop.time() - started)
            self.dropped += not sent


def message(topic: str, stamp: float) -> Any:
    if topic == "pose":
        return pose_stamped(MAP_ID, (1.0, 2.0, 0.0), stamp)
    if topic == "odom":
        still = np.zeros((3, 3))
        pose = (1.0, 2.0, 0.0)
        return odometry(
            "odom",
            "base_footprint",
            stamp,
            pose=pose,
            pose_covariance=still,
            velocity=(0.0, 0.0),
            velocity_covariance=still,
        )
    if topic == "scan":
        return laser_scan("base_laser", [1.0] * 360, stamp, **SCAN)
    return compressed_image_message(FRAME, stamp)


@pytest.fixture
def token(building) -> str:
    return make_robot(name="r1", buildings=[building])[1]


@pytest.fixture
def handshake(daphne_server: LiveServer, token: str) -> dict[str, str]:
    return operator_handshake(daphne_server)


@pytest.fixture
async def link(daphne_server: LiveServer) -> AsyncIterator[Link]:
    cut = Link(daphne_server)
    yield cut
    await cut.close()


@contextlib.asynccontextmanager
async def running(*coroutines: Any) -> AsyncIterator[None]:
    tasks = [asyncio.create_task(coroutine) for coroutine in coroutines]
    try:
        yield
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)


def stamp_of(msg: dict[str, Any]) -> float:
    return float(msg["header"]["stamp"]["sec"] + msg["header"]["stamp"]["nanosec"] / 1e9)


def largest_count_in_a_second(times: list[float]) -> int:
    return max((sum(t <= at < t + 1.0 for at in times) for t in times), default=0)


@contextlib.asynccontextmanager
async def watched_robot(
    link: Link, server: LiveServer, handshake: dict[str, str], robot: Robot
) -> AsyncIterator[Operator]:
    """Run ``robot`` through ``link`` with an operator watching its pose and latched
    topics; yield the operator once poses flow."""
    client = robot.client
    robot.declare()
    async with (
        websockets.connect(server.rosbridge_url(), additional_headers=handshake) as ws,
        running(client.run()),
    ):
        operator = Operator(ws)
        async with running(operator.listen()):
            for topic in ("pose", "map_id", "localisation"):
                await operator.send(op="subscribe", topic=f"/r1/{topic}")
            await asyncio.wait_for(client.wait_connected(), DEADLINE)
            await client.call_service("/rosapi/get_time")  # the declarations were handled
            await client.publish("map_id", string_message(MAP_ID))
            place = Whereabouts(Localisation.LOCALISED, MAP_ID, "tag 3")
            await client.publish("localisation", dict(place.status()))
            async with running(robot.run()):
                await until(lambda: len(operator.on("/r1/pose")) >= 5, "poses", DEADLINE)
                yield operator


async def back_for_two_seconds(link: Link, client: RosbridgeClient, operator: Operator) -> float:
    """Restore ``link``; return the wall clock when the client reconnected, once two
    seconds of poses have followed."""
    link.come_back()
    await until(lambda: client.connections == 2, "the reconnection", DEADLINE)
    back = time.time()
    await until(
        lambda: any(h.at >= back + 2.0 for h in operator.on("/r1/pose")),
        "two seconds of poses after the reconnection",
        DEADLINE,
    )
    return back


def assert_only_fresh_poses(operator: Operator, went_down: float, back: float) -> None:
    """What was published while the cloud was away never reached it; poses came again
    at the robot's rate, no burst of queued ones."""
    after = operator.on("/r1/pose", since=went_down)
    assert min(stamp_of(heard.msg) for heard in after) >= back - SLACK
    assert largest_count_in_a_second([heard.at for heard in after]) <= RATES["pose"] + 3
    assert len(operator.on("/r1/pose", since=back + 0.5)) >= 10


async def test_after_an_outage_it_reconnects_with_backoff_and_sends_only_fresh_messages(
    daphne_server: LiveServer, link: Link, token: str, handshake: dict[str, str]
) -> None:
    client = RosbridgeClient(await link.open(), token, backoff=BACKOFF, seed=SEED)
    robot = Robot(client)
    async with watched_robot(link, daphne_server, handshake, robot) as operator:
        went_down = time.time()
        down_at = asyncio.get_running_loop().time()
        link.go_down()
        await until(lambda: len(link.attempts) >= ATTEMPTS_WHILE_DOWN, "retries", DEADLINE)
        dropped_while_down = robot.dropped
        back = await back_for_two_seconds(link, client, operator)

        lock = {"robot": "r1", "action": "acquire"}
        await operator.send(op="call_service", id="lock", service=TELEOP_LOCK, args=lock)
        await until(lambda: "lock" in operator.replies, "the teleop lock", DEADLINE)
        await operator.send(op="publish", topic="/r1/cmd_vel", msg=twist_2d(0.1, 0.0))
        await operator.send(op="call_service", id="cancel", service=f"/r1/{CANCEL_GOAL}")
        await until(
            lambda: bool(robot.commands) and "cancel" in operator.replies, "commands", DEADLINE
        )

    # Retries are spaced by the client's jittered backoff, drawn from its seeded generator:
    # the first after the loss, then one more per failed attempt.
    rng = random.Random(SEED)
    delays = [BACKOFF.delay(attempt, rng) for attempt in range(ATTEMPTS_WHILE_DOWN)]
    attempts = [down_at, *link.attempts[:ATTEMPTS_WHILE_DOWN]]
    waited = [later - earlier for earlier, later in itertools.pairwise(attempts)]
    for seconds, delay in zip(waited, delays, strict=True):
        assert delay - 0.01 <= seconds <= delay + SLACK, (waited, delays)
    # This seed draws delays well below their ceilings: matching them shows the jitter.
    ceilings = [min(BACKOFF.maximum, BACKOFF.initial * BACKOFF.factor**n) for n in range(6)]
    assert any(delay < ceiling - SLACK for delay, ceiling in zip(delays, ceilings, strict=True))

    # The robot kept publishing while the cloud was away, and none of that was sent late.
    assert dropped_while_down >= 20
    assert_only_fresh_poses(operator, went_down, back)

    # The latched topics were sent again once each; the subscription and service are back.
    assert [h.msg for h in operator.on("/r1/map_id", since=went_down)] == [{"data": MAP_ID}]
    assert len(operator.on("/r1/localisation", since=went_down)) == 1
    assert robot.commands[0]["linear"]["x"] == 0.1
    assert operator.replies["cancel"]["result"] is True


async def test_a_link_gone_silent_never_blocks_the_robot_and_is_given_up_in_time(
    daphne_server: LiveServer, link: Link, token: str, handshake: dict[str, str]
) -> None:
    client = RosbridgeClient(
        await link.open(), token, backoff=BACKOFF, seed=SEED, keepalive=KEEPALIVE
    )
    # The robot streams its camera too, so the silent link's buffers fill.
    robot = Robot(client, rates={**RATES, "camera/image/compressed": 10.0})
    async with watched_robot(link, daphne_server, handshake, robot) as operator:
        went_down = time.time()
        down_at = asyncio.get_running_loop().time()
        link.go_down(silently=True)
        await until(lambda: len(link.attempts) >= 2, "retries", DEADLINE)
        back = await back_for_two_seconds(link, client, operator)

    # Given up after a keepalive's ping interval, timeout and close timeout at most.
    assert link.attempts[0] - down_at <= 3 * KEEPALIVE + BACKOFF.initial + SLACK
    # No publication waited on the dead link longer than its bounded send.
    assert robot.slowest <= KEEPALIVE / 10 + SLACK
    assert robot.dropped >= 10
    assert_only_fresh_poses(operator, went_down, back)
