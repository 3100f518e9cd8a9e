"""The robot's rosbridge client against a real daphne: reconnection, no stale poses,
latched messages, service calls both ways."""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import AsyncIterator, Callable

import pytest
import websockets

from cloudnav_core.messages import pose_stamped, string_message
from robots.agent.client import Backoff, NotConnected, RosbridgeClient, ServiceError
from tests import fixtures_live
from tests.conftest import make_robot
from tests.fixtures_live import LiveServer, LiveServers, until

FAST = Backoff(initial=0.1, factor=2.0, maximum=0.5)
DEADLINE = 15.0


@pytest.fixture
def tokens(building):
    return {name: make_robot(name=name, buildings=[building])[1] for name in ("r1", "r2")}


@pytest.fixture
async def running() -> AsyncIterator[Callable[[RosbridgeClient], RosbridgeClient]]:
    """Start clients' ``run`` loops; all closed at the end."""
    started: list[tuple[RosbridgeClient, asyncio.Task[None]]] = []

    def start(client: RosbridgeClient) -> RosbridgeClient:
        started.append((client, asyncio.create_task(client.run())))
        return client

    yield start
    for client, task in started:
        await client.close()
        await asyncio.wait_for(task, 5)


def restart_on_same_port(servers: LiveServers, server: LiveServer, monkeypatch) -> LiveServer:
    """Stop ``server`` and start a fresh daphne (knowing nothing) on its port."""
    server.stop()
    monkeypatch.setattr(fixtures_live, "free_port", lambda _host="127.0.0.1": server.port)
    return servers.start()


def stamp_of(msg: dict) -> float:
    stamp = msg["header"]["stamp"]
    return stamp["sec"] + stamp["nanosec"] / 1e9


async def publish_poses(client: RosbridgeClient, stop: asyncio.Event) -> None:
    """Publish the robot's pose at 20 Hz, stamped with the wall clock, as a robot does."""
    while not stop.is_set():
        await client.publish("pose", pose_stamped("boccioni_1/CorridorA", (1, 2, 0), time.time()))
        await asyncio.sleep(0.05)


async def test_it_reconnects_after_a_restart_and_sends_no_stale_pose(
    daphne_servers, tokens, running, monkeypatch
):
    server = daphne_servers.start()
    client = RosbridgeClient(server.rosbridge_url(), tokens["r1"], backoff=FAST, seed=1)
    received: list[dict] = []
    client.advertise("pose", "geometry_msgs/PoseStamped")
    # The robot listens to its own pose: that subscription is declared again before any
    # publication on a new connection, so a stale pose sent on reconnecting would land here.
    client.subscribe("pose", "geometry_msgs/PoseStamped", received.append)
    running(client)
    stop = asyncio.Event()
    publisher = asyncio.create_task(publish_poses(client, stop))
    await until(lambda: len(received) >= 3, "poses before the restart", DEADLINE)

    went_down = time.time()
    restart_on_same_port(daphne_servers, server, monkeypatch)
    await until(lambda: client.connections == 2, "the reconnection", DEADLINE)
    reconnected = time.time()
    count = len(received)
    await until(lambda: len(received) >= count + 3, "poses after the restart", DEADLINE)
    stop.set()
    await publisher

    after = [stamp_of(m) for m in received if stamp_of(m) > went_down]
    # Whatever was published while the server was away was dropped, not sent late.
    assert after
    assert min(after) >= reconnected - 0.2


async def test_a_latched_message_is_sent_again_to_a_restarted_server(
    daphne_servers, tokens, running, monkeypatch
):
    server = daphne_servers.start()
    client = running(RosbridgeClient(server.rosbridge_url(), tokens["r1"], backoff=FAST))
    client.advertise("map_id", "std_msgs/String", latch=True)
    await asyncio.wait_for(client.wait_connected(), DEADLINE)
    assert await client.publish("map_id", string_message("boccioni_1/Atrium1"))

    restarted = restart_on_same_port(daphne_servers, server, monkeypatch)
    await until(lambda: client.connections == 2, "the reconnection", DEADLINE)
    await client.call_service("/rosapi/get_time")  # the declarations were handled
    async with websockets.connect(restarted.rosbridge_url(tokens["r2"])) as observer:
        await observer.send(json.dumps({"op": "subscribe", "topic": "/r1/map_id"}))
        frame = json.loads(await asyncio.wait_for(observer.recv(), 5))
    assert frame["msg"] == {"data": "boccioni_1/Atrium1"}


async def test_it_drops_publications_while_disconnected(tokens):
    client = RosbridgeClient("ws://127.0.0.1:9/rosbridge", tokens["r1"])
    client.advertise("pose", "geometry_msgs/PoseStamped")
    assert await client.publish("pose", pose_stamped("m", (0, 0, 0), 0.0)) is False
    with pytest.raises(NotConnected):
        await client.call_service("/rosapi/get_time")


async def test_service_calls_are_answered_by_id_or_fail_or_time_out(daphne_server, tokens, running):
    client = RosbridgeClient(daphne_server.rosbridge_url(), tokens["r1"], call_timeout=0.3)
    never = asyncio.Event()

    async def stalls(args: object) -> dict:
        await never.wait()
        return {}

    client.advertise_service("stall", "std_srvs/Trigger", stalls)
    running(client)
    await asyncio.wait_for(client.wait_connected(), DEADLINE)
    first, second = await asyncio.gather(
        client.call_service("/rosapi/get_time"), client.call_service("rosapi/get_time")
    )
    assert "sec" in first["time"]
    assert "sec" in second["time"]
    with pytest.raises(ServiceError):
        await client.call_service("/r1/nobody_serves_this")
    with pytest.raises(TimeoutError):
        await client.call_service("stall")


async def test_it_serves_its_services_to_an_operator_connection(daphne_server, tokens, running):
    client = RosbridgeClient(daphne_server.rosbridge_url(), tokens["r1"])
    client.advertise_service("echo", "std_srvs/Trigger", lambda _args: {"message": "yes"})
    running(client)
    await asyncio.wait_for(client.wait_connected(), DEADLINE)
    await client.call_service("/rosapi/get_time")  # the advertisement was handled
    # A robot may call its own services; its answer comes back routed by id.
    assert await client.call_service("echo") == {"message": "yes"}


def test_backoff_grows_with_jitter_up_to_its_maximum():
    import random

    backoff, rng = Backoff(initial=0.5, factor=2.0, maximum=4.0), random.Random(3)
    delays = [backoff.delay(attempt, rng) for attempt in range(6)]
    for attempt, delay in enumerate(delays):
        ceiling = min(4.0, 0.5 * 2**attempt)
        assert ceiling / 2 <= delay <= ceiling
